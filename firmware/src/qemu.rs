//! QEMU-only pieces: the run verdict, explicit exit codes, and a panic handler and
//! HardFault handler that exit non-zero instead of hanging (panic-probe would hang).
//!
//! Exit codes (passed to the host through semihosting `SYS_EXIT`):
//! 0 = figures within bounds, 1 = figures out of bounds, 2 = invalid configuration,
//! 3 = the run ended in a fault state, 101 = panic, 102 = HardFault.

use firmware::safety::SafetyState;
use firmware::scenario::{Verdict, BOUNDS, BOUNDS_SOURCE};
use firmware::telemetry::{Figures, Snapshot};

/// Figures within bounds.
pub const EXIT_PASS: i32 = 0;
/// Figures outside the bounds.
pub const EXIT_OUT_OF_BOUNDS: i32 = 1;
/// Rejected configuration.
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

/// Prints the final figures and the verdict, then exits with it.
pub fn finish(s: &Snapshot, plant: &Figures) -> ! {
    crate::logger::figures("controller (measured)", &s.figures);
    crate::logger::figures("plant (true state)", plant);
    defmt::info!(
        "bounds ({=str}): ITSE<=[{=f32}, {=f32}, {=f32}] max|e|<=[{=f32}, {=f32}, {=f32}] contour max<={=f32} rms<={=f32}",
        BOUNDS_SOURCE,
        BOUNDS.itse[0],
        BOUNDS.itse[1],
        BOUNDS.itse[2],
        BOUNDS.tracking_max[0],
        BOUNDS.tracking_max[1],
        BOUNDS.tracking_max[2],
        BOUNDS.contour_max,
        BOUNDS.contour_rms
    );
    defmt::info!(
        "control ISR: {=u32} periods, {=u32} overruns (QEMU does not model timer rates)",
        s.period,
        s.timing.overruns
    );
    if let SafetyState::Fault(reason) = s.state {
        defmt::error!("QEMU run FAILED: ended in fault {}", reason);
        exit(EXIT_FAULT);
    }
    let verdict = Verdict::check(plant, &BOUNDS);
    if verdict.passed() {
        defmt::info!("QEMU run PASSED: figures within host-sim bounds");
        exit(EXIT_PASS)
    } else {
        defmt::error!("QEMU run FAILED: out of bounds {}", verdict);
        exit(EXIT_OUT_OF_BOUNDS)
    }
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
