//! Hardware-free building blocks of the gantry firmware.
//!
//! Everything here compiles for the microcontroller and for the host (unit tests, and
//! the host-side reference run of the QEMU scenario). The binary (`main.rs`) adds the
//! board support and the RTIC application.
//!
//! - [`config`]: rates, scaling, limits, the board's law selection.
//! - [`safety`]: the output-enable state machine (boot disabled, latched faults).
//! - [`button`]: debounced arm/reset button.
//! - [`drive`]: effort to PWM duty and direction.
//! - [`io`]: the per-period hardware interface the control loop uses.
//! - [`control`]: the control-interrupt sequence around controller-core.
//! - [`telemetry`]: the snapshot published to the logger task.
//! - [`sim`]: the simulated gantry of the QEMU build (controller-core's plant model).
//! - [`scenario`]: the QEMU scenario (paper helix) and its pass bounds.
#![cfg_attr(not(test), no_std)]
// `!(x <= limit)` is deliberate: it is also true for NaN, which must trip, not pass.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod button;
pub mod config;
pub mod control;
pub mod drive;
pub mod io;
pub mod safety;
pub mod scenario;
pub mod sim;
pub mod telemetry;

/// Number of axes (X, Y, Z).
pub const AXES: usize = 3;
