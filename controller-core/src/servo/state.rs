//! The servo's states ([`ServoState`]): which mode it is in and whether it drives its
//! outputs. The lowest file of the servo: commands, snapshot and step all name them.

/// State of the servo and its outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ServoState {
    /// Outputs off, waiting for an explicit arm.
    Disabled,
    /// Outputs on, holding position.
    Idle,
    /// Outputs on, following the path or the planner's program.
    Run,
    /// Outputs on, jogging.
    Jog,
    /// Outputs on, running the homing sequence.
    Homing,
    /// Identifying an axis (the others hold, or are off when started from Disabled).
    Identify,
    /// Outputs on, decelerating to rest (after a controlled-stop fault, or a disarm while
    /// moving); then outputs off.
    Stopping,
    /// Reset of an encoder fault: a small effort on the faulted axes must move them.
    EncoderCheck,
    /// Outputs off, fault latched.
    Fault,
}

impl ServoState {
    /// The outputs are driven in this state (in `Identify` at least the identified axis').
    pub const fn drives(self) -> bool {
        !matches!(self, Self::Disabled | Self::Fault)
    }
}
