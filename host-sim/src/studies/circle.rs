//! `host-sim circle [--machine FILE]`: the ISO 230-4 circular test on a simulated
//! machine (host-sim/scenarios/circle.toml: two radii and feeds, both directions), each
//! circle evaluated at the tool over its last full turn ([`super::circular_test`]), its
//! radial deviation kept for the polar plot (`crate::output::circle_plots`).

use crate::builtin::{self, resolve_all};
use crate::engine::simulate;
use crate::jobs;
use crate::studies::circular_test::{evaluate_traced, CircleFigures, RadialDeviation};
use anyhow::{bail, Context, Result};
use controller_core::motion::trajectory::Trajectory;
use gantry_scenario::Resolved;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// One circle (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct CircleCase {
    pub name: String,
    pub radius_mm: f64,
    pub feed_mm_min: f64,
    /// `cw` or `ccw` (seen from +Z).
    pub direction: &'static str,
    #[serde(flatten)]
    pub figures: CircleFigures,
    /// The run's contour error at the tool (to the programmed circle), max, µm.
    pub contour_max_um: f64,
    /// The radial deviation about the least-squares centre over the judged turn, for the
    /// polar plot; not in the JSON (its keys are fixed, and a trace per case would swamp
    /// the figures).
    #[serde(skip)]
    pub trace: Vec<RadialDeviation>,
}

/// Every circle of the test on one machine.
#[derive(Clone, Debug, Serialize)]
pub struct CircleReport {
    pub machine: String,
    pub cases: Vec<CircleCase>,
}

/// The nominal circle of a run: centre (XY), radius, angular rate.
fn nominal(r: &Resolved) -> Result<([f64; 2], f64, f64)> {
    match r.reference {
        Trajectory::Helix {
            center,
            radius,
            omega,
            z_rate,
        } if z_rate == 0.0 && omega != 0.0 => Ok(([center[0], center[1]], radius, omega)),
        _ => bail!(
            "run `{}`: the circular test needs a circle (a helix with no z_rate)",
            r.name
        ),
    }
}

/// One run's circle: its last full turn of tool positions, evaluated.
fn case(r: &Resolved) -> Result<CircleCase> {
    let (centre, radius, omega) = nominal(r)?;
    let turn_s = 2.0 * std::f64::consts::PI / omega.abs();
    let from_s = 0.25 * turn_s;
    if r.horizon_s < from_s + turn_s - 1e-6 {
        bail!(
            "run `{}`: the horizon must cover 1.25 turns ({:.3} s)",
            r.name,
            from_s + turn_s
        );
    }
    let res = simulate(r).with_context(|| format!("run {}", r.name))?;
    let pts: Vec<[f64; 2]> = res
        .trace
        .t
        .iter()
        .zip(&res.trace.position)
        .filter(|(t, _)| **t >= from_s && **t < from_s + turn_s)
        .map(|(_, p)| [p[0], p[1]])
        .collect();
    let eval = evaluate_traced(&pts, centre, radius).with_context(|| format!("run {}", r.name))?;
    Ok(CircleCase {
        name: r.name.clone(),
        radius_mm: radius,
        feed_mm_min: radius * omega.abs() * 60.0,
        // x = cx + r sin(ωt), y = cy + r cos(ωt): ω > 0 turns from +Y towards +X
        direction: if omega > 0.0 { "cw" } else { "ccw" },
        figures: eval.figures,
        contour_max_um: res.contour_max * 1e3,
        trace: eval.trace,
    })
}

/// The test on the built-in gantry or on `machine`.
pub fn run(machine: Option<&Path>) -> Result<CircleReport> {
    run_compensated(machine, None)
}

/// [`run`] with the compensation tables of `comp` entered: a folder of LinuxCNC
/// COMP_FILEs of type 0 named `comp_x.txt`, `comp_y.txt`, `comp_z.txt` (an absent one: no
/// table on that axis), as `host-sim compensation --write DIR` writes them.
pub fn run_compensated(machine: Option<&Path>, comp: Option<&Path>) -> Result<CircleReport> {
    let file = match machine {
        Some(m) => builtin::load_on_machine("circle.toml", m)?,
        None => builtin::load("circle.toml")?,
    };
    let mut runs = resolve_all(&file)?;
    if let Some(dir) = comp {
        let tables = crate::comp_file::read_dir(dir)?;
        let ff = crate::comp_file::read_feedforward(dir)?;
        for r in &mut runs {
            r.compensation = Some(Box::new(tables));
            if let Some(ff) = ff {
                r.run.servo.feedforward = ff;
            }
            if let Some(f) = crate::comp_file::read_filters(dir, r.run.servo.rate_hz)? {
                r.run.servo.filters = f;
            }
        }
    }
    let cases = jobs::run_all(&runs, case)?;
    Ok(CircleReport {
        machine: machine.map_or("host-sim/machines/gantry.toml (built in)".into(), |m| {
            m.display().to_string()
        }),
        cases,
    })
}

/// The report as a table.
pub fn table(r: &CircleReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "ISO 230-4 circular test on {} (at the tool, last full turn)",
        r.machine
    );
    let _ = writeln!(
        s,
        "{:<16} {:>6} {:>6} {:>4} {:>10} {:>10} {:>10} {:>12}",
        "circle", "R mm", "F", "dir", "G µm", "D µm", "spike µm", "contour µm"
    );
    for c in &r.cases {
        let _ = writeln!(
            s,
            "{:<16} {:>6.1} {:>6.0} {:>4} {:>10.2} {:>10.2} {:>10.2} {:>12.2}",
            c.name,
            c.radius_mm,
            c.feed_mm_min,
            c.direction,
            c.figures.circular_deviation_um,
            c.figures.radius_deviation_um,
            c.figures.reversal_spike_um,
            c.contour_max_um
        );
    }
    s
}
