//! Homing and jogging as the servo keeps them: their configuration and the axes
//! referenced. The ramps themselves are [`crate::motion::homing`] and
//! [`crate::motion::jog`]; the servo advances them in its step.

use crate::motion::homing::HomingConfig;
use crate::motion::jog::JogConfig;

/// Homing's and jogging's configuration and the axes referenced.
pub(super) struct ManualState {
    pub(super) homing: HomingConfig,
    pub(super) jog: JogConfig,
    /// Periods without a jog command after which a jog stops.
    pub(super) jog_timeout_periods: u32,
    /// Axes homed since power-up (bit i = axis i); lost with an encoder fault.
    pub(super) homed: u8,
    /// Axes that take no part in homing: referenced where they stand.
    pub(super) no_homing: u8,
}

impl ManualState {
    /// The axes homed or taking no part in homing (bit i = axis i): their soft limits
    /// apply.
    #[inline]
    pub(super) fn referenced_mask(&self) -> u8 {
        self.homed | self.no_homing
    }
}
