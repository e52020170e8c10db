//! The identification tab (to be filled).

use crate::app::GantryApp;

#[derive(Debug, Default)]
pub struct IdentifyPanel {
    pub results: Vec<host_sim::cli::IdentifyJson>,
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.label(format!("{} results", app.identify.results.len()));
}
