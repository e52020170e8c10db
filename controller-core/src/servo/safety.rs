//! The output-enable state machine: outputs stay off until explicitly armed, any fault
//! latches.
//!
//! ```text
//!            arm (inputs clear)
//!  Disabled ─────────────────────▶ Enabled
//!     ▲  ▲                            │ e-stop / limit / following error
//!     │  └──── disarm ────────────────┤
//!     │                               ▼
//!     └──── reset (cause gone) ──── Fault(reason)   ◀── e-stop in any state
//! ```
//!
//! * Boot state is [`SafetyState::Disabled`].
//! * The servo step calls [`SafetyMonitor::update`] first in every period, with the inputs
//!   sampled in that period, and only drives the outputs if the result is
//!   [`SafetyState::Enabled`]: an e-stop, a limit switch or a following-error trip
//!   disables every output in the same control period.
//! * A fault latches: the reason stays visible until an explicit reset request, which is
//!   honoured only once the cause is gone, and leads back to `Disabled`, never directly to
//!   `Enabled`.

use crate::axes::{Axis, AXES};
use crate::servo::io::Inputs;

/// End of travel that a limit switch guards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LimitEnd {
    Min,
    Max,
}

/// Why the outputs were switched off. Latched until reset.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultReason {
    /// The emergency-stop input is active (pressed or wire broken).
    EStop,
    /// A limit switch is active.
    Limit { axis: Axis, end: LimitEnd },
    /// |reference - measured| exceeded the configured limit.
    FollowingError { axis: Axis, error_mm: f32 },
    /// The controller produced a non-finite command.
    NonFiniteCommand { axis: Axis },
}

/// State of the output stage.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SafetyState {
    /// Outputs off, waiting for an explicit arm request.
    Disabled,
    /// Outputs driven by the controller.
    Enabled,
    /// Outputs off, fault latched.
    Fault(FaultReason),
}

/// Operator requests that change the state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    /// Nothing new this period.
    None,
    /// Disabled -> Enabled if the inputs are clear; Fault -> Disabled if the cause is gone.
    ArmOrReset,
    /// Enabled -> Disabled (not a fault).
    Disarm,
}

fn first_limit(inputs: &Inputs) -> Option<(Axis, LimitEnd)> {
    for (axis, ends) in Axis::ALL.iter().zip(inputs.limits.iter()) {
        if ends[0] {
            return Some((*axis, LimitEnd::Min));
        }
        if ends[1] {
            return Some((*axis, LimitEnd::Max));
        }
    }
    None
}

/// The state machine. Pure logic; the servo step applies the resulting state.
#[derive(Clone, Copy, Debug)]
pub struct SafetyMonitor {
    state: SafetyState,
    following_error_limit_mm: [f32; AXES],
}

impl SafetyMonitor {
    /// Boots in [`SafetyState::Disabled`].
    pub const fn new(following_error_limit_mm: [f32; AXES]) -> Self {
        Self {
            state: SafetyState::Disabled,
            following_error_limit_mm,
        }
    }

    pub const fn state(&self) -> SafetyState {
        self.state
    }

    /// True only in [`SafetyState::Enabled`].
    pub fn outputs_enabled(&self) -> bool {
        self.state == SafetyState::Enabled
    }

    /// Evaluates the hardware inputs and the operator request. Call first in every control
    /// period, before any output is written.
    pub fn update(&mut self, inputs: &Inputs, request: Request) -> SafetyState {
        // Hard inputs win over everything, in every state.
        if inputs.estop {
            self.latch(FaultReason::EStop);
            return self.state;
        }
        let limit = first_limit(inputs);
        match (self.state, request) {
            (SafetyState::Enabled, _) => {
                if let Some((axis, end)) = limit {
                    self.latch(FaultReason::Limit { axis, end });
                } else if request == Request::Disarm {
                    self.state = SafetyState::Disabled;
                }
            }
            (SafetyState::Disabled, Request::ArmOrReset) if limit.is_none() => {
                self.state = SafetyState::Enabled;
            }
            (SafetyState::Fault(_), Request::ArmOrReset) if limit.is_none() => {
                self.state = SafetyState::Disabled;
            }
            _ => {}
        }
        self.state
    }

    /// Checks the per-axis following error (reference minus measurement, mm) while enabled.
    pub fn check_following_error(&mut self, error_mm: &[f32; AXES]) -> SafetyState {
        if self.state == SafetyState::Enabled {
            for ((axis, err), limit) in Axis::ALL
                .iter()
                .zip(error_mm.iter())
                .zip(self.following_error_limit_mm.iter())
            {
                // A NaN error also trips: `!(|e| <= limit)`.
                if !(err.abs() <= *limit) {
                    self.latch(FaultReason::FollowingError {
                        axis: *axis,
                        error_mm: *err,
                    });
                    break;
                }
            }
        }
        self.state
    }

    /// Latches a fault found by the caller.
    pub fn trip(&mut self, reason: FaultReason) {
        self.latch(reason);
    }

    fn latch(&mut self, reason: FaultReason) {
        // Keep the first reason: it is the root cause, later ones are consequences.
        if !matches!(self.state, SafetyState::Fault(_)) {
            self.state = SafetyState::Fault(reason);
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    const LIMIT_MM: [f32; AXES] = [1.0, 1.0, 2.0];

    fn clear() -> Inputs {
        Inputs::default()
    }

    #[test]
    fn boots_disabled_and_stays_disabled_without_request() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        assert_eq!(m.state(), SafetyState::Disabled);
        for _ in 0..10 {
            assert_eq!(m.update(&clear(), Request::None), SafetyState::Disabled);
        }
        assert!(!m.outputs_enabled());
    }

    #[test]
    fn arms_only_with_clear_inputs() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        let mut limit = clear();
        limit.limits[1][1] = true;
        assert_eq!(m.update(&limit, Request::ArmOrReset), SafetyState::Disabled);
        assert_eq!(
            m.update(&clear(), Request::ArmOrReset),
            SafetyState::Enabled
        );
        assert!(m.outputs_enabled());
    }

    #[test]
    fn estop_trips_in_same_period_and_latches() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        m.update(&clear(), Request::ArmOrReset);
        let estop = Inputs {
            estop: true,
            ..clear()
        };
        assert_eq!(
            m.update(&estop, Request::None),
            SafetyState::Fault(FaultReason::EStop)
        );
        // Released but not reset: still latched.
        assert_eq!(
            m.update(&clear(), Request::None),
            SafetyState::Fault(FaultReason::EStop)
        );
        // Reset while still pressed: refused.
        assert_eq!(
            m.update(&estop, Request::ArmOrReset),
            SafetyState::Fault(FaultReason::EStop)
        );
        // Reset after release goes to Disabled, not Enabled.
        assert_eq!(
            m.update(&clear(), Request::ArmOrReset),
            SafetyState::Disabled
        );
    }

    #[test]
    fn estop_while_disabled_latches_too() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        let estop = Inputs {
            estop: true,
            ..clear()
        };
        assert_eq!(
            m.update(&estop, Request::ArmOrReset),
            SafetyState::Fault(FaultReason::EStop)
        );
    }

    #[test]
    fn limit_switch_trips_with_axis_and_end() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        m.update(&clear(), Request::ArmOrReset);
        let mut limit = clear();
        limit.limits[2][0] = true;
        assert_eq!(
            m.update(&limit, Request::None),
            SafetyState::Fault(FaultReason::Limit {
                axis: Axis::Z,
                end: LimitEnd::Min
            })
        );
    }

    #[test]
    fn following_error_trips_and_keeps_first_reason() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        m.update(&clear(), Request::ArmOrReset);
        assert_eq!(
            m.check_following_error(&[0.5, -0.9, 1.9]),
            SafetyState::Enabled
        );
        assert_eq!(
            m.check_following_error(&[0.0, -1.5, 0.0]),
            SafetyState::Fault(FaultReason::FollowingError {
                axis: Axis::Y,
                error_mm: -1.5
            })
        );
        let estop = Inputs {
            estop: true,
            ..clear()
        };
        assert!(matches!(
            m.update(&estop, Request::None),
            SafetyState::Fault(FaultReason::FollowingError { .. })
        ));
    }

    #[test]
    fn nan_following_error_trips() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        m.update(&clear(), Request::ArmOrReset);
        assert!(matches!(
            m.check_following_error(&[f32::NAN, 0.0, 0.0]),
            SafetyState::Fault(FaultReason::FollowingError { axis: Axis::X, .. })
        ));
    }

    #[test]
    fn following_error_ignored_when_not_enabled() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        assert_eq!(
            m.check_following_error(&[10.0, 10.0, 10.0]),
            SafetyState::Disabled
        );
    }

    #[test]
    fn disarm_is_not_a_fault() {
        let mut m = SafetyMonitor::new(LIMIT_MM);
        m.update(&clear(), Request::ArmOrReset);
        assert_eq!(m.update(&clear(), Request::Disarm), SafetyState::Disabled);
    }
}
