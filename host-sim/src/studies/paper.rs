//! The reference paper's experiments (seed 000, Wang, Chen, Wang 2021): Table 1 (single
//! axis, PID / SMC / DSMC, ITSE and robustness) and Table 3 (3-D helix with cross-coupling,
//! per-axis ITSE), from the study file `host-sim/scenarios/paper.toml`: its cases are the
//! tables (`table1_step`, `table1_step_disturbed`, `table1_sine`, `table1_sine_disturbed`,
//! `table3`, `table3_disturbed`, `table3_discrete_<numeric>`), its variants the laws, and
//! its `[study.published]` table the published numbers.

use crate::builtin::resolve_all;
use crate::engine::{simulate, RunResult};
use crate::jobs;
use anyhow::{bail, Context, Result};
use controller_core::coupling::CouplingConfig;
use controller_core::estimator::EstimatorConfig;
use controller_core::sim::world::PlantConfig;
use gantry_scenario::file::ScenarioFile;
use gantry_scenario::{Mode, Resolved};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PublishedT1 {
    pub itse: f64,
    pub robustness: f64,
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PublishedT3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Published {
    #[serde(default)]
    pub table1: BTreeMap<String, PublishedT1>,
    #[serde(default)]
    pub table3: BTreeMap<String, PublishedT3>,
}

/// The paper study's own table in the file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct PaperStudy {
    #[serde(default)]
    published: Published,
}

/// One row of Table 1.
#[derive(Clone, Debug, Serialize)]
pub struct T1Row {
    pub itse: f64,
    pub robustness: f64,
    /// Chattering: total variation of u per second (nominal run).
    pub tv_u_per_s: f64,
}

/// One row of Table 3.
#[derive(Clone, Debug, Serialize)]
pub struct T3Row {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub contour_max: f64,
    pub contour_rms: f64,
    pub tv_u_per_s: [f64; 3],
    pub peak_u: [f64; 3],
}

impl T3Row {
    fn of(r: &RunResult, horizon_s: f64) -> Self {
        Self {
            x: r.itse[0],
            y: r.itse[1],
            z: r.itse[2],
            contour_max: r.contour_max,
            contour_rms: r.contour_rms,
            tv_u_per_s: r.tv_u.map(|v| v / horizon_s),
            peak_u: r.peak_u,
        }
    }
}

/// What the tables' headings say about the runs, read from the resolved runs.
#[derive(Clone, Debug, Default)]
pub struct PaperInfo {
    pub numeric: String,
    pub mode: String,
    pub t1_horizon_s: f64,
    pub robustness_window_s: [f64; 2],
    /// Load step of the disturbed runs: (axis, accel, from t).
    pub disturbance: (usize, f64, f64),
    pub lambda: f32,
    pub contour_from_s: f64,
    pub published: Published,
    /// Table 1's laws and Table 3's rows, in file order.
    pub t1_laws: Vec<String>,
    pub law_order: Vec<String>,
    /// How the discrete rows run.
    pub discrete: String,
}

/// Everything the paper command produces (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct PaperReport {
    pub table1_step: BTreeMap<String, T1Row>,
    pub table1_sine: BTreeMap<String, T1Row>,
    /// Helix from rest without disturbance: the runs the published Table 3 matches (the
    /// PID row within 6 %; the disturbed run's X axis does not).
    pub table3: BTreeMap<String, T3Row>,
    /// The same runs with the paper's load step on X at 10 s (its Figs. 10 and 14).
    pub table3_disturbed: BTreeMap<String, T3Row>,
    /// Table 3 as the firmware runs it (discrete, quantised), keyed by number type
    /// ("f32", "fixed", ...) and then law.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub table3_discrete: BTreeMap<String, BTreeMap<String, T3Row>>,
    /// Traces by `t1_<step|sine>_<law>_<nominal|disturbed>`, `t3_<law>_<nominal|disturbed>`,
    /// `t3d_<numeric>_<law>` (CSV file names).
    #[serde(skip)]
    pub traces: BTreeMap<String, RunResult>,
}

/// The trace key of a run (kept from the first release: CSV file names and plots).
fn trace_key(r: &Resolved) -> Option<String> {
    let (case, law) = (r.case.as_deref()?, r.variant.as_deref()?);
    Some(match case {
        "table1_step" => format!("t1_step_{law}_nominal"),
        "table1_step_disturbed" => format!("t1_step_{law}_disturbed"),
        "table1_sine" => format!("t1_sine_{law}_nominal"),
        "table1_sine_disturbed" => format!("t1_sine_{law}_disturbed"),
        "table3" => format!("t3_{law}_nominal"),
        "table3_disturbed" => format!("t3_{law}_disturbed"),
        c => format!("t3d_{}_{law}", c.strip_prefix("table3_discrete_")?),
    })
}

fn info(file: &ScenarioFile, runs: &[Resolved]) -> Result<PaperInfo> {
    let study: PaperStudy = match runs.first().and_then(|r| r.study.clone()) {
        Some(v) => v
            .try_into()
            .with_context(|| format!("{}: invalid [study] table", file.file))?,
        None => PaperStudy::default(),
    };
    let find = |case: &str| runs.iter().find(|r| r.case.as_deref() == Some(case));
    let laws = |case: &str| -> Vec<String> {
        runs.iter()
            .filter(|r| r.case.as_deref() == Some(case))
            .filter_map(|r| r.variant.clone())
            .collect()
    };
    let mut i = PaperInfo {
        published: study.published,
        t1_laws: laws("table1_step"),
        law_order: laws("table3"),
        ..Default::default()
    };
    if let Some(r) = find("table1_step") {
        i.numeric = r.numeric.name().into();
        i.mode = match r.mode {
            Mode::Continuous { dt_s } => format!("continuous, dt = {dt_s} s"),
            Mode::Discrete => format!("discrete, {} Hz", r.run.servo.rate_hz),
        };
        i.t1_horizon_s = r.horizon_s;
        i.robustness_window_s = r.run.truth.itse_window_s.unwrap_or([0.0, 0.0]);
    }
    if let Some(r) = find("table1_step_disturbed").or(find("table3_disturbed")) {
        for (axis, p) in r.run.world.plants.iter().enumerate() {
            if let PlantConfig::Paper(p) = p {
                if p.disturbance_accel != 0.0 {
                    i.disturbance = (axis, p.disturbance_accel, p.disturbance_t_s);
                }
            }
        }
    }
    if let Some(r) = find("table3") {
        if let CouplingConfig::Contour(c) = r.run.servo.controller.coupling {
            i.lambda = c.lambda;
        }
        i.contour_from_s = r.run.truth.contour_from_s.unwrap_or(0.0);
    }
    if let Some(r) = runs.iter().find(|r| {
        r.case
            .as_deref()
            .is_some_and(|c| c.starts_with("table3_discrete_"))
    }) {
        let s = &r.run.servo;
        let vel = match s.estimator.axes[0] {
            EstimatorConfig::Exact => "exact".to_string(),
            e => e.name().to_string(),
        };
        i.discrete = format!(
            "{} Hz, zero-order hold, positions quantised to {:e}, |u| <= {}, velocity {vel}",
            s.rate_hz,
            1.0 / f64::from(s.encoders[0].counts_per_mm),
            s.amplifiers[0].full_scale
        );
    }
    Ok(i)
}

/// Run Table 1 and Table 3 as the study file describes.
pub fn run_paper(file: &ScenarioFile) -> Result<(PaperInfo, PaperReport)> {
    let runs = resolve_all(file)?;
    let info = info(file, &runs)?;
    if info.law_order.is_empty() && info.t1_laws.is_empty() {
        bail!(
            "{}: no table1_* or table3 runs with law variants",
            file.file
        );
    }
    let results = jobs::run_all(&runs, |r| {
        simulate(r).with_context(|| format!("run {}", r.name))
    })?;
    let mut by_key = BTreeMap::new();
    for (r, res) in runs.iter().zip(results) {
        if let Some(k) = trace_key(r) {
            by_key.insert(k, (r.horizon_s, res));
        }
    }
    let get = |k: &str| by_key.get(k).with_context(|| format!("missing run {k}"));
    let mut report = PaperReport {
        table1_step: BTreeMap::new(),
        table1_sine: BTreeMap::new(),
        table3: BTreeMap::new(),
        table3_disturbed: BTreeMap::new(),
        table3_discrete: BTreeMap::new(),
        traces: BTreeMap::new(),
    };
    for law in &info.t1_laws {
        for (tname, table) in [
            ("step", &mut report.table1_step),
            ("sine", &mut report.table1_sine),
        ] {
            let (h, nominal) = get(&format!("t1_{tname}_{law}_nominal"))?;
            let (_, disturbed) = get(&format!("t1_{tname}_{law}_disturbed"))?;
            table.insert(
                law.clone(),
                T1Row {
                    itse: nominal.itse[0],
                    robustness: disturbed.itse_window[0],
                    tv_u_per_s: nominal.tv_u[0] / h,
                },
            );
        }
    }
    for law in &info.law_order {
        for (suffix, table) in [
            ("nominal", &mut report.table3),
            ("disturbed", &mut report.table3_disturbed),
        ] {
            if let Some((h, r)) = by_key.get(&format!("t3_{law}_{suffix}")) {
                table.insert(law.clone(), T3Row::of(r, *h));
            }
        }
    }
    for (k, (h, r)) in &by_key {
        if let Some(rest) = k.strip_prefix("t3d_") {
            for law in &info.law_order {
                if let Some(numeric) = rest.strip_suffix(&format!("_{law}")) {
                    report
                        .table3_discrete
                        .entry(numeric.to_string())
                        .or_default()
                        .insert(law.clone(), T3Row::of(r, *h));
                }
            }
        }
    }
    report.traces = by_key.into_iter().map(|(k, (_, r))| (k, r)).collect();
    Ok((info, report))
}
