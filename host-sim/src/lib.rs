//! # host-sim
//!
//! Runs the gantry's controller core (the same `controller-core` code the firmware runs)
//! against plant models on a PC.
//!
//! - [`engine`]: the simulation loop, in *continuous* mode (controller re-evaluated at
//!   every RK4 stage, for comparison with the paper's Matlab runs) and *discrete* mode
//!   (controller at a fixed sample rate with zero-order hold, position quantisation and
//!   actuator saturation: what the firmware does).
//! - [`estimators`]: velocity sources (exact, backward difference, PLL, Kalman) compared
//!   on the paper helix (issue 6).
//! - [`gcode`]: G-code programs → validated machine moves (before any motion), soft limits.
//! - [`scenario`]: scenario files (TOML) and their conversion into runs.
//! - [`paper`]: the reference paper's experiments (Tables 1 and 3) and published numbers.
//! - [`seeds`]: the patent's and the XY-table paper's methods on the physical gantry;
//!   [`seed_plots`] draws their figures.
//! - [`report`]: tables on the terminal, JSON and CSV output.
//! - [`plots`]: PNG/SVG figures (bundled font: renders on a machine without fonts).

// `!(x > 0.0)` is deliberate: it also rejects NaN, which is how bad numbers in scenario
// files are caught.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod engine;
pub mod estimators;
pub mod gcode;
pub mod paper;
pub mod plots;
pub mod report;
pub mod scenario;
pub mod seed_plots;
pub mod seeds;
