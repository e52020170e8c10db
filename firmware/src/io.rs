//! The boundary between the control loop and the machine.
//!
//! [`GantryIo`] is what the control interrupt needs from the outside world once per
//! period. The board implementation (`board_io::BoardIo`, in the binary) reads the encoder
//! timers and input pins and writes TIM1 PWM, direction and enable pins. The QEMU build
//! uses [`crate::sim::SimGantry`], which reads the same input pins but replaces the
//! encoder reads and PWM writes by controller-core's plant model.

use crate::safety::{Request, SafetyInputs};
use crate::AXES;

/// Per-period access to sensors and actuators. Every method must be short, bounded and
/// non-blocking: they run inside the highest-priority interrupt.
pub trait GantryIo {
    /// Samples e-stop and limit switches (already converted to "active").
    fn read_safety_inputs(&mut self) -> SafetyInputs;

    /// Operator request for this period (debounced arm button, scenario start, ...).
    fn read_request(&mut self) -> Request;

    /// Raw encoder counter registers, X, Y, Z (each only meaningful in its timer's width).
    fn read_encoder_raw(&mut self) -> [u32; AXES];

    /// Drives the axes with the (already saturated) control efforts and turns the output
    /// stage on if it is off.
    fn drive(&mut self, effort: &[f32; AXES]);

    /// Switches every output off: PWM main output disabled, duties zero, drive enables
    /// low. Must be idempotent and safe to call in every period.
    fn disable_outputs(&mut self);

    /// Called last in every period. Hardware: nothing to do. Simulation: integrates the
    /// plant over one period with the output held (zero-order hold).
    fn period_end(&mut self) {}
}

/// Source of the e-stop and limit-switch inputs (the board's GPIO pins).
pub trait SafetyInputSource {
    fn read_safety_inputs(&mut self) -> SafetyInputs;
}
