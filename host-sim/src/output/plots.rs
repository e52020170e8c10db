//! Figures (PNG and SVG) equivalent to the paper's: the 3-D helix and its top view,
//! per-axis tracking errors, control inputs, contour error, single-axis responses.
//!
//! Text is drawn with the bundled DejaVu Sans (`host-sim/assets`), registered at start-up,
//! so plots render on a machine without any system font packages.

use crate::engine::RunResult;
use crate::studies::paper::{PaperInfo, PaperReport};
use anyhow::{anyhow, Context, Result};
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

pub(crate) fn register_font() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut res = Ok(());
    ONCE.call_once(|| {
        res = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| anyhow!("the bundled font could not be loaded"));
    });
    res
}

fn law_color(name: &str) -> RGBColor {
    match name {
        "PID" => RGBColor(214, 39, 40),
        "SMC" => RGBColor(31, 119, 180),
        "DSMC" => RGBColor(44, 160, 44),
        _ => RGBColor(255, 127, 14),
    }
}

pub(crate) fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// The paper's length unit: its plant `θ'' = -10θ' - θ + u` is normalised, it names none.
pub(crate) const PAPER_LEN: &str = "norm. unit";
/// The paper's control input: with b = 1 it is an acceleration in that unit.
pub(crate) const PAPER_U: &str = "norm. unit/s²";

/// A y axis is drawn as log10 |value| when its series span more than this many decades
/// ([`decades_spanned`]).
pub(crate) const LOG_DECADES: f64 = 2.0;
/// The log axis reaches at most this many decades below the largest value.
const LOG_MAX_DECADES: f64 = 10.0;

const TITLE_FONT: u32 = 18;
const LABEL_FONT: u32 = 12;
const DESC_FONT: u32 = 14;
const LEGEND_FONT: u32 = 13;
/// Length of a legend's line sample and the gaps around it, pixels.
const SWATCH_PX: i32 = 22;
const LEGEND_PAD_PX: i32 = 8;

/// A figure's contents: called with a sink that takes its panels in order.
pub(crate) type Draw<'a> = &'a dyn Fn(&mut dyn FnMut(Panel) -> Result<()>) -> Result<()>;

/// A named, coloured 3-D path.
pub(crate) type Path3 = (String, RGBColor, Vec<(f64, f64, f64)>);

type Chart2d<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// One named series of (x, y) points; an empty name keeps it out of the legend.
pub(crate) struct Series {
    pub(crate) name: String,
    pub(crate) color: RGBColor,
    pub(crate) points: Vec<(f64, f64)>,
    /// Drawn dashed (limits, rapids), solid otherwise.
    pub(crate) dashed: bool,
}

impl Series {
    pub(crate) fn new(name: impl Into<String>, color: RGBColor, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            color,
            points,
            dashed: false,
        }
    }

    pub(crate) fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }
}

/// How a panel's y axis is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum YScale {
    Linear,
    /// log10 |y| when the series span more than [`LOG_DECADES`] decades, else linear.
    Auto,
}

/// Decades between the largest |y| of all series and the smallest typical |y| (the
/// median over a series' samples) of a series that is not all zero: PID's errors
/// around 1e-2 against DSMC's around 1e-6 span 4, one sine 0.15. The median ignores a
/// start-up transient within a series only if it is short: a decaying error spans the
/// decades it decays through.
pub(crate) fn decades_spanned(series: &[Series]) -> f64 {
    let mut hi = 0.0f64;
    let mut lo = f64::INFINITY;
    for s in series {
        let mut a: Vec<f64> = s
            .points
            .iter()
            .map(|p| p.1.abs())
            .filter(|v| v.is_finite())
            .collect();
        if a.is_empty() {
            continue;
        }
        a.sort_by(f64::total_cmp);
        hi = hi.max(a[a.len() - 1]);
        let median = a[a.len() / 2];
        if median > 0.0 {
            lo = lo.min(median);
        }
    }
    if hi > 0.0 && lo.is_finite() {
        (hi / lo).log10()
    } else {
        0.0
    }
}

/// The series need a log axis: they span more than [`LOG_DECADES`] decades.
pub(crate) fn wants_log(series: &[Series]) -> bool {
    decades_spanned(series) > LOG_DECADES
}

/// The series as log10 |y|, and the floor (a power of ten's exponent) where the values
/// below it (zeros included) are drawn: the decade at or under the 5th percentile of the
/// nonzero |y| (the dips of a signal through zero go no deeper), at most
/// [`LOG_MAX_DECADES`] below the largest. Also whether any was below it.
fn to_log(series: &[Series]) -> (Vec<Series>, f64, bool) {
    let mut a: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1.abs()))
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    a.sort_by(f64::total_cmp);
    let (p5, hi) = match (a.get(a.len() / 20), a.last()) {
        (Some(p), Some(h)) => (*p, *h),
        _ => (1.0, 1.0),
    };
    let floor = p5.log10().floor().max(hi.log10().ceil() - LOG_MAX_DECADES);
    let mut clipped = false;
    let out = series
        .iter()
        .map(|s| Series {
            name: s.name.clone(),
            color: s.color,
            dashed: s.dashed,
            points: s
                .points
                .iter()
                .map(|&(x, y)| {
                    let l = y.abs().log10();
                    if !(l >= floor) && !y.is_nan() {
                        clipped = true;
                    }
                    (x, if y.is_nan() { y } else { l.max(floor) })
                })
                .collect(),
        })
        .collect();
    (out, floor, clipped)
}

/// `10⁻⁶` for -6; a value between two decades as `3.2e-3`.
pub(crate) fn pow10_label(v: f64) -> String {
    if (v - v.round()).abs() < 1e-6 {
        const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
        let n = v.round() as i64;
        let mut s = String::from("10");
        if n < 0 {
            s.push('⁻');
        }
        for d in n.unsigned_abs().to_string().bytes() {
            s.push(SUP[usize::from(d - b'0')]);
        }
        s
    } else {
        format!("{:.1e}", 10f64.powf(v))
    }
}

/// The y axis' label: `name (unit)`, or `|name| (unit, log)` on a log axis; no unit is
/// `dimensionless`.
pub(crate) fn y_label(name: &str, unit: &str, log: bool) -> String {
    let unit = if unit.is_empty() {
        "dimensionless"
    } else {
        unit
    };
    match (log, name.starts_with('|')) {
        (false, _) => format!("{name} ({unit})"),
        (true, true) => format!("{name} ({unit}, log)"),
        (true, false) => format!("|{name}| ({unit}, log)"),
    }
}

fn bounds(series: &[Series]) -> ((f64, f64), (f64, f64)) {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for &(a, b) in &s.points {
            if a.is_finite() && b.is_finite() {
                x = (x.0.min(a), x.1.max(a));
                y = (y.0.min(b), y.1.max(b));
            }
        }
    }
    if !(x.0 < x.1) {
        x = if x.0.is_finite() {
            (x.0 - 1.0, x.0 + 1.0)
        } else {
            (0.0, 1.0)
        };
    }
    if !(y.0 < y.1) {
        y = if y.0.is_finite() {
            (y.0.min(0.0) - 1.0, y.1.max(0.0) + 1.0)
        } else {
            (-1.0, 1.0)
        };
    }
    (x, y)
}

fn padded((a, b): (f64, f64)) -> (f64, f64) {
    let pad = 0.05 * (b - a);
    (a - pad, b + pad)
}

/// Ranges about the data's bounds with the same length per pixel on both axes for a
/// plotting area of `w` x `h` pixels (5 % margin on the tighter axis).
pub(crate) fn equal_ranges(
    x: (f64, f64),
    y: (f64, f64),
    (w, h): (u32, u32),
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (w, h) = (f64::from(w.max(1)), f64::from(h.max(1)));
    let per_px = ((x.1 - x.0) / w).max((y.1 - y.0) / h) * 1.1;
    let per_px = if per_px > 0.0 && per_px.is_finite() {
        per_px
    } else {
        1.0 / w.min(h)
    };
    let (cx, cy) = (0.5 * (x.0 + x.1), 0.5 * (y.0 + y.1));
    let (hx, hy) = (0.5 * per_px * w, 0.5 * per_px * h);
    (cx - hx..cx + hx, cy - hy..cy + hy)
}

/// A time series thinned to what `columns` pixel columns over `x` can show: of each run
/// of consecutive points in one column, the first, the lowest, the highest and the last,
/// in their order (the drawn line is the same).
pub(crate) fn thin_columns(points: &[(f64, f64)], x: (f64, f64), columns: u32) -> Vec<(f64, f64)> {
    let cols = f64::from(columns.max(1));
    let span = x.1 - x.0;
    if points.len() <= 4 * columns as usize || span <= 0.0 {
        return points.to_vec();
    }
    let col = |p: &(f64, f64)| ((p.0 - x.0) / span * cols).floor() as i64;
    let mut out = Vec::new();
    let mut start = 0;
    while start < points.len() {
        let c = col(&points[start]);
        let mut end = start + 1;
        while end < points.len() && col(&points[end]) == c {
            end += 1;
        }
        let run = &points[start..end];
        let (mut lo, mut hi) = (0, 0);
        for (i, p) in run.iter().enumerate() {
            if p.1 < run[lo].1 {
                lo = i;
            }
            if p.1 > run[hi].1 {
                hi = i;
            }
        }
        let mut keep = [0, lo, hi, run.len() - 1];
        keep.sort_unstable();
        let mut last = usize::MAX;
        for k in keep {
            if k != last {
                out.push(run[k]);
                last = k;
            }
        }
        start = end;
    }
    out
}

/// A path thinned to one point per pixel it passes (`px`: the data's length per pixel
/// on both axes): a point within a pixel of the last kept one is dropped; the last is kept.
pub(crate) fn thin_path(points: &[(f64, f64)], px: (f64, f64)) -> Vec<(f64, f64)> {
    if px.0 <= 0.0 || px.1 <= 0.0 {
        return points.to_vec();
    }
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let keep = match out.last() {
            None => true,
            Some(q) => {
                i + 1 == points.len()
                    || ((p.0 - q.0) / px.0).abs() >= 1.0
                    || ((p.1 - q.1) / px.1).abs() >= 1.0
                    || p.0.is_nan() != q.0.is_nan()
            }
        };
        if keep {
            out.push(*p);
        }
    }
    out
}

/// What a legend entry shows before its text.
#[derive(Clone, Copy)]
pub(crate) enum Swatch {
    Line(RGBColor),
    Dashed(RGBColor),
}

/// A legend entry: its line sample and its text.
pub(crate) struct Entry {
    pub(crate) text: String,
    pub(crate) swatch: Swatch,
}

fn entries(series: &[Series]) -> Vec<Entry> {
    series
        .iter()
        .filter(|s| !s.name.is_empty())
        .map(|s| Entry {
            text: s.name.clone(),
            swatch: if s.dashed {
                Swatch::Dashed(s.color)
            } else {
                Swatch::Line(s.color)
            },
        })
        .collect()
}

fn text_width<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, text: &str, size: u32) -> u32 {
    area.estimate_text_size(text, &("sans-serif", size).into_font().into())
        .map_or(7 * text.chars().count() as u32, |s| s.0)
}

/// `text` broken at spaces into lines at most `width` pixels wide.
fn wrap<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, text: &str, width: u32) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split(' ') {
        let candidate = if line.is_empty() {
            word.to_string()
        } else {
            format!("{line} {word}")
        };
        if !line.is_empty() && text_width(area, &candidate, LEGEND_FONT) > width {
            lines.push(std::mem::replace(&mut line, word.to_string()));
        } else {
            line = candidate;
        }
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// A panel's title over the whole width (smaller type for a long one), and below it the
/// chart's area and a legend strip to its right wide enough for `texts` (at most 30 % of
/// the width; longer texts wrap). No strip without texts.
pub(crate) fn layout<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    texts: &[&str],
) -> Result<(DrawingArea<DB, Shift>, DrawingArea<DB, Shift>)> {
    let (w, _) = area.dim_in_pixel();
    let mut size = TITLE_FONT;
    while size > 11 && text_width(area, title, size) + 16 > w {
        size -= 1;
    }
    let body = area
        .margin(6, 0, 0, 0)
        .titled(title, ("sans-serif", size))
        .map_err(err)?;
    let widest = texts
        .iter()
        .map(|t| text_width(area, t, LEGEND_FONT))
        .max()
        .unwrap_or(0);
    let strip = if texts.is_empty() {
        0
    } else {
        (widest + (SWATCH_PX + 3 * LEGEND_PAD_PX) as u32).clamp(90, w * 3 / 10)
    };
    Ok(body.split_horizontally(w - strip))
}

/// The legend in its strip: one line sample and (wrapped) text per entry, then the notes;
/// returns the y (pixels in the strip) below it.
pub(crate) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[Entry],
    notes: &[String],
) -> Result<i32> {
    let (w, _) = area.dim_in_pixel();
    let text_w = (w as i32 - SWATCH_PX - 3 * LEGEND_PAD_PX).max(20) as u32;
    let font = ("sans-serif", LEGEND_FONT).into_font();
    let line_h = LEGEND_FONT as i32 + 5;
    let mut y = 20;
    let x_text = LEGEND_PAD_PX + SWATCH_PX + LEGEND_PAD_PX;
    for e in entries {
        let mid = y + line_h / 2;
        let a = (LEGEND_PAD_PX, mid);
        let b = (LEGEND_PAD_PX + SWATCH_PX, mid);
        match e.swatch {
            Swatch::Line(c) => area.draw(&PathElement::new(vec![a, b], c.stroke_width(2))),
            Swatch::Dashed(c) => {
                area.draw(&DashedPathElement::new(vec![a, b], 5, 3, c.stroke_width(2)))
            }
        }
        .map_err(err)?;
        for l in wrap(area, &e.text, text_w) {
            area.draw_text(&l, &font.color(&BLACK), (x_text, y + 2))
                .map_err(err)?;
            y += line_h;
        }
        y += 4;
    }
    for n in notes {
        y += 4;
        for l in wrap(area, n, w.saturating_sub(2 * LEGEND_PAD_PX as u32)) {
            area.draw_text(
                &l,
                &font.color(&RGBColor(80, 80, 80)),
                (LEGEND_PAD_PX, y + 2),
            )
            .map_err(err)?;
            y += line_h;
        }
    }
    Ok(y)
}

/// A 2-D chart over the ranges with the house margins (no caption: [`layout`] draws it).
fn build_2d<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
) -> Result<Chart2d<'a, DB>> {
    ChartBuilder::on(area)
        .margin(8)
        .margin_right(12)
        .x_label_area_size(42)
        .y_label_area_size(76)
        .build_cartesian_2d(x, y)
        .map_err(err)
}

/// The plotting area's size in pixels a chart on `area` gets.
fn plot_dims<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>) -> Result<(u32, u32)> {
    Ok(build_2d(area, 0.0..1.0, 0.0..1.0)?
        .plotting_area()
        .dim_in_pixel())
}

/// A chart whose x and y have the same length per pixel, about the data's bounds.
pub(crate) fn equal_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    x: (f64, f64),
    y: (f64, f64),
) -> Result<Chart2d<'a, DB>> {
    let (xr, yr) = equal_ranges(x, y, plot_dims(area)?);
    build_2d(area, xr, yr)
}

fn draw_mesh<DB: DrawingBackend>(
    chart: &mut Chart2d<'_, DB>,
    xl: &str,
    yl: &str,
    log: Option<(f64, f64)>,
) -> Result<()> {
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(xl)
        .y_desc(yl)
        .label_style(("sans-serif", LABEL_FONT))
        .axis_desc_style(("sans-serif", DESC_FONT))
        .light_line_style(RGBColor(235, 235, 235));
    let fmt = |v: &f64| pow10_label(*v);
    if let Some((lo, hi)) = log {
        // ticks at whole decades; the grid between them at 2..9 × 10ⁿ (drawn below)
        mesh.y_labels(((hi - lo).ceil() as usize + 1).max(3))
            .y_label_formatter(&fmt)
            .light_line_style(TRANSPARENT);
        mesh.draw().map_err(err)?;
        let xr = chart.x_range();
        let mut minor = Vec::new();
        for d in (lo.floor() as i64)..=(hi.ceil() as i64) {
            for k in 2..10 {
                let v = d as f64 + f64::from(k).log10();
                if v > lo && v < hi {
                    minor.push(PathElement::new(
                        vec![(xr.start, v), (xr.end, v)],
                        RGBColor(235, 235, 235),
                    ));
                }
            }
        }
        chart.draw_series(minor).map_err(err)?;
        return Ok(());
    }
    mesh.draw().map_err(err)
}

fn draw_lines<DB: DrawingBackend>(
    chart: &mut Chart2d<'_, DB>,
    s: &Series,
    points: Vec<(f64, f64)>,
) -> Result<()> {
    // width 1: plotters' bitmap backend draws wider polylines with spikes at sharp turns
    let style = s.color.stroke_width(1);
    if s.dashed {
        chart
            .draw_series(DashedLineSeries::new(points, 6, 4, style))
            .map_err(err)?;
    } else {
        chart
            .draw_series(LineSeries::new(points, style))
            .map_err(err)?;
    }
    Ok(())
}

fn line_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &LinesPanel) -> Result<()> {
    let log = !p.equal && p.scale == YScale::Auto && wants_log(&p.series);
    let mut notes = Vec::new();
    let logged;
    let (series, ylog) = if log {
        let (s, floor, clipped) = to_log(&p.series);
        if clipped {
            notes.push(format!(
                "values below {} drawn at {}",
                pow10_label(floor),
                pow10_label(floor)
            ));
        }
        logged = s;
        (&logged, Some(floor))
    } else {
        (&p.series, None)
    };
    let entries = entries(series);
    let mut texts: Vec<&str> = entries.iter().map(|e| e.text.as_str()).collect();
    texts.extend(notes.iter().map(String::as_str));
    let (chart_area, legend_area) = layout(area, &p.title, &texts)?;
    let (bx, by) = bounds(series);
    let mut chart = if p.equal {
        equal_chart(&chart_area, bx, by)?
    } else {
        let (x, y) = (bx, padded(by));
        let y = match ylog {
            Some(floor) => (floor, y.1.max(floor + 1.0)),
            None => y,
        };
        build_2d(&chart_area, x.0..x.1, y.0..y.1)?
    };
    let yl = y_label(&p.y.0, &p.y.1, log);
    let yr = chart.y_range();
    draw_mesh(&mut chart, &p.xl, &yl, ylog.map(|_| (yr.start, yr.end)))?;
    let (w, h) = chart.plotting_area().dim_in_pixel();
    let (xr, yr) = (chart.x_range(), chart.y_range());
    for s in series.iter() {
        let pts = if p.equal {
            let px = (
                (xr.end - xr.start) / f64::from(w.max(1)),
                (yr.end - yr.start) / f64::from(h.max(1)),
            );
            thin_path(&s.points, px)
        } else {
            thin_columns(&s.points, (xr.start, xr.end), w)
        };
        draw_lines(&mut chart, s, pts)?;
    }
    draw_legend(&legend_area, &entries, &notes)?;
    Ok(())
}

/// Render `draw` as `<stem>.png` and `<stem>.svg`.
pub(crate) fn both(dir: &Path, stem: &str, size: (u32, u32), draw: Draw) -> Result<usize> {
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        render(&root, draw)?;
        root.present()
            .with_context(|| format!("writing {}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        render(&root, draw)?;
        root.present()
            .with_context(|| format!("writing {}", svg.display()))?;
    }
    Ok(2)
}

/// One axis' figure drawn by hand on any backend (the Bode plots), written by
/// [`axis_figures`].
pub(crate) trait AxisFigure {
    /// Enough data to draw.
    fn drawable(&self) -> bool;
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>, name: &str) -> Result<()>;
}

/// A Bode panel's chart: log frequency against a linear value.
pub(crate) type BodeChart<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<
        plotters::coord::combinators::LogCoord<f64>,
        plotters::coord::types::RangedCoordf64,
    >,
>;

/// A Bode panel's chart: frequency `f` (Hz) on a log axis, `y` linear, its mesh drawn.
pub(crate) fn bode_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    title: &str,
    y_desc: &str,
    f: (f64, f64),
    y: (f64, f64),
) -> Result<BodeChart<'a, DB>> {
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(42)
        .y_label_area_size(70)
        .build_cartesian_2d((f.0..f.1.max(f.0 * 1.01)).log_scale(), y.0..y.1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("frequency (Hz, log)")
        .x_labels(8)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .y_desc(y_desc)
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    Ok(chart)
}

/// A Bode panel's legend, in its lower left corner.
pub(crate) fn bode_legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut BodeChart<'a, DB>,
) -> Result<()> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(200, 200, 200))
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(err)
}

/// Every axis' figure as `<stem>_<axis>.png` and `.svg` in `dir` (an axis without enough
/// data: none); the number of files written.
pub(crate) fn axis_figures<T: AxisFigure>(
    dir: &Path,
    stem: &str,
    size: (u32, u32),
    axes: &std::collections::BTreeMap<String, T>,
) -> Result<usize> {
    register_font()?;
    let mut n = 0;
    for (name, a) in axes.iter().filter(|(_, a)| a.drawable()) {
        let png = dir.join(format!("{stem}_{name}.png"));
        let svg = dir.join(format!("{stem}_{name}.svg"));
        {
            let root = BitMapBackend::new(&png, size).into_drawing_area();
            a.draw(&root, name)?;
            root.present()
                .with_context(|| format!("writing {}", png.display()))?;
        }
        {
            let root = SVGBackend::new(&svg, size).into_drawing_area();
            a.draw(&root, name)?;
            root.present()
                .with_context(|| format!("writing {}", svg.display()))?;
        }
        n += 2;
    }
    Ok(n)
}

/// Curves against a shared x axis, or an XY path at equal scales.
pub(crate) struct LinesPanel {
    title: String,
    /// x axis label with its unit, e.g. `t (s)`.
    xl: String,
    /// y quantity and unit, e.g. (`e_x`, `mm`): [`y_label`] makes the label.
    y: (String, String),
    scale: YScale,
    /// Same length per pixel on x and y (paths); never a log axis.
    equal: bool,
    series: Vec<Series>,
}

/// A figure is a vertical stack of panels, or a single 3-D view.
pub(crate) enum Panel {
    Lines(LinesPanel),
    Helix3d {
        title: String,
        /// Labels of x, y and z (vertical) with their units.
        labels: [String; 3],
        paths: Vec<Path3>,
    },
    /// A 2-D path drawn piecewise, each piece coloured by a value (blue = 0 to red =
    /// `scale`), with equal axis scales; pieces ending on a `rapid` point are drawn as a
    /// thin grey dashed line instead.
    Coloured {
        title: String,
        xl: String,
        yl: String,
        /// (x, y, value) along the path.
        points: Vec<(f64, f64, f64)>,
        /// Per point: reached by a rapid (G0) move; empty: none.
        rapid: Vec<bool>,
        scale: f64,
        /// What the colour means with its unit, e.g. "contour error (µm)", and the value
        /// of `scale` in that unit (the colour bar's top).
        colour: (String, f64),
    },
}

impl Panel {
    /// Curves on linear axes; the y axis labelled `name (unit)`.
    pub(crate) fn lines(
        title: impl Into<String>,
        xl: impl Into<String>,
        (name, unit): (&str, &str),
        series: Vec<Series>,
    ) -> Self {
        Panel::Lines(LinesPanel {
            title: title.into(),
            xl: xl.into(),
            y: (name.into(), unit.into()),
            scale: YScale::Linear,
            equal: false,
            series,
        })
    }

    /// An XY path: the same length per pixel on both axes, so a circle is round.
    pub(crate) fn path(
        title: impl Into<String>,
        xl: impl Into<String>,
        (name, unit): (&str, &str),
        series: Vec<Series>,
    ) -> Self {
        match Self::lines(title, xl, (name, unit), series) {
            Panel::Lines(mut p) => {
                p.equal = true;
                Panel::Lines(p)
            }
            other => other,
        }
    }

    /// The y axis becomes log10 |y| when the series span more than [`LOG_DECADES`] decades.
    pub(crate) fn log_auto(self) -> Self {
        match self {
            Panel::Lines(mut p) => {
                p.scale = YScale::Auto;
                Panel::Lines(p)
            }
            other => other,
        }
    }
}

fn render<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, draw: Draw) -> Result<()> {
    let mut panels = Vec::new();
    draw(&mut |p| {
        panels.push(p);
        Ok(())
    })?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (p, a) in panels.iter().zip(areas.iter()) {
        match p {
            Panel::Lines(p) => line_panel(a, p)?,
            Panel::Helix3d {
                title,
                labels,
                paths,
            } => helix_panel(a, title, labels, paths)?,
            Panel::Coloured {
                title,
                xl,
                yl,
                points,
                rapid,
                scale,
                colour,
            } => coloured_panel(a, title, (xl, yl), points, rapid, *scale, colour)?,
        }
    }
    Ok(())
}

/// Blue (0) to red (1) through green, for a value in [0, 1].
fn heat(f: f64) -> RGBColor {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let (r, g, b) = if f < 0.5 {
        (0.0, 2.0 * f, 1.0 - 2.0 * f)
    } else {
        (2.0 * f - 1.0, 2.0 - 2.0 * f, 0.0)
    };
    RGBColor((r * 220.0) as u8, (g * 180.0) as u8, (b * 220.0) as u8)
}

const RAPID: RGBColor = RGBColor(150, 150, 150);

#[allow(clippy::too_many_arguments)]
fn coloured_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    (xl, yl): (&str, &str),
    points: &[(f64, f64, f64)],
    rapid: &[bool],
    scale: f64,
    (what, top): &(String, f64),
) -> Result<()> {
    let is_rapid = |k: usize| rapid.get(k).copied().unwrap_or(false);
    let any_rapid = (0..points.len()).any(is_rapid);
    let mut legend = vec![Entry {
        text: "cut (G1/G2/G3), coloured by the bar below".into(),
        swatch: Swatch::Line(heat(0.0)),
    }];
    if any_rapid {
        legend.push(Entry {
            text: "rapid (G0), dashed grey".into(),
            swatch: Swatch::Dashed(RAPID),
        });
    }
    let texts: Vec<&str> = legend
        .iter()
        .map(|e| e.text.as_str())
        .chain([what.as_str()])
        .collect();
    let (chart_area, legend_area) = layout(area, title, &texts)?;
    let xy: Vec<Series> = vec![Series::new(
        "",
        BLACK,
        points.iter().map(|p| (p.0, p.1)).collect(),
    )];
    let (bx, by) = bounds(&xy);
    let mut chart = equal_chart(&chart_area, bx, by)?;
    draw_mesh(&mut chart, xl, yl, None)?;
    let inv = if scale > 0.0 { 1.0 / scale } else { 0.0 };
    // the rapids as dashed polylines, the cuts piece by piece in their colour
    let mut k = 1;
    while k < points.len() {
        if is_rapid(k) {
            let start = k - 1;
            while k < points.len() && is_rapid(k) {
                k += 1;
            }
            chart
                .draw_series(std::iter::once(DashedPathElement::new(
                    points[start..k].iter().map(|p| (p.0, p.1)),
                    6,
                    4,
                    RAPID.stroke_width(1),
                )))
                .map_err(err)?;
        } else {
            let w = (points[k - 1], points[k]);
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(w.0 .0, w.0 .1), (w.1 .0, w.1 .1)],
                    heat(w.1 .2 * inv).stroke_width(2),
                )))
                .map_err(err)?;
            k += 1;
        }
    }
    let y = draw_legend(&legend_area, &legend, &[])?;
    // the colour bar: 0 at the bottom, `top` at the top
    let font = ("sans-serif", LEGEND_FONT).into_font();
    let (w, h) = legend_area.dim_in_pixel();
    let mut y = y + 8;
    for l in wrap(
        &legend_area,
        what,
        w.saturating_sub(2 * LEGEND_PAD_PX as u32),
    ) {
        legend_area
            .draw_text(&l, &font.color(&BLACK), (LEGEND_PAD_PX, y))
            .map_err(err)?;
        y += LEGEND_FONT as i32 + 5;
    }
    let bar_h = (h as i32 - y - 20).clamp(0, 160);
    if bar_h > 20 {
        let x0 = LEGEND_PAD_PX;
        for i in 0..bar_h {
            let f = 1.0 - f64::from(i) / f64::from(bar_h - 1);
            legend_area
                .draw(&Rectangle::new(
                    [(x0, y + i), (x0 + 16, y + i + 1)],
                    heat(f).filled(),
                ))
                .map_err(err)?;
        }
        for (f, v) in [(1.0, *top), (0.5, 0.5 * top), (0.0, 0.0)] {
            let yy = y + ((1.0 - f) * f64::from(bar_h - 1)) as i32;
            legend_area
                .draw_text(
                    &format!("{v:.2}"),
                    &font
                        .color(&BLACK)
                        .pos(plotters::style::text_anchor::Pos::new(
                            plotters::style::text_anchor::HPos::Left,
                            plotters::style::text_anchor::VPos::Center,
                        )),
                    (x0 + 22, yy),
                )
                .map_err(err)?;
        }
    }
    Ok(())
}

fn helix_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    labels: &[String; 3],
    paths: &[Path3],
) -> Result<()> {
    let mut z1 = 1.0f64;
    for (_, _, p) in paths {
        for &(_, _, z) in p {
            if z.is_finite() {
                z1 = z1.max(z);
            }
        }
    }
    let legend: Vec<Entry> = paths
        .iter()
        .map(|(n, c, _)| Entry {
            text: n.clone(),
            swatch: Swatch::Line(*c),
        })
        .collect();
    let texts: Vec<&str> = legend.iter().map(|e| e.text.as_str()).collect();
    let (chart_area, legend_area) = layout(area, title, &texts)?;
    let mut chart = ChartBuilder::on(&chart_area)
        .margin(20)
        .build_cartesian_3d(-1.5..1.5, 0.0..z1, -1.5..1.5)
        .map_err(err)?;
    chart.with_projection(|mut p| {
        p.pitch = 0.35;
        p.yaw = 0.6;
        p.scale = 0.8;
        p.into_matrix()
    });
    chart
        .configure_axes()
        .label_style(("sans-serif", LABEL_FONT))
        .draw()
        .map_err(err)?;
    // axis labels beside the edges the ticks are on (plotters' 3-D y is vertical)
    let font = ("sans-serif", DESC_FONT).into_font().color(&BLACK);
    let centre = plotters::style::text_anchor::Pos::new(
        plotters::style::text_anchor::HPos::Center,
        plotters::style::text_anchor::VPos::Center,
    );
    let font = font.pos(centre);
    for (text, at) in [
        (&labels[0], (0.0, -0.1 * z1, 2.3)),
        (&labels[1], (2.3, -0.1 * z1, 0.0)),
        (&labels[2], (-1.5, 1.06 * z1, 1.5)),
    ] {
        chart
            .plotting_area()
            .draw(&Text::new(text.clone(), at, font.clone()))
            .map_err(err)?;
    }
    for (_, c, pts) in paths {
        // a smooth curve: at most 4000 points of it
        let step = (pts.len() / 4000).max(1);
        let last = pts.len().saturating_sub(1);
        chart
            .draw_series(LineSeries::new(
                pts.iter()
                    .enumerate()
                    .filter(|(k, _)| k % step == 0 || *k == last)
                    .map(|(_, &(x, y, z))| (x, z, y)),
                c.stroke_width(1),
            ))
            .map_err(err)?;
    }
    draw_legend(&legend_area, &legend, &[])?;
    Ok(())
}

fn axis_series(
    runs: &[(String, &RunResult)],
    pick: impl Fn(&RunResult, usize) -> f64,
) -> Vec<Series> {
    runs.iter()
        .map(|(name, r)| {
            Series::new(
                name.clone(),
                law_color(name),
                (0..r.trace.t.len())
                    .map(|k| (r.trace.t[k], pick(r, k)))
                    .collect(),
            )
        })
        .collect()
}

/// All paper figures; returns the number of files written.
pub fn paper_figures(dir: &Path, sc: &PaperInfo, rep: &PaperReport) -> Result<usize> {
    register_font()?;
    let t3: Vec<(String, &RunResult)> = sc
        .law_order
        .iter()
        .filter_map(|n| {
            rep.traces
                .get(&format!("t3_{n}_disturbed"))
                .map(|r| (n.clone(), r))
        })
        .collect();
    if t3.is_empty() {
        return Ok(0);
    }
    Ok(helix_path_figures(dir, sc, &t3)?
        + helix_signal_figures(dir, sc, &t3)?
        + table1_figures(dir, sc, rep)?)
}

/// The disturbance of the paper's runs, in words.
fn disturbance_note(sc: &PaperInfo) -> String {
    let (axis, accel, t_s) = sc.disturbance;
    format!(
        "+{accel} on axis {} at {t_s} s",
        ["x", "y", "z"][axis.min(2)]
    )
}

/// An axis label in the paper's length unit.
fn paper_axis(a: &str) -> String {
    format!("{a} ({PAPER_LEN})")
}

/// The helix's reference and actual paths: in 3-D, and its top and side views.
fn helix_path_figures(dir: &Path, sc: &PaperInfo, t3: &[(String, &RunResult)]) -> Result<usize> {
    let Some((_, first)) = t3.first() else {
        return Ok(0);
    };
    let mut files = 0;
    let reference: Vec<(f64, f64, f64)> = first
        .trace
        .reference
        .iter()
        .map(|p| (p[0], p[1], p[2]))
        .collect();
    let note = disturbance_note(sc);

    files += both(dir, "helix_3d", (1000, 800), &|add| {
        let mut paths = vec![("reference".to_string(), BLACK, reference.clone())];
        for (n, r) in t3 {
            paths.push((
                n.clone(),
                law_color(n),
                r.trace
                    .position
                    .iter()
                    .map(|p| (p[0], p[1], p[2]))
                    .collect(),
            ));
        }
        add(Panel::Helix3d {
            title: format!(
                "Helix x = sin t, y = cos t, z = 5t: reference and actual paths ({note})"
            ),
            labels: [paper_axis("x"), paper_axis("y"), paper_axis("z")],
            paths,
        })
    })?;

    files += both(dir, "helix_projections", (1000, 1300), &|add| {
        let mut xy = vec![Series::new(
            "reference",
            BLACK,
            reference.iter().map(|p| (p.0, p.1)).collect(),
        )];
        let mut xz = vec![Series::new(
            "reference",
            BLACK,
            reference.iter().map(|p| (p.0, p.2)).collect(),
        )];
        for (n, r) in t3 {
            xy.push(Series::new(
                n.clone(),
                law_color(n),
                r.trace.position.iter().map(|p| (p[0], p[1])).collect(),
            ));
            xz.push(Series::new(
                n.clone(),
                law_color(n),
                r.trace.position.iter().map(|p| (p[0], p[2])).collect(),
            ));
        }
        add(Panel::path(
            "Top view (XY), equal scales",
            paper_axis("x"),
            ("y", PAPER_LEN),
            xy,
        ))?;
        add(Panel::lines(
            "Side view (XZ), axes not to scale",
            paper_axis("x"),
            ("z", PAPER_LEN),
            xz,
        ))
    })?;

    Ok(files)
}

/// The helix's tracking errors, contour error and control inputs over time.
fn helix_signal_figures(dir: &Path, sc: &PaperInfo, t3: &[(String, &RunResult)]) -> Result<usize> {
    let mut files = 0;
    let note = disturbance_note(sc);
    files += both(dir, "helix_errors", (1000, 1200), &|add| {
        for (i, ax) in ["x", "y", "z"].iter().enumerate() {
            add(Panel::lines(
                format!("Tracking error e_{ax} = {ax}_d - {ax} ({note})"),
                "t (s)",
                (&format!("e_{ax}"), PAPER_LEN),
                axis_series(t3, |r, k| r.trace.reference[k][i] - r.trace.position[k][i]),
            )
            .log_auto())?;
        }
        Ok(())
    })?;

    files += both(dir, "helix_contour", (1000, 500), &|add| {
        add(Panel::lines(
            "Contour error |ε| of the controller's model (eq. 14)",
            "t (s)",
            ("|ε|", PAPER_LEN),
            axis_series(t3, |r, k| {
                let c = r.trace.contour_model[k];
                (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
            }),
        )
        .log_auto())
    })?;

    files += both(dir, "helix_control", (1000, 1200), &|add| {
        for (i, ax) in ["x", "y", "z"].iter().enumerate() {
            add(Panel::lines(
                format!("Control input u_{ax}"),
                "t (s)",
                (&format!("u_{ax}"), PAPER_U),
                axis_series(t3, |r, k| r.trace.u[k][i]),
            ))?;
        }
        Ok(())
    })?;

    Ok(files)
}

/// Table 1's single-axis runs (step and sine references) and their control inputs.
fn table1_figures(dir: &Path, sc: &PaperInfo, rep: &PaperReport) -> Result<usize> {
    let mut files = 0;
    let (_, accel, t_s) = sc.disturbance;
    for tname in ["step", "sine"] {
        let runs: Vec<(String, &RunResult)> = sc
            .t1_laws
            .iter()
            .filter_map(|l| {
                rep.traces
                    .get(&format!("t1_{tname}_{l}_disturbed"))
                    .map(|r| (l.clone(), r))
            })
            .collect();
        if runs.is_empty() {
            continue;
        }
        files += both(dir, &format!("table1_{tname}"), (1000, 1000), &|add| {
            let mut pos = vec![Series::new(
                "reference",
                BLACK,
                runs[0]
                    .1
                    .trace
                    .t
                    .iter()
                    .zip(&runs[0].1.trace.reference)
                    .map(|(t, r)| (*t, r[0]))
                    .collect(),
            )];
            pos.extend(axis_series(&runs, |r, k| r.trace.position[k][0]));
            add(Panel::lines(
                format!("Single axis, {tname} reference, +{accel} on θ'' from {t_s} s"),
                "t (s)",
                ("θ", PAPER_LEN),
                pos,
            ))?;
            add(Panel::lines(
                "Control input",
                "t (s)",
                ("u", PAPER_U),
                axis_series(&runs, |r, k| r.trace.u[k][0]),
            ))
        })?;
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(amp: f64, n: usize) -> Vec<(f64, f64)> {
        (0..n)
            .map(|k| {
                let t = k as f64 * 1e-3;
                (t, amp * (2.0 * t).sin())
            })
            .collect()
    }

    #[test]
    fn the_log_axis_comes_when_the_series_span_more_than_two_decades() {
        // PID's error around 1e-2 beside DSMC's around 1e-6: 4 decades
        let pid_dsmc = [
            Series::new("PID", BLACK, sine(1e-2, 15_000)),
            Series::new("DSMC", BLACK, sine(1e-6, 15_000)),
        ];
        let d = decades_spanned(&pid_dsmc);
        assert!((d - 4.15).abs() < 0.1, "{d}");
        assert!(wants_log(&pid_dsmc));
        // one sine: its peak over its median |value| (0.15 decades)
        let one = [Series::new("PID", BLACK, sine(1e-2, 15_000))];
        assert!(decades_spanned(&one) < 0.3);
        assert!(!wants_log(&one));
        // 1.5 decades apart: linear; 2.5: log
        for (ratio, log) in [(10f64.powf(1.5), false), (10f64.powf(2.5), true)] {
            let s = [
                Series::new("a", BLACK, sine(1.0, 1000)),
                Series::new("b", BLACK, sine(1.0 / ratio, 1000)),
            ];
            assert_eq!(wants_log(&s), log, "ratio {ratio}");
        }
        // a series that is all zero does not make a log axis
        let zero = [
            Series::new("a", BLACK, sine(1.0, 1000)),
            Series::new("b", BLACK, vec![(0.0, 0.0), (1.0, 0.0)]),
        ];
        assert!(!wants_log(&zero));
    }

    #[test]
    fn the_log_axis_draws_zeros_at_its_floor_and_says_so() {
        let mut points = sine(1e-2, 1000);
        points.push((1.0, 0.0));
        let (out, floor, clipped) = to_log(&[Series::new("a", BLACK, points)]);
        assert!(clipped);
        assert_eq!(floor, floor.round(), "a whole decade");
        assert!((-12.0..-2.0).contains(&floor), "{floor}");
        let ys: Vec<f64> = out[0].points.iter().map(|p| p.1).collect();
        assert!(ys.iter().all(|y| *y >= floor && *y <= -2.0 + 1e-9));
        assert_eq!(*ys.last().unwrap(), floor);
        assert_eq!(pow10_label(-6.0), "10⁻⁶");
        assert_eq!(pow10_label(2.0), "10²");
        assert_eq!(pow10_label(-12.0), "10⁻¹²");
        assert_eq!(y_label("e_x", "mm", true), "|e_x| (mm, log)");
        assert_eq!(y_label("|ε|", "µm", true), "|ε| (µm, log)");
        assert_eq!(y_label("e_x", "mm", false), "e_x (mm)");
        assert_eq!(
            y_label("feed ratio", "", false),
            "feed ratio (dimensionless)"
        );
    }

    /// Pixels per data unit of `chart` along x and y, measured through its own mapping.
    fn px_per_unit<DB: DrawingBackend>(
        chart: &Chart2d<'_, DB>,
        at: (f64, f64),
        d: f64,
    ) -> (f64, f64) {
        let o = chart.backend_coord(&at);
        let x = chart.backend_coord(&(at.0 + d, at.1));
        let y = chart.backend_coord(&(at.0, at.1 + d));
        (f64::from(x.0 - o.0) / d, f64::from(o.1 - y.1) / d)
    }

    #[test]
    fn an_xy_path_has_the_same_pixels_per_mm_on_both_axes() {
        let mut buf = vec![0u8; 1000 * 600 * 3];
        let root = BitMapBackend::with_buffer(&mut buf, (1000, 600)).into_drawing_area();
        // wide data (the gcode top view), tall data (a side view turned), a circle
        for (x, y) in [
            ((-70.0, 80.0), (-40.0, 60.0)),
            ((0.0, 5.0), (0.0, 300.0)),
            ((-20.0, 20.0), (-40.0, 0.0)),
        ] {
            let chart = equal_chart(&root, x, y).unwrap();
            let (px, py) = px_per_unit(&chart, (x.0, y.0), (x.1 - x.0).max(y.1 - y.0));
            assert!(
                px > 0.0 && (px - py).abs() / px < 0.005,
                "{x:?} {y:?}: {px} vs {py}"
            );
            // and the data is inside the plotting area
            let (xr, yr) = (chart.x_range(), chart.y_range());
            assert!(xr.start <= x.0 && xr.end >= x.1 && yr.start <= y.0 && yr.end >= y.1);
        }
        // the same rule for the ranges alone
        let (xr, yr) = equal_ranges((0.0, 100.0), (0.0, 10.0), (800, 400));
        let (sx, sy) = ((xr.end - xr.start) / 800.0, (yr.end - yr.start) / 400.0);
        assert!((sx - sy).abs() < 1e-12, "{sx} {sy}");
    }

    #[test]
    fn thinning_keeps_what_the_pixels_show() {
        // 150 001 noisy samples into 800 columns: at most 4 per column, extremes kept
        let pts: Vec<(f64, f64)> = (0..150_001)
            .map(|k| {
                let t = k as f64 * 1e-4;
                (t, (t * 3.0).sin() + if k % 7 == 0 { 0.3 } else { 0.0 })
            })
            .collect();
        let thin = thin_columns(&pts, (0.0, 15.0), 800);
        assert!(thin.len() <= 4 * 801, "{}", thin.len());
        let max = |v: &[(f64, f64)]| v.iter().map(|p| p.1).fold(f64::MIN, f64::max);
        let min = |v: &[(f64, f64)]| v.iter().map(|p| p.1).fold(f64::MAX, f64::min);
        assert_eq!(max(&thin), max(&pts));
        assert_eq!(min(&thin), min(&pts));
        assert_eq!(thin.first(), pts.first());
        assert_eq!(thin.last(), pts.last());
        assert!(thin.windows(2).all(|w| w[0].0 <= w[1].0), "order kept");
        // a path: one point per pixel passed, the ends kept
        let circle: Vec<(f64, f64)> = (0..=100_000)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 100_000.0;
                (20.0 * a.cos(), 20.0 * a.sin())
            })
            .collect();
        let thin = thin_path(&circle, (0.1, 0.1));
        // 2π·20 mm at 0.1 mm per pixel: ~1257 pixels, not more points than that
        assert!(thin.len() > 800 && thin.len() < 1300, "{}", thin.len());
        assert_eq!(thin.last(), circle.last());
    }
}
