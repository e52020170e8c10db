//! Servo outputs: TIM1 PWM magnitude (CH1..CH3 on PE9/PE11/PE13, 20 kHz), direction pins,
//! drive enables and the holding-brake outputs (PD4/PD5/PD6: high = coil energised,
//! brake released; low = gripping, the reset and fault state). (The QEMU rig configures and disables them, and drives the
//! simulated machine instead.)
//!
//! All three PWM channels are on TIM1, so one register write (clearing BDTR.MOE) turns
//! every servo output off at once; OSSI/OSSR keep a disabled output at its idle level.
//! TIM1's break input (the e-stop line, PB12) clears MOE in hardware, even with the CPU
//! halted; automatic output enable is off and locked, so only this module turns the
//! outputs on again (BDTR values in [`super::shutdown`]).

use stm32f4xx_hal::{
    gpio::{AnyPin, Output, PinState},
    pac,
    timer::{ErasedChannel, PwmHzManager},
};

use controller_core::axes::AXES;
use firmware::drive::DriveCommand;

use super::shutdown::{BDTR_ON, BDTR_SAFE};

/// TIM1's three PWM channels, direction, enable and brake pins.
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct ServoOutputs {
    pwm: [ErasedChannel<pac::TIM1>; AXES],
    direction: [AnyPin<Output>; AXES],
    enable: [AnyPin<Output>; AXES],
    /// Brake coils X, Y, Z (high = released).
    brake: [AnyPin<Output>; AXES],
    max_duty_counts: u16,
    active: bool,
    /// Owns TIM1's period settings (kept so nothing else can reconfigure the timer).
    _timer: PwmHzManager<pac::TIM1>,
}

#[cfg_attr(feature = "qemu", allow(dead_code))]
impl ServoOutputs {
    /// Takes the configured timer and pins and switches everything off.
    pub fn new(
        timer: PwmHzManager<pac::TIM1>,
        mut pwm: [ErasedChannel<pac::TIM1>; AXES],
        direction: [AnyPin<Output>; AXES],
        enable: [AnyPin<Output>; AXES],
        brake: [AnyPin<Output>; AXES],
    ) -> Self {
        configure_tim1_break_and_idle();
        for ch in pwm.iter_mut() {
            ch.set_duty(0);
            ch.enable();
        }
        let mut s = Self {
            max_duty_counts: timer.get_max_duty(),
            pwm,
            direction,
            enable,
            brake,
            active: true,
            _timer: timer,
        };
        s.disable();
        s
    }

    /// Compare value for 100 % duty.
    pub fn max_duty_counts(&self) -> u16 {
        self.max_duty_counts
    }

    /// Writes duty and direction per axis and turns the output stage on if needed.
    #[inline]
    pub fn write(&mut self, cmd: &[DriveCommand; AXES]) {
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
    /// to zero, drive enables low and every brake gripping (an axis whose amplifier is off
    /// must never hang on an open brake, whatever the servo commanded). Cheap enough to
    /// call every period.
    #[inline]
    pub fn disable(&mut self) {
        tim1_main_output(false);
        for pwm in self.pwm.iter_mut() {
            pwm.set_duty(0);
        }
        for en in self.enable.iter_mut() {
            en.set_low();
        }
        for b in self.brake.iter_mut() {
            b.set_low();
        }
        self.active = false;
    }

    /// The brake coils: `released[i]` energises axis i's (brake open), `false` lets it
    /// grip. Only while the output stage is on: with it off every brake stays gripping.
    #[inline]
    pub fn write_brakes(&mut self, released: [bool; AXES]) {
        for (pin, r) in self.brake.iter_mut().zip(released) {
            pin.set_state(PinState::from(r && self.active));
        }
    }
}

/// TIM1's break and idle configuration, outputs off: the first write of BDTR after the
/// HAL's `pwm_hz` (which turns automatic output enable on), and the one that sets the
/// lock (see [`super::shutdown::BDTR_SAFE`]). Called before the PWM pins are switched to
/// TIM1, so they go from GPIO low straight to a driven idle low.
pub fn configure_tim1_break_and_idle() {
    tim1_main_output(false);
}

/// Sets or clears TIM1 BDTR.MOE by writing the whole register (the rest of it is the
/// locked safe configuration, so the write cannot change anything else).
#[inline]
fn tim1_main_output(on: bool) {
    // SAFETY: BDTR is written only here and by `shutdown::outputs_off_raw` (fault paths),
    // always with whole values; this is called from the control interrupt or from `init`.
    let tim1 = unsafe { &*pac::TIM1::ptr() };
    let bits = if on { BDTR_ON } else { BDTR_SAFE };
    tim1.bdtr().write(|w| unsafe { w.bits(bits) });
}
