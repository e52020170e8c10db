//! The fault matrix (`host-sim faults`): every fault class injected into the simulated
//! physical gantry through the real servo step (study file
//! `host-sim/scenarios/faults.toml`; cases: the faults, with their bounds in the case's
//! `study` table). Per case: when the fault was injected, when the servo detected it and
//! with which class, when the outputs went off, how far the machine travelled after the
//! detection, and whether that is within the case's bounds. A case may also command a
//! path start (a hold case that then moves) or a reset (which must be refused while the
//! cause persists).

use crate::builtin::{self, resolve_all};
use crate::jobs;
use anyhow::{anyhow, bail, Context, Result};
use controller_core::axes::Axis;
use controller_core::motion::path::PathConfig;
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::SimRun;
use controller_core::sim::run::TimedInjection;
use controller_core::sim::world::Injection;
use controller_core::Vec3;
use gantry_scenario::file::Run;
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
    /// Periods from the injection to the outputs off (default: `bound_periods`, the
    /// immediate stops; a controlled stop's case gives its stop time).
    #[serde(default)]
    bound_off_periods: Option<u32>,
    /// Largest travel from the injection to the detection, mm (the motion the servo did
    /// not see; default: not bounded beyond `bound_overrun_mm`).
    #[serde(default)]
    bound_blind_mm: Option<f64>,
    /// Run the case over this grid of speeds, axes and directions instead (each point a
    /// row named `<case>_<axis><+|->_<speed>`): the path is a line along the axis at the
    /// speed, the fault is on that axis.
    /// Set on a grid's rows: their speed, mm/s.
    #[serde(default)]
    speed_mm_s: Option<f64>,
}

/// A case's speed grid.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Grid {
    speeds_mm_s: Vec<f64>,
    axes: Vec<Axis>,
    /// +1 and/or -1.
    directions: Vec<i8>,
    /// Per speed (same length as `speeds_mm_s`): the overrun bound at that speed, mm
    /// (the stop distance grows with the speed); default: the case's one bound.
    #[serde(default)]
    bound_overrun_mm: Option<Vec<f64>>,
    /// The rows start at rest and accelerate, as a machine does: the path is
    /// `start + A (1 - cos ωt)` along the axis, reaching the row's speed at the injection
    /// (ω = π / (2 t_injection), A = speed / ω). Default: the rows start on a line at
    /// their speed (the servo arming with the axis already moving).
    #[serde(default)]
    from_rest: bool,
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
    /// How far the machine travelled from the injection to the detection (or to the end,
    /// undetected), mm.
    pub blind_mm: f64,
    /// The speed of a grid row, mm/s (`null`: not a grid row).
    pub speed_mm_s: Option<f64>,
    pub bound_periods: u32,
    pub bound_off_periods: u32,
    pub bound_blind_mm: Option<f64>,
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

/// The tool's true position (a framed axis' tool side).
fn position(run: &SimRun<f32>) -> Vec3<f64> {
    Vec3::from_array(run.world().tool_pos())
}

/// What one case's run showed.
struct Observed {
    /// The class detected first and the periods to its detection.
    detect: Option<(String, u32)>,
    /// Periods from the injection to the outputs off.
    off: Option<u32>,
    overrun_mm: f64,
    blind_mm: f64,
    /// The position when the reset was commanded, and the drift from it since, mm.
    check: Option<(Vec3<f64>, f64)>,
    /// A fault latched before the injection.
    early: Option<String>,
    /// The servo's state when the run ended.
    end_state: ServoState,
}

fn run_case(r: &Resolved) -> Result<CaseResult> {
    let (study, inject) = case_study(r)?;
    let seen = observe(r, &study, &inject)?;
    let bound_off = study.bound_off_periods.unwrap_or(study.bound_periods);
    let (why, reset_refused, check_drift) = verdict(&study, &seen, bound_off);
    Ok(CaseResult {
        case: r.case.clone().unwrap_or_else(|| r.name.clone()),
        fault: study.expect.first().cloned().unwrap_or_default(),
        axis: study.axis,
        state: study.state,
        injected_s: inject.at_s,
        detected: seen.detect.as_ref().map(|d| d.0.clone()),
        detect_periods: seen.detect.map(|d| d.1),
        outputs_off_periods: seen.off,
        overrun_mm: seen.overrun_mm,
        blind_mm: seen.blind_mm,
        speed_mm_s: study.speed_mm_s,
        bound_periods: study.bound_periods,
        bound_off_periods: bound_off,
        bound_blind_mm: study.bound_blind_mm,
        bound_overrun_mm: study.bound_overrun_mm,
        reset_refused,
        check_drift_mm: check_drift,
        passed: why.is_empty(),
        why: why.join("; "),
    })
}

/// The case's study table and its injection, the bounds checked to be finite distances.
fn case_study(r: &Resolved) -> Result<(CaseStudy, TimedInjection)> {
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
    let finite = |v: f64, what: &str| -> Result<()> {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            bail!(
                "case {}: study.{what} = {v} is not a finite distance",
                r.name
            )
        }
    };
    finite(study.bound_overrun_mm, "bound_overrun_mm")?;
    for (v, what) in [
        (study.bound_check_drift_mm, "bound_check_drift_mm"),
        (study.bound_blind_mm, "bound_blind_mm"),
    ] {
        if let Some(v) = v {
            finite(v, what)?;
        }
    }
    Ok((study, inject))
}

/// Run the case: arm (and start the path), inject, reset where the study says, and
/// follow the detection, the outputs and the travel period by period.
fn observe(r: &Resolved, study: &CaseStudy, inject: &TimedInjection) -> Result<Observed> {
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
    let mut early: Option<String> = None;
    let mut blind = 0.0f64;
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
        if run.injected_at().is_none() && early.is_none() {
            // a fault before the injection would read as its detection
            if let Some(f) = run.servo().faults().first() {
                early = Some(f.fault.kind.name().to_string());
            }
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
        if let (Some(p0), None) = (p_inject, p_detect) {
            blind = blind.max((p - p0).norm());
        }
        // undetected: everything since the injection is overrun
        let from = if study.drift_from_injection || detect.is_none() {
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
    Ok(Observed {
        detect,
        off,
        overrun_mm: overrun,
        blind_mm: blind,
        check,
        early,
        end_state: run.servo().state(),
    })
}

/// What failed in a case (empty: passed), whether its reset was refused and the drift
/// during the encoder check (reset cases).
fn verdict(
    study: &CaseStudy,
    seen: &Observed,
    bound_off: u32,
) -> (Vec<String>, Option<bool>, Option<f64>) {
    let Observed {
        detect,
        off,
        overrun_mm: overrun,
        blind_mm: blind,
        check,
        early,
        end_state,
    } = seen;
    let (off, overrun, blind) = (*off, *overrun, *blind);
    let mut why = Vec::new();
    if let Some(kind) = &early {
        why.push(format!("{kind} latched before the injection"));
    }
    match off {
        Some(o) if o > bound_off => {
            why.push(format!("outputs off after {o} periods > {bound_off}"))
        }
        _ => {}
    }
    if let Some(b) = study.bound_blind_mm {
        if !(blind <= b) {
            why.push(format!(
                "travelled {blind:.3} mm before the detection > {b} mm"
            ));
        }
    }
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
        let refused = *end_state == ServoState::Fault;
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
    (why, reset_refused, check_drift)
}

/// The fault of `inj` moved onto `axis` (the kinds without an axis stay as they are).
fn on_axis(inj: Injection, axis: Axis) -> Injection {
    match inj {
        Injection::Limit { high, .. } => Injection::Limit { axis, high },
        Injection::AmplifierFault { .. } => Injection::AmplifierFault { axis },
        Injection::EncoderStuck { .. } => Injection::EncoderStuck { axis },
        Injection::EncoderJump { counts, .. } => Injection::EncoderJump { axis, counts },
        Injection::EncoderReversed { .. } => Injection::EncoderReversed { axis },
        Injection::ExternalAccel {
            accel_mm_s2, for_s, ..
        } => Injection::ExternalAccel {
            axis,
            accel_mm_s2,
            for_s,
        },
        Injection::ExtraFriction { mnm, .. } => Injection::ExtraFriction { axis, mnm },
        Injection::CorruptState { .. } => Injection::CorruptState { axis },
        other => other,
    }
}

/// Every case with a `grid` becomes one run per speed, axis and direction.
fn expand_grids(file: &str, runs: Vec<Run>) -> Result<Vec<Run>> {
    let mut out = Vec::new();
    for r in runs {
        let Some(toml::Value::Table(table)) = r.scenario.study.clone() else {
            out.push(r);
            continue;
        };
        let Some(grid) = table.get("grid").cloned() else {
            out.push(r);
            continue;
        };
        let grid: Grid = grid
            .try_into()
            .with_context(|| format!("{file}: case {}: invalid grid", r.name))?;
        let bad = |m: String| anyhow!("{file}: case {}: grid: {m}", r.name);
        if grid.speeds_mm_s.is_empty() || grid.axes.is_empty() || grid.directions.is_empty() {
            return Err(bad(
                "speeds_mm_s, axes and directions must not be empty".into()
            ));
        }
        if let Some(v) = grid
            .speeds_mm_s
            .iter()
            .find(|v| !(v.is_finite() && **v > 0.0))
        {
            return Err(bad(format!(
                "speed {v} mm/s is not a positive finite number"
            )));
        }
        if let Some(d) = grid.directions.iter().find(|d| !matches!(d, 1 | -1)) {
            return Err(bad(format!("direction {d} is not 1 or -1")));
        }
        if let Some(b) = &grid.bound_overrun_mm {
            if b.len() != grid.speeds_mm_s.len() {
                return Err(bad(format!(
                    "bound_overrun_mm has {} values for {} speeds",
                    b.len(),
                    grid.speeds_mm_s.len()
                )));
            }
            if let Some(v) = b.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
                return Err(bad(format!(
                    "bound_overrun_mm {v} is not a finite distance"
                )));
            }
        }
        let fault = r
            .scenario
            .fault
            .ok_or_else(|| bad("the case injects no fault".into()))?;
        if grid.from_rest && !(fault.at_s > 0.0 && fault.at_s.is_finite()) {
            return Err(bad(
                "from_rest needs the fault injected at a positive time".into()
            ));
        }
        for &axis in &grid.axes {
            for &dir in &grid.directions {
                for (j, &speed) in grid.speeds_mm_s.iter().enumerate() {
                    let mut g = r.clone();
                    let mut vel = [0.0; 3];
                    vel[axis.index()] = f64::from(dir) * speed;
                    let start = match g.scenario.path {
                        PathConfig::Line { start, .. } => start,
                        _ => [0.0; 3],
                    };
                    g.scenario.path = if grid.from_rest {
                        // (at_s > 0: checked above)
                        let omega = core::f64::consts::FRAC_PI_2 / fault.at_s;
                        let amp = vel.map(|v| v / omega);
                        PathConfig::Sine {
                            amp,
                            omega,
                            phase: [-core::f64::consts::FRAC_PI_2; 3],
                            offset: [0, 1, 2].map(|i| start[i] + amp[i]),
                        }
                    } else {
                        PathConfig::Line { start, vel }
                    };
                    g.scenario.fault = Some(TimedInjection {
                        at_s: fault.at_s,
                        fault: on_axis(fault.fault, axis),
                    });
                    let sign = if dir > 0 { '+' } else { '-' };
                    g.name = format!("{}_{}{sign}_{speed}", r.name, axis.name());
                    g.case = Some(g.name.clone());
                    let mut t = table.clone();
                    t.remove("grid");
                    t.insert("axis".into(), toml::Value::String(axis.name().into()));
                    t.insert("speed_mm_s".into(), toml::Value::Float(speed));
                    if let Some(b) = &grid.bound_overrun_mm {
                        t.insert("bound_overrun_mm".into(), toml::Value::Float(b[j]));
                    }
                    let state = t
                        .get("state")
                        .and_then(|v| v.as_str())
                        .unwrap_or("moving")
                        .to_string();
                    t.insert(
                        "state".into(),
                        toml::Value::String(format!("{state} {sign}{speed} mm/s")),
                    );
                    g.scenario.study = Some(toml::Value::Table(t));
                    out.push(g);
                }
            }
        }
    }
    Ok(out)
}

/// Run the matrix of `file` (default: the built-in `faults.toml`).
pub fn run_matrix(file: Option<&std::path::Path>) -> Result<Matrix> {
    let mut f = builtin::load_or("faults.toml", file)?;
    f.runs = expand_grids(&f.file, std::mem::take(&mut f.runs))?;
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

/// The grid rows by case and speed, worst over the axes and directions.
pub fn grid_summary(m: &Matrix) -> String {
    let mut groups: Vec<(String, f64, Vec<&CaseResult>)> = Vec::new();
    for c in &m.cases {
        let Some(v) = c.speed_mm_s else { continue };
        // `<case>_<axis><sign>_<speed>`
        let case = c.case.rsplitn(3, '_').nth(2).unwrap_or(&c.case).to_string();
        match groups.iter_mut().find(|g| g.0 == case && g.1 == v) {
            Some(g) => g.2.push(c),
            None => groups.push((case, v, vec![c])),
        }
    }
    if groups.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "\n| grid | speed mm/s | rows | detected as | worst detect periods | worst blind mm | worst overrun mm | passed |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for (case, v, rows) in &groups {
        let mut kinds: Vec<&str> = rows.iter().filter_map(|c| c.detected.as_deref()).collect();
        kinds.sort_unstable();
        kinds.dedup();
        let det = rows
            .iter()
            .map(|c| c.detect_periods.map_or("-".to_string(), |p| p.to_string()))
            .max_by_key(|p| p.parse::<u32>().unwrap_or(u32::MAX))
            .unwrap_or_default();
        let blind = rows.iter().map(|c| c.blind_mm).fold(0.0, f64::max);
        let over = rows.iter().map(|c| c.overrun_mm).fold(0.0, f64::max);
        let passed = rows.iter().filter(|c| c.passed).count();
        let _ = writeln!(
            s,
            "| {case} | {v} | {} | {} | {det} | {blind:.4} | {over:.3} | {passed}/{} |",
            rows.len(),
            kinds.join(", "),
            rows.len()
        );
    }
    s
}

/// The terminal table.
pub fn table(m: &Matrix) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| case | class | axis | state | injected at s | detected as | detect periods | outputs off periods | blind mm | overrun mm | bound | result |"
    );
    let _ = writeln!(
        s,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for c in &m.cases {
        let opt = |v: Option<u32>| v.map_or("-".to_string(), |v| v.to_string());
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | {} | {} | {} | {:.4} | {:.3} | {} periods, off {}, {}{} mm | {} |",
            c.case,
            c.fault,
            c.axis,
            c.state,
            c.injected_s,
            c.detected.as_deref().unwrap_or("-"),
            opt(c.detect_periods),
            opt(c.outputs_off_periods),
            c.blind_mm,
            c.overrun_mm,
            c.bound_periods,
            c.bound_off_periods,
            c.bound_blind_mm
                .map_or(String::new(), |b| format!("blind {b} mm, ")),
            c.bound_overrun_mm,
            if c.passed {
                "pass".to_string()
            } else {
                format!("FAIL: {}", c.why)
            }
        );
    }
    s.push_str(&grid_summary(m));
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
