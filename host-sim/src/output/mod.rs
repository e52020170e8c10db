//! What host-sim writes: terminal tables, JSON and CSV ([`report`]), and figures
//! ([`plots`], [`seed_plots`]) as PNG and SVG.

pub mod gcode_plots;
pub mod identify_plots;
pub mod plots;
pub mod report;
pub mod scope_plots;
pub mod seed_plots;
