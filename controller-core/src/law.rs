//! The per-axis law interface shared by every controller, and the anti-windup integrator.
//!
//! Laws are continuous-time: [`AxisLaw::evaluate`] is a pure function of the law's state
//! and the axis signals, returning the output *and* the rate of the law's internal
//! integral. The host's continuous mode integrates that rate with RK4 together with the
//! plant; the firmware (and the host's discrete mode) calls [`AxisLaw::step`], which
//! integrates it over one sample period. Both paths run the same law code.

use crate::params::{ConfigError, LawConfig};
use crate::pid::Pid;
use crate::smc::Smc;
use crate::Real;

/// Signals one axis law sees in one evaluation. `e = q_d - q` (paper convention); with
/// cross-coupling, `e` and `e_dot` are the coupled errors `C_i`, `C_i'`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisSignals<R> {
    pub e: R,
    pub e_dot: R,
    pub qd_dot: R,
    pub qd_ddot: R,
    pub q: R,
    pub q_dot: R,
}

/// The law's internal state: the integral of the position error.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawState<R> {
    pub integral: R,
}

/// One evaluation of a law.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawOutput<R> {
    /// Saturated control output.
    pub u: R,
    /// `d/dt` of [`LawState::integral`] (0 while anti-windup holds the integrator).
    pub integral_rate: R,
    /// Sliding variable (0 for PID), for telemetry and plots.
    pub s: R,
}

/// Saturation and conditional integration shared by all laws: the output is clamped to
/// `±u_max`, and the error is not integrated while the output is saturated in the
/// direction the error would push it further.
pub(crate) fn finish<R: Real>(u_raw: R, e: R, u_max: R, s: R) -> LawOutput<R> {
    let u_raw = u_raw.finite_or_zero();
    let u = u_raw.clamp_sym(u_max);
    let saturated = u != u_raw;
    let winds_up = saturated && (e * u_raw > R::ZERO);
    LawOutput {
        u,
        integral_rate: if winds_up {
            R::ZERO
        } else {
            e.finite_or_zero()
        },
        s: s.finite_or_zero(),
    }
}

/// Advance the integrator by one period, clamped to `±limit`.
pub(crate) fn integrate<R: Real>(state: &mut LawState<R>, rate: R, dt: R, limit: R) {
    state.integral = (state.integral + rate * dt).clamp_sym(limit);
}

/// One axis's law, selected by configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AxisLaw<R> {
    Pid(Pid<R>),
    Smc(Smc<R>),
}

impl<R: Real> AxisLaw<R> {
    pub fn new(cfg: &LawConfig) -> Result<Self, ConfigError> {
        Ok(match cfg {
            LawConfig::Pid(c) => Self::Pid(Pid::new(c)?),
            LawConfig::Smc(c) => Self::Smc(Smc::new(c)?),
        })
    }

    pub fn evaluate(&self, st: &LawState<R>, sig: &AxisSignals<R>) -> LawOutput<R> {
        match self {
            Self::Pid(l) => l.evaluate(st, sig),
            Self::Smc(l) => l.evaluate(st, sig),
        }
    }

    fn integral_limit(&self) -> R {
        match self {
            Self::Pid(l) => l.integral_limit,
            Self::Smc(l) => l.integral_limit,
        }
    }

    /// Clamp the integral state to its limit (used after a continuous-mode RK step).
    pub fn clamp_state(&self, st: &mut LawState<R>) {
        st.integral = st.integral.clamp_sym(self.integral_limit());
    }

    /// Evaluate, then integrate the law's state over one period `dt` (zero-order hold).
    pub fn step(&self, st: &mut LawState<R>, sig: &AxisSignals<R>, dt: R) -> LawOutput<R> {
        let out = self.evaluate(st, sig);
        integrate(st, out.integral_rate, dt, self.integral_limit());
        out
    }
}
