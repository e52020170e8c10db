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

use stm32f4xx_hal::{
    gpio::{AnyPin, Input, Output, PinState},
    pac,
    prelude::*,
    qei::Qei,
    rcc::{Config, Rcc},
    timer::{CounterHz, ErasedChannel, Event, Flag, PwmHzManager},
};

use firmware::safety::SafetyInputs;
use firmware::AXES;

/// SYSCLK the firmware runs at (the QEMU build's core also runs at 168 MHz, whatever the
/// clock tree registers say).
pub const SYSCLK_HZ: u32 = 168_000_000;

/// Rate programmed into the control timer (TIM4).
#[cfg(not(feature = "qemu"))]
pub const CONTROL_TICK_PROGRAMMED_HZ: u32 = firmware::config::CONTROL_RATE_HZ;

/// QEMU: the emulated TIM4 counts 1 GHz of *virtual* time (1 ns per instruction with
/// `-icount shift=0`) whatever the RCC says, while the HAL computes the prescaler for the
/// 16 MHz HSI. Programming 25 Hz therefore gives an emulated period of 640 µs, i.e.
/// 640 000 instructions: room for the control task *and* the simulated plant with its
/// true-contour-error metric (about 200 000 instructions every tenth period, f64 soft
/// float inside libm's `sincosf`), so the telemetry task runs between periods and the
/// overrun counter means something. Each interrupt still advances the simulated gantry by
/// the scenario's 100 µs control period: the run is a faithful 10 kHz discrete simulation;
/// only the emulated wall clock runs 6.4 times slower (idle time costs no host time with
/// `-icount sleep=off`).
#[cfg(feature = "qemu")]
pub const CONTROL_TICK_PROGRAMMED_HZ: u32 = 25;

/// Interval between telemetry log lines (virtual time in QEMU), milliseconds.
#[cfg(not(feature = "qemu"))]
pub const TELEMETRY_PERIOD_MS: u32 = firmware::config::TELEMETRY_PERIOD_MS;
/// QEMU: one line every 4 emulated seconds (6 250 control periods, 0.625 s of the
/// simulated run).
#[cfg(feature = "qemu")]
pub const TELEMETRY_PERIOD_MS: u32 = 4_000;

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

/// The three quadrature encoder timers. (The QEMU build configures them but reads the
/// simulated gantry instead.)
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct Encoders {
    x: Qei<pac::TIM2>,
    y: Qei<pac::TIM5>,
    z: Qei<pac::TIM3>,
}

#[cfg_attr(feature = "qemu", allow(dead_code))]
impl Encoders {
    /// Raw counter registers X, Y, Z (Z is 16 bits wide).
    #[inline]
    pub fn read_raw(&self) -> [u32; AXES] {
        [self.x.count(), self.y.count(), u32::from(self.z.count())]
    }
}

/// Servo outputs: TIM1 PWM magnitude, direction and enable pins. (The QEMU build
/// configures and disables them, and drives the simulated gantry instead.)
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct ServoOutputs {
    pwm: [ErasedChannel<pac::TIM1>; AXES],
    direction: [AnyPin<Output>; AXES],
    enable: [AnyPin<Output>; AXES],
    max_duty_counts: u16,
    active: bool,
    /// Owns TIM1's period settings (kept so nothing else can reconfigure the timer).
    _timer: PwmHzManager<pac::TIM1>,
}

#[cfg_attr(feature = "qemu", allow(dead_code))]
impl ServoOutputs {
    /// Compare value for 100 % duty.
    pub fn max_duty_counts(&self) -> u16 {
        self.max_duty_counts
    }

    /// Writes duty and direction per axis and turns the output stage on if needed.
    #[inline]
    pub fn write(&mut self, cmd: &[firmware::drive::DriveCommand; AXES]) {
        for ((pwm, dir), c) in self.pwm.iter_mut().zip(self.direction.iter_mut()).zip(cmd) {
            dir.set_state(PinState::from(c.reverse));
            pwm.set_duty(c.duty_counts);
        }
        if !self.active {
            for en in self.enable.iter_mut() {
                en.set_high();
            }
            tim1_main_output(true);
            self.active = true;
        }
    }

    /// Main output off first (all three PWM pins to idle low in one write), then duties
    /// to zero and drive enables low. Cheap enough to call every period.
    #[inline]
    pub fn disable(&mut self) {
        tim1_main_output(false);
        for pwm in self.pwm.iter_mut() {
            pwm.set_duty(0);
        }
        for en in self.enable.iter_mut() {
            en.set_low();
        }
        self.active = false;
    }
}

/// Sets or clears TIM1 BDTR.MOE (with AOE kept clear, so only software re-enables it).
#[inline]
fn tim1_main_output(on: bool) {
    // SAFETY: after `init` the HAL only touches TIM1's CCR/CCER registers (duty, channel
    // enable); BDTR is owned by this function, and it is only called from the control
    // interrupt (or from `init` before interrupts run), so there is no concurrent access.
    let tim1 = unsafe { &*pac::TIM1::ptr() };
    tim1.bdtr().modify(|_, w| {
        w.ossi().set_bit();
        w.ossr().set_bit();
        w.aoe().clear_bit();
        w.moe().bit(on)
    });
}

/// E-stop, limit switches and the arm button.
pub struct InputPins {
    estop: AnyPin<Input>,
    limits: [[AnyPin<Input>; 2]; AXES],
    arm: AnyPin<Input>,
}

impl InputPins {
    /// Samples e-stop and limits (high = active for both, see the pin map).
    #[inline]
    pub fn read_safety(&self) -> SafetyInputs {
        let mut inputs = SafetyInputs {
            estop: self.estop.is_high(),
            ..SafetyInputs::default()
        };
        for (active, pins) in inputs.limits.iter_mut().zip(self.limits.iter()) {
            active[0] = pins[0].is_high();
            active[1] = pins[1].is_high();
        }
        inputs
    }

    /// Arm/reset button level (true = pressed).
    #[inline]
    pub fn arm_pressed(&self) -> bool {
        self.arm.is_low()
    }
}

impl firmware::io::SafetyInputSource for InputPins {
    fn read_safety_inputs(&mut self) -> SafetyInputs {
        self.read_safety()
    }
}

/// Status LEDs.
pub struct Leds {
    enabled: AnyPin<Output>,
    fault: AnyPin<Output>,
}

impl Leds {
    /// Shows the safety state.
    pub fn show(&mut self, enabled: bool, fault: bool) {
        self.enabled.set_state(PinState::from(enabled));
        self.fault.set_state(PinState::from(fault));
    }
}

/// The timer whose update interrupt runs the control loop.
pub struct ControlTick {
    timer: CounterHz<pac::TIM4>,
}

impl ControlTick {
    /// Starts the timer at `rate_hz` with its update interrupt enabled.
    pub fn start(&mut self, rate_hz: u32) {
        // `start` only fails for an ARR out of range; at 84 MHz every rate from 2 Hz to
        // 42 MHz fits (PSC is computed), so a failure means a misconfigured build.
        if self.timer.start(rate_hz.Hz()).is_err() {
            defmt::error!("control timer rejected rate {=u32} Hz", rate_hz);
        }
        self.timer.listen(Event::Update);
    }

    /// Acknowledges the update interrupt (first thing in the control task).
    #[inline]
    pub fn acknowledge(&mut self) {
        self.timer.clear_flags(Flag::Update);
    }

    /// True if another update happened since [`acknowledge`](Self::acknowledge): the
    /// control task did not finish within its period.
    #[inline]
    pub fn overran(&self) -> bool {
        self.timer.flags().contains(Flag::Update)
    }

    /// Stops the timer interrupt (end of a finite QEMU run).
    pub fn stop(&mut self) {
        self.timer.unlisten(Event::Update);
    }
}

/// Everything `init` hands to the RTIC tasks.
pub struct Board {
    pub encoders: Encoders,
    pub servo: ServoOutputs,
    pub inputs: InputPins,
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
    tim1_main_output(false);
    let max_duty_counts = pwm_timer.get_max_duty();
    let mut pwm = [
        ch1.with(gpioe.pe9).erase(),
        ch2.with(gpioe.pe11).erase(),
        ch3.with(gpioe.pe13).erase(),
    ];
    for ch in pwm.iter_mut() {
        ch.set_duty(0);
        ch.enable();
    }
    let mut servo = ServoOutputs {
        pwm,
        direction,
        enable,
        max_duty_counts,
        active: true,
        _timer: pwm_timer,
    };
    servo.disable();

    let encoders = Encoders {
        // PA15 and PB3 come out of reset as JTAG pins (AF0); SWD only needs PA13/PA14.
        x: dp
            .TIM2
            .qei((gpioa.pa15.into_input(), gpiob.pb3.into_input()), &mut rcc),
        y: dp.TIM5.qei((gpioa.pa0, gpioa.pa1), &mut rcc),
        z: dp.TIM3.qei((gpioa.pa6, gpioa.pa7), &mut rcc),
    };

    let inputs = InputPins {
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
        arm: gpiod.pd3.into_pull_up_input().erase(),
    };

    let mut leds = Leds {
        enabled: gpiod.pd12.into_push_pull_output().erase(),
        fault: gpiod.pd14.into_push_pull_output().erase(),
    };
    leds.show(false, false);

    let tick = ControlTick {
        timer: dp.TIM4.counter_hz(&mut rcc),
    };

    Board {
        encoders,
        servo,
        inputs,
        leds,
        tick,
    }
}
