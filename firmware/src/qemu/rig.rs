//! What the control interrupt runs in QEMU: one period of the core's simulated run.
//! [`Rig::control`] is the servo step against the simulated world (the part the board's
//! interrupt runs, and the part that is measured), [`Rig::finish`] records the period's
//! true-state figures and advances the world (not measured).

use controller_core::servo::snapshot::Snapshot;
use controller_core::sim::run::SimRun;
use controller_core::sim::truth::TruthFigures;
use firmware::scenarios::{self, ScenarioError};

use super::{exit, EXIT_CONFIG};
use crate::board::inputs::SafetyPins;

/// A finished run.
#[derive(Clone, Copy, Debug)]
pub struct End {
    /// Scenario name (the file stem).
    pub name: &'static str,
    /// The true-state figures of the whole run.
    pub figures: TruthFigures,
    /// Periods run.
    pub periods: u32,
}

/// The control interrupt's state in QEMU.
pub struct Rig {
    run: SimRun<f32>,
    /// The board's e-stop and limit pins: QEMU reads them as healthy (all low), and the
    /// servo step sees them through the simulated world as the board's servo does.
    safety: SafetyPins,
    name: &'static str,
}

impl Rig {
    /// The scenario named on the semihosting command line, decoded and validated; exits
    /// QEMU with [`EXIT_CONFIG`] if it is unknown or rejected.
    pub fn boot(safety: SafetyPins) -> Self {
        let (name, cfg) = super::cmdline::with_scenario_name(|arg| {
            let Some(name) = scenarios::names().find(|n| *n == arg) else {
                defmt::error!("unknown scenario `{=str}`; this build has:", arg);
                for n in scenarios::names() {
                    defmt::error!("  {=str}", n);
                }
                exit(EXIT_CONFIG)
            };
            match scenarios::load(name) {
                Ok(cfg) => (name, cfg),
                Err(ScenarioError::Unknown | ScenarioError::Decode) => {
                    defmt::error!("scenario `{=str}`: its table entry does not decode", name);
                    exit(EXIT_CONFIG)
                }
            }
        });
        let run = match SimRun::<f32>::new(&cfg) {
            Ok(r) => r,
            Err(e) => {
                defmt::error!(
                    "scenario `{=str}`: invalid configuration: {}",
                    name,
                    defmt::Display2Format(&e)
                );
                exit(EXIT_CONFIG)
            }
        };
        defmt::info!(
            "scenario {=str}: {=u32} periods at {=u32} Hz",
            name,
            cfg.periods,
            cfg.servo.rate_hz
        );
        Self { run, safety, name }
    }

    /// The servo step of this period against the simulated world.
    #[inline]
    pub fn control(&mut self) -> &Snapshot {
        self.run.world_mut().inputs = self.safety.read();
        self.run.control()
    }

    /// The last period's snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        self.run.servo().snapshot()
    }

    /// Figures and world advance; the result once every period has run.
    #[inline]
    pub fn finish(&mut self) -> Option<End> {
        self.run.finish_period();
        if self.run.done() {
            Some(End {
                name: self.name,
                figures: self.run.figures(),
                periods: self.run.periods_run(),
            })
        } else {
            None
        }
    }
}
