//! Board support for the STM32F407VGT6 gantry controller: the one module that knows which
//! pin and timer does what, and how the clocks are set up.
//!
//! | function | pin(s) | peripheral | notes |
//! | --- | --- | --- | --- |
//! | clock | PH0/PH1 | HSE 8 MHz crystal | PLL to SYSCLK 168 MHz, APB1 42 MHz, APB2 84 MHz |
//! | X encoder A/B | PA15 / PB3 | TIM2 CH1/CH2, AF1 | 32-bit counter, encoder mode 3 (x4) |
//! | Y encoder A/B | PA0 / PA1 | TIM5 CH1/CH2, AF2 | 32-bit counter, encoder mode 3 (x4) |
//! | Z encoder A/B | PA6 / PA7 | TIM3 CH1/CH2, AF2 | 16-bit counter, extended in software |
//! | X/Y/Z servo PWM | PE9 / PE11 / PE13 | TIM1 CH1/CH2/CH3, AF1 | 20 kHz, ARR 8399 (8400 steps) |
//! | X/Y/Z direction | PE10 / PE12 / PE14 | GPIO push-pull | high = negative direction |
//! | X/Y/Z drive enable | PD0 / PD1 / PD2 | GPIO push-pull | high = enabled, low at reset |
//! | e-stop | PB12 | GPIO input, pull-up | NC contact to GND: high = stop (also on wire break) |
//! | limits X-/X+/Y-/Y+/Z-/Z+ | PC0..PC5 | GPIO input, pull-up | NC contacts to GND: high = active |
//! | arm / fault reset | PD3 | GPIO input, pull-up | NO button to GND: low = pressed, 20 ms debounce |
//! | LED enabled / fault | PD12 / PD14 | GPIO push-pull | the green / red LED of an STM32F4DISCOVERY |
//! | control tick | (none) | TIM4 update interrupt | 84 MHz timer clock, 10 kHz default, 20 kHz fits |
//! | defmt log, flashing | PA13 / PA14 | SWD + RTT | probe-rs |
//!
//! TIM4 is used as the control timer (rather than a basic timer) because it is one of the
//! timers QEMU's STM32F405 model emulates, so the QEMU build keeps the same interrupt.
//!
//! All three PWM channels are on TIM1, so one register write (clearing BDTR.MOE) turns
//! every servo output off at once. OSSI/OSSR are set, so with MOE clear the outputs are
//! driven to their idle level (low) instead of floating. Drive enables are low from reset
//! (push-pull, initial state low) and the main output stays off until the safety state
//! machine enables it.
//!
//! Submodules, one per kind of hardware: [`encoders`], [`pwm`] (servo outputs),
//! [`inputs`] (safety inputs, arm button), [`leds`], [`tick`] (control timer),
//! [`cycles`] (execution-time counter), and [`io`], the core's `ServoIo` for the board.

pub mod cycles;
pub mod encoders;
pub mod inputs;
#[cfg(not(feature = "qemu"))]
pub mod io;
pub mod leds;
pub mod pwm;
pub mod tick;

use stm32f4xx_hal::{
    gpio::PinState,
    pac,
    prelude::*,
    rcc::{Config, Rcc},
};

use encoders::Encoders;
use inputs::{ArmButton, SafetyPins};
use leds::Leds;
use pwm::ServoOutputs;
use tick::ControlTick;

/// SYSCLK the firmware runs at (the QEMU build's core also runs at 168 MHz, whatever the
/// clock tree registers say).
pub const SYSCLK_HZ: u32 = 168_000_000;

/// Clock tree: HSE 8 MHz -> PLL -> 168 MHz.
#[cfg(not(feature = "qemu"))]
fn clock_config() -> Config {
    Config::hse(8.MHz())
        .sysclk(SYSCLK_HZ.Hz())
        .hclk(SYSCLK_HZ.Hz())
        .pclk1(42.MHz())
        .pclk2(84.MHz())
}

/// QEMU does not model the RCC: the HSE/PLL start-up would wait forever for HSERDY.
/// Stay on the 16 MHz HSI (the emulated core runs at its own speed anyway).
#[cfg(feature = "qemu")]
fn clock_config() -> Config {
    Config::hsi()
}

/// Everything `init` hands to the RTIC tasks.
pub struct Board {
    pub encoders: Encoders,
    pub servo: ServoOutputs,
    pub safety: SafetyPins,
    pub arm: ArmButton,
    pub leds: Leds,
    pub tick: ControlTick,
}

/// Clocks, pins and timers. Outputs end up disabled; the control timer is configured but
/// not started.
pub fn init(dp: pac::Peripherals) -> Board {
    let mut rcc: Rcc = dp.RCC.freeze(clock_config());

    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);
    let gpiod = dp.GPIOD.split(&mut rcc);
    let gpioe = dp.GPIOE.split(&mut rcc);

    // Drive enables first, low, so the amplifiers stay off whatever happens next.
    let enable = [
        gpiod
            .pd0
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        gpiod
            .pd1
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        gpiod
            .pd2
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
    ];
    let direction = [
        gpioe
            .pe10
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        gpioe
            .pe12
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        gpioe
            .pe14
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
    ];

    // Servo PWM on TIM1, all channels at 0 duty, main output off.
    let (pwm_timer, (ch1, ch2, ch3, _ch4)) = dp
        .TIM1
        .pwm_hz(firmware::config::PWM_FREQUENCY_HZ.Hz(), &mut rcc);
    let pwm = [
        ch1.with(gpioe.pe9).erase(),
        ch2.with(gpioe.pe11).erase(),
        ch3.with(gpioe.pe13).erase(),
    ];
    let servo = ServoOutputs::new(pwm_timer, pwm, direction, enable);

    let encoders = Encoders {
        // PA15 and PB3 come out of reset as JTAG pins (AF0); SWD only needs PA13/PA14.
        x: dp
            .TIM2
            .qei((gpioa.pa15.into_input(), gpiob.pb3.into_input()), &mut rcc),
        y: dp.TIM5.qei((gpioa.pa0, gpioa.pa1), &mut rcc),
        z: dp.TIM3.qei((gpioa.pa6, gpioa.pa7), &mut rcc),
    };

    let safety = SafetyPins {
        estop: gpiob.pb12.into_pull_up_input().erase(),
        limits: [
            [
                gpioc.pc0.into_pull_up_input().erase(),
                gpioc.pc1.into_pull_up_input().erase(),
            ],
            [
                gpioc.pc2.into_pull_up_input().erase(),
                gpioc.pc3.into_pull_up_input().erase(),
            ],
            [
                gpioc.pc4.into_pull_up_input().erase(),
                gpioc.pc5.into_pull_up_input().erase(),
            ],
        ],
    };
    let arm = ArmButton {
        pin: gpiod.pd3.into_pull_up_input().erase(),
    };

    let mut leds = Leds {
        enabled: gpiod.pd12.into_push_pull_output().erase(),
        fault: gpiod.pd14.into_push_pull_output().erase(),
    };
    leds.show(false, false);

    let tick = ControlTick::new(dp.TIM4.counter_hz(&mut rcc));

    Board {
        encoders,
        servo,
        safety,
        arm,
        leds,
        tick,
    }
}
