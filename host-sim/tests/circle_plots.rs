//! The circular test's polar plot (`host-sim circle`, `output/circle_plots.rs`) on a
//! synthetic circle, no simulation: the files are written, a deviation lands at the radius
//! the scale says, a case without a trace is refused by name, and the trace stays out of
//! the JSON.

use host_sim::output::circle_plots::{
    case_figure, figures, plotted_radius_div, polar_point, scale_um_per_div, HALF_SPAN_DIV,
    RING_DIV,
};
use host_sim::studies::circle::{CircleCase, CircleReport};
use host_sim::studies::circular_test::evaluate_traced;
use std::f64::consts::FRAC_PI_2;
use std::path::PathBuf;

/// A fresh folder for one test's files.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "host-sim-circle-plots-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// R 50 mm about (0, -50) with ±5 µm of ovality (+5 µm on the X axis) and a 4 µm bump 1°
/// wide just past +X, traced clockwise from +Y as the study's cw circle is.
fn synthetic_case() -> CircleCase {
    let (centre, radius_mm, n) = ([0.0, -50.0], 50.0, 3600);
    let pts: Vec<[f64; 2]> = (0..n)
        .map(|k| {
            // the test's angle: from +Y, clockwise
            let a_deg = 360.0 * f64::from(k) / f64::from(n);
            let bump_mm = if (90.0..91.0).contains(&a_deg) {
                4e-3
            } else {
                0.0
            };
            let r = radius_mm - 5e-3 * (2.0 * a_deg.to_radians()).cos() + bump_mm;
            let a = a_deg.to_radians();
            [centre[0] + r * a.sin(), centre[1] + r * a.cos()]
        })
        .collect();
    let e = evaluate_traced(&pts, centre, radius_mm).unwrap();
    CircleCase {
        name: "synthetic_r50_cw".into(),
        radius_mm,
        feed_mm_min: 3000.0,
        direction: "cw",
        figures: e.figures,
        contour_max_um: 9.0,
        trace: e.trace,
    }
}

#[test]
fn a_deviation_is_drawn_at_the_ring_plus_its_magnified_value() {
    // +5 µm at 5 µm/div: one division outside the reference ring
    assert!((plotted_radius_div(5.0, 5.0) - (RING_DIV + 1.0)).abs() < 1e-12);
    assert!((plotted_radius_div(-5.0, 5.0) - (RING_DIV - 1.0)).abs() < 1e-12);
    assert!((plotted_radius_div(5.0, 2.0) - (RING_DIV + 2.5)).abs() < 1e-12);
    assert!((plotted_radius_div(0.0, 5.0) - RING_DIV).abs() < 1e-12);
    // in direction θ: +X at 0, +Y at 90°
    let (x, y) = polar_point(0.0, 5.0, 5.0);
    assert!(
        (x - (RING_DIV + 1.0)).abs() < 1e-12 && y.abs() < 1e-12,
        "{x}, {y}"
    );
    let (x, y) = polar_point(FRAC_PI_2, 5.0, 5.0);
    assert!(
        x.abs() < 1e-12 && (y - (RING_DIV + 1.0)).abs() < 1e-12,
        "{x}, {y}"
    );
    let (x, y) = polar_point(std::f64::consts::PI, -5.0, 5.0);
    assert!(
        (x + (RING_DIV - 1.0)).abs() < 1e-12 && y.abs() < 1e-12,
        "{x}, {y}"
    );
}

#[test]
fn the_synthetic_circle_is_plotted_at_5_um_per_division_within_the_grid() {
    let c = synthetic_case();
    let f = &c.figures;
    // G: the ovality's 10 µm and the bump on its crest
    assert!(
        (f.circular_deviation_um - 14.0).abs() < 0.2,
        "{}",
        f.circular_deviation_um
    );
    // the bump over the ovality's crest, read off a baseline a little below the crest
    assert!((f.reversal_spike_um - 4.0).abs() < 0.5, "{f:?}");
    let max_abs_um = c.trace.iter().map(|t| t.dev_um.abs()).fold(0.0, f64::max);
    let scale = scale_um_per_div(max_abs_um).unwrap();
    assert_eq!(scale, 5.0, "largest |deviation| {max_abs_um} µm");
    // the +X crest (+5 µm ovality, +4 µm bump) is drawn outside the reference ring, within
    // the outermost grid ring, and to the right
    let crest = c
        .trace
        .iter()
        .max_by(|a, b| a.dev_um.total_cmp(&b.dev_um))
        .unwrap();
    let (x, y) = polar_point(crest.angle_rad, crest.dev_um, scale);
    let r = x.hypot(y);
    assert!(r > RING_DIV + 1.5 && r <= RING_DIV + HALF_SPAN_DIV, "{r}");
    assert!(x > 0.0 && y.abs() < 0.1 * x, "{x}, {y}");
}

#[test]
fn every_case_gets_a_png_and_an_svg() {
    let dir = scratch("files");
    let r = CircleReport {
        machine: "synthetic".into(),
        cases: vec![synthetic_case()],
    };
    let n = figures(&dir, &r).unwrap();
    assert_eq!(n, 2);
    let png = std::fs::read(dir.join("circle_synthetic_r50_cw.png")).unwrap();
    let svg = std::fs::read_to_string(dir.join("circle_synthetic_r50_cw.svg")).unwrap();
    assert!(png.len() > 1000, "{} bytes", png.len());
    assert_eq!(&png[1..4], b"PNG");
    assert!(
        svg.contains("<svg") && svg.contains("5 µm/div"),
        "{} bytes",
        svg.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_case_without_a_trace_is_refused_by_name() {
    let dir = scratch("empty");
    let mut c = synthetic_case();
    c.trace.clear();
    let e = case_figure(&dir, "synthetic", &c).unwrap_err().to_string();
    assert!(e.contains("synthetic_r50_cw") && e.contains("trace"), "{e}");
    let mut c = synthetic_case();
    c.trace[7].dev_um = f64::NAN;
    let e = case_figure(&dir, "synthetic", &c).unwrap_err().to_string();
    assert!(
        e.contains("synthetic_r50_cw") && e.contains("sample 7"),
        "{e}"
    );
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "no files");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_trace_stays_out_of_the_json() {
    let v = serde_json::to_value(synthetic_case()).unwrap();
    let mut keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
    keys.sort_unstable();
    // CircleCase's JSON keys are public interface (README, "circle"), sorted here
    assert_eq!(
        keys,
        [
            "centre_offset_um",
            "circular_deviation_um",
            "contour_max_um",
            "direction",
            "feed_mm_min",
            "name",
            "radius_deviation_um",
            "radius_mm",
            "reversal_spike_um",
        ]
    );
}
