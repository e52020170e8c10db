//! The seed methods' comparison (`host-sim seeds`): the patent's XY contouring (PID, DSMC,
//! DOB-SMC, each with and without variable-gain cross-coupling), the XY-table paper's
//! friction identification (fixed vs adaptive SMC), and the paper's DSMC with its 3-D
//! cross-coupling on the physical 3-axis gantry (helix). Every run is the servo step at
//! the firmware rate against the simulated physical axes; the study files are
//! `host-sim/scenarios/seeds_{contouring,friction,helix}.toml` (cases: scenarios;
//! variants: laws, `_` in a variant name reads `+` in the report).

use crate::builtin;
use crate::builtin::resolve_all;
use crate::engine::discrete::{self, Observer, PeriodView};
use crate::engine::{simulate, RunResult};
use crate::jobs;
use anyhow::{anyhow, Context, Result};
use controller_core::law::adaptive_smc::AdaptiveState;
use controller_core::motion::trajectory::Trajectory;
use controller_core::sim::run::SimRun;
use controller_core::sim::world::PlantConfig;
use gantry_scenario::Resolved;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The built-in study files, in report order.
pub const FILES: [&str; 3] = [
    "seeds_contouring.toml",
    "seeds_friction.toml",
    "seeds_helix.toml",
];

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
    /// velocity of the axis, from the study's `reversal_from_s` on (mm; 0 when the axis
    /// does not reverse there).
    pub reversal_max_error: [f64; 3],
}

/// Half width of the window around a velocity reversal in which the reversal error is
/// measured: 20 ms, longer than the friction transient (the s-loop settles in
/// ~3/(k_d/J) = 10 ms) and short against the 250 ms between reversals at 2 Hz.
pub const REVERSAL_HALF_WIDTH_S: f64 = 0.02;

/// Decimation of the recorded estimates: one sample per 10 ms.
pub const ESTIMATE_TRACE_EVERY_S: f64 = 0.01;

/// Names of the estimates in [`EstimateSample::axes`] order.
pub const ESTIMATE_NAMES: [&str; 4] = ["J", "B", "f_pos", "f_neg"];

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

/// The study table of a seeds file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct SeedStudy {
    /// Reversal errors are measured from this time on (s).
    #[serde(default)]
    reversal_from_s: f64,
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
    /// The JSON (public interface): `{"<scenario>": {"<law>": {...}}, "adaptation":
    /// {"J"|"B"|"f_pos"|"f_neg": {"estimate", "truth"}}}`, where "adaptation" is the X
    /// axis; every adapted axis is under "adaptation_axes".
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

/// The report key of a variant: `_` reads `+` (`PID_ccc` → `PID+ccc`).
pub fn law_key(variant: &str) -> String {
    variant.replace('_', "+")
}

fn figures(r: &RunResult, horizon_s: f64, traj: &Trajectory<f64>, from_s: f64) -> LawFigures {
    LawFigures {
        contour_max: r.contour_max,
        contour_rms: r.contour_rms,
        itse: r.itse,
        peak_torque: r.peak_u,
        max_error: r.max_abs_error,
        chattering: r.tv_u.map(|v| v / horizon_s),
        reversal_max_error: reversal_errors(r, traj, from_s),
    }
}

/// Per axis, the largest |e| on the trace within ±[`REVERSAL_HALF_WIDTH_S`] of an
/// instant where the reference velocity of that axis changes sign, from `from_s` on.
pub fn reversal_errors(r: &RunResult, traj: &Trajectory<f64>, from_s: f64) -> [f64; 3] {
    let tr = &r.trace;
    let vel: Vec<_> = tr.t.iter().map(|&t| traj.sample(t).vel).collect();
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

fn estimate_row(a: &AdaptiveState<f32>) -> [f64; 4] {
    [a.j, a.b, a.f_pos, a.f_neg].map(f64::from)
}

/// Records the adaptive estimates every `every` periods.
struct EstimateLog {
    every: u32,
    dt_s: f64,
    log: Vec<EstimateSample>,
    last: [[f64; 4]; 3],
}

impl Observer<f32> for EstimateLog {
    fn period(&mut self, run: &PeriodView<'_, f32>) {
        let st = run.servo.controller().states();
        let axes = [0, 1, 2].map(|i| estimate_row(&st[i].adapt));
        // the servo step already committed this period: the estimates at its end; the
        // sample at period k shows the estimates the law used in period k
        let k = run.periods_run;
        if k.is_multiple_of(self.every) {
            self.log.push(EstimateSample {
                t: f64::from(k) * self.dt_s,
                axes: self.last,
            });
        }
        self.last = axes;
    }
}

struct Job {
    resolved: Resolved,
    reversal_from_s: f64,
    /// Record the adaptive estimates (the friction study's adaptive run).
    adaptive: bool,
}

struct Done {
    result: RunResult,
    estimates: Vec<EstimateSample>,
    last: [[f64; 4]; 3],
}

fn run_job(j: &Job) -> Result<Done> {
    let r = &j.resolved;
    if j.adaptive {
        let dt_s = 1.0 / f64::from(r.run.servo.rate_hz);
        let initial = SimRun::<f32>::new(&r.run)
            .map_err(|e| anyhow!("run {}: {e}", r.name))?
            .servo()
            .controller()
            .states()
            .map(|s| estimate_row(&s.adapt));
        let mut obs = EstimateLog {
            every: ((ESTIMATE_TRACE_EVERY_S / dt_s).round() as u32).max(1),
            dt_s,
            log: Vec::new(),
            last: initial,
        };
        let result = discrete::run::<f32>(r, &mut obs)?;
        Ok(Done {
            result,
            estimates: obs.log,
            last: obs.last,
        })
    } else {
        Ok(Done {
            result: simulate(r)?,
            estimates: Vec::new(),
            last: [[0.0; 4]; 3],
        })
    }
}

/// Run the built-in seed study files.
pub fn run_builtin() -> Result<SeedsReport> {
    run_files(&FILES)
}

/// Run the named built-in seed study files.
pub fn run_files(files: &[&str]) -> Result<SeedsReport> {
    let mut jobs = Vec::new();
    for &name in files {
        let file = builtin::load(name)?;
        for r in resolve_all(&file)? {
            let study: SeedStudy = match &r.study {
                Some(v) => v
                    .clone()
                    .try_into()
                    .with_context(|| format!("{}: invalid [study] table", file.file))?,
                None => SeedStudy::default(),
            };
            let adaptive = r.variant.as_deref() == Some("ASMC");
            jobs.push(Job {
                resolved: r,
                reversal_from_s: study.reversal_from_s,
                adaptive,
            });
        }
    }
    let done = jobs::run_all(&jobs, |j| {
        run_job(j).with_context(|| format!("run {}", j.resolved.name))
    })?;
    let mut rep = SeedsReport::default();
    for (j, d) in jobs.iter().zip(done) {
        let r = &j.resolved;
        let case = r.case.clone().unwrap_or_else(|| r.name.clone());
        let law = law_key(r.variant.as_deref().unwrap_or(&r.name));
        let f = figures(&d.result, r.horizon_s, &r.reference, j.reversal_from_s);
        rep.scenarios
            .entry(case.clone())
            .or_default()
            .insert(law.clone(), f);
        if j.adaptive {
            rep.estimates = d.estimates;
            for (i, axis) in ["x", "y"].iter().enumerate() {
                let PlantConfig::Physical(a) = r.run.world.plants[i] else {
                    continue;
                };
                let truth = [a.inertia, a.viscous, a.coulomb_pos_mnm, a.coulomb_neg_mnm];
                let m = ESTIMATE_NAMES
                    .iter()
                    .zip(d.last[i].iter().zip(truth))
                    .map(|(k, (&estimate, t))| {
                        (
                            k.to_string(),
                            Estimate {
                                estimate,
                                truth: f64::from(t),
                            },
                        )
                    })
                    .collect();
                rep.adaptation.insert(axis.to_string(), m);
            }
        }
        rep.traces.push((format!("{case}_{law}"), d.result));
    }
    Ok(rep)
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
