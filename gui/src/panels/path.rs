//! The tool path tab (to be filled: 2-D and 3-D views, live position, trail by contour error).

use crate::app::GantryApp;

#[derive(Debug, Default)]
pub struct PathView {
    /// Fit the view to the program at the next frame.
    pub fit: bool,
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.label(format!("{} trail points", app.live.trail.len()));
}
