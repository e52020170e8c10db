//! Variable-gain cross-coupling (spec 3.2, patent seed 002 claim 4; Koren & Lo 1991).
//!
//! A PID on the *estimated* contour error produces a correction that is added to the axis
//! inputs along the path normal, so the gains `C_i = n_i` change with the path direction.
//!
//! - [`VariableGainMode::Planar`] (the patent's two axes): unit tangent `t` of the reference path in
//!   the XY plane, normal `n = (-t_y, t_x)`, contour error estimate `ε = E · n` (distance of
//!   the actual point from the tangent line, `E = R - P`), `U_c = PID(ε)`,
//!   `u_x += n_x U_c`, `u_y += n_y U_c`. Positive `ε` means the reference lies on the `+n`
//!   side, so pushing along `+n` reduces it. The Z axis gets nothing.
//! - [`VariableGainMode::Normal3`] (three axes): the contour error vector is the normal component of
//!   `E` (spec 3.1, [`crate::coupling::contour::normal_component`]); the PID acts on that vector
//!   componentwise and the correction is added to the axes. In the plane this equals the
//!   planar mode's proportional and derivative terms; the integral of a rotating normal
//!   vector is weaker than the patent's scalar integral on curved paths.
//!
//! The rate of `ε` is taken as `E' · n` with the normal held over the period (the same
//! local linearisation as [`crate::coupling::contour::cross_couple`]). Where the tangent is
//! undefined (`|v_ref|²` at or below `min_direction_norm_sq`) the correction is zero and
//! the integral is held.

use crate::config::{limit, non_negative, ConfigError};
use crate::coupling::contour::normal_component;
use crate::{Real, Vec3};

/// Which contour-error estimate the coupling uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum VariableGainMode {
    /// Scalar `ε = E · n` in the XY plane (patent).
    #[default]
    Planar,
    /// Normal component of the 3-D tracking error.
    Normal3,
}

/// Gains of the contour-error PID (output in the axes' input units per length unit).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct VariableGainConfig {
    #[cfg_attr(feature = "serde", serde(default))]
    pub mode: VariableGainMode,
    pub kp: f32,
    pub ki: f32,
    pub kd: f32,
    /// Clamp on each component of `∫ε dt`.
    pub integral_limit: f32,
    /// Clamp on each component of the correction.
    pub u_max: f32,
    /// Tangents with `|v_ref|²` at or below this are undefined.
    pub min_direction_norm_sq: f32,
}

/// The PID's integral (a scalar in the planar mode, stored in `x`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VariableGainState<R> {
    pub integral: Vec3<R>,
}

/// One evaluation: the per-axis correction and the contour error estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VariableGainOutput<R> {
    pub correction: Vec3<R>,
    /// Estimated contour error vector (normal component of `E`).
    pub contour: Vec3<R>,
    /// Rate of the integral state.
    pub integral_rate: Vec3<R>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VariableGain<R> {
    mode: VariableGainMode,
    kp: R,
    ki: R,
    kd: R,
    integral_limit: R,
    u_max: R,
    min_dir_sq: R,
}

impl<R: Real> VariableGain<R> {
    pub fn new(c: &VariableGainConfig) -> Result<Self, ConfigError> {
        Ok(Self {
            mode: c.mode,
            kp: R::from_f32(non_negative(c.kp, "ccc.kp")?),
            ki: R::from_f32(non_negative(c.ki, "ccc.ki")?),
            kd: R::from_f32(non_negative(c.kd, "ccc.kd")?),
            integral_limit: R::from_f32(limit(c.integral_limit, "ccc.integral_limit")?),
            u_max: R::from_f32(limit(c.u_max, "ccc.u_max")?),
            min_dir_sq: R::from_f32(non_negative(
                c.min_direction_norm_sq,
                "ccc.min_direction_norm_sq",
            )?),
        })
    }

    /// Correction for tracking error `tracking = R - P`, its rate, and the path tangent.
    pub fn evaluate(
        &self,
        st: &VariableGainState<R>,
        tracking: Vec3<R>,
        tracking_rate: Vec3<R>,
        tangent: Vec3<R>,
    ) -> VariableGainOutput<R> {
        match self.mode {
            VariableGainMode::Planar => {
                let t2 = Vec3::new(tangent.x, tangent.y, R::ZERO);
                let n2 = t2.norm_sq();
                if !(n2 > self.min_dir_sq) {
                    return VariableGainOutput::default();
                }
                let inv_len = R::ONE.div_or(n2.sqrt_pos(), R::ZERO);
                let n = Vec3::new(-t2.y * inv_len, t2.x * inv_len, R::ZERO);
                let eps = tracking.dot(n);
                let eps_rate = tracking_rate.dot(n);
                let uc =
                    (self.kp * eps + self.ki * st.integral.x + self.kd * eps_rate).finite_or_zero();
                VariableGainOutput {
                    correction: (n * uc).map(|v| v.clamp_sym(self.u_max)),
                    contour: n * eps,
                    integral_rate: Vec3::new(eps.finite_or_zero(), R::ZERO, R::ZERO),
                }
            }
            VariableGainMode::Normal3 => {
                let (Some(e), Some(e_rate)) = (
                    normal_component(tracking, tangent, self.min_dir_sq),
                    normal_component(tracking_rate, tangent, self.min_dir_sq),
                ) else {
                    return VariableGainOutput::default();
                };
                let u = e * self.kp + st.integral * self.ki + e_rate * self.kd;
                VariableGainOutput {
                    correction: u.map(|v| v.finite_or_zero().clamp_sym(self.u_max)),
                    contour: e,
                    integral_rate: e.map(|v| v.finite_or_zero()),
                }
            }
        }
    }

    /// Integrate the PID state over `dt`, clamped.
    pub fn integrate(&self, st: &mut VariableGainState<R>, out: &VariableGainOutput<R>, dt: R) {
        self.integrate_rate(st, out.integral_rate, dt);
    }

    /// Integrate the PID state at `rate` over `dt`, clamped.
    pub fn integrate_rate(&self, st: &mut VariableGainState<R>, rate: Vec3<R>, dt: R) {
        let lim = self.integral_limit;
        st.integral = (st.integral + rate * dt).map(|v| v.clamp_sym(lim));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::gantry::VARIABLE_GAIN_XY;

    #[test]
    fn planar_correction_is_along_the_normal() {
        let ccc = VariableGain::<f64>::new(&VARIABLE_GAIN_XY).unwrap();
        // path along +x: n = +y. Actual point 0.01 below the path: E = (0.3, 0.01, 0)
        let out = ccc.evaluate(
            &VariableGainState::default(),
            Vec3::new(0.3, 0.01, 0.0),
            Vec3::zero(),
            Vec3::new(50.0, 0.0, 0.0),
        );
        assert_eq!(out.correction.x, 0.0);
        assert!((out.correction.y - VARIABLE_GAIN_XY.kp as f64 * 0.01).abs() < 1e-9);
        assert!((out.contour.y - 0.01).abs() < 1e-12);
        // path at 30°: the correction is perpendicular to the path
        let (s, c) = (0.5f64, libm::sqrt(3.0) / 2.0);
        let out = ccc.evaluate(
            &VariableGainState::default(),
            Vec3::new(0.02, -0.01, 0.0),
            Vec3::zero(),
            Vec3::new(c, s, 0.0),
        );
        assert!(out.correction.dot(Vec3::new(c, s, 0.0)).abs() < 1e-9);
        assert!(out.correction.norm() > 0.0);
    }

    #[test]
    fn normal3_matches_planar_in_the_plane_and_undefined_tangent_gives_zero() {
        let mut c3 = VARIABLE_GAIN_XY;
        c3.mode = VariableGainMode::Normal3;
        let p = VariableGain::<f64>::new(&VARIABLE_GAIN_XY).unwrap();
        let n = VariableGain::<f64>::new(&c3).unwrap();
        let (e, er, t) = (
            Vec3::new(0.02, -0.01, 0.0),
            Vec3::new(0.1, 0.3, 0.0),
            Vec3::new(3.0, 4.0, 0.0),
        );
        let (a, b) = (
            p.evaluate(&VariableGainState::default(), e, er, t),
            n.evaluate(&VariableGainState::default(), e, er, t),
        );
        assert!((a.correction - b.correction).norm() < 1e-9);
        let z = n.evaluate(&VariableGainState::default(), e, er, Vec3::zero());
        assert_eq!(z, VariableGainOutput::default());
        let z = p.evaluate(
            &VariableGainState::default(),
            e,
            er,
            Vec3::new(0.0, 0.0, 5.0),
        );
        assert_eq!(z, VariableGainOutput::default());
    }
}
