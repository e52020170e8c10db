//! Corners between lines: the samples stay within the blend tolerance ε of the programmed
//! polyline for every turn angle (near-tangent to reversal) and keep the per-axis limits; a
//! corner is never slower than an exact stop (sharp ones stop, `motion::planner::corner`);
//! G61.1 (exact stop) and ε = 0 (G61) stop exactly on the corner, and an exact stop also
//! stops where the next line goes on straight.

use crate::planner_common;
use controller_core::motion::planner::{Blend, Segment};
use planner_common::*;

/// Two 10 mm lines meeting at (10, 0, 0) with direction change `turn_deg`, blend `blend`.
fn corner(
    turn_deg: f32,
    blend: Blend,
    feed: f32,
) -> (Vec<controller_core::motion::planner::PathSample>, Vec<Prog>) {
    let cfg = config();
    let t = turn_deg.to_radians();
    let a = [0.0f32, 0.0, 0.0];
    let b = [10.0f32, 0.0, 0.0];
    let c = [10.0 + 10.0 * t.cos(), 10.0 * t.sin(), 0.0];
    let segs = [
        Segment::line(b, feed, 1).with_blend(blend),
        Segment::line(c, feed, 2),
    ];
    let prog = vec![Prog::Line { a, b }, Prog::Line { a: b, b: c }];
    let mut mp = Mp::new(&cfg, a).unwrap();
    let s = run(&mut mp, &segs, 200_000);
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(
        rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
        "turn {turn_deg}: limits {rv} {ra} {rj}"
    );
    assert_eq!(mp.planner_status().slips, 0, "turn {turn_deg}");
    // Both lines reach the programmed feed (10 mm is ample at 50 mm/s): nothing of the
    // corner's lower speed limit outlives it.
    for tag in [1, 2] {
        let vmax = s
            .iter()
            .filter(|x| x.tag == tag)
            .map(|x| x.path_speed_mm_s)
            .fold(0.0f32, f32::max);
        assert!(
            vmax >= 0.999 * feed,
            "turn {turn_deg}: line {tag} peaks at {vmax}"
        );
    }
    let last = s.last().unwrap().pos_mm.to_array();
    for i in 0..3 {
        assert!(
            (last[i] - c[i]).abs() < 1e-4,
            "turn {turn_deg}: end {last:?}"
        );
    }
    (s, prog)
}

/// Speed along the path at the sample closest to the corner point.
fn speed_at_corner(s: &[controller_core::motion::planner::PathSample]) -> f32 {
    let mut best = (f32::INFINITY, 0.0);
    for x in s {
        let p = x.pos_mm.to_array();
        let d = ((p[0] - 10.0).powi(2) + p[1].powi(2) + p[2].powi(2)).sqrt();
        if d < best.0 {
            best = (d, x.path_speed_mm_s);
        }
    }
    best.1
}

#[test]
fn blended_corners_stay_within_tolerance() {
    // Corner angles 179.9° (near-tangent), 170°, 135°, 90°, 10° and a reversal (0°), as
    // direction changes 0.1° .. 180°.
    for turn in [0.1f32, 10.0, 45.0, 90.0, 170.0, 180.0] {
        for eps in [0.002f32, 0.01, 0.05] {
            let (s, prog) = corner(turn, Blend::Tolerance(eps), 50.0);
            let dev = max_deviation(&s, &prog);
            // ε bounds the blend; the span fit adds at most 2e-5 mm, f32 rounding 1e-5.
            assert!(
                dev <= eps as f64 + 3e-5,
                "turn {turn} ε {eps}: deviation {dev}"
            );
            // Blended or stopped, whichever is faster (`corner`): never slower than the
            // exact stop, and gentle corners are blended.
            let stop = corner(turn, Blend::ExactStop, 50.0).0;
            assert!(
                s.len() <= stop.len() + 2,
                "turn {turn} ε {eps}: {} periods, {} with an exact stop",
                s.len(),
                stop.len()
            );
            let v = speed_at_corner(&s);
            if turn <= 10.0 {
                assert!(v > 0.1, "turn {turn} ε {eps}: corner speed {v}");
            }
        }
    }
}

#[test]
fn near_tangent_join_keeps_the_feed() {
    let (s, _) = corner(0.1, Blend::Tolerance(0.01), 50.0);
    let v = speed_at_corner(&s);
    assert!(v > 49.9, "corner speed {v}");
}

#[test]
fn larger_tolerance_gives_faster_corners() {
    // 20°: a stop within 2 µm, a blend within 50 µm
    let run = |e: f32| corner(20.0, Blend::Tolerance(e), 50.0).0;
    let (s0, s1, s2) = (run(0.002), run(0.01), run(0.05));
    let n: Vec<usize> = [&s0, &s1, &s2].iter().map(|s| s.len()).collect();
    assert!(n[0] >= n[1] && n[1] >= n[2] && n[2] < n[0], "periods {n:?}");
    let v: Vec<f32> = [&s0, &s1, &s2].iter().map(|s| speed_at_corner(s)).collect();
    assert!(
        v[0] <= v[1] && v[1] < v[2] && v[2] > 10.0,
        "corner speeds {v:?}"
    );
}

#[test]
fn exact_stop_stops_on_the_corner() {
    for blend in [Blend::ExactStop, Blend::Tolerance(0.0)] {
        let (s, prog) = corner(90.0, blend, 50.0);
        let dev = max_deviation(&s, &prog);
        assert!(dev < 2e-5, "{blend:?}: deviation {dev}");
        // Somewhere the machine is at rest within 1e-5 mm of the corner.
        let stopped = s.iter().any(|x| {
            let p = x.pos_mm.to_array();
            x.path_speed_mm_s == 0.0 && ((p[0] - 10.0).powi(2) + p[1].powi(2)).sqrt() < 1e-5
        });
        assert!(stopped, "{blend:?}: no stop at the corner");
    }
}

#[test]
fn reversal_turns_back_within_tolerance() {
    let (s, _) = corner(180.0, Blend::Tolerance(0.01), 50.0);
    // Furthest point along +x: within ε of the corner, never beyond it.
    let xmax = s.iter().map(|x| x.pos_mm.x).fold(f32::MIN, f32::max);
    assert!(
        (10.0 - 0.01..=10.0 + 1e-5).contains(&xmax),
        "turn-around at x = {xmax}"
    );
    // Off-axis motion: none.
    let ymax = s.iter().map(|x| x.pos_mm.y.abs()).fold(0.0f32, f32::max);
    assert!(ymax < 1e-5, "|y| {ymax}");
}

#[test]
fn exact_stop_also_stops_where_the_path_goes_on_straight_and_exact_path_does_not() {
    // (corner() with no turn: two collinear 10 mm lines, the junction at X10)
    let (s, _) = corner(0.0, Blend::ExactStop, 50.0);
    let v = speed_at_corner(&s);
    // G61.1: at rest at the end of the first segment
    assert!(v < 0.5, "exact stop: speed {v} at the collinear junction");
    let stopped = s
        .iter()
        .any(|x| x.path_speed_mm_s == 0.0 && (x.pos_mm.x - 10.0).abs() < 1e-5);
    assert!(stopped, "exact stop: no stop at X10");
    // G61 (tolerance 0): the same junction at full feed
    let (s, _) = corner(0.0, Blend::Tolerance(0.0), 50.0);
    let v = speed_at_corner(&s);
    assert!(v > 49.9, "exact path: speed {v} at the collinear junction");
}
