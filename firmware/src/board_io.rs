//! [`GantryIo`] for the real board: encoder timers in, TIM1 PWM + direction + enable out.

use firmware::button::Debounce;
use firmware::drive::DriveCommand;
use firmware::io::GantryIo;
use firmware::safety::{Request, SafetyInputs};
use firmware::AXES;

use crate::board::{Encoders, InputPins, ServoOutputs};

/// The machine as the control loop sees it.
pub struct BoardIo {
    encoders: Encoders,
    servo: ServoOutputs,
    inputs: InputPins,
    arm_button: Debounce,
    effort_limit: f32,
}

impl BoardIo {
    /// `effort_limit` is the effort that maps to 100 % duty.
    pub fn new(
        encoders: Encoders,
        servo: ServoOutputs,
        inputs: InputPins,
        arm_hold_periods: u16,
        effort_limit: f32,
    ) -> Self {
        Self {
            encoders,
            servo,
            inputs,
            arm_button: Debounce::new(arm_hold_periods),
            effort_limit,
        }
    }

    /// Encoder registers now (for the control loop's zero).
    pub fn encoder_raw(&self) -> [u32; AXES] {
        self.encoders.read_raw()
    }
}

impl GantryIo for BoardIo {
    #[inline]
    fn read_safety_inputs(&mut self) -> SafetyInputs {
        self.inputs.read_safety()
    }

    #[inline]
    fn read_request(&mut self) -> Request {
        if self.arm_button.update(self.inputs.arm_pressed()) {
            Request::ArmOrReset
        } else {
            Request::None
        }
    }

    #[inline]
    fn read_encoder_raw(&mut self) -> [u32; AXES] {
        self.encoders.read_raw()
    }

    #[inline]
    fn drive(&mut self, effort: &[f32; AXES]) {
        let max = self.servo.max_duty_counts();
        let cmd = effort.map(|u| DriveCommand::from_effort(u, self.effort_limit, max));
        self.servo.write(&cmd);
    }

    #[inline]
    fn disable_outputs(&mut self) {
        self.servo.disable();
    }
}
