//! Digital inputs: the e-stop and limit switches (sampled by the control interrupt every
//! period, through the core's `ServoIo::read_inputs`) and the arm/reset button (sampled
//! by the button task).
//!
//! All are NC/NO contacts to GND with pull-ups: a broken e-stop or limit wire reads
//! "active", so it stops the machine.

use stm32f4xx_hal::gpio::{AnyPin, Input};

use controller_core::axes::AXES;
use controller_core::servo::io::Inputs;

/// E-stop (PB12) and limit switches X-/X+/Y-/Y+/Z-/Z+ (PC0..PC5); high = active.
pub struct SafetyPins {
    pub estop: AnyPin<Input>,
    pub limits: [[AnyPin<Input>; 2]; AXES],
}

impl SafetyPins {
    /// Samples e-stop and limits.
    #[inline]
    pub fn read(&self) -> Inputs {
        let mut inputs = Inputs {
            estop: self.estop.is_high(),
            ..Inputs::default()
        };
        for (active, pins) in inputs.limits.iter_mut().zip(self.limits.iter()) {
            active[0] = pins[0].is_high();
            active[1] = pins[1].is_high();
        }
        inputs
    }
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
