//! RTIC 2 firmware of the gantry controller (STM32F407VGT6), and its QEMU build.
//!
//! Tasks, highest priority first:
//!
//! | task | priority | trigger | does |
//! | --- | --- | --- | --- |
//! | `control` | 3 (hardware) | TIM4 update, 10 kHz | safety, encoders, controller-core step, PWM, snapshot |
//! | `telemetry` | 1 (software) | every 100 ms (SysTick monotonic) | copies the snapshot, logs it with defmt |
//!
//! The control task never logs, allocates or blocks; it publishes a [`Snapshot`] through
//! an RTIC resource (its own lock is free: it has the ceiling priority) and counts its
//! deadline overruns. Idle sleeps.
//!
//! With the `qemu` feature the same application runs on QEMU's netduinoplus2: HSI clocks,
//! defmt over semihosting, and the encoder reads and PWM writes replaced by the simulated
//! gantry ([`firmware::sim`]). The scenario ends after its horizon; the telemetry task
//! then prints the figures and exits QEMU with the verdict (see `qemu.rs`).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

/// The firmware only runs on the microcontroller; a host build (e.g. `cargo test
/// --workspace`, clippy) gets this stub entry point and the library's unit tests.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("build the firmware for the target: cargo fw (or cargo fw-qemu)");
}

#[cfg(target_os = "none")]
mod board;
#[cfg(all(target_os = "none", not(feature = "qemu")))]
mod board_io;
#[cfg(target_os = "none")]
mod cycles;
#[cfg(target_os = "none")]
mod logger;
#[cfg(all(target_os = "none", feature = "qemu"))]
mod qemu;

#[cfg(all(target_os = "none", not(feature = "qemu")))]
use {defmt_rtt as _, panic_probe as _};

#[cfg(all(target_os = "none", feature = "qemu"))]
use defmt_semihosting as _;

#[cfg(target_os = "none")]
rtic_monotonics::systick_monotonic!(Mono, 1_000);

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [USART6])]
mod app {
    use rtic_monotonics::fugit::ExtU32 as MonoExtU32;
    use rtic_monotonics::Timebase as _;

    use firmware::config::CONTROL_RATE_HZ;
    use firmware::control::ControlLoop;
    use firmware::io::GantryIo;
    use firmware::safety::SafetyState;
    use firmware::telemetry::Snapshot;

    use crate::board::{self, ControlTick, Leds, SYSCLK_HZ};
    use crate::logger::Logger;
    use crate::Mono;

    #[cfg(not(feature = "qemu"))]
    type Io = crate::board_io::BoardIo;
    #[cfg(feature = "qemu")]
    type Io = firmware::sim::SimGantry<board::InputPins>;

    #[shared]
    struct Shared {
        telemetry: Snapshot,
        /// QEMU build: true-state figures of the simulated plant, set at the end.
        plant_figures: firmware::telemetry::Figures,
    }

    #[local]
    struct Local {
        control: ControlLoop,
        io: Io,
        tick: ControlTick,
        leds: Leds,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut core = cx.core;
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();

        let board = board::init(cx.device);
        Mono::start(core.SYST, SYSCLK_HZ);

        #[cfg(not(feature = "qemu"))]
        let (io, loop_cfg) = (
            crate::board_io::BoardIo::new(
                board.encoders,
                board.servo,
                board.inputs,
                firmware::config::ARM_BUTTON_HOLD_PERIODS,
                firmware::config::BOARD_EFFORT_LIMIT,
            ),
            firmware::config::board_loop(),
        );
        #[cfg(not(feature = "qemu"))]
        let raw = io.encoder_raw();

        #[cfg(feature = "qemu")]
        let (io, loop_cfg, raw) = {
            // The encoder timers are configured but not read: the simulated gantry
            // supplies the counts. PWM writes go to the plant model instead of TIM1.
            let _ = (board.encoders, board.servo);
            let io = firmware::sim::SimGantry::new(firmware::scenario::sim_config(), board.inputs);
            (io, firmware::scenario::loop_config(), [0; firmware::AXES])
        };

        let control = match ControlLoop::new(loop_cfg, raw) {
            Ok(c) => c,
            Err(e) => config_error(e),
        };

        let mut tick = board.tick;
        tick.start(board::CONTROL_TICK_PROGRAMMED_HZ);
        defmt::info!(
            "gantry firmware up: control {=u32} Hz, outputs disabled until armed",
            CONTROL_RATE_HZ
        );
        if telemetry::spawn().is_err() {
            defmt::error!("telemetry task already running");
        }
        (
            Shared {
                telemetry: Snapshot::boot(),
                plant_figures: firmware::telemetry::Figures::default(),
            },
            Local {
                control,
                io,
                tick,
                leds: board.leds,
            },
        )
    }

    /// Invalid build-time configuration: outputs stay off, nothing runs.
    fn config_error(e: controller_core::params::ConfigError) -> ! {
        defmt::error!("invalid configuration: {}", defmt::Debug2Format(&e));
        #[cfg(feature = "qemu")]
        crate::qemu::exit(crate::qemu::EXIT_CONFIG);
        #[cfg(not(feature = "qemu"))]
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The control period. Highest priority; never logs, allocates or blocks.
    #[task(binds = TIM4, priority = 3, local = [control, io, tick, leds], shared = [telemetry, plant_figures])]
    fn control(mut cx: control::Context) {
        let start = crate::cycles::start();
        cx.local.tick.acknowledge();
        let control = cx.local.control;
        control.step(cx.local.io);
        let cycles = crate::cycles::since(start);
        // Board: nothing. QEMU: the simulated plant advances one period (not timed).
        cx.local.io.period_end();
        control.record_timing(cycles, cx.local.tick.overran());
        let snap = control.snapshot();
        let state = snap.state;
        cx.local.leds.show(
            state == SafetyState::Enabled,
            matches!(state, SafetyState::Fault(_)),
        );
        cx.shared.telemetry.lock(|t| *t = *snap);
        if snap.finished {
            // A finite run (QEMU scenario) is over: stop the control interrupt.
            cx.local.tick.stop();
            #[cfg(feature = "qemu")]
            {
                let f = cx.local.io.truth_figures();
                cx.shared.plant_figures.lock(|p| *p = f);
            }
        }
    }

    /// Low-priority telemetry: snapshot copies become defmt log lines.
    #[task(priority = 1, shared = [telemetry, plant_figures])]
    async fn telemetry(mut cx: telemetry::Context) {
        let mut logger = Logger::new();
        loop {
            Mono::delay(board::TELEMETRY_PERIOD_MS.millis()).await;
            let snap = cx.shared.telemetry.lock(|t| *t);
            logger.report(&snap);
            if snap.finished {
                let plant = cx.shared.plant_figures.lock(|p| *p);
                #[cfg(feature = "qemu")]
                crate::qemu::finish(&snap, &plant);
                #[cfg(not(feature = "qemu"))]
                {
                    crate::logger::figures("run", &snap.metrics.figures());
                    let _ = plant;
                    break;
                }
            }
        }
    }
}
