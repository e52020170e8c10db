//! Soft limits: programs and jog targets against the machine's travel, with exact arc
//! extremes.

// Axis loops index several arrays at once; ranges read clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::TAU;

use host_sim::gcode::{
    arc_extent, check_travel, parse_str, parse_str_with, ErrorKind, MoveKind, ParseOptions, Plane,
    Travel, TravelViolation,
};
use proptest::prelude::*;

fn travel() -> Travel {
    Travel::new([[-150.0, 150.0], [-150.0, 150.0], [-50.0, 50.0]]).unwrap()
}

fn check(text: &str) -> Result<(), String> {
    let p = parse_str("prog.nc", text).map_err(|e| format!("parse: {e}"))?;
    check_travel(&p, &travel()).map_err(|e| e.to_string())
}

#[test]
fn straight_moves_name_line_and_axis() {
    let text = "G21\nG0 X0\nG1 X100 F600\n\n\n\nG1 X212\n";
    assert_eq!(
        check(text).unwrap_err(),
        "prog.nc:7: X would leave the travel: 212.000 mm > +150.000 mm"
    );
    assert_eq!(
        check("G0 Z-60.5").unwrap_err(),
        "prog.nc:1: Z would leave the travel: -60.500 mm < -50.000 mm"
    );
    // Exactly on the limit is inside.
    assert_eq!(check("G0 X150 Y-150 Z50"), Ok(()));
    let e = check_travel(&parse_str("p.nc", "G0 Y151").unwrap(), &travel()).unwrap_err();
    assert_eq!((e.kind, e.line), (ErrorKind::Travel, Some(1)));
}

#[test]
fn arcs_are_checked_at_their_exact_extremes() {
    // Half circles from (80, 140) to (120, 140) about (100, 140): both ends inside.
    let text = "G0 X80 Y140\nG3 X120 Y140 I20 J0 F600\n";
    // CCW from 180° to 0° about (100, 140) passes 270°: the bottom, Y = 120: inside.
    assert_eq!(check(text), Ok(()));
    // Clockwise the same ends pass 90°: the top, Y = 160: outside.
    let text = "G0 X80 Y140\nG2 X120 Y140 I20 J0 F600\n";
    assert_eq!(
        check(text).unwrap_err(),
        "prog.nc:2: Y would leave the travel: 160.000 mm > +150.000 mm"
    );
    // A circle touching the limit exactly is accepted.
    assert_eq!(check("G0 X130\nG2 X130 Y0 I10 J0 F600"), Ok(()));
    assert!(check("G0 X130.001\nG2 X130.001 Y0 I10 J0 F600").is_err());
    // Helix: Z is linear, the end counts.
    assert_eq!(
        check("G0 X10\nG2 X10 Y0 Z-51 I-10 F600").unwrap_err(),
        "prog.nc:2: Z would leave the travel: -51.000 mm < -50.000 mm"
    );
}

#[test]
fn start_point_outside_is_reported_without_a_line() {
    let opts = ParseOptions {
        start_mm: [0.0, 0.0, 60.0],
        ..ParseOptions::default()
    };
    let p = parse_str_with("prog.nc", "G0 Z0", &opts).unwrap();
    assert_eq!(
        check_travel(&p, &travel()).unwrap_err().to_string(),
        "prog.nc: the start point is outside the travel: Z would leave the travel: 60.000 mm > +50.000 mm"
    );
}

#[test]
fn jog_targets() {
    let t = travel();
    assert_eq!(t.check_point([0.0, 150.0, -50.0]), Ok(()));
    let v = t.check_point([212.0, 0.0, 0.0]).unwrap_err();
    assert_eq!(
        v,
        TravelViolation {
            axis: 0,
            value_mm: 212.0,
            limit_mm: 150.0
        }
    );
    assert_eq!(
        v.to_string(),
        "X would leave the travel: 212.000 mm > +150.000 mm"
    );
    assert_eq!(
        t.check_point([0.0, -150.5, 0.0]).unwrap_err().to_string(),
        "Y would leave the travel: -150.500 mm < -150.000 mm"
    );
    assert!(t.check_point([0.0, 0.0, f64::NAN]).is_err());
    assert_eq!(
        t.limits_mm(),
        [[-150.0, 150.0], [-150.0, 150.0], [-50.0, 50.0]]
    );
}

#[test]
fn travel_is_validated() {
    assert_eq!(
        Travel::new([[0.0, 300.0], [10.0, 10.0], [0.0, 1.0]])
            .unwrap_err()
            .to_string(),
        "travel of Y must be finite with min < max, got [10, 10] mm"
    );
    assert!(Travel::new([[0.0, f64::INFINITY], [0.0, 1.0], [0.0, 1.0]]).is_err());
    assert!(Travel::new([[f64::NAN, 1.0], [0.0, 1.0], [0.0, 1.0]]).is_err());
}

/// Dense sampling of an arc with the radius interpolated linearly in angle (what the
/// planner is told to do), for comparing with the exact extent.
fn sample_extent(
    from: [f64; 3],
    to: [f64; 3],
    c: [f64; 3],
    plane: Plane,
    cw: bool,
    sweep: f64,
) -> [[f64; 2]; 3] {
    let [a0, a1, n] = plane.axes();
    let r0 = (from[a0] - c[a0]).hypot(from[a1] - c[a1]);
    let r1 = (to[a0] - c[a0]).hypot(to[a1] - c[a1]);
    let t0 = (from[a1] - c[a1]).atan2(from[a0] - c[a0]);
    let sign = if cw { -1.0 } else { 1.0 };
    let mut e = [[f64::INFINITY, f64::NEG_INFINITY]; 3];
    let steps = 20_000;
    for i in 0..=steps {
        let s = i as f64 / steps as f64;
        let (r, th) = (r0 + (r1 - r0) * s, t0 + sign * sweep * s);
        let mut p = [0.0; 3];
        p[a0] = c[a0] + r * th.cos();
        p[a1] = c[a1] + r * th.sin();
        p[n] = from[n] + (to[n] - from[n]) * s;
        for a in 0..3 {
            e[a][0] = e[a][0].min(p[a]);
            e[a][1] = e[a][1].max(p[a]);
        }
    }
    e
}

proptest! {
    /// The exact extent contains every sampled point of the arc, and is tight: with equal
    /// radii, dense sampling reaches it to within the sampling error (r·(1 − cos(Δθ/2))).
    #[test]
    fn arc_extent_is_exact(
        cx in -50.0f64..50.0, cy in -50.0f64..50.0, r in 0.5f64..40.0,
        t0 in -3.2f64..3.2, sweep in 0.01f64..(2.5 * TAU), cw: bool,
        dz in -5.0f64..5.0, plane_i in 0usize..3,
    ) {
        let plane = [Plane::XY, Plane::ZX, Plane::YZ][plane_i];
        let [a0, a1, n] = plane.axes();
        let sign = if cw { -1.0 } else { 1.0 };
        let mut from = [0.0; 3];
        let mut to = [0.0; 3];
        let mut c = [0.0; 3];
        c[a0] = cx; c[a1] = cy; c[n] = 1.0;
        from[a0] = cx + r * t0.cos(); from[a1] = cy + r * t0.sin(); from[n] = 1.0;
        to[a0] = cx + r * (t0 + sign * sweep).cos(); to[a1] = cy + r * (t0 + sign * sweep).sin();
        to[n] = 1.0 + dz;
        let exact = arc_extent(from, to, c, plane, cw, sweep);
        let sampled = sample_extent(from, to, c, plane, cw, sweep);
        let step = sweep / 20_000.0;
        let slack = r * (1.0 - (0.5 * step).cos()) + 1e-9;
        for a in 0..3 {
            prop_assert!(exact[a][0] <= sampled[a][0] + 1e-9 && exact[a][1] >= sampled[a][1] - 1e-9,
                "axis {a}: exact {:?} sampled {:?}", exact[a], sampled[a]);
            prop_assert!(sampled[a][0] - exact[a][0] <= slack && exact[a][1] - sampled[a][1] <= slack,
                "axis {a} not tight: exact {:?} sampled {:?}", exact[a], sampled[a]);
        }
    }

    /// Parsed arcs (I/J form, end within tolerance) are bounded by their extent too, and
    /// the program's bounds contain every move's extent.
    #[test]
    fn parsed_arc_within_bounds(
        sx in -20.0f64..20.0, sy in -20.0f64..20.0, i in -30.0f64..30.0, j in -30.0f64..30.0,
        angle in -3.2f64..3.2, cw: bool,
    ) {
        let r = i.hypot(j);
        prop_assume!(r > 0.1);
        let (cx, cy) = (sx + i, sy + j);
        let (ex, ey) = (cx + r * angle.cos(), cy + r * angle.sin());
        let g = if cw { 2 } else { 3 };
        let text = format!("G0 X{sx:.6} Y{sy:.6}\nG{g} X{ex:.6} Y{ey:.6} I{i:.6} J{j:.6} F600\n");
        let p = parse_str("p.nc", &text).unwrap();
        for m in &p.moves {
            let e = m.extent_mm();
            if let MoveKind::Arc { to, center, plane, clockwise, sweep_rad, .. } = m.kind {
                let s = sample_extent(m.from, to, center, plane, clockwise, sweep_rad);
                for a in 0..3 {
                    prop_assert!(e[a][0] <= s[a][0] + 1e-9 && e[a][1] >= s[a][1] - 1e-9);
                }
            }
            for a in 0..3 {
                prop_assert!(p.bounds_mm[a][0] <= e[a][0] && p.bounds_mm[a][1] >= e[a][1]);
            }
        }
    }
}
