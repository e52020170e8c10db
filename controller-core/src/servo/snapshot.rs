//! The telemetry snapshot the servo step publishes every period: plain copies of numbers,
//! no formatting (a lower-priority task or the simulator turns them into lines, plots or
//! statistics outside the control interrupt).

use crate::axes::AXES;
use crate::servo::commands::{Command, CommandRefusal};
use crate::servo::faults::FaultRecord;
use crate::servo::io::Inputs;
use crate::servo::state::ServoState;

/// Everything a logger or a recorder needs about the last period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snapshot {
    /// Control periods since boot.
    pub period: u32,
    /// Time since the current motion (path, stop) started, s (0 while holding).
    pub motion_t_s: f32,
    /// State after this period.
    pub state: ServoState,
    /// The first latched fault, if any.
    pub fault: Option<FaultRecord>,
    /// Latched fault kinds as bit sets (bit = `FaultKind` code): system, per axis.
    pub fault_bits: (u32, [u32; AXES]),
    /// The safety inputs sampled this period.
    pub inputs: Inputs,
    /// Axes that are homed or take no part in homing (bit i = axis i).
    pub homed: u8,
    /// Axes whose model-based law has no known model (arming is refused).
    pub model_missing: u8,
    /// A command refused in the last period that applied commands, with the reason.
    pub refused: Option<(Command, CommandRefusal)>,
    /// Progress of the current (or last) homing or identification, 0..=1.
    pub progress: f32,
    /// Measured positions (encoder counts converted to length).
    pub pos: [f32; AXES],
    /// Estimated velocities.
    pub vel: [f32; AXES],
    /// Reference positions.
    pub reference: [f32; AXES],
    /// Tracking error reference - measured, per axis.
    pub tracking: [f32; AXES],
    /// The controller's contour-error vector estimate (0 without coupling).
    pub contour: [f32; AXES],
    /// Sliding variables (0 for PID axes).
    pub s: [f32; AXES],
    /// Applied (saturated) effort per axis; 0 while the outputs are off.
    pub effort: [f32; AXES],
    /// Wide encoder positions, counts.
    pub counts: [i64; AXES],
    /// The outputs were driven this period.
    pub outputs_on: bool,
    /// Counts the index check corrected so far per axis (the net of the glitches it
    /// found; `servo::index_check`).
    pub index_corrected_counts: [i32; AXES],
    /// Per axis: the holding brake is commanded released (coil energised) after this
    /// period; always false on an axis without a brake ([`crate::servo::brake`]).
    pub brakes_released: [bool; AXES],
}

impl Snapshot {
    /// The snapshot before the first control period.
    pub const fn boot() -> Self {
        Self {
            period: 0,
            motion_t_s: 0.0,
            state: ServoState::Disabled,
            fault: None,
            fault_bits: (0, [0; AXES]),
            inputs: Inputs {
                estop: false,
                limits: [[false; 2]; AXES],
                amp_fault: [false; AXES],
                overrun: false,
            },
            homed: 0,
            model_missing: 0,
            refused: None,
            progress: 0.0,
            pos: [0.0; AXES],
            vel: [0.0; AXES],
            reference: [0.0; AXES],
            tracking: [0.0; AXES],
            contour: [0.0; AXES],
            s: [0.0; AXES],
            effort: [0.0; AXES],
            counts: [0; AXES],
            outputs_on: false,
            index_corrected_counts: [0; AXES],
            brakes_released: [false; AXES],
        }
    }

    /// Magnitude of the contour-error estimate.
    pub fn contour_norm(&self) -> f32 {
        let [x, y, z] = self.contour;
        libm::sqrtf(x * x + y * y + z * z)
    }
}
