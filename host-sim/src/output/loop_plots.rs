//! Bode plots of `host-sim filters` (PNG and SVG), one per axis: the open loop
//! `L = C·F·P` measured on the running machine, without the output filters and (when
//! some were placed) with them, gain in dB and phase in degrees against frequency on a
//! log axis, with the 0 dB and −180° lines the margins are read at, and the axis'
//! measured resonances marked. `gantry tune`'s loop, measured on a machine over the link,
//! is drawn the same way ([`tune_figures`]).

use crate::cli::tune::TuneReport;
use crate::output::plots::{axis_figures, bode_chart, bode_legend, err, AxisFigure};
use crate::studies::filters::{AxisFilters, FiltersReport, LoopJson};
use anyhow::Result;
use controller_core::filter::FilterConfig;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

const WITHOUT: RGBColor = RGBColor(31, 119, 180);
const WITH: RGBColor = RGBColor(255, 127, 14);
const REFERENCE: RGBColor = RGBColor(127, 127, 127);
const RESONANCE: RGBColor = RGBColor(214, 39, 40);
const SIZE: (u32, u32) = (1000, 800);

/// A curve: its legend and its points (frequency, value).
struct Curve {
    label: String,
    colour: RGBColor,
    points: Vec<(f64, f64)>,
}

fn label(what: &str, l: &LoopJson) -> String {
    match &l.margins {
        Some(m) => format!(
            "{what}: crossover {:.1} Hz, gain margin {:.1} dB, phase margin {:.1}°",
            m.gain_crossover_hz.unwrap_or(f32::NAN),
            m.gain_margin_db.min(m.lower_gain_margin_db),
            m.phase_margin_deg
        ),
        None => format!("{what}: no margins"),
    }
}

/// The curves of one panel: `pick` 1 (gain) or 2 (phase) of each loop's points.
fn curves(a: &AxisFilters, pick: usize) -> Vec<Curve> {
    let mut out = vec![Curve {
        label: label("without filters", &a.without),
        colour: WITHOUT,
        points: a
            .without
            .points
            .iter()
            .map(|p| (f64::from(p[0]), f64::from(p[pick])))
            .collect(),
    }];
    if let Some(w) = &a.with {
        out.push(Curve {
            label: label("with the filters", w),
            colour: WITH,
            points: w
                .points
                .iter()
                .map(|p| (f64::from(p[0]), f64::from(p[pick])))
                .collect(),
        });
    }
    out
}

/// One panel: the curves, the horizontal line `at` the margins are read on, the modes.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    y_desc: &str,
    a: &AxisFilters,
    curves: &[Curve],
    at: f64,
) -> Result<()> {
    let all = || curves.iter().flat_map(|c| c.points.iter());
    let (f_lo, f_hi) = all().fold((f64::MAX, f64::MIN), |(l, h), p| (l.min(p.0), h.max(p.0)));
    let (y_lo, y_hi) = all().fold((at, at), |(l, h), p| (l.min(p.1), h.max(p.1)));
    let pad = 0.05 * (y_hi - y_lo).max(10.0);
    let y = ((y_lo - pad), (y_hi + pad));
    let mut chart = bode_chart(area, title, y_desc, (f_lo, f_hi), y)?;
    chart
        .draw_series(DashedLineSeries::new(
            vec![(f_lo, at), (f_hi, at)],
            6,
            4,
            REFERENCE.stroke_width(1),
        ))
        .map_err(err)?;
    for m in &a.resonances {
        let f = m.freq_hz.clamp(f_lo, f_hi);
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(f, y_lo - pad), (f, y_hi + pad)],
                RESONANCE.stroke_width(1),
            )))
            .map_err(err)?;
    }
    for c in curves {
        let colour = c.colour;
        chart
            .draw_series(LineSeries::new(c.points.clone(), colour.stroke_width(2)))
            .map_err(err)?
            .label(c.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
    }
    bode_legend(&mut chart)
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    name: &str,
    a: &AxisFilters,
) -> Result<()> {
    root.fill(&WHITE).map_err(err)?;
    let (top, bottom) = root.split_vertically(SIZE.1 / 2);
    panel(
        &top,
        &format!("Axis {name}: open loop C·F·P measured on the machine, gain (red: resonances)"),
        "|L| (dB)",
        a,
        &curves(a, 1),
        0.0,
    )?;
    panel(
        &bottom,
        &format!("Axis {name}: open loop, phase"),
        "arg L (deg)",
        a,
        &curves(a, 2),
        -180.0,
    )
}

impl AxisFigure for AxisFilters {
    fn drawable(&self) -> bool {
        self.without.points.len() >= 2
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, name: &str) -> Result<()> {
        draw(root, name, self)
    }
}

/// Every axis' plot into `dir` as `loop_<axis>.png` and `.svg`; the number of files
/// written.
pub fn figures(dir: &Path, r: &FiltersReport) -> Result<usize> {
    axis_figures(dir, "loop", SIZE, &r.axes)
}

/// `gantry tune`'s loop without and with its notches into `dir` as `loop_<axis>.png` and
/// `.svg` (none when the loop was not measured); the number of files written.
pub fn tune_figures(dir: &Path, r: &TuneReport) -> Result<usize> {
    let Some(without) = r.loop_without.clone() else {
        return Ok(0);
    };
    let axis = AxisFilters {
        resonances: r.response.resonances.clone(),
        without,
        placed: r
            .notches_placed
            .iter()
            .map(|n| FilterConfig::Notch {
                freq_hz: n.freq_hz,
                width_hz: n.width_hz,
                depth_db: n.depth_db,
            })
            .collect(),
        near_bandwidth: u8::try_from(r.in_band_resonances).unwrap_or(u8::MAX),
        with: r.loop_with.clone(),
        verdict: r.notch_verdict.clone(),
    };
    let report = FiltersReport {
        machine: "the machine over the link".into(),
        axes: [(r.axis.clone(), axis)].into_iter().collect(),
    };
    figures(dir, &report)
}
