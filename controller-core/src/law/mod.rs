//! The per-axis control laws and the one interface every controller uses to run them.
//!
//! A law is configured by a [`LawConfig`] (plain `f32` values, serde behind the feature),
//! validated once into a runtime [`Law`] in the controller's number type. Its state
//! ([`LawState`]) is kept separately. Every period the controller
//!
//! 1. **evaluates** the law ([`Law::evaluate`], a pure function of state and signals),
//!    getting the law's own (saturated) output and what the state update needs;
//! 2. combines the outputs of all axes (cross-coupling corrections, saturation);
//! 3. **commits** ([`Law::commit`]) with the output *actually applied* to the axis, so
//!    that an observer or an adaptation never mistakes a correction it did not make, or a
//!    saturation, for a disturbance.
//!
//! The laws are continuous-time: [`LawEval::integral_rate`] is the rate of the law's
//! integral, which the firmware and the simulator's discrete mode integrate over one
//! period, and the simulator's continuous mode integrates with RK4 together with the
//! plant (PID and sliding-mode laws only; see [`Law::supports_continuous`]).
//!
//! - [`dispatch`]: [`LawConfig`] and [`Law`], the one interface over every law kind;
//! - [`signals`]: [`AxisSignals`], [`LawOutput`] and the saturation every law finishes with;
//! - [`state`]: [`LawState`], the state of any law;
//! - [`pid`]: PID with anti-windup and feed-forward (spec 2.1);
//! - [`smc`]: SMC and DSMC, terminal and nonsingular surfaces (spec 2.2, 2.3);
//! - [`dob_smc`]: sliding mode with a disturbance observer (spec 2.4, patent seed 002);
//! - [`adaptive_smc`]: sliding mode with online friction identification (spec 2.5, seed 004).

pub mod adaptive_smc;
pub mod dispatch;
pub mod dob_smc;
pub mod pid;
pub mod signals;
pub mod smc;
pub mod state;

pub use dispatch::{Law, LawConfig, LawEval};
pub use signals::{AxisSignals, LawOutput};
pub use state::LawState;
