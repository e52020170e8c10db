//! Reference motion: what the axes are told to follow.
//!
//! - [`trajectory`]: analytic reference paths (step, sine, line, helix, polyline) with
//!   exact first and second derivatives, evaluated at a time;
//! - [`path`]: their configuration as it appears in scenario files and settings, and where
//!   a path starts (absolute, or from the position the machine is at).

pub mod path;
pub mod trajectory;

pub use trajectory::{RefSample, Trajectory};
