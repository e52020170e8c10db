//! QEMU-only pieces: the run verdict, explicit exit codes, and a panic handler and
//! HardFault handler that exit non-zero instead of hanging (panic-probe would hang).
//!
//! Exit codes (passed to the host through semihosting `SYS_EXIT`):
//! 0 = figures agree with host-sim, 1 = they do not, 2 = invalid configuration,
//! 3 = the run ended in a fault state, 101 = panic, 102 = HardFault.

use firmware::safety::SafetyState;
use firmware::scenario::{Verdict, HOST_SIM, REL_TOLERANCE};
use firmware::telemetry::{Figures, Snapshot};

/// Figures agree with host-sim.
pub const EXIT_PASS: i32 = 0;
/// Figures disagree with host-sim.
pub const EXIT_DISAGREES: i32 = 1;
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
    crate::logger::figures("controller (measured)", &s.metrics.figures());
    crate::logger::figures("plant (true state)", plant);
    defmt::info!(
        "host-sim    (reference): ITSE=[{=f64}, {=f64}, {=f64}] max|e|=[{=f64}, {=f64}, {=f64}] contour max={=f64} rms={=f64}; tolerance {=f64} relative",
        HOST_SIM.itse[0],
        HOST_SIM.itse[1],
        HOST_SIM.itse[2],
        HOST_SIM.tracking_max[0],
        HOST_SIM.tracking_max[1],
        HOST_SIM.tracking_max[2],
        HOST_SIM.contour_max,
        HOST_SIM.contour_rms,
        REL_TOLERANCE
    );
    defmt::info!(
        "control ISR: {=u32} periods, {=u32} overruns of the emulated period",
        s.period,
        s.timing.overruns
    );
    if let SafetyState::Fault(reason) = s.state {
        defmt::error!("QEMU run FAILED: ended in fault {}", reason);
        exit(EXIT_FAULT);
    }
    let verdict = Verdict::check(plant, &HOST_SIM);
    if verdict.passed() {
        defmt::info!("QEMU run PASSED: figures agree with host-sim");
        exit(EXIT_PASS)
    } else {
        defmt::error!("QEMU run FAILED: disagrees with host-sim {}", verdict);
        exit(EXIT_DISAGREES)
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
