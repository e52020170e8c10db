//! The live plots tab (to be filled).

use crate::app::GantryApp;

#[derive(Debug, Default)]
pub struct Plots {}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.label(format!("{} samples", app.live.history.len()));
}
