//! `host-sim run FILE`: every run of any scenario file (a built-in study's included), with
//! the common figures on the terminal, in JSON and as CSV traces.

use crate::builtin::resolve_all;
use crate::engine::{simulate, RunResult};
use crate::jobs;
use anyhow::{Context, Result};
use gantry_scenario::file::ScenarioFile;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The figures of one run (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct RunFigures {
    pub itse: [f64; 3],
    pub itse_window: [f64; 3],
    pub iae: [f64; 3],
    pub max_abs_error: [f64; 3],
    pub contour_max: f64,
    pub contour_rms: f64,
    pub tv_u: [f64; 3],
    pub peak_u: [f64; 3],
}

impl From<&RunResult> for RunFigures {
    fn from(r: &RunResult) -> Self {
        Self {
            itse: r.itse,
            itse_window: r.itse_window,
            iae: r.iae,
            max_abs_error: r.max_abs_error,
            contour_max: r.contour_max,
            contour_rms: r.contour_rms,
            tv_u: r.tv_u,
            peak_u: r.peak_u,
        }
    }
}

/// Every run of a file, in file order.
pub struct FileResults {
    pub name: String,
    pub runs: Vec<(String, f64, RunResult)>,
}

/// Run every run of `file` on all cores.
pub fn run_file(file: &ScenarioFile) -> Result<FileResults> {
    let runs = resolve_all(file)?;
    let results = jobs::run_all(&runs, |r| {
        simulate(r).with_context(|| format!("run {}", r.name))
    })?;
    Ok(FileResults {
        name: file.name.clone(),
        runs: runs
            .iter()
            .zip(results)
            .map(|(r, res)| {
                let from = r.run.truth.contour_from_s.unwrap_or(f64::NAN);
                (r.name.clone(), from, res)
            })
            .collect(),
    })
}

impl FileResults {
    /// `{"name": <file's name>, "runs": {<run>: {figures}}}`; a file with a single run also
    /// has that run's figures (and its name) at the top level, as `run` always wrote.
    pub fn to_json(&self) -> serde_json::Value {
        let runs: BTreeMap<&str, RunFigures> = self
            .runs
            .iter()
            .map(|(n, _, r)| (n.as_str(), RunFigures::from(r)))
            .collect();
        let mut m = serde_json::Map::new();
        if let [(name, _, r)] = self.runs.as_slice() {
            if let Ok(serde_json::Value::Object(f)) = serde_json::to_value(RunFigures::from(r)) {
                m.extend(f);
            }
            m.insert("name".into(), name.clone().into());
        } else {
            m.insert("name".into(), self.name.clone().into());
        }
        m.insert(
            "runs".into(),
            serde_json::to_value(runs).unwrap_or_default(),
        );
        serde_json::Value::Object(m)
    }

    /// The terminal report.
    pub fn table(&self) -> String {
        let mut s = String::new();
        for (name, from, r) in &self.runs {
            let _ = writeln!(s, "run {name}");
            let _ = writeln!(
                s,
                "  ITSE x y z      : {:.6e} {:.6e} {:.6e}",
                r.itse[0], r.itse[1], r.itse[2]
            );
            let _ = writeln!(
                s,
                "  max |e| x y z   : {:.6e} {:.6e} {:.6e}",
                r.max_abs_error[0], r.max_abs_error[1], r.max_abs_error[2]
            );
            if from.is_finite() {
                let _ = writeln!(
                    s,
                    "  contour max rms : {:.6e} {:.6e} (t >= {from} s)",
                    r.contour_max, r.contour_rms
                );
            }
            let _ = writeln!(
                s,
                "  TV(u) x y z     : {:.4e} {:.4e} {:.4e}",
                r.tv_u[0], r.tv_u[1], r.tv_u[2]
            );
        }
        s
    }
}
