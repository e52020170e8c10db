//! The controlled stop's state: what it ends in, how long it may take, and the e-stop's
//! bounded stop. The transitions that start and end a stop are in [`super::modes`].

use super::state::ServoState;
use crate::axes::AXES;

/// The controlled stop's parameters (from the safety configuration) and the one under way.
pub(super) struct StopState {
    /// The state a controlled stop ends in (Fault, Disabled after a disarm, Idle after a
    /// stop command).
    pub(super) then: ServoState,
    /// Periods the stop reference has been at rest.
    pub(super) rest_periods: u32,
    /// Periods at rest after which the stop has settled.
    pub(super) settle_periods: u32,
    /// Periods at rest after which the stop ends, settled or not.
    pub(super) timeout_periods: u32,
    /// The e-stop is a controlled stop (category 1).
    pub(super) estop_controlled: bool,
    /// Periods a category-1 e-stop's stop may take before the outputs go off.
    pub(super) estop_periods: u32,
    /// Periods a category-1 e-stop's stop may still take before the outputs go off.
    pub(super) estop_left: Option<u32>,
    /// Each axis' deceleration in a stop, mm/s².
    pub(super) decel: [f32; AXES],
    /// The controlled stop under way ends with the brakes engaging: none is released, and
    /// the outputs go off once every brake grips.
    pub(super) braking: bool,
}
