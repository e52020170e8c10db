//! The fault matrix (`host-sim faults`): every fault class injected into the simulated
//! physical gantry through the real servo step (study file
//! `host-sim/scenarios/faults.toml`; cases: the faults, with their bounds in the case's
//! `study` table). Per case: when the fault was injected, when the servo detected it and
//! with which class, when the outputs went off, how far the machine travelled after the
//! detection, and whether that is within the case's bounds. A case may also command a
//! path start (a hold case that then moves) or a reset (which must be refused while the
//! cause persists).

use super::resolve_all;
use crate::builtin;
use crate::jobs;
use anyhow::{anyhow, bail, Context, Result};
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::SimRun;
use controller_core::Vec3;
use gantry_scenario::Resolved;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

/// The case's own table in the study file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseStudy {
    /// Fault classes that count as the detection (`FaultKind::name`).
    expect: Vec<String>,
    /// The faulted axis (`x`, `y`, `z`, or `-`), for the report.
    axis: String,
    /// What the machine was doing, for the report.
    state: String,
    bound_periods: u32,
    bound_overrun_mm: f64,
    /// Start the path at this time (a case that holds first).
    #[serde(default)]
    start_path_at_s: Option<f64>,
    /// Detection periods are counted from this time instead of the injection.
    #[serde(default)]
    measure_from_s: Option<f64>,
    /// The overrun is the travel since the injection, not since the detection.
    #[serde(default)]
    drift_from_injection: bool,
    /// Request a reset at this time.
    #[serde(default)]
    reset_at_s: Option<f64>,
    /// The reset must be refused (the state stays Fault).
    #[serde(default)]
    reset_refused: bool,
    /// Largest travel allowed during the encoder check of that reset, mm.
    #[serde(default)]
    bound_check_drift_mm: Option<f64>,
}

/// One row of the matrix (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    pub case: String,
    /// The injected fault (the case's first expected class).
    pub fault: String,
    pub axis: String,
    pub state: String,
    /// Injection time, s.
    pub injected_s: f64,
    /// The class the servo reported first (`null`: nothing detected).
    pub detected: Option<String>,
    /// Control periods from the injection (or the case's `measure_from_s`) to the
    /// detection (`null`: not detected).
    pub detect_periods: Option<u32>,
    /// Periods from the injection to the first period with the outputs off.
    pub outputs_off_periods: Option<u32>,
    /// How far the machine travelled after the detection (or since the injection), mm.
    pub overrun_mm: f64,
    pub bound_periods: u32,
    pub bound_overrun_mm: f64,
    /// For reset cases: the reset was refused and the axis moved this much meanwhile.
    pub reset_refused: Option<bool>,
    pub check_drift_mm: Option<f64>,
    pub passed: bool,
    /// Why it failed (empty when passed).
    pub why: String,
}

/// The whole matrix.
#[derive(Clone, Debug, Serialize)]
pub struct Matrix {
    pub cases: Vec<CaseResult>,
    pub passed: bool,
}

fn position(run: &SimRun<f32>) -> Vec3<f64> {
    let s = run.world().state();
    Vec3::new(s[0].pos, s[1].pos, s[2].pos)
}

fn run_case(r: &Resolved) -> Result<CaseResult> {
    let study: CaseStudy = r
        .study
        .clone()
        .ok_or_else(|| anyhow!("case {} has no study table", r.name))?
        .try_into()
        .with_context(|| format!("case {}: invalid study table", r.name))?;
    let inject = r
        .run
        .inject
        .ok_or_else(|| anyhow!("case {} injects no fault", r.name))?;
    let mut run = SimRun::<f32>::new(&r.run)
        .map_err(|e| anyhow!("case {}: invalid configuration: {e}", r.name))?;
    let dt = run.servo().period_s();
    let period_of = |t: f64| (t / dt).round() as u32;
    let start_at = study.start_path_at_s.map(period_of);
    let reset_at = study.reset_at_s.map(period_of);
    let measure_from = period_of(study.measure_from_s.unwrap_or(inject.at_s));
    let (mut detect, mut off) = (None, None);
    let (mut p_inject, mut p_detect) = (None, None);
    let mut overrun = 0.0f64;
    let mut check: Option<(Vec3<f64>, f64)> = None;
    let mut k = 0u32;
    while !run.done() {
        let cmds: &[Command] = if k == 0 {
            if r.run.hold {
                &[Command::Arm]
            } else {
                &[Command::Arm, Command::StartPath]
            }
        } else if Some(k) == start_at {
            &[Command::StartPath]
        } else if Some(k) == reset_at {
            &[Command::Reset]
        } else {
            &[]
        };
        let snap = *run.control_with(cmds);
        let p = position(&run);
        if run.injected_at().is_some() && p_inject.is_none() {
            p_inject = Some(p);
        }
        if let (Some(inj), None) = (run.injected_at(), &detect) {
            if let Some(f) = run.servo().faults().first() {
                // the servo's period counter runs one ahead of the run's
                let at = f.period.saturating_sub(1);
                detect = Some((
                    f.fault.kind.name().to_string(),
                    at.saturating_sub(inj.max(measure_from)),
                ));
                p_detect = Some(p);
            }
        }
        if let (Some(inj), None) = (run.injected_at(), off) {
            if !snap.outputs_on && k >= inj {
                off = Some(k - inj);
            }
        }
        let from = if study.drift_from_injection {
            p_inject
        } else {
            p_detect
        };
        if let Some(p0) = from {
            overrun = overrun.max((p - p0).norm());
        }
        if let Some(ra) = reset_at {
            if k >= ra {
                let c = check.get_or_insert((p, 0.0));
                c.1 = c.1.max((p - c.0).norm());
            }
        }
        run.finish_period();
        k += 1;
    }
    let mut why = Vec::new();
    match &detect {
        None => why.push("not detected".to_string()),
        Some((kind, periods)) => {
            if !study.expect.iter().any(|e| e == kind) {
                why.push(format!(
                    "detected as {kind}, expected {}",
                    study.expect.join(" or ")
                ));
            }
            if *periods > study.bound_periods {
                why.push(format!("{periods} periods > {}", study.bound_periods));
            }
        }
    }
    if off.is_none() {
        why.push("outputs never went off".into());
    }
    if !(overrun <= study.bound_overrun_mm) {
        why.push(format!(
            "overrun {overrun:.3} mm > {} mm",
            study.bound_overrun_mm
        ));
    }
    let mut reset_refused = None;
    let mut check_drift = None;
    if study.reset_at_s.is_some() {
        let refused = run.servo().state() == ServoState::Fault;
        reset_refused = Some(refused);
        if refused != study.reset_refused {
            why.push(format!(
                "reset {} (expected {})",
                if refused { "refused" } else { "accepted" },
                if study.reset_refused {
                    "refused"
                } else {
                    "accepted"
                }
            ));
        }
        let d = check.map_or(0.0, |c| c.1);
        check_drift = Some(d);
        if let Some(b) = study.bound_check_drift_mm {
            if !(d <= b) {
                why.push(format!("moved {d:.3} mm during the encoder check > {b} mm"));
            }
        }
    }
    Ok(CaseResult {
        case: r.case.clone().unwrap_or_else(|| r.name.clone()),
        fault: study.expect.first().cloned().unwrap_or_default(),
        axis: study.axis,
        state: study.state,
        injected_s: inject.at_s,
        detected: detect.as_ref().map(|d| d.0.clone()),
        detect_periods: detect.map(|d| d.1),
        outputs_off_periods: off,
        overrun_mm: overrun,
        bound_periods: study.bound_periods,
        bound_overrun_mm: study.bound_overrun_mm,
        reset_refused,
        check_drift_mm: check_drift,
        passed: why.is_empty(),
        why: why.join("; "),
    })
}

/// Run the matrix of `file` (default: the built-in `faults.toml`).
pub fn run_matrix(file: Option<&std::path::Path>) -> Result<Matrix> {
    let f = builtin::load_or("faults.toml", file)?;
    let runs = resolve_all(&f)?;
    if runs.is_empty() {
        bail!("{}: no cases", f.file);
    }
    let cases = jobs::run_all(&runs, |r| {
        run_case(r).with_context(|| format!("case {}", r.name))
    })?;
    let passed = cases.iter().all(|c| c.passed);
    Ok(Matrix { cases, passed })
}

/// The terminal table.
pub fn table(m: &Matrix) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| case | class | axis | state | injected at s | detected as | detect periods | outputs off periods | overrun mm | bound | result |"
    );
    let _ = writeln!(
        s,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for c in &m.cases {
        let opt = |v: Option<u32>| v.map_or("-".to_string(), |v| v.to_string());
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | {} | {} | {} | {:.3} | {} periods, {} mm | {} |",
            c.case,
            c.fault,
            c.axis,
            c.state,
            c.injected_s,
            c.detected.as_deref().unwrap_or("-"),
            opt(c.detect_periods),
            opt(c.outputs_off_periods),
            c.overrun_mm,
            c.bound_periods,
            c.bound_overrun_mm,
            if c.passed {
                "pass".to_string()
            } else {
                format!("FAIL: {}", c.why)
            }
        );
    }
    let _ = writeln!(
        s,
        "\n{}",
        if m.passed {
            "every case within its bounds"
        } else {
            "SOME CASES FAILED"
        }
    );
    s
}
