//! Figures (PNG and SVG) equivalent to the paper's: the 3-D helix and its top view,
//! per-axis tracking errors, control inputs, contour error, single-axis responses.
//!
//! Text is drawn with the bundled DejaVu Sans (`host-sim/assets`), registered at start-up,
//! so plots render on a machine without any system font packages.

use crate::engine::RunResult;
use crate::studies::paper::{PaperInfo, PaperReport};
use anyhow::{anyhow, Context, Result};
use plotters::coord::Shift;
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

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// A figure's contents: called with a sink that takes its panels in order.
pub(crate) type Draw<'a> = &'a dyn Fn(&mut dyn FnMut(Panel) -> Result<()>) -> Result<()>;

/// A named, coloured 3-D path.
pub(crate) type Path3 = (String, RGBColor, Vec<(f64, f64, f64)>);

/// The series legend, in the same style on every chart (2-D and 3-D).
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> Result<()> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 12))
        .draw()
        .map_err(err)
}

/// One named series of (x, y) points.
pub(crate) struct Series {
    pub(crate) name: String,
    pub(crate) color: RGBColor,
    pub(crate) points: Vec<(f64, f64)>,
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
        x = (0.0, 1.0);
    }
    if !(y.0 < y.1) {
        y = (y.0.min(0.0) - 1.0, y.1.max(0.0) + 1.0);
    }
    let pad = 0.05 * (y.1 - y.0);
    (x, (y.0 - pad, y.1 + pad))
}

/// A 2-D chart with the house style (caption, margins, labelled mesh) over the ranges.
fn chart_2d<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    title: &str,
    (xl, yl): (&str, &str),
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
) -> Result<
    ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
> {
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(8)
        .x_label_area_size(32)
        .y_label_area_size(64)
        .build_cartesian_2d(x, y)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(xl)
        .y_desc(yl)
        .label_style(("sans-serif", 12))
        .draw()
        .map_err(err)?;
    Ok(chart)
}

fn line_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    xl: &str,
    yl: &str,
    series: &[Series],
) -> Result<()> {
    let ((x0, x1), (y0, y1)) = bounds(series);
    let mut chart = chart_2d(area, title, (xl, yl), x0..x1, y0..y1)?;
    for s in series {
        let c = s.color;
        chart
            .draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(1)))
            .map_err(err)?
            .label(s.name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c));
    }
    draw_legend(&mut chart)
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

/// A figure is a vertical stack of panels, or a single 3-D view.
pub(crate) enum Panel {
    Lines {
        title: String,
        xl: String,
        yl: String,
        series: Vec<Series>,
    },
    Helix3d {
        title: String,
        paths: Vec<Path3>,
    },
    /// A 2-D path drawn piecewise, each piece coloured by a value (blue = 0 to red =
    /// `scale`), with equal axis scales.
    Coloured {
        title: String,
        xl: String,
        yl: String,
        /// (x, y, value) along the path.
        points: Vec<(f64, f64, f64)>,
        scale: f64,
        /// What the colour means, e.g. "contour error: blue 0 → red 12.3 µm".
        legend: String,
    },
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
            Panel::Lines {
                title,
                xl,
                yl,
                series,
            } => line_panel(a, title, xl, yl, series)?,
            Panel::Helix3d { title, paths } => helix_panel(a, title, paths)?,
            Panel::Coloured {
                title,
                xl,
                yl,
                points,
                scale,
                legend,
            } => coloured_panel(a, title, (xl, yl), points, *scale, legend)?,
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

fn coloured_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    (xl, yl): (&str, &str),
    points: &[(f64, f64, f64)],
    scale: f64,
    legend: &str,
) -> Result<()> {
    let xy: Vec<Series> = vec![Series {
        name: String::new(),
        color: BLACK,
        points: points.iter().map(|p| (p.0, p.1)).collect(),
    }];
    let ((x0, x1), (y0, y1)) = bounds(&xy);
    // equal scales: widen the narrower range about its centre
    let (w, h) = area.dim_in_pixel();
    let (w, h) = (f64::from(w.max(1)), f64::from(h.max(1)));
    let span = ((x1 - x0) / w).max((y1 - y0) / h) * 1.05;
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (hx, hy) = (0.5 * span * w, 0.5 * span * h);
    let mut chart = chart_2d(area, title, (xl, yl), cx - hx..cx + hx, cy - hy..cy + hy)?;
    let inv = if scale > 0.0 { 1.0 / scale } else { 0.0 };
    chart
        .draw_series(points.windows(2).map(|w| {
            let c = heat(w[1].2 * inv);
            PathElement::new(vec![(w[0].0, w[0].1), (w[1].0, w[1].1)], c.stroke_width(2))
        }))
        .map_err(err)?
        .label(legend.to_string())
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 8, y)], heat(0.0).stroke_width(3)));
    draw_legend(&mut chart)
}

fn helix_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
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
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .build_cartesian_3d(-1.5..1.5, 0.0..z1, -1.5..1.5)
        .map_err(err)?;
    chart.with_projection(|mut p| {
        p.pitch = 0.35;
        p.yaw = 0.6;
        p.scale = 0.85;
        p.into_matrix()
    });
    chart
        .configure_axes()
        .label_style(("sans-serif", 11))
        .draw()
        .map_err(err)?;
    for (name, c, pts) in paths {
        let c = *c;
        // plotters' 3-D y axis is vertical: map (x, y, z) -> (x, z, y)
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|&(x, y, z)| (x, z, y)),
                c.stroke_width(1),
            ))
            .map_err(err)?
            .label(name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c));
    }
    draw_legend(&mut chart)
}

fn axis_series(
    runs: &[(String, &RunResult)],
    pick: impl Fn(&RunResult, usize) -> f64,
) -> Vec<Series> {
    runs.iter()
        .map(|(name, r)| Series {
            name: name.clone(),
            color: law_color(name),
            points: (0..r.trace.t.len())
                .map(|k| (r.trace.t[k], pick(r, k)))
                .collect(),
        })
        .collect()
}

/// All paper figures; returns the number of files written.
pub fn paper_figures(dir: &Path, sc: &PaperInfo, rep: &PaperReport) -> Result<usize> {
    register_font()?;
    let mut files = 0;
    let t3: Vec<(String, &RunResult)> = sc
        .law_order
        .iter()
        .filter_map(|n| {
            rep.traces
                .get(&format!("t3_{n}_disturbed"))
                .map(|r| (n.clone(), r))
        })
        .collect();
    let Some((_, first)) = t3.first() else {
        return Ok(0);
    };
    let reference: Vec<(f64, f64, f64)> = first
        .trace
        .reference
        .iter()
        .map(|p| (p[0], p[1], p[2]))
        .collect();
    let (axis, accel, t_s) = sc.disturbance;
    let note = format!(
        "+{accel} on axis {} at {t_s} s",
        ["x", "y", "z"][axis.min(2)]
    );

    files += both(dir, "helix_3d", (900, 800), &|add| {
        let mut paths = vec![("reference".to_string(), BLACK, reference.clone())];
        for (n, r) in &t3 {
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
            paths,
        })
    })?;

    files += both(dir, "helix_projections", (900, 1200), &|add| {
        let mut xy = vec![Series {
            name: "reference".into(),
            color: BLACK,
            points: reference.iter().map(|p| (p.0, p.1)).collect(),
        }];
        let mut xz = vec![Series {
            name: "reference".into(),
            color: BLACK,
            points: reference.iter().map(|p| (p.0, p.2)).collect(),
        }];
        for (n, r) in &t3 {
            xy.push(Series {
                name: n.clone(),
                color: law_color(n),
                points: r.trace.position.iter().map(|p| (p[0], p[1])).collect(),
            });
            xz.push(Series {
                name: n.clone(),
                color: law_color(n),
                points: r.trace.position.iter().map(|p| (p[0], p[2])).collect(),
            });
        }
        add(Panel::Lines {
            title: "Top view (XY)".into(),
            xl: "x".into(),
            yl: "y".into(),
            series: xy,
        })?;
        add(Panel::Lines {
            title: "Side view (XZ)".into(),
            xl: "x".into(),
            yl: "z".into(),
            series: xz,
        })
    })?;

    files += both(dir, "helix_errors", (1000, 1200), &|add| {
        for (i, ax) in ["x", "y", "z"].iter().enumerate() {
            add(Panel::Lines {
                title: format!("Tracking error e_{ax} = {ax}_d - {ax} ({note})"),
                xl: "t [s]".into(),
                yl: format!("e_{ax}"),
                series: axis_series(&t3, |r, k| r.trace.reference[k][i] - r.trace.position[k][i]),
            })?;
        }
        Ok(())
    })?;

    files += both(dir, "helix_contour", (1000, 500), &|add| {
        add(Panel::Lines {
            title: "Contour error |e| of the controller's model (eq. 14)".into(),
            xl: "t [s]".into(),
            yl: "|e|".into(),
            series: axis_series(&t3, |r, k| {
                let c = r.trace.contour_model[k];
                (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
            }),
        })
    })?;

    files += both(dir, "helix_control", (1000, 1200), &|add| {
        for (i, ax) in ["x", "y", "z"].iter().enumerate() {
            add(Panel::Lines {
                title: format!("Control input u_{ax}"),
                xl: "t [s]".into(),
                yl: format!("u_{ax}"),
                series: axis_series(&t3, |r, k| r.trace.u[k][i]),
            })?;
        }
        Ok(())
    })?;

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
            let mut pos = vec![Series {
                name: "reference".into(),
                color: BLACK,
                points: runs[0]
                    .1
                    .trace
                    .t
                    .iter()
                    .zip(&runs[0].1.trace.reference)
                    .map(|(t, r)| (*t, r[0]))
                    .collect(),
            }];
            pos.extend(axis_series(&runs, |r, k| r.trace.position[k][0]));
            add(Panel::Lines {
                title: format!("Single axis, {tname} reference, +{accel} on θ'' from {t_s} s"),
                xl: "t [s]".into(),
                yl: "θ".into(),
                series: pos,
            })?;
            add(Panel::Lines {
                title: "Control input".into(),
                xl: "t [s]".into(),
                yl: "u".into(),
                series: axis_series(&runs, |r, k| r.trace.u[k][0]),
            })
        })?;
    }
    Ok(files)
}
