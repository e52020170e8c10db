//! Rest-to-rest lines: the planned time against the time-optimal jerk-limited move under
//! the axis limits projected on the line's direction (`min_i lim_i / |u_i|`, the path jerk
//! with the configured servo reserve), for lengths from 0.1 to 300 mm along an axis, the
//! XY diagonal and the space diagonal. A 45° line gets √2 times an axis' limits.

use crate::planner_common;
use controller_core::motion::planner::{Blend, PlannerConfig, Segment, GANTRY_PLANNER};
use planner_common::*;

/// Time-optimal rest-to-rest time of a 1-D move of `len` with limits `v`, `a`, `j`
/// (symmetric S-curve: ramp, hold, ramp to the peak speed, cruise, and back).
fn optimal_s(len: f64, v: f64, a: f64, j: f64) -> f64 {
    // time and distance to reach speed `vp` from rest (and back to rest)
    let ramp = |vp: f64| {
        let t = if vp * j >= a * a {
            vp / a + a / j
        } else {
            2.0 * (vp / j).sqrt()
        };
        (t, 0.5 * vp * t)
    };
    let (t, d) = ramp(v);
    if 2.0 * d <= len {
        return 2.0 * t + (len - 2.0 * d) / v;
    }
    let (mut lo, mut hi) = (0.0, v);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if 2.0 * ramp(mid).1 <= len {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    2.0 * ramp(lo).0
}

/// Periods from the start until the planner is at rest at the end, in seconds.
fn planned_s(cfg: &PlannerConfig, dir: [f32; 3], len: f32) -> f64 {
    let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    let end = dir.map(|d| d / n * len);
    let seg = Segment::line(end, 1.0e4, 1).with_blend(Blend::ExactStop);
    let mut mp = Mp::new(cfg, [0.0; 3]).unwrap();
    let s = run(&mut mp, &[seg], 10_000_000);
    let moving = s
        .iter()
        .rposition(|x| x.path_speed_mm_s > 0.0 || x.path_acc_mm_s2 != 0.0)
        .unwrap();
    let last = s[moving + 1].pos_mm.to_array();
    for i in 0..3 {
        assert!(
            (last[i] - end[i]).abs() < 1e-4,
            "ended at {last:?}, not {end:?}"
        );
    }
    (moving + 1) as f64 * f64::from(cfg.period_s)
}

#[test]
fn rest_to_rest_lines_are_within_3_percent_of_the_time_optimal_move() {
    for reserve in [0.0f32, GANTRY_PLANNER.servo_reserve] {
        let mut cfg = GANTRY_PLANNER;
        cfg.servo_reserve = reserve;
        for dir in [[1.0f32, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, -1.0, 1.0]] {
            let n = (dir.iter().map(|d| d * d).sum::<f32>()).sqrt();
            // the weakest axis along the direction (all alike here)
            let u = dir.iter().fold(0.0f32, |m, d| m.max(d.abs() / n)) as f64;
            let v = f64::from(cfg.vel_max_mm_s[0]) / u;
            let a = f64::from(cfg.acc_max_mm_s2[0]) / u;
            let j = f64::from(cfg.jerk_max_mm_s3[0]) * f64::from(1.0 - reserve) / u;
            for len in [0.1f32, 1.0, 10.0, 100.0, 300.0] {
                let t = planned_s(&cfg, dir, len);
                let best = optimal_s(f64::from(len), v, a, j);
                let ratio = t / best;
                println!("reserve {reserve} dir {dir:?} {len} mm: {t:.4} s, optimal {best:.4} s, ratio {ratio:.4}");
                assert!(ratio <= 1.03, "{dir:?} {len} mm: {t} s vs {best} s");
                // (the sampled profile may end up to a period before the continuous one)
                let period = f64::from(cfg.period_s);
                assert!(
                    t >= best - 2.0 * period,
                    "faster than the optimum: {t} vs {best}"
                );
            }
        }
    }
}

/// The time-optimal profile itself, checked at known values (250 mm/s, 2000 mm/s²,
/// 1e5 mm/s³: 100 mm take 0.545 s; a short move never reaches the acceleration limit).
#[test]
fn optimal_move_reference_values() {
    assert!((optimal_s(100.0, 250.0, 2000.0, 1.0e5) - 0.545).abs() < 1e-9);
    // 0.1 mm, jerk only: d = 2 J τ³ per half, T = 4τ
    let tau = (0.1f64 / (2.0 * 1.0e5)).cbrt();
    assert!((optimal_s(0.1, 250.0, 2000.0, 1.0e5) - 4.0 * tau).abs() < 1e-6);
}
