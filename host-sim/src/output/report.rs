//! Terminal tables, JSON and CSV output.

use crate::engine::RunResult;
use crate::studies::paper::{PaperInfo, PaperReport};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;

/// Fixed-point for ordinary values, scientific for the tiny ones the sliding-mode laws reach.
fn num(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-3 {
        format!("{v:.3e}")
    } else {
        format!("{v:.6}")
    }
}

fn ratio(ours: f64, paper: f64) -> String {
    if paper > 0.0 {
        format!("{:>7.2}x", ours / paper)
    } else {
        "      -".into()
    }
}

/// Table 1 and Table 3 next to the published numbers.
pub fn paper_tables(sc: &PaperInfo, r: &PaperReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Table 1 (single axis, {} mode, controller in {}): ITSE 0-{} s nominal; robustness = ITSE {}-{} s with +{} on θ'' from {} s",
        sc.mode,
        sc.numeric,
        sc.t1_horizon_s,
        sc.robustness_window_s[0],
        sc.robustness_window_s[1],
        sc.disturbance.1,
        sc.disturbance.2
    );
    for (title, table) in [("unit step", &r.table1_step), ("sin t", &r.table1_sine)] {
        let _ = writeln!(s, "  reference: {title}");
        let _ = writeln!(
            s,
            "  {:<6} {:>12} {:>12} {:>8} | {:>12} {:>12} {:>8} | {:>12}",
            "method", "ITSE", "paper", "ratio", "robustness", "paper", "ratio", "TV(u)/s"
        );
        for l in &sc.t1_laws {
            let Some(row) = table.get(l) else {
                continue;
            };
            let p = sc.published.table1.get(l);
            let _ = writeln!(
                s,
                "  {:<6} {:>12} {:>12} {} | {:>12} {:>12} {} | {:>12.1}",
                l,
                num(row.itse),
                p.map(|p| format!("{:.6}", p.itse)).unwrap_or_default(),
                p.map(|p| ratio(row.itse, p.itse)).unwrap_or_default(),
                num(row.robustness),
                p.map(|p| format!("{:.6}", p.robustness))
                    .unwrap_or_default(),
                p.map(|p| ratio(row.robustness, p.robustness))
                    .unwrap_or_default(),
                row.tv_u_per_s
            );
        }
    }
    for (title, table) in [
        (
            "no disturbance: the runs the published table matches".to_string(),
            &r.table3,
        ),
        (
            format!(
                "with +{} on axis {} from {} s, as in the paper's Figs. 10/14",
                sc.disturbance.1, sc.disturbance.0, sc.disturbance.2
            ),
            &r.table3_disturbed,
        ),
    ] {
        let _ = writeln!(
            s,
            "\nTable 3 (helix, λ = {}, ITSE per axis, {title}); contour error from t = {} s",
            sc.lambda, sc.contour_from_s
        );
        let _ = writeln!(
            s,
            "  {:<12} {:>10} {:>10} {:>10} | {:>10} {:>10} {:>10} | {:>11} {:>11}",
            "method", "x", "y", "z", "paper x", "paper y", "paper z", "contour max", "contour rms"
        );
        for name in &sc.law_order {
            let Some(row) = table.get(name) else { continue };
            let p = sc.published.table3.get(name);
            let f = |v: Option<f64>| v.map(|v| format!("{v:.6}")).unwrap_or_else(|| "-".into());
            let _ = writeln!(
                s,
                "  {:<12} {:>10} {:>10} {:>10} | {:>10} {:>10} {:>10} | {:>11.3e} {:>11.3e}",
                name,
                num(row.x),
                num(row.y),
                num(row.z),
                f(p.map(|p| p.x)),
                f(p.map(|p| p.y)),
                f(p.map(|p| p.z)),
                row.contour_max,
                row.contour_rms
            );
        }
    }
    if !r.table3_discrete.is_empty() {
        let _ = writeln!(
            s,
            "\nTable 3 as the firmware runs it: {}, no disturbance",
            sc.discrete
        );
        let _ = writeln!(
            s,
            "  {:<12} {:<9} {:>10} {:>10} {:>10} | {:>11} {:>11}",
            "method", "numeric", "x", "y", "z", "contour max", "contour rms"
        );
        for name in &sc.law_order {
            for (numeric, table) in &r.table3_discrete {
                let Some(row) = table.get(name) else { continue };
                let _ = writeln!(
                    s,
                    "  {:<12} {:<9} {:>10} {:>10} {:>10} | {:>11.3e} {:>11.3e}",
                    name,
                    numeric,
                    num(row.x),
                    num(row.y),
                    num(row.z),
                    row.contour_max,
                    row.contour_rms
                );
            }
        }
    }
    s
}

/// Write `value` as pretty JSON to `path` (creating its folder), naming the path on error.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    (|| -> Result<()> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create {}", dir.display()))?;
        }
        Ok(std::fs::write(path, text)?)
    })()
    .with_context(|| format!("cannot write {}", path.display()))
}

/// One CSV per run: time, reference, position, control, sliding variables, model contour error.
pub fn write_trace_csv(path: &Path, r: &RunResult) -> Result<()> {
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("cannot write {}", path.display()))?;
    w.write_record([
        "t_s",
        "ref_x",
        "ref_y",
        "ref_z",
        "pos_x",
        "pos_y",
        "pos_z",
        "u_x",
        "u_y",
        "u_z",
        "s_x",
        "s_y",
        "s_z",
        "contour_x",
        "contour_y",
        "contour_z",
    ])?;
    let tr = &r.trace;
    for k in 0..tr.t.len() {
        let mut row = vec![tr.t[k]];
        for v in [
            &tr.reference[k],
            &tr.position[k],
            &tr.u[k],
            &tr.s[k],
            &tr.contour_model[k],
        ] {
            row.extend_from_slice(v);
        }
        w.write_record(row.iter().map(|x| format!("{x:.9e}")))?;
    }
    w.flush()?;
    Ok(())
}
