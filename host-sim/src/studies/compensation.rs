//! `host-sim compensation [--machine FILE] [--write DIR]`: backlash and lead-screw error
//! compensation measured and verified on a simulated machine, as a user does it with a
//! laser interferometer (ISO 230-2's bidirectional positioning test).
//!
//! 1. Measure: each axis in turn (the others at 0) visits [`POINTS`] targets evenly spread
//!    over its travel (less [`MARGIN_MM`] at each end), first forward, then in reverse, each
//!    approached from [`OVERRUN_MM`] beyond the first target of its pass, dwelling
//!    [`DWELL_S`] at each; the tool's true position at the end of each dwell is the
//!    laser's reading.
//! 2. The readings become a LinuxCNC `COMP_FILE` of type 0 per axis (`nominal
//!    forward-actual reverse-actual`, [`crate::comp_file`]), read back as the machine's
//!    tables: this is the import a user's own file takes.
//! 3. Verify: the test is run again on the targets and the midpoints between them (the
//!    worst places for the tables' linear interpolation), without and with the tables
//!    entered. The figure is the largest |tool − nominal| over the travel, both
//!    directions, per axis.

use crate::comp_file::{self, CompFileType};
use crate::gcode::runner::{run_positioning, DwellReading};
use anyhow::{anyhow, Context, Result};
use controller_core::motion::compensation::AxisCompensation;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Targets per axis in the measurement (the table's points).
pub const POINTS: usize = 41;
/// Distance kept from each end of the travel, mm.
pub const MARGIN_MM: f64 = 10.0;
/// Approach distance before the first target of a pass (so that every target of the pass
/// is reached moving the same way with the nut's play taken up), mm.
pub const OVERRUN_MM: f64 = 5.0;
/// Dwell at each target before the reading, s.
pub const DWELL_S: f64 = 0.2;
/// Feed between targets, mm/min.
pub const FEED_MM_MIN: f64 = 3000.0;
/// The last stretch before each target is crept at [`CREEP_FEED_MM_MIN`], mm. Why: a
/// flexible axis' tool rests wherever its guides' friction catches the mode's ringing
/// (on the gantry's Y, ±18 mN·m of guide friction against the 35 Hz mode's 0.85 N·m/mm
/// is a ±21 µm band); a stop from creep speed rings by `v/ω` (0.5 µm at 1 mm/s on Y),
/// so the tool rests at its sliding deflection, the same at every target of a direction,
/// which the table then takes up. A gauge or a laser reading is taken the same way.
pub const CREEP_MM: f64 = 0.5;
/// Feed of the creep, mm/min.
pub const CREEP_FEED_MM_MIN: f64 = 60.0;

/// The machine studied when none is given.
pub fn default_machine() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("machines/gantry_flexible.toml")
}

/// One axis' figures (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct AxisFigures {
    pub axis: char,
    pub points: usize,
    pub span_mm: [f64; 2],
    /// Largest |tool − nominal| over the verification targets, both directions, µm.
    pub before_max_error_um: f64,
    pub after_max_error_um: f64,
    /// Range (max − min) of tool − nominal over them (ISO 230-2's positioning error E), µm.
    pub before_range_um: f64,
    pub after_range_um: f64,
    /// Mean reverse − forward difference (the reversal value B: backlash and the frame's
    /// friction hysteresis), µm.
    pub before_reversal_um: f64,
    pub after_reversal_um: f64,
}

/// The study's report.
#[derive(Clone, Debug, Serialize)]
pub struct CompReport {
    pub machine: String,
    pub axes: Vec<AxisFigures>,
}

/// Travel of `axis` on `machine` (soft limits), mm.
fn span(machine: &Path, axis: usize) -> Result<[f64; 2]> {
    let (cfg, _) = crate::sim_gantry::machine_and_planner_with(
        Some(machine),
        &controller_core::settings::FACTORY,
    )?;
    let t = cfg.servo.travel.axes[axis];
    let (lo, hi) = (f64::from(t.min_mm), f64::from(t.max_mm));
    if !(lo.is_finite() && hi.is_finite() && hi - lo > 2.0 * MARGIN_MM + 1.0) {
        anyhow::bail!(
            "axis {axis}: the test needs finite soft limits wider than {} mm",
            2.0 * MARGIN_MM
        );
    }
    Ok([lo + MARGIN_MM, hi - MARGIN_MM])
}

/// The positioning program of `axis` over `targets` (ascending): a forward pass, then a
/// reverse pass, dwelling at each target.
fn program(axis: usize, targets: &[f64]) -> String {
    let letter = ['X', 'Y', 'Z'][axis];
    let mut s =
        format!("(positioning test, axis {letter})\nG21 G90 G94 G61\nG1 X0 Y0 Z0 F{FEED_MM_MIN}\n");
    let (first, last) = (targets[0], targets[targets.len() - 1]);
    let visit = |s: &mut String, t: f64, dir: f64| {
        let _ = writeln!(
            s,
            "G1 {letter}{:.4} F{FEED_MM_MIN}\nG1 {letter}{t:.4} F{CREEP_FEED_MM_MIN}\nG4 P{DWELL_S}",
            t - dir * CREEP_MM
        );
    };
    let _ = writeln!(s, "G1 {letter}{:.4}", first - OVERRUN_MM);
    for t in targets {
        visit(&mut s, *t, 1.0);
    }
    let _ = writeln!(s, "G1 {letter}{:.4} F{FEED_MM_MIN}", last + OVERRUN_MM);
    for t in targets.iter().rev() {
        visit(&mut s, *t, -1.0);
    }
    let _ = writeln!(s, "G1 X0 Y0 Z0 F{FEED_MM_MIN}\nM2");
    s
}

/// `(nominal, actual)` readings along one axis, mm.
type Pairs = Vec<(f64, f64)>;

/// Run `axis`' positioning test over `targets` with `comp`: forward and reverse readings,
/// each `(nominal, actual)` along the axis.
fn readings(
    machine: &Path,
    axis: usize,
    targets: &[f64],
    comp: &[AxisCompensation; 3],
    scratch: &Path,
) -> Result<(Pairs, Pairs)> {
    let file = scratch.join(format!("positioning_{axis}_{}.nc", targets.len()));
    std::fs::write(&file, program(axis, targets))?;
    let r: Vec<DwellReading> = run_positioning(&file, Some(machine), comp)?;
    if r.len() != 2 * targets.len() {
        anyhow::bail!(
            "axis {axis}: {} readings for {} targets",
            r.len(),
            2 * targets.len()
        );
    }
    let pair = |d: &DwellReading| (d.nominal_mm[axis], d.tool_mm[axis]);
    let fwd = r[..targets.len()].iter().map(pair).collect();
    let mut rev: Vec<(f64, f64)> = r[targets.len()..].iter().map(pair).collect();
    rev.reverse();
    Ok((fwd, rev))
}

/// (max |error|, range, mean reverse − forward) of paired readings, µm.
fn figures(fwd: &[(f64, f64)], rev: &[(f64, f64)]) -> (f64, f64, f64) {
    let errs: Vec<f64> = fwd.iter().chain(rev).map(|(n, a)| (a - n) * 1e3).collect();
    let max = errs.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let (lo, hi) = errs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), e| {
            (l.min(*e), h.max(*e))
        });
    let b = fwd
        .iter()
        .zip(rev)
        .map(|((_, f), (_, r))| (r - f) * 1e3)
        .sum::<f64>()
        / fwd.len().max(1) as f64;
    (max, hi - lo, b)
}

/// The measurement, the tables and the verification on `machine` (default
/// [`default_machine`]); the COMP_FILEs are written to `write` (default: a scratch dir).
pub fn run(machine: Option<&Path>, write: Option<&Path>) -> Result<CompReport> {
    run_axes(machine, write, &[0, 1, 2])
}

/// [`run`] on the axes `which` (0 = X) only.
pub fn run_axes(
    machine: Option<&Path>,
    write: Option<&Path>,
    which: &[usize],
) -> Result<CompReport> {
    let machine = machine.map_or_else(default_machine, Path::to_path_buf);
    let scratch = std::env::temp_dir().join(format!("gantry-comp-{}", std::process::id()));
    std::fs::create_dir_all(&scratch)?;
    let out = write.map_or_else(|| scratch.clone(), Path::to_path_buf);
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let none = [AxisCompensation::NONE; 3];
    let mut axes = Vec::new();
    let mut tables = none;
    let mut spans = Vec::new();
    for &axis in which {
        if axis > 2 {
            anyhow::bail!("axis {axis}: the gantry has axes 0 (X), 1 (Y) and 2 (Z)");
        }
        let sp = span(&machine, axis)?;
        let h = (sp[1] - sp[0]) / (POINTS - 1) as f64;
        let grid: Vec<f64> = (0..POINTS).map(|k| sp[0] + k as f64 * h).collect();
        let (fwd, rev) = readings(&machine, axis, &grid, &none, &scratch)?;
        let pts: Vec<(f64, f64, f64)> = fwd
            .iter()
            .zip(&rev)
            .map(|((n, f), (_, r))| (*n, *f, *r))
            .collect();
        let letter = ['x', 'y', 'z'][axis];
        let header = format!(
            "axis {letter} of {}: measured by host-sim compensation (ISO 230-2, laser at the tool)\nLinuxCNC COMP_FILE_TYPE = 0: nominal forward-actual reverse-actual, mm",
            machine.display()
        );
        let path = out.join(format!("comp_{letter}.txt"));
        std::fs::write(&path, comp_file::write_actual(&header, &pts))?;
        let table = comp_file::read(&path, CompFileType::Actual)?;
        tables[axis] =
            AxisCompensation::new(&table, 0.0).map_err(|e| anyhow!("{}: {e}", path.display()))?;
        spans.push((axis, sp, grid, h));
    }
    for (axis, sp, grid, h) in spans {
        let mut check: Vec<f64> = grid.iter().flat_map(|g| [*g, g + 0.5 * h]).collect();
        check.pop();
        let (bf, br) = readings(&machine, axis, &check, &none, &scratch)?;
        let (af, ar) = readings(&machine, axis, &check, &tables, &scratch)?;
        let (b_max, b_range, b_rev) = figures(&bf, &br);
        let (a_max, a_range, a_rev) = figures(&af, &ar);
        axes.push(AxisFigures {
            axis: ['X', 'Y', 'Z'][axis],
            points: POINTS,
            span_mm: sp,
            before_max_error_um: b_max,
            after_max_error_um: a_max,
            before_range_um: b_range,
            after_range_um: a_range,
            before_reversal_um: b_rev,
            after_reversal_um: a_rev,
        });
    }
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(CompReport {
        machine: machine.display().to_string(),
        axes,
    })
}

/// The report as a table.
pub fn table(r: &CompReport) -> String {
    let mut s = format!(
        "Backlash and lead-screw compensation on {} (ISO 230-2 at the tool, targets and midpoints)\n",
        r.machine
    );
    let _ = writeln!(
        s,
        "{:<4} {:>7} {:>16} {:>16} {:>16}",
        "axis", "points", "max |err| µm", "range E µm", "reversal B µm"
    );
    for a in &r.axes {
        let _ = writeln!(
            s,
            "{:<4} {:>7} {:>7.2} → {:>6.2} {:>7.2} → {:>6.2} {:>7.2} → {:>6.2}",
            a.axis,
            a.points,
            a.before_max_error_um,
            a.after_max_error_um,
            a.before_range_um,
            a.after_range_um,
            a.before_reversal_um,
            a.after_reversal_um
        );
    }
    s
}
