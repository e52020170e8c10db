//! `host-sim estimators`: how the velocity source changes the laws' contouring
//! (docs/velocity-estimation.md). Two study files: `estimators_paper.toml` (the paper
//! helix, PID/SMC/DSMC, 10 kHz, 1e-4 counts, |u| <= 500) and `estimators_physical.toml`
//! (the seeds helix on the physical gantry, PID/DSMC/DOB-SMC, 0.625 µm counts). Their
//! cases are the laws, their variants the velocity sources (`exact`,
//! `backward_difference`, `pll`, `kalman`); every run is the servo step against the
//! simulated world, so the estimators are fed exactly as on the board.

use crate::builtin;
use crate::builtin::resolve_all;
use crate::engine::{simulate, RunResult};
use crate::jobs;
use anyhow::{Context, Result};
use gantry_scenario::file::ScenarioFile;
use serde::Serialize;
use std::collections::BTreeMap;

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

/// The velocity sources in report order.
pub const SOURCES: [&str; 4] = ["exact", "backward_difference", "pll", "kalman"];

/// The paper study file with the command's options applied: `horizon_s`, and the paper's
/// +10 load step on X at 10 s when `disturbance`.
pub fn paper_file(horizon_s: f64, disturbance: bool) -> Result<ScenarioFile> {
    let mut over = format!("horizon_s = {horizon_s:?}\n");
    if disturbance {
        over.push_str(
            "machine.axes.x.plant.paper = { disturbance_accel = 10.0, disturbance_t_s = 10.0 }\n",
        );
    }
    builtin::load_with("estimators_paper.toml", &over)
}

/// Every run of `file`, on all cores, as a comparison (case = law, variant = source).
pub fn compare(file: &ScenarioFile) -> Result<Comparison> {
    let runs = resolve_all(file)?;
    let results = jobs::run_all(&runs, |r| {
        simulate(r).with_context(|| format!("run {}", r.name))
    })?;
    let mut out = Comparison::new();
    for (r, res) in runs.iter().zip(&results) {
        let law = r.case.clone().unwrap_or_else(|| r.name.clone());
        let src = r.variant.clone().unwrap_or_else(|| "exact".into());
        out.entry(law).or_default().insert(src, Figures::from(res));
    }
    Ok(out)
}

/// The one spelling of a law in every JSON output (`PID`, `SMC`, `DSMC`, `DOB-SMC`,
/// `ASMC`, as the paper and seeds reports spell them) for this study's legacy lowercase
/// key (`pid`, `smc`, `dsmc`, `dob_smc`).
pub fn canonical_law_key(key: &str) -> String {
    match key {
        "pid" => "PID".into(),
        "smc" => "SMC".into(),
        "dsmc" => "DSMC".into(),
        "dob_smc" => "DOB-SMC".into(),
        "adaptive_smc" => "ASMC".into(),
        other => other.to_uppercase().replace('_', "-"),
    }
}

/// The comparison as JSON: every law under its canonical key and, for scripts written
/// against the first release, under its lowercase key too.
pub fn to_json(c: &Comparison) -> serde_json::Value {
    let mut m = serde_json::Map::new();
    for (law, by_src) in c {
        let v = serde_json::to_value(by_src).unwrap_or_default();
        m.insert(canonical_law_key(law), v.clone());
        m.insert(law.clone(), v);
    }
    serde_json::Value::Object(m)
}

/// A terminal table of a comparison, sources in [`SOURCES`] order.
pub fn table(c: &Comparison) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<7} {:<20} {:>12} {:>12} {:>36} {:>30}",
        "law", "velocity source", "contour max", "contour rms", "ITSE x y z", "TV(u) x y z"
    );
    for (law, by_src) in c {
        for src in SOURCES {
            if let Some(f) = by_src.get(src) {
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
