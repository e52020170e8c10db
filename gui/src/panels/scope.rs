//! The scope tab (to be filled).

use crate::app::GantryApp;

#[derive(Debug, Default)]
pub struct ScopePanel {
    pub capture: Option<host_sim::cli::scope::Capture>,
}

pub fn show(_app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.label("scope");
}
