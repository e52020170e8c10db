//! [`LawState`], the state of any law: one record for every law kind, so that a
//! controller can keep its axes' states in one array whichever laws they run.

use super::adaptive_smc::AdaptiveState;
use super::dob_smc::DobState;

/// The state of any law; each law uses its own part (the others stay at their defaults).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawState<R> {
    /// `∫e dt` of PID and the sliding-mode laws.
    pub integral: R,
    /// Disturbance observer of DOB-SMC.
    pub dob: DobState<R>,
    /// Parameter estimates of the adaptive law.
    pub adapt: AdaptiveState<R>,
}
