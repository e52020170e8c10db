//! The seed methods' comparison (issue 5), `host-sim seeds`: the patent's XY contouring
//! (PID, DSMC, DOB-SMC, each with and without variable-gain cross-coupling), the XY-table
//! paper's friction identification (fixed vs adaptive SMC), and the paper's DSMC with its
//! 3-D cross-coupling on the physical 3-axis gantry (helix). Everything runs in the
//! engine's discrete mode at the firmware rate against [`PhysicalAxis`] plants driven
//! through the [`Drive`] amplifier model. Scenario files: `host-sim/scenarios/seeds_*.toml`.

use crate::engine::{
    discrete_loop, DiscreteController, DiscreteSpec, MetricSpec, Mode, Numeric, RunResult, RunSpec,
    VelocitySource,
};
use anyhow::{anyhow, bail, Result};
use controller_core::adaptive_smc::AdaptiveState;
use controller_core::contour::Coupled;
use controller_core::estimator::{KalmanConfig, PllConfig, PAPER_SIM_KALMAN};
use controller_core::gantry::{Gantry3, GantryConfig, GantryOutput, Measured};
use controller_core::params::LawConfig;
use controller_core::physical_plant::{PhysicalAxis, PhysicalAxisConfig};
use controller_core::plant::{AxisDynamics, AxisState};
use controller_core::seed_gantry::SeedController;
use controller_core::seed_params::{dsmc_for, SeedMethod, GANTRY_AXES};
use controller_core::trajectory::{Polyline, RefSample, Trajectory};
use controller_core::variable_gain_ccc::CccMode;
use controller_core::{Real, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The built-in scenario files.
pub const BUILTIN: [(&str, &str); 3] = [
    (
        "seeds_contouring.toml",
        include_str!("../scenarios/seeds_contouring.toml"),
    ),
    (
        "seeds_friction.toml",
        include_str!("../scenarios/seeds_friction.toml"),
    ),
    (
        "seeds_helix.toml",
        include_str!("../scenarios/seeds_helix.toml"),
    ),
];

/// Amplifier: the torque command is quantised to the PWM resolution (`2 T_max / 2^bits`
/// per step) before the motor, whose peak torque clamps it ([`PhysicalAxis`]).
#[derive(Clone, Copy, Debug)]
pub struct Drive {
    pub axis: PhysicalAxis<f64>,
    pub torque_step: f64,
}

impl Drive {
    pub fn new(cfg: &PhysicalAxisConfig, pwm_bits: u32) -> Result<Self> {
        if !(1..=24).contains(&pwm_bits) {
            bail!("pwm_bits must be 1..=24, got {pwm_bits}");
        }
        let axis = PhysicalAxis::new(cfg).map_err(|e| anyhow!("invalid axis: {e}"))?;
        Ok(Self {
            axis,
            torque_step: 2.0 * cfg.torque_max_mnm as f64 / (1u64 << pwm_bits) as f64,
        })
    }
}

impl AxisDynamics<f64> for Drive {
    fn accel(&self, s: AxisState<f64>, u: f64, t: f64) -> f64 {
        let u = (u / self.torque_step).round() * self.torque_step;
        self.axis.accel(s, u, t)
    }
}

impl<R: Real> DiscreteController<R> for SeedController<R> {
    fn step_discrete(&mut self, r: &RefSample<R>, m: &Measured<R>, dt: R) -> GantryOutput<R> {
        let o = self.step(r, m, dt);
        let tracking = r.pos - m.pos;
        GantryOutput {
            u: o.u,
            s: o.s,
            integral_rate: Vec3::zero(),
            errors: Coupled {
                tracking,
                contour: o.contour_estimate,
                c: tracking,
                c_dot: r.vel - m.vel,
            },
        }
    }
}

/// Reference paths of the seed scenarios (lengths mm, speeds mm/s).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PathSpec {
    /// Straight line from the origin at `angle_deg` to the X axis.
    Line { angle_deg: f64, speed: f64 },
    /// Circle of `radius` through the origin (centre below it), at `speed`.
    Circle { radius: f64, speed: f64 },
    /// Square with sharp corners, exact stop at each corner ([`Polyline`]).
    Square { side: f64, speed: f64, accel: f64 },
    /// Per-axis sines `amp_i sin(2π f t + phase_i)`.
    Sine {
        amp: [f64; 3],
        freq_hz: f64,
        phase: [f64; 3],
    },
    /// Helix around the Z axis through the origin's circle, rising at `z_rate`.
    Helix {
        radius: f64,
        speed: f64,
        z_rate: f64,
    },
}

impl PathSpec {
    pub fn trajectory(&self) -> Result<Trajectory<f64>> {
        Ok(match *self {
            Self::Line { angle_deg, speed } => {
                let a = angle_deg.to_radians();
                Trajectory::Line {
                    start: Vec3::zero(),
                    vel: Vec3::new(speed * a.cos(), speed * a.sin(), 0.0),
                }
            }
            Self::Circle { radius, speed } => {
                Trajectory::circle(Vec3::new(0.0, -radius, 0.0), radius, speed / radius)
            }
            Self::Square { side, speed, accel } => Trajectory::Polyline(
                Polyline::square(Vec3::zero(), side, speed, accel)
                    .ok_or_else(|| anyhow!("square needs side, speed, accel > 0"))?,
            ),
            Self::Sine {
                amp,
                freq_hz,
                phase,
            } => Trajectory::Sine {
                amp: Vec3::from_array(amp),
                omega: 2.0 * std::f64::consts::PI * freq_hz,
                phase: Vec3::from_array(phase),
                offset: Vec3::zero(),
            },
            Self::Helix {
                radius,
                speed,
                z_rate,
            } => Trajectory::Helix {
                center: Vec3::new(0.0, -radius, 0.0),
                radius,
                omega: speed / radius,
                z_rate,
            },
        })
    }
}

/// What a scenario compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Study {
    /// PID, DSMC, DOB-SMC, each without and with variable-gain cross-coupling.
    Contouring,
    /// Fixed-parameter SMC vs adaptive SMC; reports the X axis' estimates.
    Friction,
    /// DSMC alone, with the paper's 3-D error coupling (λ), and with the 3-D
    /// variable-gain coupling.
    Helix,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeedScenario {
    pub name: String,
    pub study: Study,
    pub path: PathSpec,
    pub horizon_s: f64,
    /// Load step on the X axis (mN·m) at `load_step_t_s` (0 = none).
    #[serde(default)]
    pub load_step_mnm: f32,
    #[serde(default)]
    pub load_step_t_s: f32,
    /// The paper's coupling gain for the helix study.
    #[serde(default)]
    pub lambda: f32,
    /// Start of the window over which the errors at velocity reversals are measured
    /// (s; 0 = whole run). The friction study measures after adaptation has converged.
    #[serde(default)]
    pub reversal_from_s: f64,
}

/// Settings shared by every seed scenario file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeedFile {
    pub rate_hz: f64,
    pub plant_substeps: u32,
    /// Velocity PLL bandwidth, rad/s.
    pub pll_bandwidth_rad_s: f32,
    /// When set, the Kalman estimator driven by the reference acceleration replaces the
    /// PLL: σ of the unexplained acceleration's change per period, mm/s².
    #[serde(default)]
    pub kalman_accel_noise_mm_s2: Option<f32>,
    pub pwm_bits: u32,
    pub scenario: Vec<SeedScenario>,
}

/// Figures of one law on one scenario (lengths mm, torques mN·m).
#[derive(Clone, Debug, Serialize)]
pub struct LawFigures {
    pub contour_max: f64,
    pub contour_rms: f64,
    pub itse: [f64; 3],
    pub peak_torque: [f64; 3],
    pub max_error: [f64; 3],
    /// Total variation of the torque per second, per axis (mN·m/s).
    pub chattering: [f64; 3],
    /// Largest |e| within ±[`REVERSAL_HALF_WIDTH_S`] of a reversal of the reference
    /// velocity of the axis, from the scenario's `reversal_from_s` on (mm; 0 when the
    /// axis does not reverse there).
    pub reversal_max_error: [f64; 3],
}

/// Half width of the window around a velocity reversal in which the reversal error is
/// measured: 20 ms, longer than the friction transient (the s-loop settles in
/// ~3/(k_d/J) = 10 ms) and short against the 250 ms between reversals at 2 Hz.
pub const REVERSAL_HALF_WIDTH_S: f64 = 0.02;

/// Decimation of the recorded estimates: one sample per 10 ms.
pub const ESTIMATE_TRACE_EVERY_S: f64 = 0.01;

/// Estimates `[Ĵ, B̂, f̂+, f̂-]` of each axis at one instant.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct EstimateSample {
    pub t: f64,
    pub axes: [[f64; 4]; 3],
}

#[derive(Clone, Debug, Serialize)]
pub struct Estimate {
    pub estimate: f64,
    pub truth: f64,
}

/// Everything `host-sim seeds` reports.
#[derive(Clone, Debug, Default)]
pub struct SeedsReport {
    pub scenarios: BTreeMap<String, BTreeMap<String, LawFigures>>,
    /// Final estimates of the adaptive law per moving axis ("x", "y"), keyed "J", "B",
    /// "f_pos", "f_neg".
    pub adaptation: BTreeMap<String, BTreeMap<String, Estimate>>,
    /// The adaptive law's estimates over time (friction study).
    pub estimates: Vec<EstimateSample>,
    pub traces: Vec<(String, RunResult)>,
}

impl SeedsReport {
    /// The JSON of issue 5 (public interface): `{"<scenario>": {"<law>": {...}},
    /// "adaptation": {"J"|"B"|"f_pos"|"f_neg": {"estimate", "truth"}}}`, where
    /// "adaptation" is the X axis; every adapted axis is under "adaptation_axes".
    pub fn to_json(&self) -> serde_json::Value {
        let mut m = serde_json::Map::new();
        for (k, v) in &self.scenarios {
            m.insert(k.clone(), serde_json::to_value(v).unwrap_or_default());
        }
        if let Some(x) = self.adaptation.get("x") {
            m.insert(
                "adaptation".into(),
                serde_json::to_value(x).unwrap_or_default(),
            );
        }
        m.insert(
            "adaptation_axes".into(),
            serde_json::to_value(&self.adaptation).unwrap_or_default(),
        );
        serde_json::Value::Object(m)
    }
}

fn figures(r: &RunResult, sc: &SeedScenario, traj: &Trajectory<f64>) -> LawFigures {
    LawFigures {
        contour_max: r.contour_max,
        contour_rms: r.contour_rms,
        itse: r.itse,
        peak_torque: r.peak_u,
        max_error: r.max_abs_error,
        chattering: r.tv_u.map(|v| v / sc.horizon_s),
        reversal_max_error: reversal_errors(r, traj, sc.reversal_from_s),
    }
}

/// Per axis, the largest |e| on the trace within ±[`REVERSAL_HALF_WIDTH_S`] of an
/// instant where the reference velocity of that axis changes sign, from `from_s` on.
pub fn reversal_errors(r: &RunResult, traj: &Trajectory<f64>, from_s: f64) -> [f64; 3] {
    let tr = &r.trace;
    let vel: Vec<Vec3<f64>> = tr.t.iter().map(|&t| traj.sample(t).vel).collect();
    let mut out = [0.0; 3];
    for (i, o) in out.iter_mut().enumerate() {
        let reversals: Vec<f64> = (1..tr.t.len())
            .filter(|&k| vel[k - 1][i] * vel[k][i] < 0.0)
            .map(|k| tr.t[k])
            .collect();
        for (k, &t) in tr.t.iter().enumerate() {
            if t >= from_s
                && reversals
                    .iter()
                    .any(|&tr_s| (t - tr_s).abs() <= REVERSAL_HALF_WIDTH_S)
            {
                *o = f64::max(*o, (tr.reference[k][i] - tr.position[k][i]).abs());
            }
        }
    }
    out
}

/// A [`SeedController`] that records its adaptive estimates every `every` periods.
struct Recording {
    ctl: SeedController<f32>,
    every: usize,
    k: usize,
    dt_s: f64,
    log: Vec<EstimateSample>,
}

fn estimate_row(a: &AdaptiveState<f32>) -> [f64; 4] {
    [a.j, a.b, a.f_pos, a.f_neg].map(f64::from)
}

impl DiscreteController<f32> for Recording {
    fn step_discrete(
        &mut self,
        r: &RefSample<f32>,
        m: &Measured<f32>,
        dt: f32,
    ) -> GantryOutput<f32> {
        if self.k.is_multiple_of(self.every) {
            let st = self.ctl.states();
            self.log.push(EstimateSample {
                t: self.k as f64 * self.dt_s,
                axes: [0, 1, 2].map(|i| estimate_row(&st[i].adapt)),
            });
        }
        self.k += 1;
        self.ctl.step_discrete(r, m, dt)
    }
}

pub(crate) struct Setup {
    pub(crate) spec: RunSpec,
    pub(crate) disc: DiscreteSpec,
    pub(crate) plants: [Drive; 3],
}

pub(crate) fn setup(file: &SeedFile, sc: &SeedScenario) -> Result<Setup> {
    let traj = sc.path.trajectory()?;
    let mut axes = GANTRY_AXES;
    if sc.load_step_mnm != 0.0 {
        axes[0].load_step_mnm = sc.load_step_mnm;
        axes[0].load_step_t_s = sc.load_step_t_s;
    }
    let plants = [
        Drive::new(&axes[0], file.pwm_bits)?,
        Drive::new(&axes[1], file.pwm_bits)?,
        Drive::new(&axes[2], file.pwm_bits)?,
    ];
    let r0 = traj.sample(0.0);
    let disc = DiscreteSpec {
        rate_hz: file.rate_hz,
        plant_substeps: file.plant_substeps,
        position_quantum: controller_core::seed_params::COUNT_MM as f64,
        actuator_limit: f64::INFINITY,
        velocity: match file.kalman_accel_noise_mm_s2 {
            Some(q) => VelocitySource::Kalman(KalmanConfig {
                accel_noise_units_s2: q,
                // uniform quantisation of one count, as for the paper simulation
                ..PAPER_SIM_KALMAN
            }),
            None => VelocitySource::Pll(PllConfig {
                bandwidth_rad_s: file.pll_bandwidth_rad_s,
                damping: 1.0,
            }),
        },
    };
    let spec = RunSpec {
        horizon_s: sc.horizon_s,
        trajectory: traj,
        // the helix study runs this Gantry3 configuration; the others pass their own
        // controller to the discrete loop (see `run_seed`)
        controller: GantryConfig {
            laws: GANTRY_AXES.map(|a| LawConfig::Smc(dsmc_for(&a))),
            ..GantryConfig::uniform(LawConfig::Smc(dsmc_for(&GANTRY_AXES[0])), 0.0)
        },
        mode: Mode::Discrete(disc),
        numeric: Numeric::F32,
        metrics: MetricSpec {
            contour_from_s: Some(0.0),
            contour_every_s: 1e-3,
            trace_every_s: 1e-3,
            ..Default::default()
        },
        // start on the reference, at its velocity
        initial: [0, 1, 2].map(|i| AxisState {
            pos: r0.pos[i],
            vel: r0.vel[i],
        }),
    };
    Ok(Setup { spec, disc, plants })
}

fn run_seed(
    s: &Setup,
    method: SeedMethod,
    coupled: bool,
) -> Result<(RunResult, SeedController<f32>)> {
    let mut ctl = SeedController::<f32>::new(&method.controller(coupled))
        .map_err(|e| anyhow!("invalid {} configuration: {e}", method.name()))?;
    let traj = s.spec.trajectory.cast();
    let r = discrete_loop(&s.spec, &s.disc, &s.plants, &traj, &mut ctl)?;
    Ok((r, ctl))
}

/// Run the adaptive law recording its estimates.
fn run_adaptive(s: &Setup) -> Result<(RunResult, SeedController<f32>, Vec<EstimateSample>)> {
    let method = SeedMethod::Adaptive;
    let ctl = SeedController::<f32>::new(&method.controller(false))
        .map_err(|e| anyhow!("invalid {} configuration: {e}", method.name()))?;
    let dt_s = 1.0 / s.disc.rate_hz;
    let mut rec = Recording {
        ctl,
        every: ((ESTIMATE_TRACE_EVERY_S / dt_s).round() as usize).max(1),
        k: 0,
        dt_s,
        log: Vec::new(),
    };
    let traj = s.spec.trajectory.cast();
    let r = discrete_loop(&s.spec, &s.disc, &s.plants, &traj, &mut rec)?;
    Ok((r, rec.ctl, rec.log))
}

/// Names of the estimates in [`EstimateSample::axes`] order.
pub const ESTIMATE_NAMES: [&str; 4] = ["J", "B", "f_pos", "f_neg"];

/// Run every scenario of `file`.
pub fn run_file(file: &SeedFile, rep: &mut SeedsReport) -> Result<()> {
    for sc in &file.scenario {
        let s = setup(file, sc)?;
        let mut laws = BTreeMap::new();
        match sc.study {
            Study::Contouring => {
                for m in [SeedMethod::Pid, SeedMethod::Dsmc, SeedMethod::DobSmc] {
                    for coupled in [false, true] {
                        let (r, _) = run_seed(&s, m, coupled)?;
                        let key = format!("{}{}", m.name(), if coupled { "+ccc" } else { "" });
                        laws.insert(key.clone(), figures(&r, sc, &s.spec.trajectory));
                        rep.traces.push((format!("{}_{key}", sc.name), r));
                    }
                }
            }
            Study::Friction => {
                let (r, _) = run_seed(&s, SeedMethod::FixedSmc, false)?;
                let fixed = SeedMethod::FixedSmc.name();
                laws.insert(fixed.to_string(), figures(&r, sc, &s.spec.trajectory));
                rep.traces.push((format!("{}_{fixed}", sc.name), r));
                let (r, ctl, log) = run_adaptive(&s)?;
                let adaptive = SeedMethod::Adaptive.name();
                laws.insert(adaptive.to_string(), figures(&r, sc, &s.spec.trajectory));
                rep.traces.push((format!("{}_{adaptive}", sc.name), r));
                rep.estimates = log;
                for (i, axis) in ["x", "y"].iter().enumerate() {
                    let e = estimate_row(&ctl.states()[i].adapt);
                    let a = GANTRY_AXES[i];
                    let truth = [a.inertia, a.viscous, a.coulomb_pos_mnm, a.coulomb_neg_mnm];
                    let m = ESTIMATE_NAMES
                        .iter()
                        .zip(e.iter().zip(truth))
                        .map(|(k, (&estimate, t))| {
                            (
                                k.to_string(),
                                Estimate {
                                    estimate,
                                    truth: t as f64,
                                },
                            )
                        })
                        .collect();
                    rep.adaptation.insert(axis.to_string(), m);
                }
            }
            Study::Helix => {
                let mut cfg = s.spec.controller;
                for (key, lambda) in [("DSMC", 0.0), ("DSMC+ccc", sc.lambda)] {
                    cfg.lambda = lambda;
                    let mut g = Gantry3::<f32>::new(&cfg)
                        .map_err(|e| anyhow!("invalid helix configuration: {e}"))?;
                    let traj = s.spec.trajectory.cast();
                    let r = discrete_loop(&s.spec, &s.disc, &s.plants, &traj, &mut g)?;
                    laws.insert(key.to_string(), figures(&r, sc, &s.spec.trajectory));
                    rep.traces.push((format!("{}_{key}", sc.name), r));
                }
                // the patent's coupling in its 3-D form on the same DSMC axes
                let mut c = SeedMethod::Dsmc.controller(true);
                if let Some(cc) = &mut c.ccc {
                    cc.mode = CccMode::Normal3;
                }
                let mut ctl = SeedController::<f32>::new(&c)
                    .map_err(|e| anyhow!("invalid helix configuration: {e}"))?;
                let traj = s.spec.trajectory.cast();
                let r = discrete_loop(&s.spec, &s.disc, &s.plants, &traj, &mut ctl)?;
                laws.insert("DSMC+vgccc".into(), figures(&r, sc, &s.spec.trajectory));
                rep.traces.push((format!("{}_DSMC+vgccc", sc.name), r));
            }
        }
        rep.scenarios.insert(sc.name.clone(), laws);
    }
    Ok(())
}

/// Run the built-in scenario files.
pub fn run_builtin() -> Result<SeedsReport> {
    let mut rep = SeedsReport::default();
    for (name, _) in BUILTIN {
        run_file(&builtin_file(name)?, &mut rep)?;
    }
    Ok(rep)
}

/// One built-in scenario file by name (e.g. `seeds_friction.toml`).
pub fn builtin_file(name: &str) -> Result<SeedFile> {
    let (_, text) = BUILTIN
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| anyhow!("no built-in seed scenario file {name}"))?;
    toml::from_str(text).map_err(|e| anyhow!("{name}: {e}"))
}

/// The comparison table printed by `host-sim seeds` (contour µm, ITSE mm²·s, torque mN·m).
pub fn table(rep: &SeedsReport) -> String {
    let mut s = String::new();
    s.push_str("| scenario | law | contour max µm | contour RMS µm | ITSE x | ITSE y | ITSE z | peak torque x/y/z mN·m | chattering x/y N·m/s | reversal max |e| x/y µm |\n");
    s.push_str("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for (sc, laws) in &rep.scenarios {
        for (law, f) in laws {
            s.push_str(&format!(
                "| {sc} | {law} | {:.2} | {:.2} | {:.3e} | {:.3e} | {:.3e} | {:.0}/{:.0}/{:.0} | {:.1}/{:.1} | {:.2}/{:.2} |\n",
                f.contour_max * 1e3,
                f.contour_rms * 1e3,
                f.itse[0],
                f.itse[1],
                f.itse[2],
                f.peak_torque[0],
                f.peak_torque[1],
                f.peak_torque[2],
                f.chattering[0] * 1e-3,
                f.chattering[1] * 1e-3,
                f.reversal_max_error[0] * 1e3,
                f.reversal_max_error[1] * 1e3,
            ));
        }
    }
    s.push_str("\n| adaptation | estimate | truth | error % |\n| --- | --- | --- | --- |\n");
    for (axis, m) in &rep.adaptation {
        for k in ESTIMATE_NAMES {
            if let Some(e) = m.get(k) {
                s.push_str(&format!(
                    "| {axis} {k} | {:.4} | {:.4} | {:+.1} |\n",
                    e.estimate,
                    e.truth,
                    100.0 * (e.estimate - e.truth) / e.truth
                ));
            }
        }
    }
    s
}
