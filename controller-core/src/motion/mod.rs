//! Reference motion: what the axes are told to follow.
//!
//! - [`trajectory`]: analytic reference paths (step, sine, line, helix, polyline) with
//!   exact first and second derivatives, evaluated at a time;
//! - [`path`]: their configuration as it appears in scenario files and settings, and where
//!   a path starts (absolute, or from the position the machine is at);
//! - [`planner`]: the segment planner (queue, blending within a path tolerance, look-ahead,
//!   jerk-limited feed, hold/resume/abort, feed override) and its per-period executor;
//! - [`reference`]: what produces the servo step's reference each period (hold, the
//!   configured path, a controlled stop, a jog, homing, the planner's sample), with the
//!   reference generators it steps: [`jog`], [`homing`] and their one-axis [`ramp`];
//! - [`shaper`]: input shaping of a sampled reference per axis (Klipper's ZV … 3-hump EI)
//!   on a common delay, with its bound on the added contour deviation.
//!
//! - [`compensation`]: backlash and lead-screw error tables added to the reference.
//!
//! Nothing here knows the servo: the servo step ([`crate::servo`]) drives these.

pub mod compensation;
pub mod feedforward;
pub mod homing;
pub mod jog;
pub mod path;
pub mod planner;
pub mod ramp;
pub mod reference;
pub mod shaper;
pub mod trajectory;

pub use trajectory::{RefSample, Trajectory};
