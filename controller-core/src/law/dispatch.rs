//! The one interface a controller runs any law through: [`LawConfig`] (which law, with
//! its parameters), validated into a [`Law`] in the controller's number type, evaluated
//! into a [`LawEval`] and committed with the output actually applied.

use super::adaptive_smc::{AdaptiveRegressors, AdaptiveSmc, AdaptiveSmcConfig};
use super::dob_smc::{DobSmc, DobSmcConfig};
use super::pid::{Pid, PidConfig};
use super::signals::{integrate, AxisSignals, LawOutput};
use super::smc::{Smc, SmcConfig};
use super::state::LawState;
use crate::config::ConfigError;
use crate::Real;

/// Which law an axis runs, with its parameters. TOML: `{ pid = { kp = ... } }`,
/// `{ smc = { ... } }`, `{ dob_smc = { ... } }`, `{ adaptive_smc = { ... } }`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum LawConfig {
    Pid(PidConfig),
    /// SMC and DSMC (the reaching law and `k4` select which).
    Smc(SmcConfig),
    DobSmc(DobSmcConfig),
    AdaptiveSmc(AdaptiveSmcConfig),
}

impl LawConfig {
    /// Short snake_case name of the law kind (`pid`, `smc`, `dob_smc`, `adaptive_smc`).
    pub const fn kind(&self) -> &'static str {
        match self {
            Self::Pid(_) => "pid",
            Self::Smc(_) => "smc",
            Self::DobSmc(_) => "dob_smc",
            Self::AdaptiveSmc(_) => "adaptive_smc",
        }
    }

    /// True for the laws that cancel a model of the axis (everything but PID): they need
    /// an identified or entered model before they may run on a machine.
    pub const fn is_model_based(&self) -> bool {
        !matches!(self, Self::Pid(_))
    }
}

/// A validated law in number type `R`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Law<R> {
    Pid(Pid<R>),
    Smc(Smc<R>),
    DobSmc(DobSmc<R>),
    AdaptiveSmc(AdaptiveSmc<R>),
}

/// One evaluation of any law: its output and what [`Law::commit`] needs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawEval<R> {
    /// The law's own saturated output.
    pub u: R,
    /// Sliding variable (0 for PID).
    pub s: R,
    /// Rate of [`LawState::integral`] (PID and sliding mode; 0 otherwise).
    pub integral_rate: R,
    /// Regressors of the adaptive law's update (default otherwise).
    pub adapt: AdaptiveRegressors<R>,
    /// False when the raw output was not finite (see [`LawOutput::finite`]).
    pub finite: bool,
}

impl<R: Real> Law<R> {
    /// Validate `cfg` into a runtime law; nothing is built when it is rejected.
    pub fn new(cfg: &LawConfig) -> Result<Self, ConfigError> {
        Ok(match cfg {
            LawConfig::Pid(c) => Self::Pid(Pid::new(c)?),
            LawConfig::Smc(c) => Self::Smc(Smc::new(c)?),
            LawConfig::DobSmc(c) => Self::DobSmc(DobSmc::new(c)?),
            LawConfig::AdaptiveSmc(c) => Self::AdaptiveSmc(AdaptiveSmc::new(c)?),
        })
    }

    /// The state a fresh law starts from: zero integral and observer, the configured
    /// initial estimates of the adaptive law.
    pub fn initial_state(&self) -> LawState<R> {
        let mut st = LawState::default();
        if let Self::AdaptiveSmc(a) = self {
            st.adapt = a.initial_state();
        }
        st
    }

    /// Whether the simulator's continuous mode can integrate this law's state with the
    /// plant (only the integral of PID and the sliding-mode laws is part of that ODE).
    pub const fn supports_continuous(&self) -> bool {
        matches!(self, Self::Pid(_) | Self::Smc(_))
    }

    /// Evaluate the law for the given state (pure).
    pub fn evaluate(&self, st: &LawState<R>, sig: &AxisSignals<R>) -> LawEval<R> {
        let plain = |o: LawOutput<R>| LawEval {
            u: o.u,
            s: o.s,
            integral_rate: o.integral_rate,
            adapt: AdaptiveRegressors::default(),
            finite: o.finite,
        };
        match self {
            Self::Pid(l) => plain(l.evaluate(st, sig)),
            Self::Smc(l) => plain(l.evaluate(st, sig)),
            Self::DobSmc(l) => plain(l.evaluate(&st.dob, sig)),
            Self::AdaptiveSmc(l) => {
                let o = l.evaluate(&st.adapt, sig);
                LawEval {
                    u: o.law.u,
                    s: o.law.s,
                    integral_rate: R::ZERO,
                    adapt: o.reg,
                    finite: o.law.finite,
                }
            }
        }
    }

    /// Advance the state over one period `dt` after `ev`, given the output `u_applied`
    /// actually applied to the axis and the measured axis velocity `q_dot`.
    pub fn commit(&self, st: &mut LawState<R>, ev: &LawEval<R>, u_applied: R, q_dot: R, dt: R) {
        match self {
            Self::Pid(l) => {
                st.integral = integrate(st.integral, ev.integral_rate, dt, l.integral_limit)
            }
            Self::Smc(l) => {
                st.integral = integrate(st.integral, ev.integral_rate, dt, l.integral_limit)
            }
            Self::DobSmc(l) => l.observe(&mut st.dob, u_applied, q_dot, dt),
            Self::AdaptiveSmc(l) => l.adapt(&mut st.adapt, &ev.adapt, dt),
        }
    }

    /// True when every state of the law is finite and inside the number type's range
    /// (a fixed-point state pinned at the type's limit has saturated).
    pub fn state_healthy(&self, st: &LawState<R>) -> bool {
        let big = R::from_f32(f32::MAX);
        // `|x| < MAX` is false for ±inf and NaN: finite and unsaturated in one comparison
        let ok = |x: R| x.abs() < big;
        match self {
            Self::Pid(_) | Self::Smc(_) => ok(st.integral),
            Self::DobSmc(_) => ok(st.dob.v_hat) && ok(st.dob.d_hat),
            Self::AdaptiveSmc(_) => {
                ok(st.adapt.j) && ok(st.adapt.b) && ok(st.adapt.f_pos) && ok(st.adapt.f_neg)
            }
        }
    }

    /// Clamp the integral state to its limit (after a continuous-mode RK step).
    pub fn clamp_state(&self, st: &mut LawState<R>) {
        match self {
            Self::Pid(l) => st.integral = st.integral.clamp_sym(l.integral_limit),
            Self::Smc(l) => st.integral = st.integral.clamp_sym(l.integral_limit),
            Self::DobSmc(_) | Self::AdaptiveSmc(_) => {}
        }
    }

    /// Evaluate, then commit with the law's own output (a single axis on its own).
    pub fn step(&self, st: &mut LawState<R>, sig: &AxisSignals<R>, dt: R) -> R {
        let ev = self.evaluate(st, sig);
        self.commit(st, &ev, ev.u, sig.q_dot, dt);
        ev.u
    }
}
