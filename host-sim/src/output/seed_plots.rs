//! Figures of `host-sim seeds` (PNG and SVG, the paper figures' style and helpers from
//! [`crate::output::plots`]): the adaptive law's estimates converging to the truth, the tracking
//! error at velocity reversals with and without adaptation, and the XY contours of the
//! circle and the square with and without the patent's cross-coupling.

use crate::engine::RunResult;
use crate::output::plots::{both, register_font, Panel, Series};
use crate::studies::seeds::{SeedsReport, ESTIMATE_NAMES};
use anyhow::Result;
use plotters::style::{RGBColor, BLACK};
use std::path::Path;

/// Magnification of the deviation from the path in the XY contour plots: 20 µm of
/// contour error on a 20 mm circle becomes 10 mm on the plot.
pub const CONTOUR_MAGNIFICATION: f64 = 500.0;

/// Start of the reversal-error figure's window (s): the last 2 s of the 8 s friction
/// run, the window of the reversal metric (seeds_friction.toml `reversal_from_s`).
const REVERSAL_PLOT_FROM_S: f64 = 6.0;
/// Length of the reversal-error figure's window: one 2 Hz period, so the four
/// reversals of X and Y are readable.
const REVERSAL_PLOT_LEN_S: f64 = 0.5;

const AXIS_COLORS: [RGBColor; 2] = [RGBColor(31, 119, 180), RGBColor(214, 39, 40)];

/// Colour of a seed law; the coupled variant (`+ccc`) is darker.
fn seed_color(law: &str) -> RGBColor {
    let coupled = law.ends_with("+ccc");
    match (law.trim_end_matches("+ccc"), coupled) {
        ("PID", false) => RGBColor(255, 152, 150),
        ("PID", true) => RGBColor(214, 39, 40),
        ("DSMC", false) => RGBColor(152, 223, 138),
        ("DSMC", true) => RGBColor(44, 160, 44),
        ("DOB-SMC", false) => RGBColor(255, 187, 120),
        ("DOB-SMC", true) => RGBColor(230, 85, 13),
        ("SMC", _) => RGBColor(31, 119, 180),
        ("ASMC", _) => RGBColor(255, 127, 14),
        _ => RGBColor(127, 127, 127),
    }
}

fn trace<'a>(rep: &'a SeedsReport, name: &str) -> Option<&'a RunResult> {
    rep.traces.iter().find(|(n, _)| n == name).map(|(_, r)| r)
}

/// Error `p_ref - p` in the XY plane with its component along the reference's direction
/// of motion removed (the normal, i.e. contour, part). Where the reference stands still
/// (the square's corners) the whole error is kept.
fn normal_error(r: &RunResult, k: usize) -> (f64, f64) {
    let tr = &r.trace;
    let e = (
        tr.reference[k][0] - tr.position[k][0],
        tr.reference[k][1] - tr.position[k][1],
    );
    let (a, b) = (k.saturating_sub(1), (k + 1).min(tr.t.len() - 1));
    let d = (
        tr.reference[b][0] - tr.reference[a][0],
        tr.reference[b][1] - tr.reference[a][1],
    );
    let n2 = d.0 * d.0 + d.1 * d.1;
    if n2 < 1e-18 {
        return e;
    }
    let along = (e.0 * d.0 + e.1 * d.1) / n2;
    (e.0 - along * d.0, e.1 - along * d.1)
}

/// All seed figures; returns the number of files written.
pub fn seed_figures(dir: &Path, rep: &SeedsReport) -> Result<usize> {
    register_font()?;
    Ok(estimates_figure(dir, rep)? + reversals_figure(dir, rep)? + contour_figures(dir, rep)?)
}

/// The adaptive SMC's estimates against the truth (none without estimates).
fn estimates_figure(dir: &Path, rep: &SeedsReport) -> Result<usize> {
    let mut files = 0;
    if !rep.estimates.is_empty() {
        files += both(dir, "seeds_estimates", (1000, 1400), &|add| {
            let units = ["mN·m/(mm/s²)", "mN·m/(mm/s)", "mN·m", "mN·m"];
            for (p, name) in ESTIMATE_NAMES.iter().enumerate() {
                let mut series = Vec::new();
                for (i, ax) in ["x", "y"].iter().enumerate() {
                    let Some(truth) = rep
                        .adaptation
                        .get(*ax)
                        .and_then(|m| m.get(*name))
                        .map(|e| e.truth)
                    else {
                        continue;
                    };
                    series.push(Series::new(
                        format!("{ax} estimate"),
                        AXIS_COLORS[i],
                        rep.estimates.iter().map(|e| (e.t, e.axes[i][p])).collect(),
                    ));
                    let t_end = rep.estimates.last().map_or(1.0, |e| e.t);
                    series.push(
                        Series::new(
                            format!("{ax} truth"),
                            AXIS_COLORS[i],
                            vec![(0.0, truth), (t_end, truth)],
                        )
                        .dashed(),
                    );
                }
                add(Panel::lines(
                    format!("Adaptive SMC: {name} estimate vs truth (friction_sine)"),
                    "t (s)",
                    (name, units[p]),
                    series,
                ))?;
            }
            Ok(())
        })?;
    }
    Ok(files)
}

/// The tracking error at the sine's reversals, fixed against adaptive SMC.
fn reversals_figure(dir: &Path, rep: &SeedsReport) -> Result<usize> {
    let mut files = 0;
    let runs: Vec<(&str, &RunResult)> = ["SMC", "ASMC"]
        .iter()
        .filter_map(|l| trace(rep, &format!("friction_sine_{l}")).map(|r| (*l, r)))
        .collect();
    if !runs.is_empty() {
        files += both(dir, "seeds_reversals", (1000, 900), &|add| {
            for (i, ax) in ["x", "y"].iter().enumerate() {
                let series = runs
                    .iter()
                    .map(|(law, r)| {
                        Series::new(
                            if *law == "SMC" {
                                "fixed SMC"
                            } else {
                                "adaptive SMC"
                            },
                            seed_color(law),
                            (0..r.trace.t.len())
                                .filter(|&k| {
                                    let t = r.trace.t[k];
                                    (REVERSAL_PLOT_FROM_S
                                        ..REVERSAL_PLOT_FROM_S + REVERSAL_PLOT_LEN_S)
                                        .contains(&t)
                                })
                                .map(|k| {
                                    let e = r.trace.reference[k][i] - r.trace.position[k][i];
                                    (r.trace.t[k], e * 1e3)
                                })
                                .collect(),
                        )
                    })
                    .collect();
                add(Panel::lines(
                    format!(
                        "Tracking error e_{ax} after convergence: reversals at the peaks of the 2 Hz sine"
                    ),
                    "t (s)",
                    (&format!("e_{ax}"), "µm"),
                    series,
                ))?;
            }
            Ok(())
        })?;
    }
    Ok(files)
}

/// The contours of the circle and the square, with and without cross-coupling.
fn contour_figures(dir: &Path, rep: &SeedsReport) -> Result<usize> {
    let mut files = 0;
    for sc in ["circle", "square"] {
        let laws: Vec<(String, &RunResult)> = ["PID", "DSMC", "DOB-SMC"]
            .iter()
            .flat_map(|l| [l.to_string(), format!("{l}+ccc")])
            .filter_map(|l| trace(rep, &format!("{sc}_{l}")).map(|r| (l, r)))
            .collect();
        let Some((_, first)) = laws.first() else {
            continue;
        };
        let reference: Vec<(f64, f64)> =
            first.trace.reference.iter().map(|p| (p[0], p[1])).collect();
        files += both(dir, &format!("seeds_contour_{sc}"), (1000, 1600), &|add| {
            for base in ["DOB-SMC", "PID"] {
                let mut series = vec![Series::new("reference", BLACK, reference.clone())];
                for (l, r) in laws
                    .iter()
                    .filter(|(l, _)| l.trim_end_matches("+ccc") == base)
                {
                    series.push(Series::new(
                        l.clone(),
                        seed_color(l),
                        (0..r.trace.t.len())
                            .map(|k| {
                                let (ex, ey) = normal_error(r, k);
                                let p = r.trace.reference[k];
                                (
                                    p[0] - CONTOUR_MAGNIFICATION * ex,
                                    p[1] - CONTOUR_MAGNIFICATION * ey,
                                )
                            })
                            .collect(),
                    ));
                }
                add(Panel::path(
                    format!(
                        "{sc}, {base} with/without cross-coupling: contour deviation ×{CONTOUR_MAGNIFICATION} (load step on X at 1.5 s)"
                    ),
                    "x (mm)",
                    ("y", "mm"),
                    series,
                ))?;
            }
            let series = laws
                .iter()
                .map(|(l, r)| {
                    Series::new(
                        l.clone(),
                        seed_color(l),
                        (0..r.trace.t.len())
                            .map(|k| {
                                let (ex, ey) = normal_error(r, k);
                                (r.trace.t[k], (ex * ex + ey * ey).sqrt() * 1e3)
                            })
                            .collect(),
                    )
                })
                .collect();
            add(Panel::lines(
                format!("{sc}: contour error (normal part of the XY error)"),
                "t (s)",
                ("|ε|", "µm"),
                series,
            )
            .log_auto())
        })?;
    }
    Ok(files)
}
