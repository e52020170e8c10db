//! A scenario's driver in the QEMU rig: the scenario host-sim's `qemu-verdict` runs too
//! (`host-sim/scenarios/qemu/*.toml`, from the firmware's table), as a simulated run of
//! the machine ([`FwRun`], the rig's one run, [`super::rig`]) with its scripted commands
//! or program requests. Each period is the machine's period against the simulated world
//! (the part the board's interrupt runs, and the part that is measured), then the
//! period's true-state figures and the world's advance (not measured).
//!
//! Faults are injected through the simulated run's own hook (`SimRun`'s scripted
//! `TimedInjection` of the scenario file, into the simulated world's sensors and inputs),
//! exactly as host-sim injects them, so the firmware's detection is compared with
//! host-sim's period for period. A program run's planning half must run once between
//! two periods, as in host-sim ([`super::plan_watch`]); the run exits with
//! [`EXIT_PLAN_IRREGULAR`] when it did not.
//!
//! Besides the scenario table, three self-test names make the real binary take its
//! fault paths at boot: `selftest_panic` (a panic, exit 101), `selftest_hardfault` (an
//! undefined instruction, exit 102) and `selftest_exception` (an interrupt without a
//! handler, exit 103).

use controller_core::servo::faults::FaultRecord;
use controller_core::servo::io::Inputs;
use controller_core::servo::snapshot::Snapshot;
use controller_core::sim::run::{factory_planner, SimRun};
use controller_core::sim::truth::TruthFigures;
use firmware::scenarios::{self, ScenarioError};

use crate::board::inputs::SafetyPins;
use crate::machine_slot::{self, FwRun};
use crate::qemu_exit::{exit, EXIT_CONFIG, EXIT_PLAN_IRREGULAR};

/// A finished run.
#[derive(Clone, Copy, Debug)]
pub struct End {
    /// Scenario name (the file stem).
    pub name: &'static str,
    /// The true-state figures of the whole run.
    pub figures: TruthFigures,
    /// Periods run.
    pub periods: u32,
    /// The scenario injects a fault.
    pub injects: bool,
    /// The run's period of the injection, once it happened.
    pub injected_at: Option<u32>,
    /// The first latched fault (the servo's fault log).
    pub fault: Option<FaultRecord>,
}

/// What a scenario adds to its run: the board's pins, the world's own inputs, the
/// scenario's name.
pub struct ScenarioDriver {
    /// The board's e-stop, limit and amplifier-fault pins: QEMU reads them as healthy
    /// (all low), and the servo step sees them through the simulated world as the board's
    /// servo does.
    safety: SafetyPins,
    /// The simulated world's own inputs (its injected faults, which persist), without
    /// the pins: each period the world reads these merged with the pins.
    world_inputs: Inputs,
    injects: bool,
    /// A program run (its planning half must run once between two periods).
    program: bool,
    name: &'static str,
}

/// `a` or `b`, per input.
fn merged(a: Inputs, b: Inputs) -> Inputs {
    let mut m = a;
    m.estop |= b.estop;
    m.overrun |= b.overrun;
    for i in 0..a.limits.len() {
        m.limits[i][0] |= b.limits[i][0];
        m.limits[i][1] |= b.limits[i][1];
        m.amp_fault[i] |= b.amp_fault[i];
    }
    m
}

/// `a` without what `pins` holds active.
fn without(a: Inputs, pins: Inputs) -> Inputs {
    let mut m = a;
    m.estop &= !pins.estop;
    m.overrun &= !pins.overrun;
    for i in 0..a.limits.len() {
        m.limits[i][0] &= !pins.limits[i][0];
        m.limits[i][1] &= !pins.limits[i][1];
        m.amp_fault[i] &= !pins.amp_fault[i];
    }
    m
}

/// The self-tests: the board's fault handlers on the real binary.
fn self_test(name: &str) {
    match name {
        "selftest_panic" => {
            defmt::info!("self-test: panic");
            panic!("self-test panic");
        }
        "selftest_hardfault" => {
            defmt::info!("self-test: HardFault (undefined instruction)");
            cortex_m::asm::udf();
        }
        "selftest_exception" => {
            defmt::info!("self-test: an interrupt without a handler (EXTI0)");
            let irq = stm32f4xx_hal::pac::Interrupt::EXTI0;
            cortex_m::peripheral::NVIC::pend(irq);
            // SAFETY: EXTI0 has no handler of its own: it is meant to reach the default
            // handler at once (interrupts are enabled inside init for that alone; the
            // handler never returns).
            unsafe {
                cortex_m::peripheral::NVIC::unmask(irq);
                cortex_m::interrupt::enable();
            }
        }
        _ => {}
    }
}

impl ScenarioDriver {
    /// The scenario named on the semihosting command line, decoded, validated and built
    /// in `slot` (in place: it is too large to pass around on the stack); exits QEMU with
    /// [`EXIT_CONFIG`] if it is unknown or rejected.
    // (never inlined into `Rig::boot` with the other rig's: their frames would add up
    // on the boot stack)
    #[inline(never)]
    pub fn boot(
        slot: &'static mut Option<FwRun>,
        safety: SafetyPins,
    ) -> (&'static mut FwRun, Self) {
        let (name, cfg) = super::cmdline::with_scenario_name(|arg| {
            self_test(arg);
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
        let Ok(memory) = machine_slot::memory() else {
            defmt::error!("scenario `{=str}`: the machine's memory is taken", name);
            exit(EXIT_CONFIG)
        };
        let planner = factory_planner(cfg.servo.rate_hz);
        let run = match SimRun::with_memory_in(slot, &cfg, &planner, memory) {
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
        let driver = Self {
            safety,
            world_inputs: Inputs::default(),
            injects: cfg.inject.is_some(),
            program: cfg.program,
            name,
        };
        (run, driver)
    }

    /// The machine's period against the simulated world (whose inputs are its own,
    /// injected ones and the board's pins). `plan`: the planning half's runs since the
    /// last period and whether it is running; a program run exits with
    /// [`EXIT_PLAN_IRREGULAR`] unless it ran exactly once.
    #[inline]
    pub fn control<'r>(&mut self, run: &'r mut FwRun, plan: (u32, bool)) -> &'r Snapshot {
        let k = run.periods_run();
        if self.program && k > 0 && plan != (1, false) {
            defmt::error!(
                "scenario `{=str}`: the planning half ran {=u32} times before period {=u32} (busy: {=bool}); host-sim runs it once",
                self.name,
                plan.0,
                k,
                plan.1
            );
            exit(EXIT_PLAN_IRREGULAR)
        }
        let pins = self.safety.read();
        run.world_mut().inputs = merged(self.world_inputs, pins);
        run.control();
        // an injection in this period added to the world's inputs: keep it
        self.world_inputs = merged(self.world_inputs, without(run.world().inputs, pins));
        run.servo().snapshot()
    }

    /// Figures and world advance; the result once every period has run.
    #[inline]
    pub fn finish(&mut self, run: &mut FwRun) -> Option<End> {
        run.finish_period();
        if run.done() {
            Some(End {
                name: self.name,
                figures: run.figures(),
                periods: run.periods_run(),
                injects: self.injects,
                injected_at: run.injected_at(),
                fault: run.servo().faults().first(),
            })
        } else {
            None
        }
    }
}
