//! Polar plots of `host-sim circle` (PNG and SVG), one per circle: ISO 230-4's picture of
//! the circular test. The radial deviation about the least-squares centre is drawn against
//! its angle, magnified, around a reference ring that stands for the least-squares circle
//! (deviation 0), with grid rings one division apart, the two rings of the `G` band (the
//! smallest and the largest deviation), the quadrant axes, and the case's `G`, `D` and
//! reversal spike in the title.
//!
//! Plotters has no polar chart: the plot is a square chart at equal scales in divisions,
//! a deviation `dev_um` at angle `θ` drawn at radius [`plotted_radius_div`]
//! (`RING_DIV + dev_um / scale`) in direction `θ` ([`polar_point`]), the rings drawn as
//! circles. The angle is the XY plane's own, about the least-squares centre: 0° at +X,
//! counter-clockwise seen from +Z, so the picture keeps the machine's orientation.

use crate::output::plots::{draw_legend, equal_ranges, err, layout, register_font, thin_path};
use crate::output::plots::{Entry, Swatch};
use crate::studies::circle::{CircleCase, CircleReport};
use anyhow::{bail, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::f64::consts::TAU;
use std::path::Path;

/// The reference ring's radius (the least-squares circle, deviation 0), divisions: far
/// enough out that the inner band ring stays clear of the centre.
pub const RING_DIV: f64 = 6.0;
/// Grid rings either side of the reference ring, divisions; the scale is chosen so the
/// whole trace lies within them.
pub const HALF_SPAN_DIV: f64 = 4.0;
/// The finest scale, µm/div: a perfect circle (all deviations 0) still gets a finite
/// scale.
pub const MIN_SCALE_UM_PER_DIV: f64 = 0.01;
/// Room beyond the outermost ring for the quadrant labels, divisions.
const LABEL_ROOM_DIV: f64 = 1.5;
/// Points on a drawn ring: smooth at any size the figure is drawn.
const RING_POINTS: usize = 360;
/// Wide enough for the legend strip beside a chart about as wide as it is high.
const SIZE: (u32, u32) = (1100, 800);

const TRACE: RGBColor = RGBColor(31, 119, 180);
const REFERENCE: RGBColor = RGBColor(90, 90, 90);
const BAND: RGBColor = RGBColor(214, 39, 40);
const GRID: RGBColor = RGBColor(225, 225, 225);
const AXIS: RGBColor = RGBColor(170, 170, 170);

/// The scale for a trace whose largest |deviation| is `max_abs_dev_um`: the smallest of
/// 1, 2, 5 × 10ⁿ µm/div (at least [`MIN_SCALE_UM_PER_DIV`]) that keeps it within
/// ±[`HALF_SPAN_DIV`] divisions of the reference ring.
pub fn scale_um_per_div(max_abs_dev_um: f64) -> Result<f64> {
    if !(max_abs_dev_um.is_finite() && max_abs_dev_um >= 0.0) {
        bail!("the largest radial deviation must be a finite |value| in µm, got {max_abs_dev_um}");
    }
    let need = (max_abs_dev_um / HALF_SPAN_DIV).max(MIN_SCALE_UM_PER_DIV);
    let decade = 10f64.powi(need.log10().floor() as i32);
    // the tolerance: a step computed as m × 10ⁿ may land a hair below a need that is on
    // the grid itself (20 µm needs exactly 5 µm/div), which must not cost a step
    Ok([1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|s| *s >= need * (1.0 - 1e-9))
        .unwrap_or(10.0 * decade))
}

/// The plotted radius of a deviation of `dev_um` at `scale_um_per_div` (> 0), divisions:
/// the reference ring plus the magnified deviation.
pub fn plotted_radius_div(dev_um: f64, scale_um_per_div: f64) -> f64 {
    RING_DIV + dev_um / scale_um_per_div
}

/// Where a deviation of `dev_um` at `angle_rad` (from +X, counter-clockwise) is drawn,
/// (x, y) in divisions from the plot's centre.
pub fn polar_point(angle_rad: f64, dev_um: f64, scale_um_per_div: f64) -> (f64, f64) {
    let r = plotted_radius_div(dev_um, scale_um_per_div);
    (r * angle_rad.cos(), r * angle_rad.sin())
}

/// The decimals a value on `scale`'s grid needs (2 for 0.05, 0 for 5).
fn decimals(scale: f64) -> usize {
    // nudged up first: a scale computed as m × 10ⁿ may land a hair under a power of ten
    // (0.01), its logarithm under -2, which would cost a spurious decimal
    (-(scale.log10() + 1e-9).floor()).max(0.0) as usize
}

/// `scale` written with as many decimals as its decade needs (0.05, 0.2, 5, 20).
fn scale_text(scale: f64) -> String {
    format!("{scale:.*}", decimals(scale))
}

/// A case name as a file name: anything but letters, digits, `-`, `_` becomes `_` (a
/// scenario's case names are free text).
fn file_stem(name: &str) -> String {
    let clean: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("circle_{clean}")
}

/// What one plot needs of a case, checked: the band and the scale.
struct Polar {
    min_dev_um: f64,
    max_dev_um: f64,
    scale_um_per_div: f64,
}

impl Polar {
    fn of(c: &CircleCase) -> Result<Self> {
        if c.trace.is_empty() {
            bail!(
                "circle `{}`: no radial deviation trace to plot (the study fills it)",
                c.name
            );
        }
        if let Some((k, p)) = c
            .trace
            .iter()
            .enumerate()
            .find(|(_, p)| !(p.angle_rad.is_finite() && p.dev_um.is_finite()))
        {
            bail!(
                "circle `{}`: sample {k} of the radial deviation trace is not finite \
                 (angle {} rad, deviation {} µm)",
                c.name,
                p.angle_rad,
                p.dev_um
            );
        }
        let (lo, hi) = c
            .trace
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                (l.min(p.dev_um), h.max(p.dev_um))
            });
        let scale = scale_um_per_div(lo.abs().max(hi.abs()))
            .with_context(|| format!("circle `{}`", c.name))?;
        Ok(Self {
            min_dev_um: lo,
            max_dev_um: hi,
            scale_um_per_div: scale,
        })
    }
}

/// A circle of `radius_div` about the centre, closed.
fn ring(radius_div: f64) -> Vec<(f64, f64)> {
    (0..=RING_POINTS)
        .map(|k| {
            let a = TAU * k as f64 / RING_POINTS as f64;
            (radius_div * a.cos(), radius_div * a.sin())
        })
        .collect()
}

fn title(c: &CircleCase) -> String {
    let f = &c.figures;
    format!(
        "{}: R {} mm, F {:.0} mm/min, {}; G {:.2} µm, D {:.2} µm, reversal spike {:.2} µm",
        c.name,
        c.radius_mm,
        c.feed_mm_min,
        c.direction,
        f.circular_deviation_um,
        f.radius_deviation_um,
        f.reversal_spike_um
    )
}

/// The legend's entries and the notes under them.
fn legend(machine: &str, c: &CircleCase, p: &Polar) -> (Vec<Entry>, Vec<String>) {
    let scale = scale_text(p.scale_um_per_div);
    let entries = vec![
        Entry {
            text: format!("radial deviation, {scale} µm/div"),
            swatch: Swatch::Line(TRACE),
        },
        Entry {
            text: "least-squares circle (0 µm)".into(),
            swatch: Swatch::Line(REFERENCE),
        },
        Entry {
            text: format!("G band: {:+.2} … {:+.2} µm", p.min_dev_um, p.max_dev_um),
            swatch: Swatch::Dashed(BAND),
        },
    ];
    let notes = vec![
        format!(
            "Scale {scale} µm/div: a grey ring every division, the least-squares circle drawn \
             {RING_DIV:.0} divisions out."
        ),
        "Angle about the least-squares centre, 0° at +X, counter-clockwise seen from +Z."
            .to_string(),
        format!(
            "Least-squares centre {:+.2}, {:+.2} µm (X, Y) from the nominal one.",
            c.figures.centre_offset_um[0], c.figures.centre_offset_um[1]
        ),
        format!(
            "At the tool over the last full turn, {} points; contour error max {:.2} µm.",
            c.trace.len(),
            c.contour_max_um
        ),
        format!("Machine: {machine}"),
    ];
    (entries, notes)
}

type PolarChart<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// The polar grid: rings one division apart with their values, spokes every 45° (the
/// quadrant axes darker) and the quadrants' angles.
fn grid<DB: DrawingBackend>(chart: &mut PolarChart<'_, DB>, scale_um_per_div: f64) -> Result<()> {
    let outer = RING_DIV + HALF_SPAN_DIV;
    let span = HALF_SPAN_DIV as i32;
    for j in (-span..=span).filter(|j| *j != 0) {
        chart
            .draw_series(LineSeries::new(ring(RING_DIV + f64::from(j)), GRID))
            .map_err(err)?;
    }
    for k in 0..8 {
        let a = TAU * f64::from(k) / 8.0;
        let colour = if k % 2 == 0 { AXIS } else { GRID };
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(0.0, 0.0), (outer * a.cos(), outer * a.sin())],
                colour,
            )))
            .map_err(err)?;
    }
    let label = ("sans-serif", 13).into_font().color(&BLACK);
    let gap_div = 0.25;
    for (text, at, h, v) in [
        ("0° (+X)", (outer + gap_div, 0.0), HPos::Left, VPos::Center),
        (
            "90° (+Y)",
            (0.0, outer + gap_div),
            HPos::Center,
            VPos::Bottom,
        ),
        (
            "180° (−X)",
            (-outer - gap_div, 0.0),
            HPos::Right,
            VPos::Center,
        ),
        (
            "270° (−Y)",
            (0.0, -outer - gap_div),
            HPos::Center,
            VPos::Top,
        ),
    ] {
        chart
            .plotting_area()
            .draw(&Text::new(text, at, label.clone().pos(Pos::new(h, v))))
            .map_err(err)?;
    }
    // every other ring's value, on the 22.5° ray: between two spokes, clear of the labels
    let small = ("sans-serif", 11)
        .into_font()
        .color(&RGBColor(110, 110, 110));
    let ray = TAU / 16.0;
    for j in (-span..=span).step_by(2) {
        let r = RING_DIV + f64::from(j);
        let value_um = f64::from(j) * scale_um_per_div;
        let text = if j == 0 {
            "0 µm".to_string()
        } else {
            format!("{value_um:+.*} µm", decimals(scale_um_per_div))
        };
        chart
            .plotting_area()
            .draw(&Text::new(
                text,
                (r * ray.cos(), r * ray.sin()),
                small.clone().pos(Pos::new(HPos::Left, VPos::Bottom)),
            ))
            .map_err(err)?;
    }
    Ok(())
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    machine: &str,
    c: &CircleCase,
    p: &Polar,
) -> Result<()> {
    root.fill(&WHITE).map_err(err)?;
    let scale = p.scale_um_per_div;
    let (entries, notes) = legend(machine, c, p);
    let mut texts: Vec<&str> = entries.iter().map(|e| e.text.as_str()).collect();
    texts.extend(notes.iter().map(String::as_str));
    let (chart_area, legend_area) = layout(root, &title(c), &texts)?;

    let lim = RING_DIV + HALF_SPAN_DIV + LABEL_ROOM_DIV;
    let dims = ChartBuilder::on(&chart_area)
        .margin(10)
        .build_cartesian_2d(-lim..lim, -lim..lim)
        .map_err(err)?
        .plotting_area()
        .dim_in_pixel();
    // equal length per pixel on both axes: a circle must look like one
    let (xr, yr) = equal_ranges((-lim, lim), (-lim, lim), dims);
    let px = (
        (xr.end - xr.start) / f64::from(dims.0.max(1)),
        (yr.end - yr.start) / f64::from(dims.1.max(1)),
    );
    let mut chart = ChartBuilder::on(&chart_area)
        .margin(10)
        .build_cartesian_2d(xr, yr)
        .map_err(err)?;
    grid(&mut chart, scale)?;
    chart
        .draw_series(LineSeries::new(ring(RING_DIV), REFERENCE.stroke_width(1)))
        .map_err(err)?;
    for dev_um in [p.min_dev_um, p.max_dev_um] {
        chart
            .draw_series(DashedLineSeries::new(
                ring(plotted_radius_div(dev_um, scale)),
                6,
                4,
                BAND.stroke_width(1),
            ))
            .map_err(err)?;
    }
    // closed: the judged turn ends where it began
    let mut curve: Vec<(f64, f64)> = c
        .trace
        .iter()
        .map(|t| polar_point(t.angle_rad, t.dev_um, scale))
        .collect();
    if let Some(first) = curve.first().copied() {
        curve.push(first);
    }
    // width 1: plotters' bitmap backend draws wider polylines with spikes at sharp turns
    chart
        .draw_series(LineSeries::new(
            thin_path(&curve, px),
            TRACE.stroke_width(1),
        ))
        .map_err(err)?;
    draw_legend(&legend_area, &entries, &notes)?;
    Ok(())
}

/// One case's polar plot into `dir` as `circle_<case>.png` and `.svg`; the number of
/// files written. `machine` is named in the notes.
pub fn case_figure(dir: &Path, machine: &str, c: &CircleCase) -> Result<usize> {
    register_font()?;
    let p = Polar::of(c)?;
    let stem = file_stem(&c.name);
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    {
        let root = BitMapBackend::new(&png, SIZE).into_drawing_area();
        draw(&root, machine, c, &p)?;
        root.present()
            .with_context(|| format!("writing {}", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, SIZE).into_drawing_area();
        draw(&root, machine, c, &p)?;
        root.present()
            .with_context(|| format!("writing {}", svg.display()))?;
    }
    Ok(2)
}

/// Every case's polar plot into `dir`; the number of files written.
pub fn figures(dir: &Path, r: &CircleReport) -> Result<usize> {
    let mut n = 0;
    for c in &r.cases {
        n += case_figure(dir, &r.machine, c)?;
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_is_the_smallest_1_2_5_step_that_fits() {
        for (max_abs_dev_um, scale) in [
            (9.0, 5.0),
            (20.0, 5.0),
            (20.1, 10.0),
            (70.0, 20.0),
            (1.0, 0.5),
            (0.3, 0.1),
            (0.0, MIN_SCALE_UM_PER_DIV),
        ] {
            let s = scale_um_per_div(max_abs_dev_um).unwrap();
            assert!((s - scale).abs() < 1e-9 * scale, "{max_abs_dev_um} µm: {s}");
        }
        assert!(scale_um_per_div(f64::NAN).is_err());
        assert!(scale_um_per_div(-1.0).is_err());
        assert!(scale_um_per_div(f64::INFINITY).is_err());
    }

    #[test]
    fn scales_are_written_with_the_decimals_they_need() {
        assert_eq!(scale_text(5.0), "5");
        assert_eq!(scale_text(20.0), "20");
        assert_eq!(scale_text(0.2), "0.2");
        assert_eq!(scale_text(0.05), "0.05");
        assert_eq!(scale_text(0.1 * 5.0), "0.5");
        assert_eq!(scale_text(0.01), "0.01");
    }

    #[test]
    fn case_names_become_safe_file_names() {
        assert_eq!(file_stem("r50_f3000_cw"), "circle_r50_f3000_cw");
        assert_eq!(file_stem("../a b"), "circle____a_b");
    }
}
