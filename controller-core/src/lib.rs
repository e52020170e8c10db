//! # controller-core
//!
//! The motion-control core of the gantry, shared verbatim by the STM32 firmware and the
//! host simulator. `no_std`, no allocation, no panics.
//!
//! Every law is written once over the [`Real`] number trait, so the same code runs in
//! `f32` (the firmware's type), `f64` (host reference) and fixed point.
//!
//! Module map:
//! - [`real`]: the number trait, guarded division and fractional powers.
//! - [`powers`]: fast cube-root based fractional powers (f32 and the fixed-point core).
//! - [`fixed`]: saturating fixed-point types implementing [`Real`].
//! - [`vec3`]: three-axis vectors.
//! - [`ode`]: fixed-step RK4 over any state.
//! - [`plant`]: axis plant models used by the simulators (paper plant, eq. 5).
//! - [`trajectory`]: reference paths with analytic first and second derivatives.
//! - [`shared_root`]: several powers of one base from a single root.
//! - [`pid`], [`smc`]: the per-axis control laws; [`law`] selects between them.
//! - [`contour`]: 3-D contour error and cross-coupling (paper eqs. 6-15).
//! - [`estimator`]: velocity from quantised positions (tracking observer, spec 6).
//! - [`gantry`]: the complete 3-axis control step the firmware runs every period.
//! - [`metrics`]: ITSE, IAE, contour error statistics, chattering.
//! - [`motion`]: the segment planner (blending, look-ahead, jerk-limited feed, hold).
//! - [`params`]: named parameter presets with their sources.
//! - Seed methods (patent, XY-table paper): [`physical_plant`] (friction, load, torque
//!   limit), [`dob_smc`], [`adaptive_smc`], [`variable_gain_ccc`], combined per axis by
//!   [`seed_gantry`]; presets and their reasoning in [`seed_params`].
#![no_std]
#![forbid(unsafe_code)]
// `!(x > y)` is deliberate throughout: it is also true for NaN, which is how NaN inputs are
// caught and replaced before they reach an output.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod adaptive_smc;
pub mod contour;
pub mod dob_smc;
pub mod estimator;
pub mod fixed;
pub mod gantry;
pub mod law;
pub mod metrics;
pub mod motion;
pub mod ode;
pub mod params;
pub mod physical_plant;
pub mod pid;
pub mod plant;
pub mod powers;
pub mod real;
pub mod seed_gantry;
pub mod seed_params;
pub mod shared_root;
pub mod smc;
pub mod trajectory;
pub mod variable_gain_ccc;
pub mod vec3;

pub use real::{Exponent, LibmF32, Real};
pub use vec3::Vec3;
