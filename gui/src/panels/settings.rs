//! The settings tab (to be filled).

use crate::app::GantryApp;

#[derive(Debug, Default)]
pub struct SettingsPanel {
    pub values: Vec<(String, String)>,
}

impl SettingsPanel {
    pub fn set_values(&mut self, all: Vec<(String, String)>) {
        self.values = all;
    }
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.label(format!("{} settings", app.settings.values.len()));
}
