//! Operator commands ([`Command`]), why one is refused ([`CommandRefusal`], with the line the user
//! reads), and the axis bit sets the servo publishes. Which command is valid when is
//! decided by [`super::modes::check`].

use crate::axes::{Axis, AXES};

/// Operator commands, applied at the start of a period in the order given.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Disabled -> Idle (inputs clear, no fault latched, every model-based law's model
    /// known), holding the current position.
    Arm,
    /// Outputs off: at once from Idle and Identify, after a controlled stop while moving.
    Disarm,
    /// Fault -> Disabled once every cause is gone (an encoder fault runs the encoder
    /// check first).
    Reset,
    /// Follow the configured path (from Idle or Run).
    StartPath,
    /// Run the homing sequence (from Idle).
    Home,
    /// Jog `axis` at `vel_mm_s` (0 stops) until the jog timeout; from Idle or Jog.
    Jog { axis: Axis, vel_mm_s: f32 },
    /// Identify `axis` (from Disabled or Idle): inside its travel when homed, else inside
    /// the user-confirmed window `window_mm` (machine coordinates, mm).
    Identify {
        axis: Axis,
        window_mm: Option<[f32; 2]>,
    },
    /// Follow the planner's reference (from Idle): the program queue.
    Run,
    /// Stop whatever moves (path, jog, homing, program) with a controlled stop and hold
    /// there (Idle); ends an identification.
    Stop,
    /// The host link's heartbeat watchdog expired: `LinkLost` fault, controlled stop.
    LinkLost,
    /// A new link session started: the `LinkLost` fault's cause is gone (a reset clears
    /// it).
    LinkUp,
    /// Measure `axis`' frequency response from effort to encoder (from Disabled or Idle,
    /// in Identify mode, the window as for [`Command::Identify`]): a stepped sine riding
    /// on a slow travel back and forth ([`crate::sysid::frequency`]).
    MeasureResponse {
        axis: Axis,
        window_mm: Option<[f32; 2]>,
    },
    /// Measure `axis`' open loop (from Idle: the laws hold it; in Identify mode, the
    /// window as for [`Command::Identify`]): the axis travels back and forth on its laws
    /// while a stepped sine is added to their effort
    /// ([`crate::sysid::frequency::loop_measure`]).
    MeasureLoop {
        axis: Axis,
        window_mm: Option<[f32; 2]>,
    },
}

/// Why a command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandRefusal {
    /// Not valid in the current state (the state is in the status).
    WrongState,
    /// A fault is latched: reset it first.
    FaultLatched,
    /// The e-stop is pressed.
    EStopActive,
    /// A limit switch is active (jog off it after a reset... or move it by hand).
    LimitActive,
    /// The axis runs a model-based law but its model was never identified or entered.
    ModelMissing { axis: Axis },
    /// The command needs the axis homed (homing is configured for it).
    NotHomed { axis: Axis },
    /// No path is configured.
    NoPath,
    /// Homing is not configured for any axis.
    NoHoming,
    /// The identification window is not inside the travel, or does not contain the axis.
    BadWindow { axis: Axis },
    /// The identification configuration rejected this axis' start.
    IdentifyRejected { axis: Axis },
}

impl CommandRefusal {
    /// One line for the user: what is wrong and how to fix it.
    pub const fn message(&self) -> &'static str {
        match self {
            Self::WrongState => "not allowed in the current state",
            Self::FaultLatched => "a fault is latched: clear its cause and reset",
            Self::EStopActive => "the e-stop is pressed",
            Self::LimitActive => "a limit switch is active",
            // (the axis named: a `&'static str` per axis, the interrupt formats nothing)
            Self::ModelMissing { axis: Axis::X } => {
                "axis x has no model: gantry identify --axis x --window-mm 10 --accept (or set axis.x.model)"
            }
            Self::ModelMissing { axis: Axis::Y } => {
                "axis y has no model: gantry identify --axis y --window-mm 10 --accept (or set axis.y.model)"
            }
            Self::ModelMissing { axis: Axis::Z } => {
                "axis z has no model: gantry identify --axis z --window-mm 10 --accept (or set axis.z.model)"
            }
            Self::NotHomed { axis: Axis::X } => "axis x is not homed: home the machine first (gantry home)",
            Self::NotHomed { axis: Axis::Y } => "axis y is not homed: home the machine first (gantry home)",
            Self::NotHomed { axis: Axis::Z } => "axis z is not homed: home the machine first (gantry home)",
            Self::NoPath => "no path is configured",
            Self::NoHoming => "homing is not configured",
            Self::BadWindow { .. } => {
                "the identification window must lie inside the travel and contain the axis"
            }
            Self::IdentifyRejected { .. } => {
                "identification cannot start here (too close to the window's ends, or its settings are invalid)"
            }
        }
    }
}

/// Bit set of axes (bit i = axis i) from per-axis flags.
pub fn axis_mask(flags: [bool; AXES]) -> u8 {
    flags
        .iter()
        .enumerate()
        .fold(0, |m, (i, f)| if *f { m | 1 << i } else { m })
}

#[cfg(test)]
mod message_tests {
    use super::*;
    use crate::machine::messages::TEXT_MAX;

    /// Every refusal reaches the operator whole: its text fits the link's refusal text
    /// (longer ones were cut mid-command).
    #[test]
    fn every_refusal_message_fits_the_links_text() {
        let fixed = [
            CommandRefusal::WrongState,
            CommandRefusal::FaultLatched,
            CommandRefusal::EStopActive,
            CommandRefusal::LimitActive,
            CommandRefusal::NoPath,
            CommandRefusal::NoHoming,
        ];
        let per_axis = [Axis::X, Axis::Y, Axis::Z].map(|axis| {
            [
                CommandRefusal::ModelMissing { axis },
                CommandRefusal::NotHomed { axis },
                CommandRefusal::BadWindow { axis },
                CommandRefusal::IdentifyRejected { axis },
            ]
        });
        let all = fixed.iter().chain(per_axis.iter().flatten());
        for r in all {
            let m = r.message();
            assert!(m.len() <= TEXT_MAX, "{r:?}: {} > {TEXT_MAX}: {m}", m.len());
        }
        assert!(CommandRefusal::ModelMissing { axis: Axis::Y }
            .message()
            .contains("identify --axis y"));
    }
}
