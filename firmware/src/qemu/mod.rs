//! The QEMU rig (feature `qemu`): the firmware on QEMU's netduinoplus2 (STM32F405) runs
//! the core's machine in a simulated run ([`controller_core::sim::run::SimRun`]) in the
//! control interrupt: the machine's period against the simulated world instead of
//! encoders and PWM, then the world advances.
//!
//! - [`rig`]: the rig, one run of the machine, driven by a scenario or by the link;
//! - [`scenario`]: a scenario of host-sim's (`host-sim/scenarios/qemu/*.toml`), named on
//!   the command line: scripted commands or a program's requests, the figures, an end;
//! - [`link`]: the machine behind the host link on USART2 (name `link`: what
//!   `gantry --qemu` boots);
//! - [`panel`]: the link rig's operator panel on USART1 (the simulated e-stop);
//! - [`plan_watch`]: whether the planning half ran once between two periods;
//! - [`cmdline`]: the scenario name from the semihosting command line;
//! - [`report`]: a scenario's final lines (human-readable figures, interrupt statistics,
//!   and one machine-readable `gantry-figures` line) and the exit.
//!
//! There is no verdict here: host-sim's `qemu-verdict` runs the same scenario file and
//! compares its figures with the `gantry-figures` line bit for bit.
//!
//! The exit codes and the exit itself are `crate::qemu_exit`'s, below both this rig and
//! the board's panic and exception handlers (`board::shutdown`), which exit QEMU instead
//! of waiting for the watchdog.

pub mod cmdline;
pub mod link;
pub mod panel;
pub mod plan_watch;
pub mod report;
pub mod rig;
pub mod scenario;

pub use crate::machine_slot::FwRun;
pub use rig::Rig;
pub use scenario::End;
