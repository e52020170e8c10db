//! Adaptive sliding mode with online friction identification (spec 2.5, seed 004).
//!
//! Plant (spec 1.3) `J x'' + B x' + f+ μ + f- (1 - μ) + T_load = u`, μ = 1 for x' >= 0.
//! Error `x̃ = x - x_d` (opposite sign to the paper laws: `x̃ = -e`), surface
//! `s = x̃' + λ x̃`, the switching boundary layer Φ of the control, and the adaptation
//! dead zone δ with the distance `s_δ = s - δ sat(s/δ)`:
//!
//! ```text
//! u   = -k_d s + Ĵ (x_d'' - λ x̃') + B̂ x' + f̂+ μ + f̂- (1 - μ) - k sat(s/Φ)
//! Ĵ'  = -γ_J s_δ (x_d'' - λ x̃')      B̂'  = -γ_B s_δ x'
//! f̂+' = -γ_+ s_δ μ                    f̂-' = -γ_- s_δ (1 - μ)
//! ```
//!
//! With `V = ½ J s_δ² + Σ θ̃²/(2γ)`, `V' = s_δ (-k_d s - k sat(s/Φ) - T_load)`, which is
//! `<= 0` whenever the unmodelled torque `|T_load| <= δ (k_d + k/Φ)` (δ <= Φ), i.e. the
//! feedback's torque at the dead zone's edge. Each estimate is projected onto its
//! configured bounds after every update (clamping), which keeps `V' <= 0` because the truth
//! lies inside the bounds, and bounds the estimates whatever the disturbance.
//!
//! Why δ is separate from Φ: the estimates stop moving once `|s| < δ` everywhere on the
//! path, so a parameter error whose torque the feedback absorbs inside `|s| < δ`, about
//! `δ (k_d + k/Φ)`, is never identified. The textbook choice δ = Φ (Slotine & Li) ties
//! this residual to the chattering-reduction layer: with Φ = 0.3 mm/s on the X axis it
//! is ~16 mN·m, as large as the whole viscous torque of the friction scenario. A small δ
//! keeps the control's layer and shrinks the residual; zero-mean velocity-estimator noise
//! on `s` needs no dead zone (the integrators average it), only bounded *biased*
//! disturbances do, and those are what δ (k_d + k/Φ) is sized against.

use super::signals::{AxisSignals, LawOutput};
use crate::config::{finite, limit, non_negative, positive, ConfigError};
use crate::Real;

/// Bounds `[min, max]` of one estimate and its adaptation gain `γ`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct EstimateConfig {
    /// Initial estimate (clamped into the bounds).
    pub initial: f32,
    pub min: f32,
    pub max: f32,
    /// Adaptation gain γ (0 freezes the estimate: the non-adaptive SMC).
    pub gamma: f32,
}

/// Adaptive SMC parameters (physical units: mm, s, mN·m).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AdaptiveSmcConfig {
    /// Surface slope λ (1/s).
    pub lambda: f32,
    /// Boundary layer Φ of the switching term (mm/s).
    pub boundary_layer: f32,
    /// Adaptation dead zone δ (mm/s), `0 <= δ <= Φ`: the estimates move only while
    /// `|s| > δ` (see the module docs).
    pub dead_zone: f32,
    /// Derivative-like gain k_d (mN·m per mm/s).
    pub kd: f32,
    /// Switching gain k >= T_max (mN·m).
    pub k: f32,
    pub inertia: EstimateConfig,
    pub viscous: EstimateConfig,
    pub coulomb_pos: EstimateConfig,
    pub coulomb_neg: EstimateConfig,
    /// Output saturation, mN·m.
    pub u_max: f32,
}

impl AdaptiveSmcConfig {
    /// The same law with every adaptation gain zero: a fixed-parameter SMC with friction
    /// feed-forward from the initial estimates.
    pub const fn frozen(mut self) -> Self {
        self.inertia.gamma = 0.0;
        self.viscous.gamma = 0.0;
        self.coulomb_pos.gamma = 0.0;
        self.coulomb_neg.gamma = 0.0;
        self
    }
}

/// The estimates `Ĵ, B̂, f̂+, f̂-`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AdaptiveState<R> {
    pub j: R,
    pub b: R,
    pub f_pos: R,
    pub f_neg: R,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Est<R> {
    min: R,
    max: R,
    gamma: R,
    initial: R,
}

impl<R: Real> Est<R> {
    fn new(c: &EstimateConfig, name: &'static str) -> Result<Self, ConfigError> {
        let (min, max) = (finite(c.min, name)?, finite(c.max, name)?);
        if !(max >= min) {
            return Err(ConfigError::Negative(name));
        }
        let initial = finite(c.initial, name)?.clamp(min, max);
        Ok(Self {
            min: R::from_f32(min),
            max: R::from_f32(max),
            gamma: R::from_f32(non_negative(c.gamma, name)?),
            initial: R::from_f32(initial),
        })
    }

    /// `θ̂ += -γ s_Δ φ dt`, projected onto the bounds.
    fn update(&self, v: R, s_delta: R, regressor: R, dt: R) -> R {
        (v - self.gamma * s_delta * regressor * dt)
            .finite_or_zero()
            .max_of(self.min)
            .min_of(self.max)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveSmc<R> {
    lambda: R,
    inv_phi: R,
    dead_zone: R,
    kd: R,
    k: R,
    j: Est<R>,
    b: Est<R>,
    f_pos: Est<R>,
    f_neg: Est<R>,
    u_max: R,
}

/// What the adaptation needs from an evaluation: the distance to the dead zone and the
/// regressors of `Ĵ`, `B̂` and `f̂±`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AdaptiveRegressors<R> {
    s_delta: R,
    acc_ref: R,
    vel: R,
    mu: R,
}

/// One evaluation: the output and the regressors the adaptation needs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AdaptiveOutput<R> {
    pub law: LawOutput<R>,
    pub reg: AdaptiveRegressors<R>,
}

impl<R: Real> AdaptiveSmc<R> {
    pub fn new(c: &AdaptiveSmcConfig) -> Result<Self, ConfigError> {
        let phi = positive(c.boundary_layer, "boundary_layer")?;
        let dead_zone = non_negative(c.dead_zone, "dead_zone")?;
        if dead_zone > phi {
            return Err(ConfigError::Negative("boundary_layer - dead_zone"));
        }
        let f_neg = Est::new(&c.coulomb_neg, "coulomb_neg")?;
        if f_neg.max > R::ZERO {
            return Err(ConfigError::Negative("coulomb_neg.max must be <= 0"));
        }
        Ok(Self {
            lambda: R::from_f32(positive(c.lambda, "lambda")?),
            inv_phi: R::from_f64(1.0 / phi as f64),
            dead_zone: R::from_f32(dead_zone),
            kd: R::from_f32(non_negative(c.kd, "kd")?),
            k: R::from_f32(non_negative(c.k, "k")?),
            j: Est::new(&c.inertia, "inertia")?,
            b: Est::new(&c.viscous, "viscous")?,
            f_pos: Est::new(&c.coulomb_pos, "coulomb_pos")?,
            f_neg,
            u_max: R::from_f32(limit(c.u_max, "u_max")?),
        })
    }

    /// The estimates a fresh controller starts from.
    pub fn initial_state(&self) -> AdaptiveState<R> {
        AdaptiveState {
            j: self.j.initial,
            b: self.b.initial,
            f_pos: self.f_pos.initial,
            f_neg: self.f_neg.initial,
        }
    }

    /// The control output for the current estimates (`sig.e = x_d - x`, paper sign).
    pub fn evaluate(&self, st: &AdaptiveState<R>, sig: &AxisSignals<R>) -> AdaptiveOutput<R> {
        // x̃ = -e, x̃' = -e'
        let s = -(sig.e_dot + self.lambda * sig.e);
        let sat = (s * self.inv_phi).clamp_sym(R::ONE);
        let s_delta = s - s.clamp_sym(self.dead_zone);
        let acc_ref = sig.qd_ddot + self.lambda * sig.e_dot;
        let mu = if sig.q_dot >= R::ZERO {
            R::ONE
        } else {
            R::ZERO
        };
        let u = -self.kd * s
            + st.j * acc_ref
            + st.b * sig.q_dot
            + st.f_pos * mu
            + st.f_neg * (R::ONE - mu)
            - self.k * sat;
        AdaptiveOutput {
            law: LawOutput {
                u: u.finite_or_zero().clamp_sym(self.u_max),
                integral_rate: R::ZERO,
                s: s.finite_or_zero(),
                finite: u.is_finite(),
            },
            reg: AdaptiveRegressors {
                s_delta: s_delta.finite_or_zero(),
                acc_ref: acc_ref.finite_or_zero(),
                vel: sig.q_dot.finite_or_zero(),
                mu,
            },
        }
    }

    /// Advance the estimates over one period `dt` (forward Euler, then projection).
    pub fn adapt(&self, st: &mut AdaptiveState<R>, out: &AdaptiveRegressors<R>, dt: R) {
        let sd = out.s_delta;
        st.j = self.j.update(st.j, sd, out.acc_ref, dt);
        st.b = self.b.update(st.b, sd, out.vel, dt);
        st.f_pos = self.f_pos.update(st.f_pos, sd, out.mu, dt);
        st.f_neg = self.f_neg.update(st.f_neg, sd, R::ONE - out.mu, dt);
    }

    /// Evaluate, then adapt.
    pub fn step(&self, st: &mut AdaptiveState<R>, sig: &AxisSignals<R>, dt: R) -> LawOutput<R> {
        let out = self.evaluate(st, sig);
        self.adapt(st, &out.reg, dt);
        out.law
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::gantry::ADAPTIVE_SMC_X;

    #[test]
    fn output_matches_hand_computation() {
        let law = AdaptiveSmc::<f64>::new(&ADAPTIVE_SMC_X).unwrap();
        let st = AdaptiveState {
            j: 0.05,
            b: 0.2,
            f_pos: 30.0,
            f_neg: -20.0,
        };
        let sig = AxisSignals {
            e: 0.001,
            e_dot: -0.5,
            qd_ddot: 100.0,
            q_dot: -10.0,
            ..Default::default()
        };
        let c = ADAPTIVE_SMC_X;
        let (lam, phi) = (c.lambda as f64, c.boundary_layer as f64);
        let s = 0.5 - lam * 0.001;
        let sat = (s / phi).clamp(-1.0, 1.0);
        let u =
            -c.kd as f64 * s + 0.05 * (100.0 + lam * -0.5) + 0.2 * -10.0 - 20.0 - c.k as f64 * sat;
        let out = law.evaluate(&st, &sig);
        assert!((out.law.u - u).abs() < 1e-9, "{} vs {u}", out.law.u);
        assert!((out.law.s - s).abs() < 1e-12);
    }

    #[test]
    fn estimates_frozen_inside_layer_and_projected() {
        let law = AdaptiveSmc::<f32>::new(&ADAPTIVE_SMC_X).unwrap();
        let mut st = law.initial_state();
        let inside = AxisSignals {
            e_dot: 0.5 * ADAPTIVE_SMC_X.dead_zone,
            qd_ddot: 1000.0,
            q_dot: 10.0,
            ..Default::default()
        };
        law.step(&mut st, &inside, 1e-4);
        assert_eq!(st, law.initial_state());
        // between the dead zone and the boundary layer the estimates move, by exactly
        // -γ (|s| - δ) φ dt: s = -e_dot = -2δ, so s_δ = -δ
        let c = ADAPTIVE_SMC_X;
        assert!(2.0 * c.dead_zone < c.boundary_layer);
        let between = AxisSignals {
            e_dot: 2.0 * c.dead_zone,
            ..inside
        };
        law.step(&mut st, &between, 1e-4);
        let expect_b = c.viscous.initial + c.viscous.gamma * c.dead_zone * 10.0 * 1e-4;
        assert!(
            (st.b - expect_b).abs() < 1e-4 * expect_b,
            "{} vs {expect_b}",
            st.b
        );
        let mut st = law.initial_state();
        // far outside: large updates, always within bounds
        let outside = AxisSignals {
            e_dot: 1e4,
            qd_ddot: 1e4,
            q_dot: 1e4,
            ..Default::default()
        };
        for _ in 0..1000 {
            law.step(&mut st, &outside, 1e-4);
        }
        assert_eq!(st.j, c.inertia.max);
        assert_eq!(st.b, c.viscous.max);
        assert_eq!(st.f_pos, c.coulomb_pos.max);
        assert_eq!(
            st.f_neg,
            c.coulomb_neg
                .initial
                .clamp(c.coulomb_neg.min, c.coulomb_neg.max)
        );
    }

    #[test]
    fn rejects_inverted_bounds() {
        let mut c = ADAPTIVE_SMC_X;
        c.inertia.min = 1.0;
        c.inertia.max = 0.5;
        assert!(AdaptiveSmc::<f32>::new(&c).is_err());
        let mut c = ADAPTIVE_SMC_X;
        c.coulomb_neg.max = 1.0;
        assert!(AdaptiveSmc::<f32>::new(&c).is_err());
        let mut c = ADAPTIVE_SMC_X;
        c.dead_zone = 2.0 * c.boundary_layer;
        assert!(AdaptiveSmc::<f32>::new(&c).is_err());
        c.dead_zone = -0.1;
        assert!(AdaptiveSmc::<f32>::new(&c).is_err());
    }
}
