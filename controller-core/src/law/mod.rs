//! The per-axis control laws and the one interface every controller uses to run them.
//!
//! A law is configured by a [`LawConfig`] (plain `f32` values, serde behind the feature),
//! validated once into a runtime [`Law`] in the controller's number type. Its state
//! ([`LawState`]) is kept separately. Every period the controller
//!
//! 1. **evaluates** the law ([`Law::evaluate`], a pure function of state and signals),
//!    getting the law's own (saturated) output and what the state update needs;
//! 2. combines the outputs of all axes (cross-coupling corrections, saturation);
//! 3. **commits** ([`Law::commit`]) with the output *actually applied* to the axis, so
//!    that an observer or an adaptation never mistakes a correction it did not make, or a
//!    saturation, for a disturbance.
//!
//! The laws are continuous-time: [`LawEval::integral_rate`] is the rate of the law's
//! integral, which the firmware and the simulator's discrete mode integrate over one
//! period, and the simulator's continuous mode integrates with RK4 together with the
//! plant (PID and sliding-mode laws only; see [`Law::supports_continuous`]).
//!
//! - [`pid`]: PID with anti-windup and feed-forward (spec 2.1);
//! - [`smc`]: SMC and DSMC, terminal and nonsingular surfaces (spec 2.2, 2.3);
//! - [`dob_smc`]: sliding mode with a disturbance observer (spec 2.4, patent seed 002);
//! - [`adaptive_smc`]: sliding mode with online friction identification (spec 2.5, seed 004).

pub mod adaptive_smc;
pub mod dob_smc;
pub mod pid;
pub mod smc;

use crate::config::ConfigError;
use crate::Real;
use adaptive_smc::{AdaptiveRegressors, AdaptiveSmc, AdaptiveSmcConfig, AdaptiveState};
use dob_smc::{DobSmc, DobSmcConfig, DobState};
use pid::{Pid, PidConfig};
use smc::{Smc, SmcConfig};

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

/// One evaluation of a PID or sliding-mode law.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawOutput<R> {
    /// Saturated control output.
    pub u: R,
    /// `d/dt` of [`LawState::integral`] (0 while anti-windup holds the integrator).
    pub integral_rate: R,
    /// Sliding variable (0 for PID), for telemetry and plots.
    pub s: R,
    /// False when the law's raw output was not finite (then replaced by 0): a fault the
    /// servo step reports instead of letting the replacement hide it.
    pub finite: bool,
}

/// Saturation and conditional integration shared by PID and the sliding-mode laws: the
/// output is clamped to `±u_max`, and the error is not integrated while the output is
/// saturated in the direction the error would push it further.
#[inline(always)]
pub(crate) fn finish<R: Real>(u_raw: R, e: R, u_max: R, s: R) -> LawOutput<R> {
    // The common case: `u_raw` finite and not saturated, `e` and `s` finite (one range
    // test covers all three, see `zero_if_finite`); the result is what the general path
    // below gives.
    if (u_raw + (zero_if_finite(e) + zero_if_finite(s))).in_range(u_max) {
        return LawOutput {
            u: u_raw,
            integral_rate: e,
            s,
            finite: true,
        };
    }
    let finite = u_raw.is_finite();
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
        finite,
    }
}

/// `x - x`: zero for a finite `x`, NaN for ±inf and NaN (in fixed point always zero), so
/// adding it to a value makes that value fail a finiteness or range test exactly when `x`
/// is not finite: several tests in one.
#[allow(clippy::eq_op)]
#[inline(always)]
fn zero_if_finite<R: Real>(x: R) -> R {
    x - x
}

/// Advance an integral by one period, clamped to `±limit`.
#[inline(always)]
pub(crate) fn integrate<R: Real>(integral: R, rate: R, dt: R, limit: R) -> R {
    (integral + rate * dt).clamp_sym(limit)
}

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

#[cfg(test)]
mod tests {
    use super::*;

    /// `finish` as it was written before its fast path (the general path alone).
    fn finish_general(u_raw: f32, e: f32, u_max: f32, s: f32) -> LawOutput<f32> {
        let finite = u_raw.is_finite();
        let u_raw = u_raw.finite_or_zero();
        let u = u_raw.max_of(-u_max).min_of(u_max);
        let saturated = u != u_raw;
        let winds_up = saturated && (e * u_raw > 0.0);
        LawOutput {
            u,
            integral_rate: if winds_up { 0.0 } else { e.finite_or_zero() },
            s: s.finite_or_zero(),
            finite,
        }
    }

    #[test]
    fn finish_fast_path_equals_the_general_path() {
        let values = [
            0.0,
            -0.0,
            1.0e-3,
            -2.5,
            99.0,
            100.0,
            100.000_01,
            -250.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut fast = 0;
        for u in values {
            for e in values {
                for s in values {
                    for u_max in [100.0, f32::INFINITY] {
                        let a = finish(u, e, u_max, s);
                        let b = finish_general(u, e, u_max, s);
                        let same = |x: f32, y: f32| x.to_bits() == y.to_bits();
                        assert!(
                            same(a.u, b.u)
                                && same(a.integral_rate, b.integral_rate)
                                && same(a.s, b.s)
                                && a.finite == b.finite,
                            "finish({u}, {e}, {u_max}, {s}): {a:?} vs {b:?}"
                        );
                        fast += usize::from(u.in_range(u_max) && e.is_finite() && s.is_finite());
                    }
                }
            }
        }
        // both paths were exercised
        assert!(fast > 100 && fast < values.len().pow(3) * 2, "{fast}");
    }
}
