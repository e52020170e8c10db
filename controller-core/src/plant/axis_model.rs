//! The identified model of one axis: what identification produces and what every
//! model-based law is tuned from ([`crate::sysid::tuning`]).
//!
//! `J x'' + B x' + f(x') = u`, with `f = f+` while moving forward and `f = f-` while moving
//! backward (spec 1.3 without the load term). Units as in [`super::physical`]: mm,
//! s, and the *effort* the controller commands, mN·m when the command-to-torque scale is
//! known (see docs/identification.md: the scale itself is not observable from counts and
//! effort alone, so every parameter is "per unit of commanded effort").
//!
//! A constant load (gravity on a vertical axis) cannot be told apart from a direction
//! offset of the Coulomb terms while the axis moves (`L = L μ + L (1 - μ)`), so the
//! identified `f+`/`f-` include it: `f+ = f+_true + L`, `f- = f-_true + L`. That is the
//! torque the laws must supply in each direction, so it is what they need; it also means
//! `f-` may come out positive on an axis whose load exceeds its reverse friction.

use super::physical::PhysicalAxisConfig;
use crate::config::{finite, non_negative, positive, ConfigError};

/// Rigid-body model of one axis (see the module docs for the equation and units).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisModel {
    /// Inertia reflected to the table, mN·m/(mm/s²).
    pub inertia: f32,
    /// Viscous friction coefficient, mN·m/(mm/s).
    pub viscous: f32,
    /// Torque needed to keep moving forward, beyond the viscous part (Coulomb `f+` plus
    /// any constant load), mN·m.
    pub coulomb_pos_mnm: f32,
    /// Torque needed to keep moving backward, beyond the viscous part (Coulomb `f-`, < 0
    /// without load, plus any constant load), mN·m.
    pub coulomb_neg_mnm: f32,
}

impl AxisModel {
    /// The rigid-body part of a simulated physical axis (its Stribeck excess, load and
    /// torque limit are not part of the model).
    pub const fn from_physical(axis: &PhysicalAxisConfig) -> Self {
        Self {
            inertia: axis.inertia,
            viscous: axis.viscous,
            coulomb_pos_mnm: axis.coulomb_pos_mnm,
            coulomb_neg_mnm: axis.coulomb_neg_mnm,
        }
    }

    /// The same axis seen by identification: a constant load folded into both Coulomb
    /// terms (module docs).
    pub const fn from_physical_with_load(axis: &PhysicalAxisConfig) -> Self {
        Self {
            coulomb_pos_mnm: axis.coulomb_pos_mnm + axis.load_const_mnm,
            coulomb_neg_mnm: axis.coulomb_neg_mnm + axis.load_const_mnm,
            ..Self::from_physical(axis)
        }
    }

    /// A model a law may be built from: inertia > 0, viscous >= 0, Coulomb terms finite
    /// and dissipative (`f+ >= f-`: friction opposes motion whatever the load).
    pub fn validate(&self) -> Result<(), ConfigError> {
        positive(self.inertia, "inertia")?;
        non_negative(self.viscous, "viscous")?;
        let fp = finite(self.coulomb_pos_mnm, "coulomb_pos_mnm")?;
        let fn_ = finite(self.coulomb_neg_mnm, "coulomb_neg_mnm")?;
        if fp - fn_ >= 0.0 {
            Ok(())
        } else {
            Err(ConfigError::Negative("coulomb_pos_mnm - coulomb_neg_mnm"))
        }
    }

    /// Friction (plus folded load) at velocity `vel_mm_s`: `B v + f±`, with `f+` for
    /// `v > 0`, `f-` for `v < 0` and 0 at rest, mN·m.
    pub fn friction_mnm(&self, vel_mm_s: f32) -> f32 {
        let coulomb = if vel_mm_s > 0.0 {
            self.coulomb_pos_mnm
        } else if vel_mm_s < 0.0 {
            self.coulomb_neg_mnm
        } else {
            0.0
        };
        self.viscous * vel_mm_s + coulomb
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::gantry::{GANTRY_X, GANTRY_Z};

    #[test]
    fn load_is_folded_into_both_coulomb_terms() {
        let m = AxisModel::from_physical_with_load(&GANTRY_Z);
        assert_eq!(m.coulomb_pos_mnm, 35.0 + 23.0);
        assert_eq!(m.coulomb_neg_mnm, -30.0 + 23.0);
        assert_eq!(m.validate(), Ok(()));
        assert_eq!(AxisModel::from_physical(&GANTRY_Z).coulomb_neg_mnm, -30.0);
    }

    #[test]
    fn friction_by_direction() {
        let m = AxisModel::from_physical(&GANTRY_X);
        assert_eq!(m.friction_mnm(0.0), 0.0);
        assert_eq!(m.friction_mnm(10.0), 0.25 * 10.0 + 40.0);
        assert_eq!(m.friction_mnm(-10.0), -0.25 * 10.0 - 32.0);
    }

    #[test]
    fn rejects_non_dissipative_or_bad_values() {
        let m = AxisModel::from_physical(&GANTRY_X);
        let bad = AxisModel {
            coulomb_pos_mnm: -40.0,
            ..m
        };
        assert_eq!(
            bad.validate(),
            Err(ConfigError::Negative("coulomb_pos_mnm - coulomb_neg_mnm"))
        );
        let bad = AxisModel {
            inertia: f32::NAN,
            ..m
        };
        assert_eq!(bad.validate(), Err(ConfigError::NotFinite("inertia")));
        let bad = AxisModel { viscous: -0.1, ..m };
        assert_eq!(bad.validate(), Err(ConfigError::Negative("viscous")));
    }
}
