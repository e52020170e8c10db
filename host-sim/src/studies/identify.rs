//! `host-sim identify`: identification of every axis of a simulated machine through the
//! servo step, and what the identified model is worth in contouring.
//!
//! Per axis, the servo (with every axis model unknown, so nothing can be armed) is told
//! `Identify` from Disabled inside a ±50 mm window around where the axis stands, exactly as
//! `gantry identify` tells the board. The identification sees the counts, the estimator's
//! velocity and its own effort; the simulated world owns the truth (study file
//! `host-sim/scenarios/identify.toml`: quantisation, 12-bit amplifiers, ±1 count of noise,
//! one period of delay, Stribeck friction). Then DSMC with cross-coupling runs the study's
//! circle and helix, tuned once from the true model and once from the identified one.
//!
//! With `--seed N` the machine's axes are drawn at random from the documented range
//! ([`random_axis`], docs/identification.md) instead of the machine file's.

use crate::builtin;
use crate::builtin::resolve_all;
use crate::engine;
use crate::jobs;
use anyhow::{anyhow, bail, Result};
use controller_core::axes::Axis;
use controller_core::law::LawConfig;
use controller_core::plant::physical::PhysicalAxisConfig;
use controller_core::plant::AxisModel;
use controller_core::presets::gantry::{gantry_safety, tuning_for};
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::RunConfig;
use controller_core::sim::world::PlantConfig;
use controller_core::sysid::{tuning, IdentifyStatus};
use gantry_scenario::Resolved;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Half-width of the window each axis is identified in, around where it stands, mm (the
/// user-confirmed window of an unhomed axis; the identification's default).
pub const WINDOW_HALF_MM: f32 = 50.0;
/// Periods an identification may take before the study gives up (the identification's own
/// 10 s budget ends it far earlier at 10 kHz).
const MAX_PERIODS: u32 = 400_000;
/// One recorded sample per this many periods (1 kHz at 10 kHz).
const RECORD_EVERY: u32 = 10;
/// Deceleration of a controlled stop on a random machine, mm/s² (the gantry's X).
const RANDOM_STOP_DECEL_MM_S2: f32 = 2000.0;

/// A model as the JSON reports it (keys are public interface).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ModelJson {
    #[serde(rename = "J")]
    pub j: f64,
    #[serde(rename = "B")]
    pub b: f64,
    pub f_pos: f64,
    pub f_neg: f64,
}

impl From<&AxisModel> for ModelJson {
    fn from(m: &AxisModel) -> Self {
        Self {
            j: f64::from(m.inertia),
            b: f64::from(m.viscous),
            f_pos: f64::from(m.coulomb_pos_mnm),
            f_neg: f64::from(m.coulomb_neg_mnm),
        }
    }
}

/// What one axis' identification gave.
#[derive(Clone, Debug, Serialize)]
pub struct AxisReport {
    /// The truth as identification can see it (a constant load folded into f±).
    pub truth: ModelJson,
    pub identified: Option<ModelJson>,
    /// `100 (identified - truth) / |truth|`; the Coulomb terms relative to the true
    /// Coulomb magnitude (without the load).
    pub error_pct: Option<ModelJson>,
    pub nrmse: Option<f64>,
    pub r2: Option<f64>,
    /// `done`, or why it stopped.
    pub status: String,
    /// Machine time of the identification, s.
    pub machine_time_s: f64,
    /// Travel of the true axis during identification, mm (start-relative min, max).
    pub travel_mm: [f64; 2],
    /// Decimated record for the plots.
    #[serde(skip)]
    pub record: Vec<Sample>,
}

/// One recorded sample of an identification.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub t_s: f64,
    pub vel_mm_s: f64,
    pub effort_mnm: f64,
}

/// Contour figures of one model over the study's paths.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct ContourJson {
    pub contour_max_mm: f64,
    pub contour_rms_mm: f64,
}

/// The contour comparison.
#[derive(Clone, Debug, Serialize)]
pub struct ContourReport {
    pub true_model: ContourJson,
    /// `null` when an axis could not be identified.
    pub identified_model: Option<ContourJson>,
    /// Per path (`circle`, `helix`): (true model, identified model).
    pub paths: BTreeMap<String, [Option<ContourJson>; 2]>,
}

/// The whole study.
#[derive(Clone, Debug, Serialize)]
pub struct IdentifyReport {
    pub axes: BTreeMap<String, AxisReport>,
    pub contour: ContourReport,
    /// The random machine's seed, if one was drawn.
    pub seed: Option<u64>,
}

impl IdentifyReport {
    /// Every axis identified.
    pub fn all_done(&self) -> bool {
        self.axes.values().all(|a| a.identified.is_some())
    }
}

/// The study's generator (one implementation for every simulation).
pub use controller_core::sim::rng::SplitMix64 as Rng;

pub use controller_core::sim::random::random_axis;

/// Put `axes` into every run: plants, amplifier full scales, fault thresholds and the
/// true-model DSMC laws.
fn set_machine(runs: &mut [Resolved], axes: &[PhysicalAxisConfig; 3]) {
    for r in runs {
        let c = &mut r.run;
        for (i, a) in axes.iter().enumerate() {
            c.world.plants[i] = PlantConfig::Physical(*a);
            c.servo.amplifiers[i].full_scale = a.torque_max_mnm;
            c.servo.safety.axes[i] = gantry_safety(a, RANDOM_STOP_DECEL_MM_S2);
            c.servo.controller.laws[i] =
                LawConfig::Smc(tuning::dsmc(&AxisModel::from_physical(a), &tuning_for(a)));
        }
    }
}

fn physical_axes(r: &Resolved) -> Result<[PhysicalAxisConfig; 3]> {
    let axis = |i: usize| match r.run.world.plants[i] {
        PlantConfig::Physical(a) => Ok(a),
        PlantConfig::Paper(_) => Err(anyhow!(
            "identification needs physical axes (mm, mN·m); axis {} is the paper's",
            Axis::ALL[i].name()
        )),
    };
    Ok([axis(0)?, axis(1)?, axis(2)?])
}

fn pct(a: f32, b: f32, scale: f32) -> f64 {
    100.0 * f64::from(a - b) / f64::from(scale)
}

/// Identify `axis` of the machine of run `base` through the servo step.
pub fn identify_axis(
    base: &RunConfig,
    axis: Axis,
    truth: &PhysicalAxisConfig,
) -> Result<AxisReport> {
    let mut cfg = *base;
    // the identification does not know the models; nothing but identification can run
    cfg.servo.model_known = [false; 3];
    let mut run = super::driven_run(cfg)?;
    let i = axis.index();
    let start = run.world().state()[i].pos;
    let at = start as f32;
    let cmd = Command::Identify {
        axis,
        window_mm: Some([at - WINDOW_HALF_MM, at + WINDOW_HALF_MM]),
    };
    let s = run.control_with(&[cmd]);
    if let Some((_, why)) = s.refused {
        bail!(
            "axis {}: identification refused: {}",
            axis.name(),
            why.message()
        );
    }
    run.finish_period();
    let mut record = Vec::new();
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    let mut k = 1u32;
    while run.servo().state() == ServoState::Identify {
        if k >= MAX_PERIODS {
            bail!("axis {}: identification did not end", axis.name());
        }
        let s = *run.control_with(&[]);
        if k.is_multiple_of(RECORD_EVERY) {
            record.push(Sample {
                t_s: run.world().time_s(),
                vel_mm_s: f64::from(s.vel[i]),
                effort_mnm: f64::from(s.effort[i]),
            });
        }
        run.finish_period();
        let p = run.world().state()[i].pos - start;
        lo = lo.min(p);
        hi = hi.max(p);
        k += 1;
    }
    let outcome = run.servo().identify_outcome().copied().ok_or_else(|| {
        anyhow!(
            "axis {}: identification did not run (state {:?}, fault {:?})",
            axis.name(),
            run.servo().state(),
            run.servo().faults().first()
        )
    })?;
    let t = AxisModel::from_physical_with_load(truth);
    let status = match outcome.status {
        IdentifyStatus::Done => "done".to_string(),
        other => format!("{other:?}"),
    };
    let (identified, error_pct, nrmse, r2) = match (&outcome.status, &outcome.result) {
        (IdentifyStatus::Done, Some(res)) => {
            let m = &res.model;
            let e = ModelJson {
                j: pct(m.inertia, t.inertia, t.inertia),
                b: pct(m.viscous, t.viscous, t.viscous),
                f_pos: pct(
                    m.coulomb_pos_mnm,
                    t.coulomb_pos_mnm,
                    truth.coulomb_pos_mnm.abs(),
                ),
                f_neg: pct(
                    m.coulomb_neg_mnm,
                    t.coulomb_neg_mnm,
                    truth.coulomb_neg_mnm.abs(),
                ),
            };
            (
                Some(ModelJson::from(m)),
                Some(e),
                Some(f64::from(res.nrmse)),
                Some(f64::from(res.r2)),
            )
        }
        _ => (None, None, None, None),
    };
    Ok(AxisReport {
        truth: ModelJson::from(&t),
        identified,
        error_pct,
        nrmse,
        r2,
        status,
        machine_time_s: f64::from(k) * run.servo().period_s(),
        travel_mm: [lo, hi],
        record,
    })
}

/// The identified model of an axis report, back as the law's model.
fn model_of(j: &ModelJson) -> AxisModel {
    AxisModel {
        inertia: j.j as f32,
        viscous: j.b as f32,
        coulomb_pos_mnm: j.f_pos as f32,
        coulomb_neg_mnm: j.f_neg as f32,
    }
}

/// Combine per-path figures: the largest maximum, the RMS over all samples (the paths
/// have the same length).
fn combine(figs: &[ContourJson]) -> ContourJson {
    let n = figs.len().max(1) as f64;
    ContourJson {
        contour_max_mm: figs.iter().map(|f| f.contour_max_mm).fold(0.0, f64::max),
        contour_rms_mm: (figs.iter().map(|f| f.contour_rms_mm.powi(2)).sum::<f64>() / n).sqrt(),
    }
}

/// Run the study: the built-in machine (or `machine`), or a random one for `seed`.
pub fn run(machine: Option<&Path>, seed: Option<u64>) -> Result<IdentifyReport> {
    let file = match machine {
        Some(m) => builtin::load_on_machine("identify.toml", m)?,
        None => builtin::load("identify.toml")?,
    };
    let mut runs = resolve_all(&file)?;
    let first = runs
        .first()
        .ok_or_else(|| anyhow!("identify.toml has no runs"))?;
    let mut axes = physical_axes(first)?;
    if let Some(s) = seed {
        let mut rng = Rng::new(s);
        for (i, a) in axes.iter_mut().enumerate() {
            // the vertical Z carries the load, as on the gantry
            *a = random_axis(&mut rng, i == 2, a);
        }
        set_machine(&mut runs, &axes);
    }
    let base = runs[0].run;
    let reports = jobs::run_all(&Axis::ALL, |a| identify_axis(&base, *a, &axes[a.index()]))?;
    let mut out = BTreeMap::new();
    for (a, r) in Axis::ALL.iter().zip(reports) {
        out.insert(a.name().to_string(), r);
    }
    let identified: Option<[AxisModel; 3]> = (|| {
        Some([
            model_of(out.get("x")?.identified.as_ref()?),
            model_of(out.get("y")?.identified.as_ref()?),
            model_of(out.get("z")?.identified.as_ref()?),
        ])
    })();
    // every path with the true model, and with the identified one
    let mut jobs_list: Vec<(usize, bool)> = (0..runs.len()).map(|i| (i, false)).collect();
    if identified.is_some() {
        jobs_list.extend((0..runs.len()).map(|i| (i, true)));
    }
    let figures = jobs::run_all(&jobs_list, |&(i, ident)| {
        let mut r = runs[i].clone();
        if let (true, Some(models)) = (ident, &identified) {
            for (law, (m, a)) in r
                .run
                .servo
                .controller
                .laws
                .iter_mut()
                .zip(models.iter().zip(&axes))
            {
                *law = LawConfig::Smc(tuning::dsmc(m, &tuning_for(a)));
            }
        }
        let res = engine::simulate(&r)?;
        Ok(ContourJson {
            contour_max_mm: res.contour_max,
            contour_rms_mm: res.contour_rms,
        })
    })?;
    let mut paths = BTreeMap::new();
    for (&(i, ident), f) in jobs_list.iter().zip(&figures) {
        let name = runs[i].case.clone().unwrap_or_else(|| runs[i].name.clone());
        let e: &mut [Option<ContourJson>; 2] = paths.entry(name).or_default();
        e[usize::from(ident)] = Some(*f);
    }
    let pick = |ident: bool| -> Vec<ContourJson> {
        jobs_list
            .iter()
            .zip(&figures)
            .filter(|((_, id), _)| *id == ident)
            .map(|(_, f)| *f)
            .collect()
    };
    Ok(IdentifyReport {
        axes: out,
        contour: ContourReport {
            true_model: combine(&pick(false)),
            identified_model: identified.map(|_| combine(&pick(true))),
            paths,
        },
        seed,
    })
}

/// The report as a table for the terminal.
pub fn table(r: &IdentifyReport) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "axis  param        truth   identified   error %   (nrmse, r², machine time, status)"
    );
    for (name, a) in &r.axes {
        let rows = [
            (
                "J",
                a.truth.j,
                a.identified.map(|m| m.j),
                a.error_pct.map(|e| e.j),
            ),
            (
                "B",
                a.truth.b,
                a.identified.map(|m| m.b),
                a.error_pct.map(|e| e.b),
            ),
            (
                "f+",
                a.truth.f_pos,
                a.identified.map(|m| m.f_pos),
                a.error_pct.map(|e| e.f_pos),
            ),
            (
                "f-",
                a.truth.f_neg,
                a.identified.map(|m| m.f_neg),
                a.error_pct.map(|e| e.f_neg),
            ),
        ];
        for (k, (p, t, m, e)) in rows.iter().enumerate() {
            let fmt = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |v| format!("{v:.d$}"));
            let tail = if k == 0 {
                format!(
                    "   ({}, {}, {:.2} s, {})",
                    fmt(a.nrmse, 4),
                    fmt(a.r2, 4),
                    a.machine_time_s,
                    a.status
                )
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "{:<5} {:<6} {:>11.4} {:>12} {:>9}{tail}",
                if k == 0 { name.as_str() } else { "" },
                p,
                t,
                fmt(*m, 4),
                fmt(*e, 2)
            );
        }
    }
    let c = &r.contour;
    let _ = writeln!(
        s,
        "contour (DSMC + cross-coupling, circle and helix): true model max {:.2} µm rms {:.2} µm",
        1e3 * c.true_model.contour_max_mm,
        1e3 * c.true_model.contour_rms_mm
    );
    match &c.identified_model {
        Some(m) => {
            let _ = writeln!(
                s,
                "                                     identified model max {:.2} µm rms {:.2} µm ({:+.1} % rms)",
                1e3 * m.contour_max_mm,
                1e3 * m.contour_rms_mm,
                100.0 * (m.contour_rms_mm / c.true_model.contour_rms_mm - 1.0)
            );
        }
        None => {
            let _ = writeln!(s, "identified model: not every axis was identified");
        }
    }
    s
}
