//! Filters on the control output: per-axis notch and low-pass biquads, placed from the
//! measured resonances, accepted only when the loop's stability margins, computed on the
//! measured response, stay within bounds.
//!
//! A lightly damped mode of the machine (a screw's axial stiffness against the carriage,
//! a beam's bending) multiplies the loop gain by its resonance peak near the mode's
//! frequency; a notch there, or a low-pass well above the loop's bandwidth, takes the
//! peak back out of the loop ("gain stabilisation", G. Ellis, *Control System Design
//! Guide*, 4th ed., ch. 16 "Mechanical Resonance"; the notches and torque-reference
//! filters of industrial drives, e.g. Yaskawa Σ-V Pn401-Pn410).
//!
//! - [`cookbook`]: the biquads' designs in `f64` (Audio EQ Cookbook: notch of finite depth,
//!   low-pass), [`Coefficients`];
//! - [`biquad`]: one section in the period's number type (transposed direct form II),
//!   its kick-free steady state and its exact discrete response;
//! - [`design`]: the configuration ([`FilterConfig`], [`AxisFilterConfig`]) validated
//!   against the control period;
//! - [`chain`]: a chain per axis ([`FilterChain`]) and the three axes' [`OutputFilters`];
//! - [`placement`]: notches (and optionally a low-pass) placed from measured resonances
//!   and the loop's bandwidth;
//! - [`margins`]: gain and phase margins and the Nyquist stability of `C·F·P` from
//!   sampled responses, the acceptance rule, and a PID's linear response;
//! - [`response`]: the [`FrequencyResponse`] trait and complex arithmetic.
//!
//! The filters sit beside the laws: they depend on the numbers and the configuration
//! validators only.

pub mod biquad;
pub mod chain;
pub mod cookbook;
pub mod design;
pub mod margins;
pub mod placement;
pub mod response;

#[cfg(test)]
mod tests;

pub use biquad::Biquad;
pub use chain::{FilterChain, OutputFilters};
pub use cookbook::Coefficients;
pub use design::{AxisFilterConfig, FilterConfig, BUTTERWORTH_Q, MAX_STAGES};
pub use margins::{
    accept, loop_margins, margins_of_samples, pid_response, Margins, Rejection, SampleError,
    MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG,
};
pub use placement::{place, Placement, Resonance};
pub use response::FrequencyResponse;
