//! The QEMU rig (feature `qemu`): the firmware on QEMU's netduinoplus2 (STM32F405) runs a
//! scenario of host-sim's (`host-sim/scenarios/qemu/*.toml`) with the core's simulated
//! run ([`controller_core::sim::run::SimRun`]) in the control interrupt: the servo step
//! against the simulated world instead of encoders and PWM, then the world advances.
//!
//! - [`cmdline`]: the scenario name from the semihosting command line;
//! - [`rig`]: the per-period work of the control interrupt for a scenario;
//! - [`link_rig`]: the machine behind the host link on USART2 (name `link`: what
//!   `gantry --qemu` boots);
//! - [`panel`]: the link rig's operator panel on USART1 (the simulated e-stop);
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
pub mod link_rig;
pub mod panel;
pub mod report;
pub mod rig;

use controller_core::machine::ControlSide;
use controller_core::servo::snapshot::Snapshot;

use crate::board::inputs::SafetyPins;
use crate::machine_slot::FwMachine;
use link_rig::LinkRig;
use rig::{End, Rig};

/// Command-line name of the link rig.
pub const LINK_RIG: &str = "link";

/// What the control interrupt runs in QEMU: a scenario ([`Rig`]) or the machine behind
/// the host link ([`LinkRig`]).
// (it lives in a static: its size is the larger rig's whichever runs)
#[allow(clippy::large_enum_variant)]
pub enum Period {
    Scenario(Rig),
    Link(LinkRig),
}

impl Period {
    /// The rig the command line names (`link`, or a scenario; only the link rig has an
    /// operator panel on `panel_usart`).
    pub fn boot(
        safety: SafetyPins,
        machine: &'static mut Option<FwMachine>,
        control: ControlSide<'static>,
        panel_usart: stm32f4xx_hal::pac::USART1,
    ) -> Self {
        if cmdline::with_scenario_name(|n| n == LINK_RIG) {
            Self::Link(LinkRig::boot(machine, control, panel_usart))
        } else {
            Self::Scenario(Rig::boot(safety))
        }
    }

    /// The link rig's machine settings and control rate (what the link task starts
    /// from); `None` for a scenario.
    pub fn link_machine(&self) -> Option<(controller_core::settings::Settings, u32)> {
        match self {
            Self::Link(r) => Some(r.machine_settings()),
            Self::Scenario(_) => None,
        }
    }

    #[inline]
    pub fn control(&mut self) -> &Snapshot {
        match self {
            Self::Scenario(r) => r.control(),
            Self::Link(r) => r.control(),
        }
    }

    #[inline]
    pub fn end_of_period(&mut self, overran: bool) {
        if let Self::Scenario(r) = self {
            r.end_of_period(overran);
        }
    }

    pub fn snapshot(&self) -> &Snapshot {
        match self {
            Self::Scenario(r) => r.snapshot(),
            Self::Link(r) => r.snapshot(),
        }
    }

    /// The period's figures and the world's advance; the result once a scenario is over
    /// (the link rig runs until QEMU is stopped).
    #[inline]
    pub fn finish(&mut self) -> Option<End> {
        match self {
            Self::Scenario(r) => r.finish(),
            Self::Link(r) => {
                r.finish();
                None
            }
        }
    }
}

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
