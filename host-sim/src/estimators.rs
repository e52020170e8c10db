//! `host-sim estimators`: how the velocity source changes the laws' contouring (issue 6).
//!
//! The paper helix (paper plant, table 3's helix and λ, from rest) runs in discrete mode at
//! 10 kHz with positions quantised to 1e-4 units and `|u| <= 500`, for PID, SMC and DSMC
//! (the paper scenario's Table 2 gains), once per velocity source:
//!
//! - `exact`: the plant's true velocity (not available on hardware; the reference),
//! - `backward_difference`: `(q[k] - q[k-1]) / Ts` of the quantised positions,
//! - `pll`, `kalman`: controller-core's estimators fed the encoder counts, exactly as the
//!   firmware's control interrupt uses them ([`Estimators3`]); the Kalman filter gets the
//!   commanded acceleration from the paper plant model and the applied (saturated) `u`.
//!
//! Every run goes through the engine's discrete loop ([`discrete_loop`]); the estimating
//! sources wrap the gantry controller in [`Estimating`], which turns the engine's
//! quantised positions back into counts. Figures: contour error max and RMS over
//! `t >= contour_from_s`, per-axis ITSE and total variation of `u` (chattering).
//!
//! [`physical`] runs the same comparison on the physical gantry (friction axes, 0.625 µm
//! counts) for PID, DSMC and DOB-SMC.

use crate::engine::{
    discrete_loop, DiscreteController, DiscreteSpec, MetricSpec, Mode, Numeric, RunResult, RunSpec,
    VelocitySource,
};
use crate::paper::PaperScenario;
use crate::scenario::paper_plants;
use anyhow::{anyhow, bail, Result};
use controller_core::estimator::{
    EstimatorConfig, EstimatorTiming, Estimators3, PAPER_SIM_KALMAN, PAPER_SIM_PLL,
};
use controller_core::gantry::{Gantry3, GantryConfig, GantryOutput, Measured};
use controller_core::params::{LawConfig, PlantParams};
use controller_core::plant::AxisState;
use controller_core::trajectory::{RefSample, Trajectory};
use controller_core::{Real, Vec3};
use serde::Serialize;
use std::collections::BTreeMap;

pub mod physical;

/// Issue 6's setting: 10 kHz control.
pub const RATE_HZ: f64 = 10_000.0;
/// Issue 6's setting: positions quantised to 1e-4 units (one "count").
pub const POSITION_QUANTUM: f64 = 1e-4;
/// Issue 6's setting: actuator limited to `|u| <= 500`.
pub const ACTUATOR_LIMIT: f64 = 500.0;

/// One velocity source of the comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Source {
    Exact,
    BackwardDifference,
    /// A controller-core estimator; `accel_model`: the plant model for the commanded
    /// acceleration (the Kalman filter's input).
    Estimator {
        config: EstimatorConfig,
        accel_model: Option<PlantParams>,
    },
}

impl Source {
    pub fn name(&self) -> &'static str {
        match self {
            Self::Exact => "exact",
            Self::BackwardDifference => "backward_difference",
            Self::Estimator { config, .. } => config.name(),
        }
    }
}

/// The sources compared by default, with the paper-simulation presets.
pub fn default_sources(plant: PlantParams) -> Vec<Source> {
    vec![
        Source::Exact,
        Source::BackwardDifference,
        Source::Estimator {
            config: EstimatorConfig::Pll(PAPER_SIM_PLL),
            accel_model: None,
        },
        Source::Estimator {
            config: EstimatorConfig::Kalman(PAPER_SIM_KALMAN),
            accel_model: Some(plant),
        },
    ]
}

/// Figures of one law with one source (the JSON schema).
#[derive(Clone, Debug, Serialize)]
pub struct Figures {
    pub contour_max: f64,
    pub contour_rms: f64,
    pub itse: [f64; 3],
    pub tv_u: [f64; 3],
}

impl From<&RunResult> for Figures {
    fn from(r: &RunResult) -> Self {
        Self {
            contour_max: r.contour_max,
            contour_rms: r.contour_rms,
            itse: r.itse,
            tv_u: r.tv_u,
        }
    }
}

/// `law -> source -> figures`.
pub type Comparison = BTreeMap<String, BTreeMap<String, Figures>>;

/// A controller (the gantry controller, or a seed method's on the physical axes) with its
/// velocities from [`Estimators3`], as on the firmware.
pub struct Estimating<R: Real, C = Gantry3<R>> {
    inner: C,
    estimators: Estimators3<R>,
    quantum: f64,
    /// Per axis: the drive's limit, so the estimators are told the command applied.
    u_limit: Vec3<R>,
}

impl<R: Real, C> Estimating<R, C> {
    fn counts(&self, pos: [f64; 3]) -> [i64; 3] {
        pos.map(|p| (p / self.quantum).round() as i64)
    }
}

impl<R: Real, C: DiscreteController<R>> DiscreteController<R> for Estimating<R, C> {
    fn step_discrete(&mut self, r: &RefSample<R>, m: &Measured<R>, dt: R) -> GantryOutput<R> {
        // the engine's positions are whole counts times the quantum: recover the counts
        let counts = self.counts(m.pos.to_array().map(|p| p.to_f64()));
        let est = self.estimators.update(counts);
        let meas = Measured {
            pos: m.pos,
            vel: est.vel,
        };
        let out = self.inner.step_discrete(r, &meas, dt);
        // the drive applies the saturated command; that is what accelerates the axis
        let mut applied = out.u;
        for i in 0..3 {
            applied[i] = applied[i].clamp_sym(self.u_limit[i]);
        }
        self.estimators.applied(applied);
        out
    }
}

/// The comparison's run specification for one law and source.
fn spec(sc: &PaperScenario, law: LawConfig, source: &Source, horizon_s: f64) -> Result<RunSpec> {
    let velocity = match source {
        Source::BackwardDifference => VelocitySource::BackwardDifference,
        // estimating sources overwrite the velocity in [`Estimating`]
        _ => VelocitySource::Exact,
    };
    Ok(RunSpec {
        horizon_s,
        trajectory: sc.table3.helix.build()?,
        controller: GantryConfig::uniform(law, sc.table3.lambda),
        mode: Mode::Discrete(DiscreteSpec {
            rate_hz: RATE_HZ,
            plant_substeps: 4,
            position_quantum: POSITION_QUANTUM,
            actuator_limit: ACTUATOR_LIMIT,
            velocity,
        }),
        numeric: Numeric::F32,
        metrics: MetricSpec {
            contour_from_s: Some(sc.table3.contour_from_s),
            ..MetricSpec::default()
        },
        initial: [AxisState::default(); 3],
    })
}

/// Run one law with one source (controller in f32, the firmware's type).
pub fn run_one(
    sc: &PaperScenario,
    law: LawConfig,
    source: &Source,
    horizon_s: f64,
    disturbance: bool,
) -> Result<RunResult> {
    let spec = spec(sc, law, source, horizon_s)?;
    let dist = if disturbance {
        vec![sc.table3.disturbance]
    } else {
        Vec::new()
    };
    let plants = paper_plants(&sc.plant, &dist)?;
    let Mode::Discrete(d) = spec.mode else {
        bail!("the comparison runs in discrete mode");
    };
    let traj: Trajectory<f32> = spec.trajectory.cast();
    let gantry = Gantry3::<f32>::new(&spec.controller)
        .map_err(|e| anyhow!("invalid controller configuration: {e}"))?;
    match source {
        Source::Exact | Source::BackwardDifference => {
            let mut g = gantry;
            discrete_loop(&spec, &d, &plants, &traj, &mut g)
        }
        Source::Estimator {
            config,
            accel_model,
        } => {
            let timing = EstimatorTiming {
                period_s: (1.0 / RATE_HZ) as f32,
                count_size: POSITION_QUANTUM as f32,
            };
            let n0 = spec
                .initial
                .map(|s| (s.pos / POSITION_QUANTUM).round() as i64);
            let estimators = Estimators3::new(&[*config; 3], &[*accel_model; 3], &timing, n0)
                .map_err(|e| anyhow!("invalid estimator configuration: {e}"))?;
            let mut ctl = Estimating {
                inner: gantry,
                estimators,
                quantum: POSITION_QUANTUM,
                u_limit: Vec3::splat(ACTUATOR_LIMIT as f32),
            };
            discrete_loop(&spec, &d, &plants, &traj, &mut ctl)
        }
    }
}

/// PID, SMC and DSMC (the paper scenario's laws) with every source in `sources`, on two
/// threads (the build machine has two cores).
pub fn compare(
    sc: &PaperScenario,
    sources: &[Source],
    horizon_s: f64,
    disturbance: bool,
) -> Result<Comparison> {
    let jobs: Vec<(String, LawConfig, Source)> = sc
        .laws
        .iter()
        .flat_map(|l| {
            sources
                .iter()
                .map(move |s| (l.name.to_lowercase(), l.law, *s))
        })
        .collect();
    compare_parallel(&jobs, |(law_name, law, src)| {
        let r = run_one(sc, *law, src, horizon_s, disturbance)?;
        Ok((law_name.clone(), src.name().to_string(), Figures::from(&r)))
    })
}

/// Run `one` over `jobs` on two threads (the machine's cores) and gather the
/// `(law, source, figures)` rows into a [`Comparison`]; the first error wins.
pub(crate) fn compare_parallel<J: Sync>(
    jobs: &[J],
    one: impl Fn(&J) -> Result<(String, String, Figures)> + Sync,
) -> Result<Comparison> {
    let one = &one;
    let results: Vec<Result<(String, String, Figures)>> = std::thread::scope(|scope| {
        let halves: Vec<_> = [0usize, 1]
            .into_iter()
            .map(|part| {
                scope.spawn(move || {
                    jobs.iter()
                        .skip(part)
                        .step_by(2)
                        .map(one)
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        halves
            .into_iter()
            .flat_map(|h| {
                h.join()
                    .unwrap_or_else(|_| vec![Err(anyhow!("a run panicked"))])
            })
            .collect()
    });
    let mut out = Comparison::new();
    for r in results {
        let (law, src, fig) = r?;
        out.entry(law).or_default().insert(src, fig);
    }
    Ok(out)
}

/// A terminal table of the comparison.
pub fn table(c: &Comparison, sources: &[Source]) -> String {
    let names: Vec<&str> = sources.iter().map(|s| s.name()).collect();
    table_named(c, &names)
}

/// The table with the sources in the order of `names`.
fn table_named(c: &Comparison, names: &[&str]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<7} {:<20} {:>12} {:>12} {:>36} {:>30}",
        "law", "velocity source", "contour max", "contour rms", "ITSE x y z", "TV(u) x y z"
    );
    for (law, by_src) in c {
        for src in names {
            if let Some(f) = by_src.get(*src) {
                let _ = writeln!(
                    s,
                    "{:<7} {:<20} {:>12.3e} {:>12.3e} {:>11.3e} {:>11.3e} {:>11.3e} {:>9.2e} {:>9.2e} {:>9.2e}",
                    law,
                    src,
                    f.contour_max,
                    f.contour_rms,
                    f.itse[0],
                    f.itse[1],
                    f.itse[2],
                    f.tv_u[0],
                    f.tv_u[1],
                    f.tv_u[2]
                );
            }
        }
    }
    s
}
