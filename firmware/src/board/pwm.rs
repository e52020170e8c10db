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
    gpio::{AnyPin, Output, PinExt, PinState},
    pac,
    timer::{ErasedChannel, PwmHzManager},
};

use controller_core::axes::AXES;
use firmware::drive::DriveCommand;

use super::shutdown::{self, BDTR_ON, BDTR_SAFE};

/// TIM1's three PWM channels, direction, enable and brake pins.
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct ServoOutputs {
    pwm: [ErasedChannel<pac::TIM1>; AXES],
    direction: [AnyPin<Output>; AXES],
    /// The drive enables and the brake coils (X, Y, Z; high = enabled / released): owned
    /// here, driven together through GPIOD BSRR (`shutdown`'s pin masks, one store for
    /// all of them).
    _enable: [AnyPin<Output>; AXES],
    _brake: [AnyPin<Output>; AXES],
    /// The enable and brake pins are the GPIOD pins `shutdown`'s masks name (checked in
    /// `new`; if not, the outputs never turn on).
    pins_as_wired: bool,
    max_duty_counts: u16,
    /// The direction each pin drives now (true = negative).
    reverse: [bool; AXES],
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
        compare_preload_off();
        let on_port_d = |pins: &[AnyPin<Output>; AXES], ids: [u8; AXES]| {
            pins.iter()
                .zip(ids)
                .all(|(p, id)| p.port_id() == shutdown::GPIOD_PORT_ID && p.pin_id() == id)
        };
        let pins_as_wired = on_port_d(&enable, shutdown::ENABLE_PIN_IDS)
            && on_port_d(&brake, shutdown::BRAKE_PIN_IDS);
        if !pins_as_wired {
            defmt::error!(
                "servo outputs: the enable/brake pins are not PD0-2/PD4-6: outputs stay off"
            );
        }
        let mut s = Self {
            max_duty_counts: timer.get_max_duty(),
            pwm,
            direction,
            _enable: enable,
            _brake: brake,
            pins_as_wired,
            reverse: [false; AXES],
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
        let pins = self.pwm.iter_mut().zip(self.direction.iter_mut());
        for (((pwm, dir), c), reverse) in pins.zip(cmd).zip(self.reverse.iter_mut()) {
            // a sign change: the duty goes to 0 before the direction pin flips, so no
            // magnitude is ever driven the wrong way (the compare preload is off: every
            // duty takes effect as it is written)
            if c.reverse != *reverse {
                pwm.set_duty(0);
                dir.set_state(PinState::from(c.reverse));
                *reverse = c.reverse;
            }
            pwm.set_duty(c.duty_counts);
        }
        if !self.active && self.pins_as_wired {
            shutdown::gpiod_set_reset(shutdown::ENABLE_PINS, 0);
            tim1_main_output(true);
            self.active = true;
        }
    }

    /// The fault path's stores ([`shutdown::outputs_off_raw`]): main output off first
    /// (all three PWM pins to idle low in one write), duties to zero, then every drive
    /// enable low and every brake gripping in one GPIOD store (an axis whose amplifier is
    /// off must never hang on an open brake, whatever the servo commanded). Five stores:
    /// cheap enough to call every period.
    #[inline]
    pub fn disable(&mut self) {
        shutdown::outputs_off_raw();
        self.active = false;
    }

    /// The brake coils: `released[i]` energises axis i's (brake open), `false` lets it
    /// grip; all three in one GPIOD store. Only while the output stage is on: with it off
    /// every brake stays gripping.
    #[inline]
    pub fn write_brakes(&mut self, released: [bool; AXES]) {
        let mut open = 0;
        for (id, r) in shutdown::BRAKE_PIN_IDS.into_iter().zip(released) {
            if r && self.active {
                open |= 1 << id;
            }
        }
        shutdown::gpiod_set_reset(open, shutdown::BRAKE_PINS & !open);
    }
}

/// TIM1's break and idle configuration, outputs off (MOE cleared; the rest of BDTR is
/// locked by [`reset_and_lock_tim1`]).
pub fn configure_tim1_break_and_idle() {
    tim1_main_output(false);
}

/// TIM1 CCMR1/CCMR2 output-compare preload enables (OC1PE, OC2PE; OC3PE), RM0090 17.4.7.
const CCMR1_OC1PE_OC2PE: u32 = (1 << 3) | (1 << 11);
const CCMR2_OC3PE: u32 = 1 << 3;

/// Re-initialises TIM1 with its configuration locked: BDTR's LOCK can be written once
/// after a reset, by the first write of BDTR, and the HAL's `pwm_hz` has already written it
/// (automatic output enable), which left LOCK at 0 for good. So: keep the period and the
/// PWM modes the HAL computed, reset the timer through RCC, write BDTR first
/// ([`BDTR_SAFE`]: break on, AOE off, idle low, LOCK level 1), then the period, the modes
/// and the counter back. Called once, in `init`, before the PWM pins become TIM1 outputs
/// and before any channel is enabled.
pub fn reset_and_lock_tim1() {
    // SAFETY: init, interrupts disabled; TIM1 is not enabled as an output yet (MOE off,
    // CCER 0) and nothing else uses it; the RCC reset bit is TIM1's alone.
    let (rcc, tim1) = unsafe { (&*pac::RCC::ptr(), &*pac::TIM1::ptr()) };
    let psc = tim1.psc().read().bits();
    let arr = tim1.arr().read().bits();
    let ccmr1 = tim1.ccmr1_output().read().bits();
    let ccmr2 = tim1.ccmr2_output().read().bits();
    let cr1 = tim1.cr1().read().bits();
    rcc.apb2rstr().modify(|_, w| w.tim1rst().set_bit());
    rcc.apb2rstr().modify(|_, w| w.tim1rst().clear_bit());
    tim1.bdtr().write(|w| unsafe { w.bits(BDTR_SAFE) });
    tim1.psc().write(|w| unsafe { w.bits(psc) });
    tim1.arr().write(|w| unsafe { w.bits(arr) });
    tim1.ccmr1_output().write(|w| unsafe { w.bits(ccmr1) });
    tim1.ccmr2_output().write(|w| unsafe { w.bits(ccmr2) });
    // load PSC/ARR into their shadows, then count as the HAL had it (ARPE, CEN)
    tim1.egr().write(|w| w.ug().set_bit());
    tim1.cr1().write(|w| unsafe { w.bits(cr1) });
}

/// Turns TIM1's compare preload off on CH1..CH3 (the HAL's channel enable turns it on):
/// a new duty takes effect when it is written, together with its direction pin; with the
/// preload the old duty would drive the new direction until the next update, up to a PWM
/// period (50 µs) ([`ServoOutputs::write`]).
fn compare_preload_off() {
    // SAFETY: init (from `ServoOutputs::new`), before the outputs are on; CCMR1/CCMR2 are
    // written nowhere else after this.
    let tim1 = unsafe { &*pac::TIM1::ptr() };
    tim1.ccmr1_output()
        .modify(|r, w| unsafe { w.bits(r.bits() & !CCMR1_OC1PE_OC2PE) });
    tim1.ccmr2_output()
        .modify(|r, w| unsafe { w.bits(r.bits() & !CCMR2_OC3PE) });
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
