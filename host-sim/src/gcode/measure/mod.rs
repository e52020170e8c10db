//! A program run measured against its programmed path: the figures of `host-sim gcode` and
//! `gantry run`, sample by sample.
//!
//! Modules: [`distance`] (exact distance to a move's path), [`cursor`] (the search over the
//! moves near the tool), [`tolerance`] (the tolerance in force at each move), [`directions`]
//! (axis limits along a direction), [`metrics`] (the figures, sample by sample) and
//! [`bound`] (the lower bound of the machine time).

pub mod bound;
pub mod cursor;
pub mod directions;
pub mod distance;
pub mod metrics;
pub mod tolerance;

pub use distance::length;
pub use metrics::{MetricSample, PathMetrics};
