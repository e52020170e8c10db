//! The physical ball-screw axis (spec 1.3, seed 004): the truth a simulated axis follows.
//!
//! The normalised plant of the paper has no friction and no torque limit. A real axis
//! does, and the seed methods (disturbance observer, adaptive friction compensation) exist
//! because of it. Per axis, in table coordinates:
//!
//! ```text
//! J x'' = sat(u) - B x' - F_c(x') - T_load(t)
//! ```
//!
//! Units: position mm, time s, torque mN·m (motor torque; the screw converts it to table
//! force). So `J` is in mN·m/(mm/s²) and `B` in mN·m/(mm/s). mN·m rather than N·m keeps
//! every parameter between ~0.01 and ~10⁴, which a fixed-point [`Real`] represents well.
//!
//! Coulomb friction is asymmetric (`f+ > 0` forward, `f- < 0` reverse) with an optional
//! Stribeck peak. An ideal `sign(x')` makes the ODE discontinuous; RK4 then needs a
//! step far below the control period at every reversal. The sign is therefore regularised
//! as `x' / sqrt(x'² + v_reg²)`, a standard smooth friction model: with `v_reg` = 0.5 mm/s
//! (well below one count per period, 6.25 mm/s) the friction is within 1 % of full value
//! above 3.5 mm/s, and at rest it is zero, so a resting axis is not pushed by an
//! asymmetric friction. Stiction is the Stribeck peak `f_s` at low speed, decaying to
//! `f_c` over `v_stribeck` with the rational shape `1 / (1 + (x'/v_s)²)` (exp is not part
//! of [`Real`]; the rational curve has the same peak and width).

use super::frame::FrameConfig;
use super::state::{AxisDynamics, AxisState};
use crate::config::{finite, non_negative, positive, ConfigError};
use crate::Real;

/// Parameters of one physical axis (see the module docs for units).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PhysicalAxisConfig {
    /// Equivalent inertia reflected to the table, mN·m/(mm/s²).
    pub inertia: f32,
    /// Viscous friction coefficient, mN·m/(mm/s).
    pub viscous: f32,
    /// Forward Coulomb friction `f+` (> 0), mN·m.
    pub coulomb_pos_mnm: f32,
    /// Reverse Coulomb friction `f-` (< 0), mN·m.
    pub coulomb_neg_mnm: f32,
    /// Static (breakaway) friction as a multiple of the Coulomb level (1 = no Stribeck
    /// peak).
    #[cfg_attr(feature = "serde", serde(default = "one"))]
    pub stiction_ratio: f32,
    /// Stribeck velocity, mm/s.
    #[cfg_attr(feature = "serde", serde(default = "default_v_stribeck"))]
    pub v_stribeck_mm_s: f32,
    /// Regularisation velocity of the friction sign, mm/s.
    #[cfg_attr(feature = "serde", serde(default = "default_v_reg"))]
    pub v_reg_mm_s: f32,
    /// Constant load torque (e.g. gravity on a vertical axis), mN·m.
    #[cfg_attr(feature = "serde", serde(default))]
    pub load_const_mnm: f32,
    /// Load torque step (e.g. a cutting force), mN·m, applied from `load_step_t_s` on.
    #[cfg_attr(feature = "serde", serde(default))]
    pub load_step_mnm: f32,
    #[cfg_attr(feature = "serde", serde(default = "never"))]
    pub load_step_t_s: f32,
    /// Motor peak torque, mN·m: the input is clamped to `±torque_max_mnm`.
    pub torque_max_mnm: f32,
    /// What lies between the motor and the tool (default: nothing, a rigid axis): a
    /// compliant mode, backlash, lead error ([`super::frame`]). The simulated world
    /// integrates it; this axis' own dynamics ([`PhysicalAxis`]) are the rigid model.
    #[cfg_attr(feature = "serde", serde(default))]
    pub frame: Option<FrameConfig>,
}

#[cfg(feature = "serde")]
fn one() -> f32 {
    1.0
}
#[cfg(feature = "serde")]
fn default_v_stribeck() -> f32 {
    DEFAULT_V_STRIBECK_MM_S
}
#[cfg(feature = "serde")]
fn default_v_reg() -> f32 {
    DEFAULT_V_REG_MM_S
}
#[cfg(feature = "serde")]
fn never() -> f32 {
    f32::INFINITY
}

/// Friction-sign regularisation velocity: 0.5 mm/s (see the module docs).
pub const DEFAULT_V_REG_MM_S: f32 = 0.5;
/// Stribeck velocity: 2 mm/s, typical of lubricated ball-screw/linear-guide contacts
/// (the friction minimum of such axes lies at a few mm/s).
pub const DEFAULT_V_STRIBECK_MM_S: f32 = 2.0;

/// One physical axis, implementing [`AxisDynamics`] for the RK4 integrator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhysicalAxis<R> {
    inv_j: R,
    b: R,
    f_pos: R,
    f_neg: R,
    /// `f_s - f_c` for each direction.
    stiction_pos: R,
    stiction_neg: R,
    inv_v_stribeck: R,
    v_reg_sq: R,
    load_const: R,
    load_step: R,
    load_step_t: R,
    torque_max: R,
}

impl<R: Real> PhysicalAxis<R> {
    pub fn new(c: &PhysicalAxisConfig) -> Result<Self, ConfigError> {
        let f = R::from_f32;
        let j = positive(c.inertia, "inertia")?;
        let f_pos = non_negative(c.coulomb_pos_mnm, "coulomb_pos_mnm")?;
        let f_neg = -non_negative(
            -finite(c.coulomb_neg_mnm, "coulomb_neg_mnm")?,
            "-coulomb_neg_mnm",
        )?;
        let ratio = positive(c.stiction_ratio, "stiction_ratio")?;
        if ratio < 1.0 {
            return Err(ConfigError::NotPositive("stiction_ratio - 1"));
        }
        let load_step_t = if c.load_step_t_s.is_nan() {
            return Err(ConfigError::NotFinite("load_step_t_s"));
        } else {
            c.load_step_t_s
        };
        Ok(Self {
            inv_j: R::from_f64(1.0 / j as f64),
            b: f(non_negative(c.viscous, "viscous")?),
            f_pos: f(f_pos),
            f_neg: f(f_neg),
            stiction_pos: f(f_pos * (ratio - 1.0)),
            stiction_neg: f(f_neg * (ratio - 1.0)),
            inv_v_stribeck: R::from_f64(
                1.0 / positive(c.v_stribeck_mm_s, "v_stribeck_mm_s")? as f64,
            ),
            v_reg_sq: f(positive(c.v_reg_mm_s, "v_reg_mm_s")?) * f(c.v_reg_mm_s),
            load_const: f(finite(c.load_const_mnm, "load_const_mnm")?),
            load_step: f(finite(c.load_step_mnm, "load_step_mnm")?),
            // +inf (never) saturates to the type's largest value
            load_step_t: R::from_f32(load_step_t.min(f32::MAX)),
            torque_max: f(positive(c.torque_max_mnm, "torque_max_mnm")?),
        })
    }

    /// Friction torque `B x' + F_c(x')` at velocity `v`, mN·m.
    pub fn friction(&self, v: R) -> R {
        // regularised sign in (-1, 1), zero at rest
        let sgn = v.div_or((v * v + self.v_reg_sq).sqrt_pos(), R::ZERO);
        let x = v * self.inv_v_stribeck;
        let peak = R::ONE.div_or(R::ONE + x * x, R::ZERO);
        let level = if v >= R::ZERO {
            self.f_pos + self.stiction_pos * peak
        } else {
            // f- < 0 and sgn < 0: the product is positive, so negate
            -(self.f_neg + self.stiction_neg * peak)
        };
        self.b * v + level * sgn
    }

    /// Load torque at time `t`, mN·m.
    pub fn load(&self, t: R) -> R {
        if t >= self.load_step_t {
            self.load_const + self.load_step
        } else {
            self.load_const
        }
    }

    pub fn torque_max(&self) -> R {
        self.torque_max
    }

    /// `1 / J`.
    pub fn inv_inertia(&self) -> R {
        self.inv_j
    }
}

impl<R: Real> AxisDynamics<R> for PhysicalAxis<R> {
    fn accel(&self, s: AxisState<R>, u: R, t: R) -> R {
        let u = u.finite_or_zero().clamp_sym(self.torque_max);
        (u - self.friction(s.vel) - self.load(t)) * self.inv_j
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::state::rk4_step;
    use crate::presets::gantry::GANTRY_X;

    #[test]
    fn friction_is_asymmetric_and_zero_at_rest() {
        let ax = PhysicalAxis::<f64>::new(&GANTRY_X).unwrap();
        assert_eq!(ax.friction(0.0), 0.0);
        let fwd = ax.friction(100.0) - GANTRY_X.viscous as f64 * 100.0;
        let rev = ax.friction(-100.0) + GANTRY_X.viscous as f64 * 100.0;
        // far above v_reg and v_stribeck: the Coulomb levels within 0.1 %
        assert!(
            (fwd - GANTRY_X.coulomb_pos_mnm as f64).abs() < 1e-3 * fwd,
            "{fwd}"
        );
        assert!(
            (rev - GANTRY_X.coulomb_neg_mnm as f64).abs() < 1e-3 * rev.abs(),
            "{rev}"
        );
        // near the Stribeck velocity the friction exceeds the Coulomb level
        assert!(ax.friction(1.5) > GANTRY_X.coulomb_pos_mnm as f64);
    }

    #[test]
    fn constant_torque_reaches_friction_limited_speed() {
        // u = f+ + B v_ss gives steady speed v_ss = 50 mm/s
        let c = PhysicalAxisConfig {
            stiction_ratio: 1.0,
            ..GANTRY_X
        };
        let ax = [PhysicalAxis::<f64>::new(&c).unwrap()];
        let u = c.coulomb_pos_mnm as f64 + c.viscous as f64 * 50.0;
        let mut s = [AxisState::default()];
        for k in 0..50_000 {
            rk4_step(&ax, &mut s, k as f64 * 1e-4, 1e-4, |_, _| [u]);
        }
        assert!((s[0].vel - 50.0).abs() < 0.05, "{}", s[0].vel);
    }

    #[test]
    fn torque_is_saturated_and_load_steps() {
        let c = PhysicalAxisConfig {
            load_step_mnm: 100.0,
            load_step_t_s: 1.0,
            ..GANTRY_X
        };
        let ax = PhysicalAxis::<f32>::new(&c).unwrap();
        let rest = AxisState::default();
        let a_max = ax.accel(rest, 1e9, 0.0);
        assert!((a_max - c.torque_max_mnm / c.inertia).abs() < 1e-2 * a_max);
        assert_eq!(ax.accel(rest, f32::NAN, 0.0), 0.0);
        assert!((ax.accel(rest, 0.0, 1.0) + 100.0 / c.inertia).abs() < 1e-2);
    }

    #[test]
    fn rejects_bad_config() {
        let bad = PhysicalAxisConfig {
            coulomb_neg_mnm: 5.0,
            ..GANTRY_X
        };
        assert!(PhysicalAxis::<f32>::new(&bad).is_err());
        let bad = PhysicalAxisConfig {
            inertia: 0.0,
            ..GANTRY_X
        };
        assert_eq!(
            PhysicalAxis::<f32>::new(&bad),
            Err(ConfigError::NotPositive("inertia"))
        );
    }
}
