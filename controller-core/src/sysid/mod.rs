//! Identification of an axis: friction, inertia and a validation figure from
//! motion the axis makes under its own velocity loop, and the law gains that follow from
//! the model ([`crate::plant::AxisModel`]).
//!
//! Runs per axis, once per control period, identically on the board (control
//! interrupt), in host-sim and in QEMU. It sees only what the board sees: the position
//! from encoder counts, the estimator's velocity, and the effort it commanded itself.
//!
//! - [`config`]: [`IdentifyConfig`], validated once.
//! - [`identifier`]: [`Identifier`], the per-period state machine (friction passes,
//!   inertia excitation, validation), with its safety checks.
//! - [`lsq`]: 4-parameter least squares accumulated as normal equations.
//! - [`tuning`]: the law configurations from a model ([`TuningConfig`]);
//! - [`frequency`]: the frequency response from effort to encoder (stepped sine on a
//!   constant travel), its resonances and anti-resonances.
//!
//! Method, equations, accuracy over random machines: docs/identification.md.

pub mod config;
pub mod frequency;
pub mod identifier;
pub mod lsq;
pub mod tuning;
mod velocity_loop;

pub use config::{IdentifyConfig, IdentifyConfigError, IDENTIFY_DEFAULTS, MAX_PASS_SPEEDS};
pub use identifier::{
    AbortReason, AxisSample, FitDiagnostics, FitStage, Identifier, IdentifyOutput, IdentifyPhase,
    IdentifyResult, IdentifyStatus, ParamDiagnostic,
};
pub use tuning::TuningConfig;
