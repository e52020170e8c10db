//! # controller-core
//!
//! The motion-control core of the gantry, shared verbatim by the STM32 firmware and the
//! host simulator. `no_std`, no allocation, no panics.
//!
//! Every law is written once over the [`Real`] number trait, so the same code runs in
//! `f32` (the firmware's type), `f64` (host reference) and fixed point. Layers point one
//! way: numbers → laws, estimators, trajectories → controller → servo step → the firmware
//! tasks and the simulator.
//!
//! - [`num`]: the number trait, fast powers and trig, fixed point, vectors, RK4;
//! - [`config`]: configuration errors and validators; [`axes`]: axis names, per-axis serde;
//! - [`plant`]: axis models: the normalised axis the laws and estimators use, the
//!   identified rigid-body model, and the physical axis a simulation follows;
//! - [`law`]: PID, SMC/DSMC, DOB-SMC, adaptive friction SMC behind one interface;
//! - [`coupling`]: the paper's 3-D contour coupling and the variable-gain contour PID;
//! - [`filter`]: notch and low-pass biquads on the control output, their placement from
//!   measured resonances and the stability margins that accept them;
//! - [`controller`]: the 3-axis controller (a law per axis, coupling);
//! - [`estimator`]: wide counts, PLL and Kalman velocity estimators, the per-axis bank;
//! - [`motion`]: reference trajectories and their configuration;
//! - [`servo`]: the per-period servo step over an IO trait, and its safety state machine;
//! - [`sim`]: the simulated world the servo step runs against;
//! - [`link`]: the host-link protocol (framing, handshake, command / telemetry /
//!   real-time channels, watchdog), shared by the firmware and the host tools;
//! - [`sysid`]: identification of an axis' model on the machine, and the tuning rules
//!   from a model to every law's gains;
//! - [`metrics`]: ITSE, IAE, contour error statistics, chattering;
//! - [`presets`]: named parameter sets with their sources;
//! - [`settings`]: the user's settings tree, its dotted keys, the servo configuration it
//!   gives, and its record in flash (feature `store`).
#![no_std]
#![forbid(unsafe_code)]
// `!(x > y)` is deliberate throughout: it is also true for NaN, which is how NaN inputs are
// caught and replaced before they reach an output.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod axes;
pub mod config;
pub mod controller;
pub mod coupling;
pub mod estimator;
pub mod filter;
pub mod law;
pub mod link;
pub mod machine;
pub mod metrics;
pub mod motion;
pub mod num;
pub mod plant;
pub mod presets;
pub mod servo;
pub mod settings;
pub mod sim;
pub mod sysid;

pub use num::exponent::Exponent;
pub use num::real::{LibmF32, Real};
pub use num::vec3::Vec3;
