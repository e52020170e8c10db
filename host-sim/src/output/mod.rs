//! What host-sim writes: terminal tables, JSON and CSV ([`report`]), and figures as PNG
//! and SVG: the paper's ([`plots`], which also holds the drawing every figure uses), the
//! seed methods' ([`seed_plots`]), a G-code run's ([`gcode_plots`]), the identification's
//! ([`identify_plots`]), a scope capture's ([`scope_plots`]), and the Bode plots of the
//! frequency response ([`freqresp_plots`]) and of the measured loop ([`loop_plots`]), and
//! the circular test's polar plots ([`circle_plots`]).

pub mod circle_plots;
pub mod freqresp_plots;
pub mod gcode_plots;
pub mod identify_plots;
pub mod loop_plots;
pub mod plots;
pub mod report;
pub mod scope_plots;
pub mod seed_plots;
