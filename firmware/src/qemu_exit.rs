//! How the QEMU build ends (feature `qemu`): its exit codes, passed to the host through
//! semihosting `SYS_EXIT`, and the exit itself. A leaf below both the QEMU rig (`qemu`:
//! a run's verdict, a rejected configuration) and the board's panic and exception
//! handlers (`board::shutdown`: outputs off by direct register writes first, harmless in
//! QEMU, then the log; only their last step differs, they exit here instead of waiting
//! for the watchdog).
//!
//! 0 = the run completed, 2 = configuration error (unknown scenario, undecodable or
//! rejected configuration), 3 = a run without an injected fault ended in a latched
//! fault, 4 = a run with an injected fault ended without one, 101 = panic, 102 =
//! HardFault, 103 = any other exception.

/// The run completed.
pub const EXIT_COMPLETED: i32 = 0;
/// Unknown scenario or rejected configuration.
pub const EXIT_CONFIG: i32 = 2;
/// A run without an injected fault ended in a latched fault.
pub const EXIT_FAULT: i32 = 3;
/// A run with an injected fault ended without a latched fault (the fault went undetected).
pub const EXIT_UNDETECTED: i32 = 4;
/// A program run's planning half did not run exactly once between two control periods
/// (the run is not the one host-sim computes).
pub const EXIT_PLAN_IRREGULAR: i32 = 5;
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
