//! PID with anti-windup (integrator clamp + conditional integration) and optional
//! velocity/acceleration feed-forward (spec 2.1).

use super::signals::{finish, AxisSignals, LawOutput};
use super::state::LawState;
use crate::config::{finite, limit, non_negative, ConfigError};
use crate::Real;

/// PID gains and limits (units: the axis's, e.g. mN·m per mm for the physical axis).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PidConfig {
    pub kp: f32,
    pub ki: f32,
    pub kd: f32,
    /// Velocity feed-forward gain on `q_d'`.
    #[cfg_attr(feature = "serde", serde(default))]
    pub kv_ff: f32,
    /// Acceleration feed-forward gain on `q_d''`.
    #[cfg_attr(feature = "serde", serde(default))]
    pub ka_ff: f32,
    /// Clamp on `|∫e dt|`.
    #[cfg_attr(feature = "serde", serde(default = "crate::config::inf"))]
    pub integral_limit: f32,
    /// Output saturation `|u| <= u_max`.
    #[cfg_attr(feature = "serde", serde(default = "crate::config::inf"))]
    pub u_max: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pid<R> {
    kp: R,
    ki: R,
    kd: R,
    kv_ff: R,
    ka_ff: R,
    pub(crate) integral_limit: R,
    u_max: R,
}

impl<R: Real> Pid<R> {
    pub fn new(c: &PidConfig) -> Result<Self, ConfigError> {
        Ok(Self {
            kp: R::from_f32(non_negative(c.kp, "kp")?),
            ki: R::from_f32(non_negative(c.ki, "ki")?),
            kd: R::from_f32(non_negative(c.kd, "kd")?),
            kv_ff: R::from_f32(finite(c.kv_ff, "kv_ff")?),
            ka_ff: R::from_f32(finite(c.ka_ff, "ka_ff")?),
            integral_limit: R::from_f32(limit(c.integral_limit, "integral_limit")?),
            u_max: R::from_f32(limit(c.u_max, "u_max")?),
        })
    }

    /// `u = kp e + ki ∫e + kd e' + kv q_d' + ka q_d''`, saturated.
    pub fn evaluate(&self, st: &LawState<R>, sig: &AxisSignals<R>) -> LawOutput<R> {
        let u = self.kp * sig.e
            + self.ki * st.integral
            + self.kd * sig.e_dot
            + self.kv_ff * sig.qd_dot
            + self.ka_ff * sig.qd_ddot;
        finish(u, sig.e, self.u_max, R::ZERO)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::{Law, LawConfig};
    use crate::presets::paper::PAPER_PID;

    #[test]
    fn proportional_and_saturation() {
        let pid = Pid::<f32>::new(&PAPER_PID).unwrap();
        let sig = AxisSignals {
            e: 0.01,
            ..Default::default()
        };
        assert!((pid.evaluate(&LawState::default(), &sig).u - 6.0).abs() < 1e-5);

        let sat = PidConfig {
            u_max: 5.0,
            integral_limit: 0.5,
            ..PAPER_PID
        };
        let law = Law::<f32>::new(&LawConfig::Pid(sat)).unwrap();
        let mut st = law.initial_state();
        let big = AxisSignals {
            e: 1.0,
            ..Default::default()
        };
        let out = law.step(&mut st, &big, 0.1);
        assert_eq!(out, 5.0);
        // saturated in the direction of e: no integration (conditional integration)
        assert_eq!(st.integral, 0.0);
        // unsaturated: integrates, but never beyond the clamp
        let small = AxisSignals {
            e: 0.001,
            ..Default::default()
        };
        for _ in 0..10_000 {
            law.step(&mut st, &small, 0.1);
        }
        assert_eq!(st.integral, 0.5);
    }

    #[test]
    fn rejects_bad_gains() {
        let bad = PidConfig {
            kp: -1.0,
            ..PAPER_PID
        };
        assert_eq!(Pid::<f32>::new(&bad), Err(ConfigError::Negative("kp")));
        let nan = PidConfig {
            u_max: f32::NAN,
            ..PAPER_PID
        };
        assert!(Pid::<f32>::new(&nan).is_err());
    }
}
