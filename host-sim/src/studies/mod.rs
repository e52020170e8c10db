//! The studies host-sim runs, each from its scenario files (`host-sim/scenarios/`):
//!
//! - [`paper`]: the reference paper's Tables 1 and 3 (the main job);
//! - [`seeds`]: the patent's and the XY-table paper's methods on the physical gantry;
//! - [`estimators`]: velocity sources × laws;
//! - [`faults`]: the fault matrix (every fault class injected, detection and overrun);
//! - [`identify`]: identification of every axis through the servo step, and the contour it buys;
//! - [`circle`]: the ISO 230-4 circular test on a machine, evaluated by [`circular_test`];
//! - [`freqresp`]: each axis' frequency response through the servo step, its resonances
//!   and anti-resonances;
//! - [`filters`]: each axis' output filters placed from its measured response and
//!   accepted on the loop's margins, measured on the running machine ([`loop_response`]);
//! - [`vibration`]: the residual vibration at the tool after a rapid stop, unshaped and
//!   with the input shapers tuned to each axis' measured mode;
//! - [`generic`]: any scenario file, every run, the common figures (`host-sim run FILE`);
//! - [`machine_replay`]: the QEMU link rig's machine replayed in host-sim, bit for bit;
//! - [`qemu_verdict`]: a scenario's host-sim figures against the firmware's in QEMU.

pub mod circle;
pub mod circular_test;
pub mod compensation;
pub mod estimators;
pub mod faults;
pub mod filters;
pub mod freqresp;
pub mod generic;
pub mod identify;
pub mod loop_response;
pub mod machine_replay;
pub mod paper;
pub mod qemu_verdict;
pub mod seeds;
pub mod vibration;

use anyhow::{anyhow, Result};
use controller_core::sim::run::{RunConfig, SimRun};
use controller_core::sim::world::InitialState;

/// A run of `base`'s machine that the study drives itself: every axis at rest at its
/// origin, no end, no scripted start or injection (the servo holds until commanded).
pub fn driven_run(mut cfg: RunConfig) -> Result<SimRun<f32>> {
    cfg.world.initial = [InitialState::default(); 3];
    cfg.periods = u32::MAX;
    cfg.hold = true;
    cfg.inject = None;
    SimRun::<f32>::new(&cfg).map_err(|e| anyhow!("invalid machine: {e}"))
}
