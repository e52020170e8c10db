//! The simulation loop shared by every host experiment.
//!
//! The plant is always integrated in `f64` with RK4; the controller runs in the number
//! type chosen by the scenario ([`Numeric`]), so a run shows what the firmware's arithmetic
//! does. Metrics are taken on the *true* plant state against the `f64` reference.

use anyhow::{bail, Result};
use controller_core::estimator::{
    EstimatorConfig, EstimatorTiming, KalmanConfig, PllConfig, VelocityEstimator,
};
use controller_core::gantry::{Gantry3, GantryConfig, GantryOutput, Measured};
use controller_core::law::LawState;
use controller_core::metrics::{distance_to_path, Itse, MaxRms, TotalVariation};
use controller_core::ode::{rk4, OdeState};
use controller_core::plant::{axis_derivative, rk4_step, AxisDynamics, AxisState};
use controller_core::trajectory::RefSample;
use controller_core::trajectory::Trajectory;
use controller_core::{Real, Vec3};
use serde::{Deserialize, Serialize};

/// Number type the controller runs in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Numeric {
    /// The firmware's float type.
    #[default]
    F32,
    /// Host reference precision.
    F64,
    /// Saturating fixed point Q32.32 (`controller_core::fixed::FxQ32`): the format the
    /// range analysis in docs/fixed-point.md chooses.
    Fixed,
    /// Saturating fixed point Q16.16 (`FxQ16`): one `SMULL` per multiply, too coarse for
    /// the integrator at kHz rates (see docs/fixed-point.md); for comparison.
    FixedQ16,
}

/// Where the controller's axis velocities come from in discrete mode.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocitySource {
    /// The plant's true velocity (not available on hardware; the reference case).
    #[default]
    Exact,
    /// `(q[k] - q[k-1]) / Ts` of the quantised positions.
    BackwardDifference,
    /// controller-core's PLL estimator on the encoder counts (needs `position_quantum`
    /// > 0), fed with the reference acceleration as the firmware does.
    Pll(PllConfig),
    /// controller-core's Kalman estimator on the encoder counts, driven by the reference
    /// acceleration as the commanded acceleration (no lag on the planned motion).
    Kalman(KalmanConfig),
}

/// Controller at a fixed rate with zero-order hold, as the firmware runs it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiscreteSpec {
    pub rate_hz: f64,
    /// RK4 steps of the plant per control period.
    #[serde(default = "default_substeps")]
    pub plant_substeps: u32,
    /// Position quantisation step (one encoder count in plant units); 0 = none.
    #[serde(default)]
    pub position_quantum: f64,
    /// Actuator saturation `|u| <= actuator_limit` (amplifier); `inf` = none.
    #[serde(default = "inf")]
    pub actuator_limit: f64,
    #[serde(default)]
    pub velocity: VelocitySource,
}

fn default_substeps() -> u32 {
    4
}

fn inf() -> f64 {
    f64::INFINITY
}

/// How the controller is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Mode {
    /// Controller evaluated at every RK4 stage (the paper's continuous-time setting).
    Continuous {
        dt_s: f64,
    },
    Discrete(DiscreteSpec),
}

/// What to measure besides ITSE over the whole run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetricSpec {
    /// Extra ITSE over `[from, to)` (the paper's robustness window).
    pub itse_window_s: Option<(f64, f64)>,
    /// Compute the true distance to the path (contour error) from this time on.
    pub contour_from_s: Option<f64>,
    /// Contour error sampling period.
    pub contour_every_s: f64,
    /// Trace decimation period (CSV and plots).
    pub trace_every_s: f64,
}

impl Default for MetricSpec {
    fn default() -> Self {
        Self {
            itse_window_s: None,
            contour_from_s: None,
            contour_every_s: 1e-3,
            trace_every_s: 1e-3,
        }
    }
}

/// One simulation run.
#[derive(Clone, Debug)]
pub struct RunSpec {
    pub horizon_s: f64,
    pub trajectory: Trajectory<f64>,
    pub controller: GantryConfig,
    pub mode: Mode,
    pub numeric: Numeric,
    pub metrics: MetricSpec,
    /// Initial plant state per axis (rest at the origin by default).
    pub initial: [AxisState<f64>; 3],
}

/// Decimated time series of a run.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    pub t: Vec<f64>,
    pub reference: Vec<[f64; 3]>,
    pub position: Vec<[f64; 3]>,
    pub u: Vec<[f64; 3]>,
    pub s: Vec<[f64; 3]>,
    /// The controller's own contour-error vector (model of paper eq. 14).
    pub contour_model: Vec<[f64; 3]>,
}

/// Figures of one run. Errors are `q_d - q` on the true plant state.
#[derive(Clone, Debug, Default)]
pub struct RunResult {
    pub itse: [f64; 3],
    pub itse_window: [f64; 3],
    pub iae: [f64; 3],
    pub max_abs_error: [f64; 3],
    pub contour_max: f64,
    pub contour_rms: f64,
    /// Total variation of u over the run, per axis.
    pub tv_u: [f64; 3],
    pub peak_u: [f64; 3],
    pub trace: Trace,
}

/// Collects the metrics during a run.
struct Recorder<'a> {
    spec: &'a RunSpec,
    itse: [Itse<f64>; 3],
    window: [Itse<f64>; 3],
    iae: [f64; 3],
    max_err: [f64; 3],
    contour: MaxRms<f64>,
    tv: [TotalVariation<f64>; 3],
    peak: [f64; 3],
    trace: Trace,
    next_contour_t: f64,
    next_trace_t: f64,
}

impl<'a> Recorder<'a> {
    fn new(spec: &'a RunSpec) -> Self {
        let (a, b) = spec.metrics.itse_window_s.unwrap_or((0.0, 0.0));
        Self {
            spec,
            itse: [Itse::new(); 3],
            window: [Itse::window(a, b); 3],
            iae: [0.0; 3],
            max_err: [0.0; 3],
            contour: MaxRms::default(),
            tv: [TotalVariation::default(); 3],
            peak: [0.0; 3],
            trace: Trace::default(),
            next_contour_t: spec.metrics.contour_from_s.unwrap_or(f64::INFINITY),
            next_trace_t: 0.0,
        }
    }

    fn record<R: Real>(
        &mut self,
        t: f64,
        dt: f64,
        plant: &[AxisState<f64>; 3],
        u: [f64; 3],
        out: &GantryOutput<R>,
    ) {
        let r = self.spec.trajectory.sample(t);
        let p = Vec3::new(plant[0].pos, plant[1].pos, plant[2].pos);
        for i in 0..3 {
            let e = r.pos[i] - p[i];
            self.itse[i].add(t, e, dt);
            self.window[i].add(t, e, dt);
            self.iae[i] += e.abs() * dt;
            self.max_err[i] = self.max_err[i].max(e.abs());
            self.tv[i].add(u[i]);
            self.peak[i] = self.peak[i].max(u[i].abs());
        }
        // half a step of slack so float drift in t never skips a sample
        if t + 0.5 * dt >= self.next_contour_t {
            self.contour
                .add(distance_to_path(&self.spec.trajectory, p, t, 0.5));
            self.next_contour_t += self.spec.metrics.contour_every_s;
        }
        if t + 0.5 * dt >= self.next_trace_t {
            let tr = &mut self.trace;
            tr.t.push(t);
            tr.reference.push(r.pos.to_array());
            tr.position.push(p.to_array());
            tr.u.push(u);
            tr.s.push(out.s.cast::<f64>().to_array());
            tr.contour_model
                .push(out.errors.contour.cast::<f64>().to_array());
            self.next_trace_t += self.spec.metrics.trace_every_s;
        }
    }

    fn finish(self) -> RunResult {
        RunResult {
            itse: self.itse.map(|i| i.value),
            itse_window: self.window.map(|i| i.value),
            iae: self.iae,
            max_abs_error: self.max_err,
            contour_max: self.contour.max,
            contour_rms: self.contour.rms(),
            tv_u: self.tv.map(|t| t.value),
            peak_u: self.peak,
            trace: self.trace,
        }
    }
}

/// Plant states plus the controller's integral states: the continuous-mode ODE state.
#[derive(Clone, Copy)]
struct Augmented {
    plant: [AxisState<f64>; 3],
    integral: [f64; 3],
}

impl OdeState<f64> for Augmented {
    fn add_scaled(&self, d: &Self, h: f64) -> Self {
        let mut integral = self.integral;
        for (x, dx) in integral.iter_mut().zip(d.integral) {
            *x += dx * h;
        }
        Self {
            plant: self.plant.add_scaled(&d.plant, h),
            integral,
        }
    }
}

fn measured<R: Real>(pos: Vec3<f64>, vel: Vec3<f64>) -> Measured<R> {
    Measured {
        pos: pos.cast(),
        vel: vel.cast(),
    }
}

fn positions(p: &[AxisState<f64>; 3]) -> Vec3<f64> {
    Vec3::new(p[0].pos, p[1].pos, p[2].pos)
}

fn velocities(p: &[AxisState<f64>; 3]) -> Vec3<f64> {
    Vec3::new(p[0].vel, p[1].vel, p[2].vel)
}

fn steps(horizon_s: f64, dt: f64) -> Result<usize> {
    if !(dt > 0.0 && dt.is_finite() && horizon_s > 0.0 && horizon_s.is_finite()) {
        bail!("time step ({dt} s) and horizon ({horizon_s} s) must be positive and finite");
    }
    Ok((horizon_s / dt).round() as usize)
}

/// Run `spec` against `plants` (one dynamics model per axis) in the scenario's number type.
pub fn run<D: AxisDynamics<f64>>(spec: &RunSpec, plants: &[D; 3]) -> Result<RunResult> {
    match spec.numeric {
        Numeric::F32 => run_as::<f32, D>(spec, plants),
        Numeric::F64 => run_as::<f64, D>(spec, plants),
        Numeric::Fixed => run_as::<controller_core::fixed::FxQ32, D>(spec, plants),
        Numeric::FixedQ16 => run_as::<controller_core::fixed::FxQ16, D>(spec, plants),
    }
}

/// A controller the discrete loop can run: [`Gantry3`] and the seed methods'
/// [`controller_core::seed_gantry::SeedController`] (see [`crate::seeds`]).
pub trait DiscreteController<R: Real> {
    /// One control period; the output's `u`, `s` and `errors.contour` are recorded.
    fn step_discrete(&mut self, r: &RefSample<R>, m: &Measured<R>, dt: R) -> GantryOutput<R>;
}

impl<R: Real> DiscreteController<R> for Gantry3<R> {
    fn step_discrete(&mut self, r: &RefSample<R>, m: &Measured<R>, dt: R) -> GantryOutput<R> {
        self.step(r, m, dt)
    }
}

/// Run with the controller in number type `R`.
pub fn run_as<R: Real, D: AxisDynamics<f64>>(spec: &RunSpec, plants: &[D; 3]) -> Result<RunResult> {
    let mut gantry = Gantry3::<R>::new(&spec.controller)
        .map_err(|e| anyhow::anyhow!("invalid controller configuration: {e}"))?;
    let traj: Trajectory<R> = spec.trajectory.cast();
    let mut rec = Recorder::new(spec);
    match spec.mode {
        Mode::Continuous { dt_s } => {
            let n = steps(spec.horizon_s, dt_s)?;
            let mut x = Augmented {
                plant: spec.initial,
                integral: [0.0; 3],
            };
            let eval = |g: &Gantry3<R>, t: f64, x: &Augmented| {
                let states = x.integral.map(|v| LawState {
                    integral: R::from_f64(v),
                });
                let r = traj.sample(R::from_f64(t));
                let m = measured::<R>(positions(&x.plant), velocities(&x.plant));
                g.evaluate(&states, &r, &m, r.vel)
            };
            for k in 0..n {
                let t = k as f64 * dt_s;
                let out = eval(&gantry, t, &x);
                rec.record(t, dt_s, &x.plant, out.u.cast::<f64>().to_array(), &out);
                x = rk4(&x, t, dt_s, |tt, s| {
                    let o = eval(&gantry, tt, s);
                    let mut d = *s;
                    for (i, plant) in plants.iter().enumerate() {
                        let acc = plant.accel(s.plant[i], o.u[i].to_f64(), tt);
                        d.plant[i] = axis_derivative(s.plant[i], acc);
                        d.integral[i] = o.integral_rate[i].to_f64();
                    }
                    d
                });
                // integral limits apply to the continuous state as well
                gantry.set_states(x.integral.map(|v| LawState {
                    integral: R::from_f64(v),
                }));
                for i in 0..3 {
                    x.integral[i] = gantry.states()[i].integral.to_f64();
                }
            }
        }
        Mode::Discrete(d) => return discrete_loop(spec, &d, plants, &traj, &mut gantry),
    }
    Ok(rec.finish())
}

/// The discrete mode's loop for any [`DiscreteController`]: `spec.mode` must be
/// [`Mode::Discrete`] (passed as `d`); `spec.controller` is not used, `ctl` is.
pub fn discrete_loop<R: Real, D: AxisDynamics<f64>, C: DiscreteController<R>>(
    spec: &RunSpec,
    d: &DiscreteSpec,
    plants: &[D; 3],
    traj: &Trajectory<R>,
    ctl: &mut C,
) -> Result<RunResult> {
    let mut rec = Recorder::new(spec);
    if d.plant_substeps == 0 {
        bail!("plant_substeps must be at least 1");
    }
    if !(d.position_quantum >= 0.0) || d.actuator_limit.is_nan() || d.actuator_limit <= 0.0 {
        bail!("position_quantum must be >= 0 and actuator_limit > 0");
    }
    let ts = 1.0 / d.rate_hz;
    let n = steps(spec.horizon_s, ts)?;
    let sub = ts / d.plant_substeps as f64;
    let mut plant = spec.initial;
    let mut prev_q: Option<Vec3<f64>> = None;
    let mut pll = Vec::new();
    let estimator = match d.velocity {
        VelocitySource::Pll(c) => Some(EstimatorConfig::Pll(c)),
        VelocitySource::Kalman(c) => Some(EstimatorConfig::Kalman(c)),
        _ => None,
    };
    if let Some(cfg) = estimator {
        if d.position_quantum.is_nan() || d.position_quantum <= 0.0 {
            bail!(
                "the {} velocity source needs position_quantum > 0",
                cfg.name()
            );
        }
        let timing = EstimatorTiming {
            period_s: ts as f32,
            count_size: d.position_quantum as f32,
        };
        for st in &plant {
            let c0 = (st.pos / d.position_quantum).round() as i64;
            pll.push(
                VelocityEstimator::<R>::new(&cfg, &timing, c0)
                    .map_err(|e| anyhow::anyhow!("invalid {} configuration: {e}", cfg.name()))?,
            );
        }
    }
    let quantise = |v: f64| {
        if d.position_quantum > 0.0 {
            (v / d.position_quantum).round() * d.position_quantum
        } else {
            v
        }
    };
    for k in 0..n {
        let t = k as f64 * ts;
        let q = positions(&plant).map(quantise);
        let r = traj.sample(R::from_f64(t));
        let mut m = measured::<R>(q, Vec3::zero());
        match d.velocity {
            VelocitySource::Exact => m.vel = velocities(&plant).cast(),
            VelocitySource::BackwardDifference => {
                if let Some(p) = prev_q {
                    m.vel = (q - p).scale(1.0 / ts).cast();
                }
            }
            VelocitySource::Pll(_) | VelocitySource::Kalman(_) => {
                for (i, e) in pll.iter_mut().enumerate() {
                    let c = (plant[i].pos / d.position_quantum).round() as i64;
                    m.vel[i] = e.update(c, r.acc[i]).vel;
                }
            }
        }
        prev_q = Some(q);
        let out = ctl.step_discrete(&r, &m, R::from_f64(ts));
        let u = out
            .u
            .cast::<f64>()
            .map(|x| x.clamp(-d.actuator_limit, d.actuator_limit));
        rec.record(t, ts, &plant, u.to_array(), &out);
        for j in 0..d.plant_substeps {
            rk4_step(plants, &mut plant, t + j as f64 * sub, sub, |_, _| {
                u.to_array()
            });
        }
    }
    Ok(rec.finish())
}
