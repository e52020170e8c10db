//! Axis models as the control laws and estimators see them.
//!
//! [`PlantParams`] is the normalised second-order axis of the reference paper (spec 1.1,
//! paper eq. 5), `θ'' = -a θ' - b θ + k u`: what a sliding-mode law's equivalent control
//! cancels and what the Kalman estimator turns the applied output into a commanded
//! acceleration with. A physical ball-screw axis `J x'' + B x' = u` (friction and load
//! left to the laws' robust terms) is the same model with `a = B/J`, `b = 0`, `k = 1/J`
//! ([`PlantParams::from_inertia`]).

/// Coefficients of the normalised axis `θ'' = -a θ' - b θ + k u` (spec 1.1).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PlantParams {
    pub a: f32,
    pub b: f32,
    pub k: f32,
}

impl PlantParams {
    /// The rigid physical axis `J x'' + B x' = u`: `a = B/J`, `b = 0`, `k = 1/J`.
    pub const fn from_inertia(inertia: f32, viscous: f32) -> Self {
        Self {
            a: viscous / inertia,
            b: 0.0,
            k: 1.0 / inertia,
        }
    }
}
