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
//! 3 = the run ended in a latched fault, 101 = panic, 102 = HardFault.

pub mod cmdline;
pub mod report;
pub mod rig;

/// The run completed.
pub const EXIT_COMPLETED: i32 = 0;
/// Unknown scenario or rejected configuration.
pub const EXIT_CONFIG: i32 = 2;
/// The run ended in a latched fault.
pub const EXIT_FAULT: i32 = 3;
/// Panic.
pub const EXIT_PANIC: i32 = 101;
/// HardFault.
pub const EXIT_HARD_FAULT: i32 = 102;

/// Terminates QEMU with `code`.
pub fn exit(code: i32) -> ! {
    semihosting::process::exit(code)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    exit(EXIT_PANIC)
}

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    defmt::error!("HardFault at pc={=u32:#x}", frame.pc());
    exit(EXIT_HARD_FAULT)
}
