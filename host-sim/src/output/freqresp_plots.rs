//! Bode plots of `host-sim freqresp` (PNG and SVG), one per axis: the measured response
//! from effort to encoder (magnitude in dB re 1 mm/(mN·m), phase in degrees) against
//! frequency on a log axis, the rigid-body line `1/(J s² + B s)` the mode finder fitted,
//! and the resonances (red) and anti-resonances (blue) it found, each marked with its
//! frequency and damping.

use crate::output::plots::{axis_figures, bode_chart, bode_legend, err, AxisFigure};
use crate::studies::freqresp::{AxisResponse, FreqRespReport, ModeJson};
use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Where a frequency-response report goes: the flags `cargo sim freqresp` and `gantry
/// freqresp` share.
#[derive(Clone, Debug, clap::Args)]
pub struct FreqRespOutput {
    /// Also write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Where the Bode plots go (`freqresp_<axis>.png` and `.svg`).
    #[arg(long, default_value = "out/freqresp")]
    pub out: PathBuf,
    /// No plots.
    #[arg(long)]
    pub no_plots: bool,
}

impl FreqRespOutput {
    /// Write `r`'s JSON (when asked) and its Bode plots (unless `no_plots`), saying where.
    pub fn write(&self, r: &FreqRespReport) -> Result<()> {
        if let Some(j) = &self.json {
            crate::output::report::write_json(j, r)?;
            println!("JSON: {}", j.display());
        }
        if !self.no_plots {
            std::fs::create_dir_all(&self.out)
                .with_context(|| format!("cannot create {}", self.out.display()))?;
            let n = figures(&self.out, r)?;
            println!("{n} figures (PNG + SVG) in {}", self.out.display());
        }
        Ok(())
    }
}

const MEASURED: RGBColor = RGBColor(31, 119, 180);
const RIGID: RGBColor = RGBColor(127, 127, 127);
const RESONANCE: RGBColor = RGBColor(214, 39, 40);
const ANTI: RGBColor = RGBColor(44, 160, 44);
const SIZE: (u32, u32) = (1000, 800);

/// The rigid-body line at `f`: (dB, degrees).
fn rigid(a: &AxisResponse, f: f64) -> (f64, f64) {
    let w = 2.0 * std::f64::consts::PI * f;
    // 1/(-J ω² + j B ω)
    let (re, im) = (-a.inertia * w * w, a.viscous * w);
    let m2 = re * re + im * im;
    // (in (-360, 0], as the study unwraps the measured phase)
    let mut deg = (-im).atan2(re).to_degrees();
    if deg > 0.0 {
        deg -= 360.0;
    }
    (-10.0 * m2.max(1e-300).log10(), deg)
}

/// Lower and upper bound of `v`, padded by 5 % of the span (and at least `min_span`).
fn range(v: impl Iterator<Item = f64>, min_span: f64) -> (f64, f64) {
    let (lo, hi) = v.fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(x), h.max(x)));
    let span = (hi - lo).max(min_span);
    let mid = 0.5 * (lo + hi);
    (mid - 0.55 * span, mid + 0.55 * span)
}

fn label(kind: &str, m: &ModeJson) -> String {
    format!(
        "{kind} {:.1} Hz, ζ {:.3}, {:+.1} dB",
        m.freq_hz, m.damping_ratio, m.peak_db
    )
}

/// One panel: the measured curve (`pick` of each point), the rigid line, the modes.
#[allow(clippy::too_many_arguments)]
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    y_desc: &str,
    a: &AxisResponse,
    measured: Vec<(f64, f64)>,
    rigid_line: Vec<(f64, f64)>,
    y: (f64, f64),
    legend: bool,
) -> Result<()> {
    let f_lo = a.points.first().map_or(1.0, |p| p.freq_hz);
    let f_hi = a.points.last().map_or(10.0, |p| p.freq_hz).max(f_lo * 1.01);
    let mut chart = bode_chart(area, title, y_desc, (f_lo, f_hi), y)?;
    chart
        .draw_series(DashedLineSeries::new(
            rigid_line,
            6,
            4,
            RIGID.stroke_width(1),
        ))
        .map_err(err)?
        .label("rigid-body line 1/(J s² + B s)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RIGID));
    chart
        .draw_series(LineSeries::new(measured.clone(), MEASURED.stroke_width(1)))
        .map_err(err)?
        .label("measured (servo, stepped sine)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], MEASURED));
    chart
        .draw_series(
            measured
                .iter()
                .map(|p| Circle::new(*p, 2, MEASURED.filled())),
        )
        .map_err(err)?;
    for (modes, colour, kind) in [
        (&a.resonances, RESONANCE, "resonance"),
        (&a.anti_resonances, ANTI, "anti-resonance"),
    ] {
        for m in modes {
            let f = m.freq_hz.clamp(f_lo, f_hi);
            let s = chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(f, y.0), (f, y.1)],
                    colour.stroke_width(1),
                )))
                .map_err(err)?;
            if legend {
                s.label(label(kind, m))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            }
        }
    }
    if legend {
        bode_legend(&mut chart)?;
    }
    Ok(())
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    name: &str,
    a: &AxisResponse,
) -> Result<()> {
    root.fill(&WHITE).map_err(err)?;
    let (top, bottom) = root.split_vertically(SIZE.1 / 2);
    let f_lo = a.points.first().map_or(1.0, |p| p.freq_hz);
    let f_hi = a.points.last().map_or(10.0, |p| p.freq_hz);
    let grid: Vec<f64> = (0..=400)
        .map(|k| f_lo * (f_hi / f_lo).powf(f64::from(k) / 400.0))
        .collect();
    let mag: Vec<(f64, f64)> = a
        .points
        .iter()
        .map(|p| (p.freq_hz, p.magnitude_db))
        .collect();
    let phase: Vec<(f64, f64)> = a.points.iter().map(|p| (p.freq_hz, p.phase_deg)).collect();
    let rigid_mag: Vec<(f64, f64)> = grid.iter().map(|&f| (f, rigid(a, f).0)).collect();
    let rigid_phase: Vec<(f64, f64)> = grid.iter().map(|&f| (f, rigid(a, f).1)).collect();
    let y_mag = range(mag.iter().chain(&rigid_mag).map(|p| p.1), 10.0);
    let y_phase = range(phase.iter().chain(&rigid_phase).map(|p| p.1), 30.0);
    panel(
        &top,
        &format!("Axis {name}: effort to encoder, magnitude"),
        "|H| (dB re 1 mm/(mN·m))",
        a,
        mag,
        rigid_mag,
        y_mag,
        true,
    )?;
    panel(
        &bottom,
        &format!("Axis {name}: effort to encoder, phase"),
        "arg H (deg)",
        a,
        phase,
        rigid_phase,
        y_phase,
        false,
    )
}

impl AxisFigure for AxisResponse {
    fn drawable(&self) -> bool {
        self.points.len() >= 2
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, name: &str) -> Result<()> {
        draw(root, name, self)
    }
}

/// Every axis' plot into `dir` as `freqresp_<axis>.png` and `.svg`; the number of files
/// written.
pub fn figures(dir: &Path, r: &FreqRespReport) -> Result<usize> {
    axis_figures(dir, "freqresp", SIZE, &r.axes)
}
