//! The QEMU rig (feature `qemu`): the firmware on QEMU's netduinoplus2 (STM32F405) runs a
//! scenario of host-sim's (`host-sim/scenarios/qemu/*.toml`) with the core's simulated
//! run ([`controller_core::sim::run::SimRun`]) in the control interrupt: the machine's
//! period (its servo step) against the simulated world instead of encoders and PWM, then
//! the world advances.
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
//! The exit codes and the exit itself are `crate::qemu_exit`'s, below both this rig and
//! the board's panic and exception handlers (`board::shutdown`), which exit QEMU instead
//! of waiting for the watchdog.

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
