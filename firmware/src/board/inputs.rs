//! Digital inputs: the e-stop, limit switches and amplifier faults (sampled by the control
//! interrupt every period, through the core's `ServoIo::read_inputs`) and the arm/reset
//! button (sampled by the button task).
//!
//! All are contacts or open-collector outputs to GND with pull-ups: a broken wire reads
//! "active", so it stops the machine.
//!
//! The e-stop pin PB12 is TIM1's break input (TIM1_BKIN, AF1): an active e-stop (high)
//! switches the PWM off in hardware, whatever the CPU does. The pin's level is still
//! readable in alternate-function mode; the software e-stop is that level *or* TIM1's break
//! flag (BIF), so a pulse on the line too short for a period's sample still latches an
//! e-stop fault instead of silently leaving the PWM off.

use stm32f4xx_hal::{
    gpio::{Alternate, AnyPin, Input, PB12},
    pac,
};

use controller_core::axes::AXES;
use controller_core::servo::io::Inputs;

/// E-stop (PB12, TIM1_BKIN), limit switches X-/X+/Y-/Y+/Z-/Z+ (PC0..PC5) and amplifier
/// faults X/Y/Z (PD8..PD10); high = active.
pub struct SafetyPins {
    pub estop: PB12<Alternate<1>>,
    pub limits: [[AnyPin<Input>; 2]; AXES],
    pub amp_fault: [AnyPin<Input>; AXES],
}

impl SafetyPins {
    /// Samples e-stop (pin and TIM1 break flag), limits and amplifier faults.
    #[inline]
    pub fn read(&self) -> Inputs {
        let mut inputs = Inputs {
            estop: self.estop.is_high() | take_tim1_break(),
            ..Inputs::default()
        };
        for (active, pins) in inputs.limits.iter_mut().zip(self.limits.iter()) {
            active[0] = pins[0].is_high();
            active[1] = pins[1].is_high();
        }
        for (active, pin) in inputs.amp_fault.iter_mut().zip(self.amp_fault.iter()) {
            *active = pin.is_high();
        }
        inputs
    }
}

/// TIM1's break flag (set by hardware when the break input went active, also by the clock
/// security system), cleared after reading; it stays set while the break input is active.
#[inline]
fn take_tim1_break() -> bool {
    // SAFETY: TIM1 SR is read and written only here (the firmware uses no TIM1 interrupt
    // or flag otherwise); the write clears BIF alone (the other flags are rc_w0 bits
    // written as 1, which leaves them as they are).
    let tim1 = unsafe { &*pac::TIM1::ptr() };
    let set = tim1.sr().read().bif().bit_is_set();
    if set {
        tim1.sr().write(|w| w.bif().clear_bit());
    }
    set
}

/// The arm/reset button (PD3, NO contact to GND).
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct ArmButton {
    pub pin: AnyPin<Input>,
}

#[cfg_attr(feature = "qemu", allow(dead_code))]
impl ArmButton {
    /// True while pressed.
    #[inline]
    pub fn pressed(&self) -> bool {
        self.pin.is_low()
    }
}
