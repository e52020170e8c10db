//! The core's [`ServoIo`] for the board: encoder timer registers and index captures
//! ([`super::index`]) in, e-stop, limit and
//! amplifier-fault pins and the control timer's overrun flag in, TIM1 PWM + direction +
//! drive enables + holding brakes out (through [`DriveCommand`]: full duty is
//! the amplifier's `full_scale` of the servo configuration).

use controller_core::axes::AXES;
use controller_core::servo::io::{Inputs, ServoIo};
use firmware::drive::DriveCommand;

use super::encoders::Encoders;
use super::index::IndexInputs;
use super::inputs::SafetyPins;
use super::pwm::ServoOutputs;

/// The machine as the servo step sees it.
pub struct BoardIo {
    encoders: Encoders,
    /// The encoders' index captures.
    index: IndexInputs,
    servo: ServoOutputs,
    safety: SafetyPins,
    /// Effort that maps to 100 % duty, per axis.
    full_scale: [f32; AXES],
    /// The previous control period missed its deadline (`Inputs::overrun`).
    overrun: bool,
}

impl BoardIo {
    /// The board's IO; no output until the first period (full scale from the settings
    /// then, [`Self::set_full_scale`]).
    pub fn new(
        encoders: Encoders,
        index: IndexInputs,
        servo: ServoOutputs,
        safety: SafetyPins,
    ) -> Self {
        Self {
            encoders,
            index,
            servo,
            safety,
            full_scale: [f32::INFINITY; AXES],
            overrun: false,
        }
    }

    /// Effort that maps to 100 % duty, per axis (the settings' amplifier full scale,
    /// which may change while the outputs are off).
    #[inline]
    pub fn set_full_scale(&mut self, full_scale: [f32; AXES]) {
        self.full_scale = full_scale;
    }

    /// Whether the period that just ended overran (read by the next period's inputs).
    #[inline]
    pub fn set_overrun(&mut self, overran: bool) {
        self.overrun = overran;
    }

    /// Encoder registers now (the servo's count origin at boot).
    pub fn encoder_raw(&self) -> [u32; AXES] {
        self.encoders.read_raw()
    }
}

impl ServoIo<f32> for BoardIo {
    #[inline]
    fn read_inputs(&mut self) -> Inputs {
        Inputs {
            overrun: self.overrun,
            ..self.safety.read()
        }
    }

    #[inline]
    fn read_counters(&mut self) -> [u32; AXES] {
        self.encoders.read_raw()
    }

    /// X and Z from their timers' channel 3 capture (CC3IF, CCR3), Y from the EXTI1
    /// task's capture of TIM5_CNT; each `Some` once per capture.
    #[inline]
    fn read_index(&mut self) -> [Option<u32>; AXES] {
        self.index.read()
    }

    #[inline]
    fn write_outputs(&mut self, effort: &[f32; AXES]) {
        let max = self.servo.max_duty_counts();
        let mut cmd = [DriveCommand::OFF; AXES];
        for ((c, u), fs) in cmd.iter_mut().zip(effort).zip(self.full_scale) {
            *c = DriveCommand::from_effort(*u, fs, max);
        }
        self.servo.write(&cmd);
    }

    #[inline]
    fn disable_outputs(&mut self) {
        self.servo.disable();
    }

    #[inline]
    fn write_brakes(&mut self, released: [bool; AXES]) {
        self.servo.write_brakes(released);
    }
}
