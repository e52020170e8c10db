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
use crate::coupling::variable_gain::{VariableGainOutput, VariableGainState};
use crate::coupling::{Coupling, CouplingConfig};
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

/// One evaluation of the controller.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ControlOutput<R> {
    /// Per-axis outputs: the laws' saturated outputs plus the coupling correction (the
    /// amplifier's range is applied by the caller).
    pub u: Vec3<R>,
    /// Sliding variables (0 for PID axes).
    pub s: Vec3<R>,
    /// Tracking errors, the contour-error estimate, and the errors the laws saw.
    pub errors: Coupled<R>,
    /// Variable-gain coupling correction before saturation (0 otherwise).
    pub correction: Vec3<R>,
    /// Per-axis evaluations, for [`Controller3::commit`].
    pub evals: [LawEval<R>; AXES],
    /// Axes whose law produced a non-finite raw output this period (replaced by 0).
    pub nonfinite: [bool; AXES],
    vg: VariableGainOutput<R>,
}

impl<R: Real> ControlOutput<R> {
    /// Rates of the laws' integral states (the continuous mode's ODE).
    pub fn integral_rates(&self) -> [R; AXES] {
        [
            self.evals[0].integral_rate,
            self.evals[1].integral_rate,
            self.evals[2].integral_rate,
        ]
    }
}

/// The 3-axis controller: configuration plus its state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Controller3<R> {
    laws: [Law<R>; AXES],
    coupling: Coupling<R>,
    states: [LawState<R>; AXES],
    vg_state: VariableGainState<R>,
    prev_ref: Option<Vec3<R>>,
}

impl<R: Real> Controller3<R> {
    /// Validate `cfg`; nothing is built when it is rejected.
    pub fn new(cfg: &ControllerConfig) -> Result<Self, ConfigError> {
        let laws = [
            Law::new(&cfg.laws[0])?,
            Law::new(&cfg.laws[1])?,
            Law::new(&cfg.laws[2])?,
        ];
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
        for (st, law) in self.states.iter_mut().zip(&self.laws) {
            *st = law.initial_state();
        }
        self.vg_state = VariableGainState::default();
        self.prev_ref = None;
    }

    /// Evaluate for the current state (pure): the direction of the contour model is the
    /// configured one (analytic tangent, or the chord from the previous reference point).
    pub fn evaluate(&self, reference: &RefSample<R>, meas: &Measured<R>) -> ControlOutput<R> {
        let dir = match (&self.coupling, self.prev_ref) {
            (Coupling::Contour(c), Some(prev)) if c.direction == DirectionSource::Chord => {
                reference.pos - prev
            }
            _ => reference.vel,
        };
        self.evaluate_with(&self.states, &self.vg_state, reference, meas, dir)
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
        let mut out = ControlOutput {
            errors,
            ..Default::default()
        };
        for (i, (law, st)) in self.laws.iter().zip(states).enumerate() {
            let sig = AxisSignals {
                e: errors.c[i],
                e_dot: errors.c_dot[i],
                qd_dot: reference.vel[i],
                qd_ddot: reference.acc[i],
                q: meas.pos[i],
                q_dot: meas.vel[i],
            };
            let ev = law.evaluate(st, &sig);
            out.u[i] = ev.u;
            out.s[i] = ev.s;
            out.nonfinite[i] = !ev.finite;
            out.evals[i] = ev;
        }
        if let Coupling::VariableGain(vg) = &self.coupling {
            out.vg = vg.evaluate(vg_state, tracking, tracking_rate, reference.vel);
            out.correction = out.vg.correction;
            out.errors.contour = out.vg.contour;
            for i in 0..AXES {
                let u = out.u[i] + out.correction[i];
                out.nonfinite[i] |= !u.is_finite();
                out.u[i] = u.finite_or_zero();
            }
        }
        out
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
            vg.integrate(&mut self.vg_state, &out.vg, dt);
        }
        for i in 0..AXES {
            self.laws[i].commit(
                &mut self.states[i],
                &out.evals[i],
                applied[i],
                meas.vel[i],
                dt,
            );
        }
    }

    /// Evaluate, then commit with the controller's own outputs (no amplifier limit).
    pub fn step(
        &mut self,
        reference: &RefSample<R>,
        meas: &Measured<R>,
        dt: R,
    ) -> ControlOutput<R> {
        let out = self.evaluate(reference, meas);
        self.commit(&out, reference, meas, out.u, dt);
        out
    }

    /// The first axis whose state is not finite or has saturated the number type
    /// (including the variable-gain coupling's integral, reported on its axis).
    pub fn unhealthy_axis(&self) -> Option<usize> {
        let big = R::from_f32(f32::MAX);
        (0..AXES).find(|&i| {
            let vg = self.vg_state.integral[i];
            !(self.laws[i].state_healthy(&self.states[i]) && vg.is_finite() && vg.abs() < big)
        })
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
            self.laws[i].clamp_state(&mut self.states[i]);
        }
    }

    pub fn laws(&self) -> &[Law<R>; AXES] {
        &self.laws
    }

    pub fn coupling(&self) -> &Coupling<R> {
        &self.coupling
    }

    pub fn variable_gain_state(&self) -> &VariableGainState<R> {
        &self.vg_state
    }
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
        assert!(a.evaluate(&r, &m).errors.contour.norm() > 0.0);
    }
}
