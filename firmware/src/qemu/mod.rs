//! The QEMU rig (feature `qemu`): the firmware on QEMU's netduinoplus2 (STM32F405) runs a
//! scenario of host-sim's (`host-sim/scenarios/qemu/*.toml`) with the core's simulated
//! run ([`controller_core::sim::run::SimRun`]) in the control interrupt: the servo step
//! against the simulated world instead of encoders and PWM, then the world advances.
//!
//! - [`cmdline`]: the scenario name from the semihosting command line;
//! - [`rig`]: the per-period work of the control interrupt;
//! - [`report`]: the final lines (human-readable figures, interrupt statistics, and one
//!   machine-readable `gantry-figures` line) and the exit.
//!
//! There is no verdict here: host-sim's `qemu-verdict` runs the same scenario file and
//! compares its figures with the `gantry-figures` line bit for bit.
//!
//! Exit codes (passed to the host through semihosting `SYS_EXIT`): 0 = the run completed,
//! 2 = configuration error (unknown scenario, undecodable or rejected configuration),
//! 3 = a run without an injected fault ended in a latched fault, 4 = a run with an
//! injected fault ended without one, 101 = panic, 102 = HardFault, 103 = any other
//! exception. The panic and exception handlers are the board's (`board::shutdown`: outputs
//! off by direct register writes first, harmless in QEMU, then the log), only their last
//! step differs: they exit here instead of waiting for the watchdog.

pub mod cmdline;
pub mod report;
pub mod rig;

/// The run completed.
pub const EXIT_COMPLETED: i32 = 0;
/// Unknown scenario or rejected configuration.
pub const EXIT_CONFIG: i32 = 2;
/// A run without an injected fault ended in a latched fault.
pub const EXIT_FAULT: i32 = 3;
/// A run with an injected fault ended without a latched fault (the fault went undetected).
pub const EXIT_UNDETECTED: i32 = 4;
/// Panic.
pub const EXIT_PANIC: i32 = 101;
/// HardFault.
pub const EXIT_HARD_FAULT: i32 = 102;
/// Any other exception (`DefaultHandler`).
pub const EXIT_EXCEPTION: i32 = 103;

/// Terminates QEMU with `code`.
pub fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}
