//! The QEMU rig: what the control interrupt runs in QEMU. One simulated run of the
//! machine ([`FwRun`]: controller-core's `SimRun` around the core's `Machine`, its
//! planner's executor and scope in the firmware's static memory) against
//! the simulated world, driven either by a scenario ([`ScenarioDriver`]: scripted
//! commands or a program's requests, the true-state figures, an end) or by the host link
//! ([`LinkDriver`]: the link's events, the operator panel, the recording; no end). The
//! command line names which (`link`, or a scenario).

use controller_core::machine::ControlSide;
use controller_core::servo::snapshot::Snapshot;
use controller_core::settings::Settings;

use super::cmdline;
use super::link::LinkDriver;
use super::plan_watch::PlanWatch;
use super::scenario::{End, ScenarioDriver};
use crate::board::inputs::SafetyPins;
use crate::machine_slot::FwRun;

/// Command-line name of the link rig.
pub const LINK_RIG: &str = "link";

/// What drives the run.
// (one of them for the whole boot, in the control task's local resource: 2.3 KB once)
#[allow(clippy::large_enum_variant)]
enum Driver {
    Scenario(ScenarioDriver),
    Link(LinkDriver),
}

/// The control interrupt's state in QEMU.
pub struct Rig {
    run: &'static mut FwRun,
    driver: Driver,
    plan: PlanWatch,
}

impl Rig {
    /// The run the command line names, built in `slot` (`link`, or a scenario; only the
    /// link rig has an operator panel on `panel_usart`).
    pub fn boot(
        safety: SafetyPins,
        slot: &'static mut Option<FwRun>,
        control: ControlSide<'static>,
        panel_usart: stm32f4xx_hal::pac::USART1,
    ) -> Self {
        let (run, driver) = if cmdline::with_scenario_name(|n| n == LINK_RIG) {
            let (run, d) = LinkDriver::boot(slot, control, panel_usart);
            (run, Driver::Link(d))
        } else {
            let (run, d) = ScenarioDriver::boot(slot, safety);
            (run, Driver::Scenario(d))
        };
        Self {
            run,
            driver,
            plan: PlanWatch::new(),
        }
    }

    /// The link rig's machine settings and control rate (what the link task starts
    /// from); `None` for a scenario.
    pub fn link_machine(&self) -> Option<(Settings, u32)> {
        match &self.driver {
            Driver::Link(d) => Some(d.machine_settings(self.run)),
            Driver::Scenario(_) => None,
        }
    }

    /// The machine's period (the part the board's interrupt runs, and that is measured).
    #[inline]
    pub fn control(&mut self) -> &Snapshot {
        let plan = self.plan.since_last();
        match &mut self.driver {
            Driver::Scenario(d) => d.control(self.run, plan),
            Driver::Link(d) => d.control(self.run, plan),
        }
    }

    /// The end of the control interrupt. QEMU's emulated deadline is not the scenario's
    /// (see `board::tick`): its overruns are counted in the telemetry but not given to the
    /// servo, so the run stays the one host-sim computes (the `overrun` injection stands in
    /// for them); QEMU has no watchdog to feed.
    #[inline]
    pub fn end_of_period(&mut self, _overran: bool) {}

    /// The last period's snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        self.run.servo().snapshot()
    }

    /// The period's figures (a scenario's) and the world's advance; the result once a
    /// scenario is over (the link rig runs until QEMU is stopped).
    #[inline]
    pub fn finish(&mut self) -> Option<End> {
        match &mut self.driver {
            Driver::Scenario(d) => d.finish(self.run),
            Driver::Link(d) => {
                d.finish(self.run);
                None
            }
        }
    }
}
