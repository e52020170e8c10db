//! Board support for the STM32F407VGT6 gantry controller: the one module that knows which
//! pin and timer does what, and how the clocks are set up.
//!
//! | function | pin(s) | peripheral | notes |
//! | --- | --- | --- | --- |
//! | clock | PH0/PH1 | HSE 8 MHz crystal | PLL to SYSCLK 168 MHz, APB1 42 MHz, APB2 84 MHz |
//! | X encoder A/B | PA15 / PB3 | TIM2 CH1/CH2, AF1 | 32-bit counter, encoder mode 3 (x4) |
//! | Y encoder A/B | PA0 / PA1 | TIM5 CH1/CH2, AF2 | 32-bit counter, encoder mode 3 (x4) |
//! | Z encoder A/B | PA6 / PA7 | TIM3 CH1/CH2, AF2 | 16-bit counter, extended in software |
//! | X encoder index | PB10 | TIM2 CH3, AF1, pull-down | input capture of TI3 (CCR3 latches CNT), rising edge, A/B's filter |
//! | Y encoder index | PB1 | EXTI1, pull-down | rising edge: the highest-priority task reads TIM5_CNT (TIM5's CH3/CH4 pins are USART2's, PH12/PI0 not on LQFP100) |
//! | Z encoder index | PB0 | TIM3 CH3, AF2, pull-down | input capture of TI3 (CCR3 latches CNT), rising edge, A/B's filter |
//! | X/Y/Z servo PWM | PE9 / PE11 / PE13 | TIM1 CH1/CH2/CH3, AF1 | 20 kHz, ARR 8399 (8400 steps) |
//! | X/Y/Z direction | PE10 / PE12 / PE14 | GPIO push-pull | high = negative direction |
//! | X/Y/Z drive enable | PD0 / PD1 / PD2 | GPIO push-pull | high = enabled, low at reset |
//! | X/Y/Z holding brake | PD4 / PD5 / PD6 | GPIO push-pull | high = coil energised (brake released), low = gripping: at reset (the brake driver needs a pull-down on its input), boot and on every fault |
//! | e-stop | PB12 | TIM1_BKIN (AF1), pull-up | NC contact to GND: high = stop (also on wire break); TIM1's break input, so the PWM goes off in hardware |
//! | limits X-/X+/Y-/Y+/Z-/Z+ | PC0..PC5 | GPIO input, pull-up | NC contacts to GND: high = active |
//! | amplifier fault X/Y/Z | PD8 / PD9 / PD10 | GPIO input, pull-up | amplifier "ready" output to GND (open collector, on when healthy): high = fault (also on wire break) |
//! | arm / fault reset | PD3 | GPIO input, pull-up | NO button to GND: low = pressed, 20 ms debounce |
//! | LED enabled / fault | PD12 / PD14 | GPIO push-pull | the green / red LED of an STM32F4DISCOVERY |
//! | control tick | (none) | TIM4 update interrupt | 84 MHz timer clock, 10 kHz default, 20 kHz fits |
//! | defmt log, flashing | PA13 / PA14 | SWD + RTT | probe-rs |
//! | QEMU build only: operator panel | (none) | USART1 | the link rig's simulated e-stop (`qemu::panel`); QEMU models no GPIO |
//!
//! TIM4 is used as the control timer (rather than a basic timer) because it is one of the
//! timers QEMU's STM32F405 model emulates, so the QEMU build keeps the same interrupt.
//!
//! All three PWM channels are on TIM1, so one register write (clearing BDTR.MOE) turns
//! every servo output off at once. OSSI/OSSR are set, so with MOE clear the outputs are
//! driven to their idle level (low) instead of floating. The main output stays off until
//! the safety state machine enables it.
//!
//! Order of [`init`] (board-level safety, see README-firmware.md "Board-level safety"):
//! drive enables, brake outputs, direction and PWM pins become push-pull outputs driven low *before*
//! the clock setup (the pins float from reset until then: the drives need pull-downs on
//! their enable inputs for that first microsecond); then the crystal with a start-up
//! timeout and the HSI fallback ([`clock`]); then TIM1 with its break input and locked
//! idle configuration before the PWM pins are handed to it; encoder input filters on;
//! the index captures (after the encoder setup, which writes the timers' CCER whole).
//!
//! Encoder wiring: each differential encoder's A/B and Z (index) pairs go through the
//! line receiver to the pins above.
//!
//! Submodules, one per kind of hardware: [`encoders`], [`index`] (the encoders' index
//! captures), [`pwm`] (servo outputs),
//! [`inputs`] (safety inputs, arm button), [`leds`], [`tick`] (control timer),
//! [`cycles`] (execution-time counter), [`io`] (the core's `ServoIo` for the board),
//! [`clock`] (clock tree, crystal timeout, clock security system), [`brownout`] (the
//! brown-out reset level in the option bytes), [`shutdown`] (outputs
//! off from any context; panic and exception handlers), [`self_check`] (the
//! configuration after init read back against the register table), [`watchdog`] (the IWDG) and
//! [`flash`] (the settings store's sectors).

#[cfg(not(feature = "qemu"))]
pub mod brownout;
pub mod clock;
pub mod cycles;
pub mod encoders;
#[cfg(not(feature = "qemu"))]
pub mod flash;
#[cfg(not(feature = "qemu"))]
pub mod index;
pub mod inputs;
#[cfg(not(feature = "qemu"))]
pub mod io;
pub mod leds;
pub mod pwm;
#[cfg(not(feature = "qemu"))]
pub mod self_check;
pub mod serial;
pub mod shutdown;
pub mod tick;
#[cfg(not(feature = "qemu"))]
pub mod watchdog;

use controller_core::axes::AXES;
use stm32f4xx_hal::gpio::{
    AnyPin, Output, PinState, PB12, PC0, PC1, PC2, PC3, PC4, PC5, PD0, PD1, PD10, PD2, PD4, PD5,
    PD6, PD8, PD9, PE10, PE11, PE12, PE13, PE14, PE9,
};
use stm32f4xx_hal::{pac, prelude::*};

use clock::ClockStart;
use encoders::Encoders;
use inputs::{ArmButton, SafetyPins};
use leds::Leds;
use pwm::ServoOutputs;
use tick::ControlTick;

// (the clock tree's own figure, re-exported: the board's users name it here)
pub use clock::SYSCLK_HZ;

/// SysTick's hardware priority: RTIC logical priority 3 (the plan task's level) with the
/// STM32F4's 4 priority bits, `(16 - 3) << 4`: below the control interrupt (4, 0xC0).
pub const SYSTICK_PRIORITY_HW: u8 = (16 - 3) << 4;

/// Why the chip last reset (RCC_CSR's flags), the flags then cleared (RMVF) so the next
/// boot reports its own cause.
#[cfg(not(feature = "qemu"))]
pub fn take_reset_cause() -> firmware::reset_cause::ResetCause {
    // SAFETY: init runs before anything else uses RCC; CSR's RMVF only clears the flags
    // (LSION, the other bit written, is kept as read).
    let rcc = unsafe { &*pac::RCC::ptr() };
    let csr = rcc.csr().read().bits();
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    firmware::reset_cause::ResetCause::from_csr(csr)
}

/// Everything `init` hands to the RTIC tasks.
pub struct Board {
    pub encoders: Encoders,
    /// The encoders' index inputs, capturing (not in QEMU: no GPIO or EXTI model).
    #[cfg(not(feature = "qemu"))]
    pub index: index::IndexInputs,
    pub servo: ServoOutputs,
    pub safety: SafetyPins,
    pub arm: ArmButton,
    pub leds: Leds,
    pub tick: ControlTick,
    /// The oscillator the clocks run from (`HsiFallback`: a clock fault to latch).
    pub clock: ClockStart,
    /// The independent watchdog, not started yet.
    #[cfg(not(feature = "qemu"))]
    pub watchdog: watchdog::Watchdog,
    /// The host link's USART2 (PA2/PA3), configured with its receive interrupt.
    pub host_uart: Option<stm32f4xx_hal::serial::Serial<pac::USART2>>,
    /// QEMU: USART1, clocked, for the link rig's operator panel (`qemu::panel`).
    #[cfg(feature = "qemu")]
    pub panel_usart: pac::USART1,
    /// The flash controller (the settings store).
    #[cfg(not(feature = "qemu"))]
    pub flash: pac::FLASH,
    /// The brown-out reset level found at boot, and whether it was programmed.
    #[cfg(not(feature = "qemu"))]
    pub brownout: brownout::BorSetting,
}

/// Safe pins, clocks, timers. Outputs end up disabled; the control timer is configured but
/// not started.
pub fn init(dp: pac::Peripherals) -> Board {
    // Nothing but pin setup before the outputs are in their safe state: GPIO clocks on
    // (that needs no clock tree), drive enables, direction and PWM pins driven low.
    let mut rcc = dp.RCC.constrain();
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);
    let gpiod = dp.GPIOD.split(&mut rcc);
    let gpioe = dp.GPIOE.split(&mut rcc);

    let SafeOutputPins {
        enable,
        brake,
        direction,
        pwm: pwm_pins,
    } = safe_output_pins(
        (gpiod.pd0, gpiod.pd1, gpiod.pd2),
        (gpiod.pd4, gpiod.pd5, gpiod.pd6),
        (gpioe.pe10, gpioe.pe12, gpioe.pe14),
        (gpioe.pe9, gpioe.pe11, gpioe.pe13),
    );

    if !shutdown::addresses_match() {
        defmt::error!("shutdown: TIM1/GPIOD register addresses differ from the PAC's");
    }

    // Clocks: the crystal with a start-up timeout, else the HSI (a clock fault).
    let (mut rcc, clock) = clock::setup(rcc);

    // Servo PWM on TIM1: break input and the locked idle configuration first (the HAL's
    // `pwm_hz` turns automatic output enable on), then the pins, duties 0, main output off.
    let (pwm_timer, (ch1, ch2, ch3, _ch4)) = dp
        .TIM1
        .pwm_hz(firmware::config::PWM_FREQUENCY_HZ.Hz(), &mut rcc);
    pwm::reset_and_lock_tim1();
    let pwm = [
        ch1.with(pwm_pins.0).erase(),
        ch2.with(pwm_pins.1).erase(),
        ch3.with(pwm_pins.2).erase(),
    ];
    let servo = ServoOutputs::new(pwm_timer, pwm, direction, enable, brake);

    let mut encoders = Encoders {
        // PA15 and PB3 come out of reset as JTAG pins (AF0); SWD only needs PA13/PA14.
        x: dp
            .TIM2
            .qei((gpioa.pa15.into_input(), gpiob.pb3.into_input()), &mut rcc),
        y: dp.TIM5.qei((gpioa.pa0, gpioa.pa1), &mut rcc),
        z: dp.TIM3.qei((gpioa.pa6, gpioa.pa7), &mut rcc),
    };
    encoders.enable_input_filters();

    // The index captures (after the encoder-mode setup above, which writes CCER whole).
    #[cfg(not(feature = "qemu"))]
    let index = {
        use stm32f4xx_hal::syscfg::SysCfgExt;
        let mut syscfg = dp.SYSCFG.constrain(&mut rcc);
        let mut exti = dp.EXTI;
        index::IndexInputs::new(gpiob.pb10, gpiob.pb1, gpiob.pb0, &mut syscfg, &mut exti)
    };

    let safety = safety_pins(
        gpiob.pb12,
        (
            gpioc.pc0, gpioc.pc1, gpioc.pc2, gpioc.pc3, gpioc.pc4, gpioc.pc5,
        ),
        (gpiod.pd8, gpiod.pd9, gpiod.pd10),
    );
    let arm = ArmButton {
        pin: gpiod.pd3.into_pull_up_input().erase(),
    };

    let mut leds = Leds {
        enabled: gpiod.pd12.into_push_pull_output().erase(),
        fault: gpiod.pd14.into_push_pull_output().erase(),
    };
    leds.show(false, false);

    let tick = ControlTick::new(dp.TIM4.counter_hz(&mut rcc));

    let host_uart = serial::init_or_log(dp.USART2, gpioa.pa2, gpioa.pa3, &mut rcc);

    // QEMU: the link rig's operator panel (no pins: QEMU models no GPIO; the clock is
    // enabled as a real F405 would need, QEMU itself has no RCC model).
    #[cfg(feature = "qemu")]
    let panel_usart = {
        use stm32f4xx_hal::rcc::Enable;
        pac::USART1::enable(&mut rcc);
        dp.USART1
    };

    // the brown-out reset at 2.7 V (once per chip; every output is still off)
    #[cfg(not(feature = "qemu"))]
    let brownout = brownout::ensure_2v7(&dp.FLASH);

    Board {
        encoders,
        #[cfg(not(feature = "qemu"))]
        index,
        servo,
        safety,
        arm,
        leds,
        tick,
        clock,
        #[cfg(not(feature = "qemu"))]
        watchdog: watchdog::Watchdog::new(dp.IWDG),
        host_uart,
        #[cfg(feature = "qemu")]
        panel_usart,
        #[cfg(not(feature = "qemu"))]
        flash: dp.FLASH,
        #[cfg(not(feature = "qemu"))]
        brownout,
    }
}

/// The servo outputs' pins as [`init`] leaves its first step: push-pull outputs driven low.
struct SafeOutputPins {
    enable: [AnyPin<Output>; AXES],
    brake: [AnyPin<Output>; AXES],
    direction: [AnyPin<Output>; AXES],
    /// The PWM pins, GPIO for now (TIM1 takes them after its break setup).
    pwm: (PE9<Output>, PE11<Output>, PE13<Output>),
}

/// `init`'s first step, before the clock setup: drive enables (X, Y, Z), brake outputs,
/// direction and PWM pins become push-pull outputs driven low, in that order.
fn safe_output_pins(
    enable: (PD0, PD1, PD2),
    brake: (PD4, PD5, PD6),
    direction: (PE10, PE12, PE14),
    pwm: (PE9, PE11, PE13),
) -> SafeOutputPins {
    let enable_pins = [
        enable
            .0
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        enable
            .1
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        enable
            .2
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
    ];
    // brake coils de-energised (gripping) from the first instructions on
    let brake_pins = [
        brake
            .0
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        brake
            .1
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        brake
            .2
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
    ];
    let direction_pins = [
        direction
            .0
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        direction
            .1
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
        direction
            .2
            .into_push_pull_output_in_state(PinState::Low)
            .erase(),
    ];
    // PWM pins: GPIO low now, with the pull-down kept for the moment they become TIM1
    // outputs (before the channel is enabled TIM1 does not drive them).
    let pwm_pins = (
        pwm.0
            .into_push_pull_output_in_state(PinState::Low)
            .internal_pull_down(true),
        pwm.1
            .into_push_pull_output_in_state(PinState::Low)
            .internal_pull_down(true),
        pwm.2
            .into_push_pull_output_in_state(PinState::Low)
            .internal_pull_down(true),
    );
    SafeOutputPins {
        enable: enable_pins,
        brake: brake_pins,
        direction: direction_pins,
        pwm: pwm_pins,
    }
}

/// The safety inputs: the e-stop as TIM1's break input (pull-up), then the limit switches
/// X-/X+/Y-/Y+/Z-/Z+ and the amplifier faults X/Y/Z as pulled-up inputs, in that order.
fn safety_pins(
    estop: PB12,
    limits: (PC0, PC1, PC2, PC3, PC4, PC5),
    amp_fault: (PD8, PD9, PD10),
) -> SafetyPins {
    SafetyPins {
        // TIM1_BKIN: the e-stop line is TIM1's break input (active high)
        estop: estop.into_alternate::<1>().internal_pull_up(true),
        limits: [
            [
                limits.0.into_pull_up_input().erase(),
                limits.1.into_pull_up_input().erase(),
            ],
            [
                limits.2.into_pull_up_input().erase(),
                limits.3.into_pull_up_input().erase(),
            ],
            [
                limits.4.into_pull_up_input().erase(),
                limits.5.into_pull_up_input().erase(),
            ],
        ],
        amp_fault: [
            amp_fault.0.into_pull_up_input().erase(),
            amp_fault.1.into_pull_up_input().erase(),
            amp_fault.2.into_pull_up_input().erase(),
        ],
    }
}
