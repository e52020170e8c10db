//! Figures of `host-sim identify` (PNG and SVG), one per axis: the effort measured during
//! identification against what the identified model predicts from the same motion, and
//! the friction curve (steady-state effort against velocity) with the fitted model.

use crate::output::plots::{both, register_font, Panel, Series};
use crate::studies::identify::{AxisReport, IdentifyReport};
use anyhow::Result;
use plotters::style::RGBColor;
use std::path::Path;

const MEASURED: RGBColor = RGBColor(31, 119, 180);
const MODEL: RGBColor = RGBColor(214, 39, 40);
/// Samples whose acceleration is below this count as steady (friction curve), mm/s².
const STEADY_ACCEL_MM_S2: f64 = 20.0;
/// Velocity bins of the friction curve, mm/s.
const BIN_MM_S: f64 = 5.0;

/// Acceleration of each sample by the central difference of the recorded velocity.
fn accelerations(r: &AxisReport) -> Vec<f64> {
    let s = &r.record;
    (0..s.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(s.len().saturating_sub(1)));
            let dt = s[b].t_s - s[a].t_s;
            if dt > 0.0 {
                (s[b].vel_mm_s - s[a].vel_mm_s) / dt
            } else {
                0.0
            }
        })
        .collect()
}

fn axis_figure(dir: &Path, name: &str, r: &AxisReport) -> Result<usize> {
    let Some(m) = r.identified else {
        return Ok(0);
    };
    let friction = |v: f64| {
        let c = if v > 0.0 {
            m.f_pos
        } else if v < 0.0 {
            m.f_neg
        } else {
            0.0
        };
        m.b * v + c
    };
    let acc = accelerations(r);
    let measured: Vec<(f64, f64)> = r.record.iter().map(|s| (s.t_s, s.effort_mnm)).collect();
    let predicted: Vec<(f64, f64)> = r
        .record
        .iter()
        .zip(&acc)
        .map(|(s, a)| (s.t_s, m.j * a + friction(s.vel_mm_s)))
        .collect();
    // friction curve: mean effort of the steady samples per velocity bin
    let mut bins: std::collections::BTreeMap<i64, (f64, f64, u32)> = Default::default();
    for (s, a) in r.record.iter().zip(&acc) {
        if a.abs() < STEADY_ACCEL_MM_S2 && s.vel_mm_s.abs() > 1.0 {
            let e = bins
                .entry((s.vel_mm_s / BIN_MM_S).round() as i64)
                .or_default();
            e.0 += s.vel_mm_s;
            e.1 += s.effort_mnm;
            e.2 += 1;
        }
    }
    let steady: Vec<(f64, f64)> = bins
        .values()
        .filter(|b| b.2 >= 5)
        .map(|b| (b.0 / f64::from(b.2), b.1 / f64::from(b.2)))
        .collect();
    // one line per direction: the curve jumps at rest, a line across zero would hide it
    let (backward, forward): (Vec<_>, Vec<_>) = steady.iter().partition(|p| p.0 < 0.0);
    let vmax = steady.iter().map(|p| p.0.abs()).fold(1.0, f64::max);
    let model_curve: Vec<(f64, f64)> = (-200..=200)
        .map(|k| {
            let v = vmax * f64::from(k) / 200.0;
            (v, friction(v))
        })
        .filter(|p| p.0 != 0.0)
        .collect();
    both(dir, &format!("identify_{name}"), (1000, 800), &|add| {
        add(Panel::lines(
            format!("Axis {name}: applied effort and the identified model's prediction"),
            "time (s)",
            ("effort", "mN·m"),
            vec![
                Series::new("measured (applied)", MEASURED, measured.clone()),
                Series::new("predicted: J a + B v + f±", MODEL, predicted.clone()),
            ],
        ))?;
        add(Panel::lines(
            format!("Axis {name}: friction curve (steady motion) and the fitted model"),
            "velocity (mm/s)",
            ("effort", "mN·m"),
            vec![
                Series::new("measured, binned mean (forward)", MEASURED, forward.clone()),
                Series::new(
                    "measured, binned mean (backward)",
                    MEASURED,
                    backward.clone(),
                ),
                Series::new("model B v + f±", MODEL, model_curve.clone()),
            ],
        ))
    })
}

/// Every axis' figure into `dir`; the number of files written.
pub fn figures(dir: &Path, r: &IdentifyReport) -> Result<usize> {
    register_font()?;
    let mut n = 0;
    for (name, a) in &r.axes {
        n += axis_figure(dir, name, a)?;
    }
    Ok(n)
}
