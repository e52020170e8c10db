//! Arcs in every plane and direction, full circles with extra turns, helices: the
//! executed path stays on the programmed arc, ends on the programmed point, keeps the
//! per-axis limits and runs at the programmed feed where the limits allow.

use crate::planner_common;
use controller_core::motion::planner::{Blend, Plane, Segment};
use planner_common::*;

/// One arc (optionally helical) from `start`, checked end to end.
fn check_arc(plane: Plane, cw: bool, turns: u32, rise: f32, full: bool) {
    let cfg = config();
    let (i1, i2, n) = match plane {
        Plane::XY => (0, 1, 2),
        Plane::ZX => (2, 0, 1),
        Plane::YZ => (1, 2, 0),
    };
    let start = [5.0f32, -3.0, 2.0];
    let r = 8.0f32;
    let mut center = start;
    center[i1] -= r; // start at angle 0
    let mut end = start;
    if !full {
        // 120° counter-clockwise from the start.
        let a = 120f32.to_radians();
        end[i1] = center[i1] + r * a.cos();
        end[i2] = center[i2] + r * a.sin();
    }
    end[n] += rise;
    let seg = Segment::arc(end, center, plane, cw, turns, 40.0, 7);
    let prog = [Prog::Arc {
        start,
        end,
        center,
        plane,
        cw,
        turns,
    }];
    let mut mp = Mp::new(&cfg, start).unwrap();
    let s = run(&mut mp, &[seg], 400_000);
    let label = format!("{plane:?} cw {cw} turns {turns} rise {rise} full {full}");
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(
        rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
        "{label}: {rv} {ra} {rj}"
    );
    // On the arc: the only deviation is the f32 rounding and the span fit (2e-5 mm).
    let dev = max_deviation(&s, &prog);
    assert!(dev < 1.0e-4, "{label}: deviation {dev}");
    let last = s.last().unwrap().pos_mm.to_array();
    for i in 0..3 {
        assert!(
            (last[i] - end[i]).abs() < 1e-4,
            "{label}: end {last:?} vs {end:?}"
        );
    }
    // The feed is reached: 40 mm/s on r = 8 needs 200 mm/s² centripetal, well inside.
    let peak = s.iter().map(|x| x.path_speed_mm_s).fold(0.0f32, f32::max);
    assert!((peak - 40.0).abs() < 40.0 * 1e-4, "{label}: peak {peak}");
    assert!(s.iter().all(|x| x.tag == 7));
    assert_eq!(mp.planner_status().slips, 0);
    // Tangent: unit and along the velocity while moving.
    for x in &s {
        let t = x.tangent.to_array();
        let nt = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        assert!((nt - 1.0).abs() < 1e-6, "{label}: |tangent| {nt}");
        let v = x.vel_mm_s.to_array();
        let nv = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if nv > 1.0 {
            let c = (v[0] * t[0] + v[1] * t[1] + v[2] * t[2]) / nv;
            assert!(c > 0.9999, "{label}: tangent {t:?} velocity {v:?}");
        }
    }
}

#[test]
fn arcs_in_every_plane_both_directions() {
    for plane in [Plane::XY, Plane::ZX, Plane::YZ] {
        for cw in [false, true] {
            check_arc(plane, cw, 0, 0.0, false);
        }
    }
}

#[test]
fn helical_arcs() {
    check_arc(Plane::XY, false, 0, 6.0, false);
    check_arc(Plane::ZX, true, 0, -4.0, false);
    check_arc(Plane::YZ, false, 1, 10.0, true);
}

#[test]
fn full_circles_with_extra_turns() {
    check_arc(Plane::XY, false, 0, 0.0, true);
    check_arc(Plane::XY, true, 2, 0.0, true);
}

/// A line into a tangent arc and out on a tangent line: the curvature jumps at the joins
/// are blended (C²), the feed is kept, the deviation stays within ε.
#[test]
fn tangent_line_arc_line() {
    let cfg = config();
    let start = [0.0f32, 0.0, 0.0];
    let a = [10.0f32, 0.0, 0.0];
    let center = [10.0f32, 5.0, 0.0];
    let b = [15.0f32, 5.0, 0.0]; // quarter circle CCW, radius 5
    let c = [15.0f32, 15.0, 0.0];
    let segs = [
        Segment::line(a, 30.0, 1),
        Segment::arc(b, center, Plane::XY, false, 0, 30.0, 2),
        Segment::line(c, 30.0, 3),
    ];
    let prog = [
        Prog::Line { a: start, b: a },
        Prog::Arc {
            start: a,
            end: b,
            center,
            plane: Plane::XY,
            cw: false,
            turns: 0,
        },
        Prog::Line { a: b, b: c },
    ];
    let mut mp = Mp::new(&cfg, start).unwrap();
    let s = run(&mut mp, &segs, 200_000);
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(
        rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
        "{rv} {ra} {rj}"
    );
    let dev = max_deviation(&s, &prog);
    assert!(dev <= cfg.tolerance_mm as f64 + 1e-4, "deviation {dev}");
    // Tangent joins with a curvature step of 1/5 mm: passed at the programmed feed.
    let slow = s
        .iter()
        .skip(2000)
        .take_while(|x| x.tag < 3 || x.pos_mm.y < 12.0)
        .map(|x| x.path_speed_mm_s)
        .fold(f32::INFINITY, f32::min);
    assert!(slow > 29.0, "slowest {slow}");
}

/// A 3-D curve (a helix-like space curve) cut into arcs through a point in planes of every
/// orientation, tangent at some joins and not at others, and blended: the executed path
/// stays within the tolerance of the arcs, keeps the per-axis limits, ends on the last
/// point, never slips.
#[test]
fn arcs_through_a_point_in_tilted_planes() {
    let cfg = config();
    // points of a space curve: a helix of radius 15 whose axis wobbles
    let curve = |t: f32| {
        [
            15.0 * t.cos() + 2.0 * (3.0 * t).sin(),
            15.0 * t.sin(),
            4.0 * t + 3.0 * (2.0 * t).cos(),
        ]
    };
    let mut segs = Vec::new();
    let mut prog = Vec::new();
    let mut t = 0.0f32;
    let mut start = curve(t);
    let first = start;
    for k in 0..24u32 {
        let dt = 0.2 + 0.15 * ((k % 5) as f32);
        let (via, end) = (curve(t + 0.5 * dt), curve(t + dt));
        segs.push(
            Segment::arc_through(via, end, 80.0 + 10.0 * (k % 3) as f32, k + 1)
                .with_blend(Blend::Tolerance(0.01)),
        );
        prog.push(Prog::Through { start, via, end });
        start = end;
        t += dt;
    }
    let mut mp = Mp::new(&cfg, first).unwrap();
    let s = run(&mut mp, &segs, 2_000_000);
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(
        rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
        "{rv} {ra} {rj}"
    );
    let dev = max_deviation(&s, &prog);
    assert!(dev <= 0.01 + 1e-5, "deviation {dev}");
    let last = s.last().unwrap().pos_mm.to_array();
    for i in 0..3 {
        assert!(
            (last[i] - start[i]).abs() < 1e-4,
            "end {last:?} vs {start:?}"
        );
    }
    assert_eq!(mp.planner_status().slips, 0);
    // the feed is kept between the joins (the curve's radius is about 15 mm)
    let peak = s.iter().map(|x| x.path_speed_mm_s).fold(0.0f32, f32::max);
    assert!(peak > 79.0, "peak {peak}");
}
