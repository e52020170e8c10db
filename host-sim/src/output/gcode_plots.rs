//! Figures of `host-sim gcode` (PNG and SVG): the tool path (top view and side view)
//! coloured by the contour error, the feed ratio along the path, and each axis' planned
//! velocity and acceleration against the planner's limits.

use crate::gcode::report::GcodeReport;
use crate::output::plots::{both, register_font, Panel, Series};
use anyhow::Result;
use plotters::style::RGBColor;
use std::path::Path;

const AXIS_COLORS: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
];
const LIMIT: RGBColor = RGBColor(90, 90, 90);
const AXES: [&str; 3] = ["x", "y", "z"];

/// Every figure into `dir`; the number of files written.
pub fn figures(dir: &Path, r: &GcodeReport) -> Result<usize> {
    register_font()?;
    let t = &r.trace;
    let scale = t.contour_mm.iter().copied().fold(0.0, f64::max);
    let colour = (
        format!(
            "contour error (µm), blue 0 to red {:.2} (max of the run {:.2})",
            scale * 1e3,
            r.contour_max_mm * 1e3
        ),
        scale * 1e3,
    );
    let coloured = |a: usize, b: usize| -> Vec<(f64, f64, f64)> {
        t.pos_mm
            .iter()
            .zip(&t.contour_mm)
            .map(|(p, c)| (p[a], p[b], *c))
            .collect()
    };
    let mut n = both(dir, "path", (1000, 1400), &|add| {
        add(Panel::Coloured {
            title: format!("{}: tool path (top view, equal scales)", r.program),
            xl: "x (mm)".into(),
            yl: "y (mm)".into(),
            points: coloured(0, 1),
            rapid: t.rapid.clone(),
            scale,
            colour: colour.clone(),
        })?;
        add(Panel::Coloured {
            title: "tool path (side view, equal scales)".into(),
            xl: "x (mm)".into(),
            yl: "z (mm)".into(),
            points: coloured(0, 2),
            rapid: t.rapid.clone(),
            scale,
            colour: colour.clone(),
        })
    })?;
    n += both(dir, "feed", (1000, 500), &|add| {
        add(Panel::lines(
            format!(
                "feed ratio along the path (path speed / achievable feed, 0 on rapids; mean {:.3} on feed moves)",
                r.feed_ratio_mean
            ),
            "distance along the path (mm)",
            ("feed ratio", ""),
            vec![Series::new(
                "feed ratio",
                AXIS_COLORS[0],
                t.along_mm
                    .iter()
                    .copied()
                    .zip(t.feed_ratio.iter().copied())
                    .collect(),
            )],
        ))
    })?;
    let limits = r.limits;
    n += both(dir, "axes", (1000, 1600), &|add| {
        for (i, name) in AXES.iter().enumerate() {
            let span = (
                t.t_s.first().copied().unwrap_or(0.0),
                t.t_s.last().copied().unwrap_or(1.0),
            );
            let band = |v: f64| {
                vec![
                    Series::new(format!("limit ±{v}"), LIMIT, vec![(span.0, v), (span.1, v)])
                        .dashed(),
                    Series::new("", LIMIT, vec![(span.0, -v), (span.1, -v)]).dashed(),
                ]
            };
            let mut vs = vec![Series::new(
                format!("{name} velocity"),
                AXIS_COLORS[i],
                t.t_s
                    .iter()
                    .zip(&t.vel_mm_s)
                    .map(|(t, v)| (*t, v[i]))
                    .collect(),
            )];
            vs.extend(band(limits.vel[i]));
            add(Panel::lines(
                format!("axis {name}: planned velocity against the limit"),
                "time (s)",
                (&format!("v_{name}"), "mm/s"),
                vs,
            ))?;
            let mut acc = vec![Series::new(
                format!("{name} acceleration"),
                AXIS_COLORS[i],
                t.t_s
                    .iter()
                    .zip(&t.acc_mm_s2)
                    .map(|(t, a)| (*t, a[i]))
                    .collect(),
            )];
            acc.extend(band(limits.acc[i]));
            add(Panel::lines(
                format!("axis {name}: planned acceleration against the limit"),
                "time (s)",
                (&format!("a_{name}"), "mm/s²"),
                acc,
            ))?;
        }
        Ok(())
    })?;
    Ok(n)
}
