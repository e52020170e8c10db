//! The 3-axis controller: a law per axis (any mix), the coupling between them, and the
//! saturation of the outputs. This is what the servo step runs every period, on the board
//! and in the simulator, in any number type ([`Real`]: `f32`, `f64`, fixed point).
//!
//! Per period: tracking errors `E = q_d - q` and their rates; with the paper's contour
//! coupling the laws see the coupled errors `C = E + λ e`; every law is evaluated; the
//! variable-gain coupling adds its correction along the path normal (the servo step then
//! saturates the sum to the amplifier's range). [`Controller3::evaluate`] does all that without
//! changing any state, and [`Controller3::commit`] then advances every state with the
//! output *actually applied* (which the caller may have switched off), see [`crate::law`].

use crate::axes::AXES;
use crate::config::ConfigError;
use crate::coupling::contour::{cross_couple, Coupled, DirectionSource};
use crate::coupling::variable_gain::VariableGainState;
use crate::coupling::{Coupling, CouplingConfig};
use crate::law::adaptive_smc::AdaptiveRegressors;
use crate::law::signals::integrate;
use crate::law::smc::{OwnPowers, PaperDsmcPowers, Smc, SmcPowers};
use crate::law::{AxisSignals, Law, LawConfig, LawEval, LawState};
use crate::motion::trajectory::RefSample;
use crate::{Real, Vec3};

/// Configuration of the 3-axis controller.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ControllerConfig {
    /// Law per axis (x, y, z), any mix.
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub laws: [LawConfig; AXES],
    /// Coupling between the axes.
    pub coupling: CouplingConfig,
}

impl ControllerConfig {
    /// The same law on all three axes with the paper's contour coupling of gain `lambda`.
    pub const fn uniform(law: LawConfig, lambda: f32) -> Self {
        Self {
            laws: [law, law, law],
            coupling: CouplingConfig::Contour(crate::coupling::ContourCouplingConfig::lambda(
                lambda,
            )),
        }
    }
}

/// Measured axis positions and velocities (velocities from an estimator on hardware).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measured<R> {
    pub pos: Vec3<R>,
    pub vel: Vec3<R>,
}

/// One evaluation of the controller. Kept small and filled in place
/// ([`Controller3::evaluate_into`]): the control interrupt copies nothing it does not need.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ControlOutput<R> {
    /// Per-axis outputs: the laws' saturated outputs plus the coupling correction (the
    /// amplifier's range is applied by the caller).
    pub u: Vec3<R>,
    /// Sliding variables (0 for PID axes).
    pub s: Vec3<R>,
    /// Tracking errors `q_d - q`.
    pub tracking: Vec3<R>,
    /// The contour-error estimate (0 without coupling).
    pub contour: Vec3<R>,
    /// Variable-gain coupling correction before saturation (0 otherwise).
    pub correction: Vec3<R>,
    /// Axes whose law produced a non-finite raw output this period (replaced by 0).
    pub nonfinite: [bool; AXES],
    /// Rates of the laws' integral states, for [`Controller3::commit`].
    integral_rate: [R; AXES],
    /// Regressors of the adaptive laws' updates, for [`Controller3::commit`] (written
    /// only by controllers with an adaptive law: no other commit reads them).
    adapt: [AdaptiveRegressors<R>; AXES],
    /// Rate of the variable-gain coupling's integral.
    vg_rate: Vec3<R>,
}

impl<R: Real> ControlOutput<R> {
    /// Rates of the laws' integral states (the continuous mode's ODE).
    pub fn integral_rates(&self) -> [R; AXES] {
        self.integral_rate
    }
}

/// The three axes' laws, resolved once (in [`Controller3::new`]) from the configured mix,
/// so that the period runs the common mixes without per-axis dispatch. The law code is the
/// same either way: only how it is reached differs.
#[derive(Clone, Copy, Debug, PartialEq)]
enum LawSet<R> {
    /// A sliding-mode law ([`Smc`]: SMC, DSMC) on every axis: evaluated directly, no
    /// [`Law`] dispatch and no adaptive regressors; `paper_powers` when every axis has the
    /// paper DSMC's exponents, whose power plan is then fixed at compile time
    /// ([`PaperDsmcPowers`]) instead of dispatched per call (the board runs this mix).
    Smc {
        laws: [Smc<R>; AXES],
        paper_powers: bool,
    },
    /// Any other mix: each axis dispatches on its [`Law`].
    Mixed([Law<R>; AXES]),
}

impl<R: Real> LawSet<R> {
    fn new(laws: [Law<R>; AXES]) -> Self {
        match laws {
            [Law::Smc(x), Law::Smc(y), Law::Smc(z)] => Self::Smc {
                paper_powers: [x, y, z].iter().all(Smc::has_paper_dsmc_powers),
                laws: [x, y, z],
            },
            _ => Self::Mixed(laws),
        }
    }

    fn get(&self, i: usize) -> Law<R> {
        match self {
            Self::Smc { laws, .. } => Law::Smc(laws[i.min(AXES - 1)]),
            Self::Mixed(laws) => laws[i.min(AXES - 1)],
        }
    }
}

/// The 3-axis controller: configuration plus its state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Controller3<R> {
    laws: LawSet<R>,
    coupling: Coupling<R>,
    states: [LawState<R>; AXES],
    vg_state: VariableGainState<R>,
    prev_ref: Option<Vec3<R>>,
}

impl<R: Real> Controller3<R> {
    /// Validate `cfg`; nothing is built when it is rejected.
    pub fn new(cfg: &ControllerConfig) -> Result<Self, ConfigError> {
        let laws = LawSet::new([
            Law::new(&cfg.laws[0])?,
            Law::new(&cfg.laws[1])?,
            Law::new(&cfg.laws[2])?,
        ]);
        let mut c = Self {
            laws,
            coupling: Coupling::new(&cfg.coupling)?,
            states: [LawState::default(); AXES],
            vg_state: VariableGainState::default(),
            prev_ref: None,
        };
        c.reset();
        Ok(c)
    }

    /// Fresh states: integrals and observers zero, adaptive estimates at their initial
    /// values, no previous reference point.
    pub fn reset(&mut self) {
        for (i, st) in self.states.iter_mut().enumerate() {
            *st = self.laws.get(i).initial_state();
        }
        self.vg_state = VariableGainState::default();
        self.prev_ref = None;
    }

    /// The reference's coordinates moved by `delta` (an axis was re-based by homing): the
    /// chord direction's previous point moves with them.
    pub fn shift_reference(&mut self, delta: Vec3<R>) {
        if let Some(p) = &mut self.prev_ref {
            *p = *p + delta;
        }
    }

    /// Evaluate for the current state (pure): the direction of the contour model is the
    /// configured one (analytic tangent, or the chord from the previous reference point).
    pub fn evaluate(&self, reference: &RefSample<R>, meas: &Measured<R>) -> ControlOutput<R> {
        let mut out = ControlOutput::default();
        self.evaluate_into(reference, meas, &mut out);
        out
    }

    /// [`Self::evaluate`] into `out` (every field of `out` is written).
    pub fn evaluate_into(
        &self,
        reference: &RefSample<R>,
        meas: &Measured<R>,
        out: &mut ControlOutput<R>,
    ) {
        let dir = match (&self.coupling, self.prev_ref) {
            (Coupling::Contour(c), Some(prev)) if c.direction == DirectionSource::Chord => {
                reference.pos - prev
            }
            _ => reference.vel,
        };
        self.evaluate_with_into(&self.states, &self.vg_state, reference, meas, dir, out)
    }

    /// Evaluate for explicit law states and contour direction `dir` (the simulator's
    /// continuous mode passes the analytic tangent and its RK stage states).
    pub fn evaluate_with(
        &self,
        states: &[LawState<R>; AXES],
        vg_state: &VariableGainState<R>,
        reference: &RefSample<R>,
        meas: &Measured<R>,
        dir: Vec3<R>,
    ) -> ControlOutput<R> {
        let mut out = ControlOutput::default();
        self.evaluate_with_into(states, vg_state, reference, meas, dir, &mut out);
        out
    }

    /// [`Self::evaluate_with`] into `out` (every field of `out` that this controller's
    /// [`Self::commit`] or the caller reads is written).
    pub fn evaluate_with_into(
        &self,
        states: &[LawState<R>; AXES],
        vg_state: &VariableGainState<R>,
        reference: &RefSample<R>,
        meas: &Measured<R>,
        dir: Vec3<R>,
        out: &mut ControlOutput<R>,
    ) {
        let tracking = reference.pos - meas.pos;
        let tracking_rate = reference.vel - meas.vel;
        let errors = match &self.coupling {
            Coupling::Contour(c) => cross_couple(
                tracking,
                tracking_rate,
                dir,
                reference.vel,
                c.lambda,
                c.min_dir_sq,
            ),
            Coupling::None | Coupling::VariableGain(_) => Coupled {
                tracking,
                contour: Vec3::zero(),
                c: tracking,
                c_dot: tracking_rate,
            },
        };
        out.tracking = tracking;
        out.contour = errors.contour;
        out.correction = Vec3::zero();
        out.vg_rate = Vec3::zero();
        let sig = Signals {
            c: &errors,
            reference,
            meas,
        };
        match &self.laws {
            LawSet::Smc {
                laws,
                paper_powers: true,
            } => eval_smc(laws, states, &sig, &PaperDsmcPowers, out),
            LawSet::Smc {
                laws,
                paper_powers: false,
            } => eval_smc(laws, states, &sig, &OwnPowers, out),
            LawSet::Mixed(laws) => eval_mixed(laws, states, &sig, out),
        }
        if let Coupling::VariableGain(vg) = &self.coupling {
            let v = vg.evaluate(vg_state, tracking, tracking_rate, reference.vel);
            out.correction = v.correction;
            out.contour = v.contour;
            out.vg_rate = v.integral_rate;
            for i in 0..AXES {
                let u = out.u[i] + out.correction[i];
                out.nonfinite[i] |= !u.is_finite();
                out.u[i] = u.finite_or_zero();
            }
        }
    }

    /// Advance every state over one period `dt` after `out`, with the outputs `applied`
    /// that actually reached the axes (zero where the outputs were switched off) and the
    /// measurement the evaluation used.
    pub fn commit(
        &mut self,
        out: &ControlOutput<R>,
        reference: &RefSample<R>,
        meas: &Measured<R>,
        applied: Vec3<R>,
        dt: R,
    ) {
        self.prev_ref = Some(reference.pos);
        if let Coupling::VariableGain(vg) = &self.coupling {
            vg.integrate_rate(&mut self.vg_state, out.vg_rate, dt);
        }
        match &self.laws {
            LawSet::Smc { laws, .. } => {
                for ((st, law), rate) in self.states.iter_mut().zip(laws).zip(out.integral_rate) {
                    st.integral = integrate(st.integral, rate, dt, law.integral_limit());
                }
            }
            LawSet::Mixed(laws) => {
                let (applied, q_dot) = (applied.to_array(), meas.vel.to_array());
                for i in 0..AXES {
                    let ev = LawEval {
                        integral_rate: out.integral_rate[i],
                        adapt: out.adapt[i],
                        ..LawEval::default()
                    };
                    laws[i].commit(&mut self.states[i], &ev, applied[i], q_dot[i], dt);
                }
            }
        }
    }

    /// Evaluate, then commit with the controller's own outputs (no amplifier limit).
    pub fn step(
        &mut self,
        reference: &RefSample<R>,
        meas: &Measured<R>,
        dt: R,
    ) -> ControlOutput<R> {
        let mut out = ControlOutput::default();
        self.step_into(reference, meas, dt, &mut out);
        out
    }

    /// [`Self::step`] into `out`.
    pub fn step_into(
        &mut self,
        reference: &RefSample<R>,
        meas: &Measured<R>,
        dt: R,
        out: &mut ControlOutput<R>,
    ) {
        self.evaluate_into(reference, meas, out);
        self.commit(out, reference, meas, out.u, dt);
    }

    /// The first axis whose state is not finite or has saturated the number type
    /// (including the variable-gain coupling's integral, reported on its axis).
    pub fn unhealthy_axis(&self) -> Option<usize> {
        let big = R::from_f32(f32::MAX);
        // `|x| < MAX` is false for ±inf and NaN: finite and unsaturated in one comparison
        let ok = |x: R| x.abs() < big;
        let vg_ok = |i: usize| match self.coupling {
            // the variable-gain integral stays zero without that coupling
            Coupling::VariableGain(_) => ok(self.vg_state.integral[i]),
            Coupling::None | Coupling::Contour(_) => true,
        };
        match &self.laws {
            // a sliding-mode law's only state is its integral
            LawSet::Smc { .. } => (0..AXES).find(|&i| !(ok(self.states[i].integral) && vg_ok(i))),
            LawSet::Mixed(laws) => {
                (0..AXES).find(|&i| !(laws[i].state_healthy(&self.states[i]) && vg_ok(i)))
            }
        }
    }

    /// Corrupt axis `axis`'s law state (∞ in floating point, the type's limit in fixed
    /// point): fault injection for the simulator's and the QEMU build's fault matrix (the
    /// servo step must detect it).
    pub fn inject_corrupt_state(&mut self, axis: usize) {
        if let Some(st) = self.states.get_mut(axis) {
            let bad = R::from_f32(f32::INFINITY);
            st.integral = bad;
            st.dob.d_hat = bad;
            st.adapt.b = bad;
        }
    }

    pub fn states(&self) -> &[LawState<R>; AXES] {
        &self.states
    }

    /// Set the law states (the continuous mode integrates the integrals alongside the
    /// plant); each is clamped to its law's integral limit.
    pub fn set_states(&mut self, states: [LawState<R>; AXES]) {
        self.states = states;
        for i in 0..AXES {
            self.laws.get(i).clamp_state(&mut self.states[i]);
        }
    }

    /// The configured law of every axis.
    pub fn laws(&self) -> [Law<R>; AXES] {
        [self.laws.get(0), self.laws.get(1), self.laws.get(2)]
    }

    pub fn coupling(&self) -> &Coupling<R> {
        &self.coupling
    }

    pub fn variable_gain_state(&self) -> &VariableGainState<R> {
        &self.vg_state
    }
}

/// The per-axis signals of one evaluation.
struct Signals<'a, R> {
    /// The (coupled) errors.
    c: &'a Coupled<R>,
    reference: &'a RefSample<R>,
    meas: &'a Measured<R>,
}

impl<R: Real> Signals<'_, R> {
    /// Axis `i`'s signals (inlined with a constant `i`, the `Vec3` indexing folds away).
    #[inline(always)]
    fn axis(&self, i: usize) -> AxisSignals<R> {
        AxisSignals {
            e: self.c.c[i],
            e_dot: self.c.c_dot[i],
            qd_dot: self.reference.vel[i],
            qd_ddot: self.reference.acc[i],
            q: self.meas.pos[i],
            q_dot: self.meas.vel[i],
        }
    }
}

/// The sliding-mode laws of all three axes, their powers formed by `powers`, into `out`
/// (written out per axis: the three evaluations inline with constant indices).
#[inline(always)]
fn eval_smc<R: Real, P: SmcPowers>(
    laws: &[Smc<R>; AXES],
    states: &[LawState<R>; AXES],
    sig: &Signals<'_, R>,
    powers: &P,
    out: &mut ControlOutput<R>,
) {
    #[inline(always)]
    fn axis<R: Real, P: SmcPowers>(
        i: usize,
        laws: &[Smc<R>; AXES],
        states: &[LawState<R>; AXES],
        sig: &Signals<'_, R>,
        powers: &P,
        out: &mut ControlOutput<R>,
    ) -> (R, R) {
        let o = laws[i].evaluate_with(states[i].integral, &sig.axis(i), powers);
        out.nonfinite[i] = !o.finite;
        out.integral_rate[i] = o.integral_rate;
        (o.u, o.s)
    }
    let (ux, sx) = axis(0, laws, states, sig, powers, out);
    let (uy, sy) = axis(1, laws, states, sig, powers, out);
    let (uz, sz) = axis(2, laws, states, sig, powers, out);
    out.u = Vec3::new(ux, uy, uz);
    out.s = Vec3::new(sx, sy, sz);
}

/// Any mix of laws, each axis dispatching on its law, into `out` (written out per axis).
#[inline(always)]
fn eval_mixed<R: Real>(
    laws: &[Law<R>; AXES],
    states: &[LawState<R>; AXES],
    sig: &Signals<'_, R>,
    out: &mut ControlOutput<R>,
) {
    #[inline(always)]
    fn axis<R: Real>(
        i: usize,
        laws: &[Law<R>; AXES],
        states: &[LawState<R>; AXES],
        sig: &Signals<'_, R>,
        out: &mut ControlOutput<R>,
    ) -> (R, R) {
        let ev = laws[i].evaluate(&states[i], &sig.axis(i));
        out.nonfinite[i] = !ev.finite;
        out.integral_rate[i] = ev.integral_rate;
        out.adapt[i] = ev.adapt;
        (ev.u, ev.s)
    }
    let (ux, sx) = axis(0, laws, states, sig, out);
    let (uy, sy) = axis(1, laws, states, sig, out);
    let (uz, sz) = axis(2, laws, states, sig, out);
    out.u = Vec3::new(ux, uy, uz);
    out.s = Vec3::new(sx, sy, sz);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coupling::variable_gain::VariableGainConfig;
    use crate::presets::gantry::{dob_smc_for, GANTRY_X, VARIABLE_GAIN_XY};
    use crate::presets::paper::{PAPER_DSMC, PAPER_LAMBDA, PAPER_PID};

    fn sample() -> (RefSample<f64>, Measured<f64>) {
        let r = RefSample {
            pos: Vec3::new(1.0, 2.0, 3.0),
            vel: Vec3::new(0.5, -0.2, 0.1),
            acc: Vec3::new(0.0, 1.0, 0.0),
        };
        let m = Measured {
            pos: Vec3::new(0.99, 2.02, 2.995),
            vel: Vec3::new(0.45, -0.1, 0.12),
        };
        (r, m)
    }

    #[test]
    fn any_mix_of_laws_and_saturation() {
        let cfg = ControllerConfig {
            laws: [
                LawConfig::Pid(PAPER_PID),
                LawConfig::Smc(PAPER_DSMC),
                LawConfig::DobSmc(dob_smc_for(&GANTRY_X)),
            ],
            coupling: CouplingConfig::VariableGain(VariableGainConfig { ..VARIABLE_GAIN_XY }),
        };
        let mut c = Controller3::<f64>::new(&cfg).unwrap();
        let (r, m) = sample();
        let out = c.step(&r, &m, 1e-4);
        // PID: kp e + kd e' (+ the first period's zero integral) plus the correction
        let pid = 600.0 * 0.01 + 10.0 * 0.05;
        assert!(
            (out.u.x - out.correction.x - pid).abs() < 1e-9,
            "{}",
            out.u.x
        );
        assert!(out.correction.norm() > 0.0);
        assert!(out.u.is_finite());
        // PID integrated its error, DOB observed
        assert!(c.states()[0].integral != 0.0);
        assert!(c.states()[2].dob.started);
    }

    #[test]
    fn commit_feeds_the_applied_output_to_the_observer() {
        let cfg = ControllerConfig {
            laws: [LawConfig::DobSmc(dob_smc_for(&GANTRY_X)); 3],
            coupling: CouplingConfig::None,
        };
        let (r, m) = sample();
        let mut a = Controller3::<f64>::new(&cfg).unwrap();
        let mut b = a;
        let out = a.evaluate(&r, &m);
        a.commit(&out, &r, &m, out.u, 1e-4);
        a.commit(&out, &r, &m, out.u, 1e-4);
        b.commit(&out, &r, &m, Vec3::zero(), 1e-4);
        b.commit(&out, &r, &m, Vec3::zero(), 1e-4);
        // the observer saw different torques: different disturbance estimates
        assert!(a.states()[0].dob.d_hat != b.states()[0].dob.d_hat);
    }

    #[test]
    fn contour_coupling_with_zero_gain_is_uncoupled() {
        let (r, m) = sample();
        let mut a =
            Controller3::<f64>::new(&ControllerConfig::uniform(LawConfig::Smc(PAPER_DSMC), 0.0))
                .unwrap();
        let mut b = Controller3::<f64>::new(&ControllerConfig {
            coupling: CouplingConfig::None,
            ..ControllerConfig::uniform(LawConfig::Smc(PAPER_DSMC), PAPER_LAMBDA)
        })
        .unwrap();
        assert_eq!(a.step(&r, &m, 1e-4).u, b.step(&r, &m, 1e-4).u);
        assert!(a.evaluate(&r, &m).contour.norm() > 0.0);
    }

    /// Evaluate and commit every axis' law through `Law` one by one (the dispatching
    /// path), with the coupled errors the controller computes: what any law set must give.
    fn per_law(
        c: &Controller3<f32>,
        r: &RefSample<f32>,
        m: &Measured<f32>,
        dt: f32,
    ) -> ([LawEval<f32>; AXES], [LawState<f32>; AXES]) {
        let coupled = match c.coupling() {
            Coupling::Contour(k) => cross_couple(
                r.pos - m.pos,
                r.vel - m.vel,
                r.vel,
                r.vel,
                k.lambda,
                k.min_dir_sq,
            ),
            _ => Coupled {
                tracking: r.pos - m.pos,
                contour: Vec3::zero(),
                c: r.pos - m.pos,
                c_dot: r.vel - m.vel,
            },
        };
        let laws = c.laws();
        let mut states = *c.states();
        let evals = [0, 1, 2].map(|i| {
            let sig = AxisSignals {
                e: coupled.c[i],
                e_dot: coupled.c_dot[i],
                qd_dot: r.vel[i],
                qd_ddot: r.acc[i],
                q: m.pos[i],
                q_dot: m.vel[i],
            };
            laws[i].evaluate(&states[i], &sig)
        });
        for i in 0..AXES {
            laws[i].commit(&mut states[i], &evals[i], evals[i].u, m.vel[i], dt);
        }
        (evals, states)
    }

    proptest::proptest! {
        /// The law set resolved at construction (the SMC set with the compile-time plan,
        /// or per-axis dispatch) gives what each axis' law gives on its own, bit for bit.
        #[test]
        fn law_sets_equal_the_laws_one_by_one(
            p in proptest::array::uniform3(-50.0f32..50.0),
            v in proptest::array::uniform3(-20.0f32..20.0),
            a in proptest::array::uniform3(-5.0f32..5.0),
            dp in proptest::array::uniform3(-0.05f32..0.05),
            dv in proptest::array::uniform3(-1.0f32..1.0),
            mix in 0usize..3,
        ) {
            use crate::presets::board::servo_config;
            let r = RefSample {
                pos: Vec3::from_array(p),
                vel: Vec3::from_array(v),
                acc: Vec3::from_array(a),
            };
            let m = Measured {
                pos: r.pos - Vec3::from_array(dp),
                vel: r.vel - Vec3::from_array(dv),
            };
            let cfg = match mix {
                // the board: DSMC on every axis (paper powers), contour coupling
                0 => servo_config(10_000).controller,
                // SMC on every axis without the paper's powers
                1 => ControllerConfig::uniform(
                    LawConfig::Smc(crate::presets::paper::PAPER_SMC),
                    PAPER_LAMBDA,
                ),
                // a mix: per-axis dispatch
                _ => ControllerConfig {
                    laws: [
                        LawConfig::Pid(PAPER_PID),
                        LawConfig::Smc(PAPER_DSMC),
                        LawConfig::DobSmc(dob_smc_for(&GANTRY_X)),
                    ],
                    coupling: CouplingConfig::None,
                },
            };
            let mut c = Controller3::<f32>::new(&cfg).unwrap();
            // a populated state first
            c.step(&r, &m, 1.0e-4);
            let (evals, states) = per_law(&c, &r, &m, 1.0e-4);
            let out = c.evaluate(&r, &m);
            for (i, ev) in evals.iter().enumerate() {
                proptest::prop_assert_eq!(out.u[i].to_bits(), ev.u.to_bits());
                proptest::prop_assert_eq!(out.s[i].to_bits(), ev.s.to_bits());
                proptest::prop_assert_eq!(out.integral_rates()[i], ev.integral_rate);
                proptest::prop_assert_eq!(out.nonfinite[i], !ev.finite);
            }
            c.commit(&out, &r, &m, out.u, 1.0e-4);
            proptest::prop_assert_eq!(c.states(), &states);
        }
    }
}
