//! Corners: whether a line–line corner is passed faster by stopping exactly at it than
//! along its blend.
//!
//! A blend within ε of a sharp corner is short (half-width `d = 6ε/|Δu|`: 42 µm for 90°
//! within 10 µm) and tightly curved (peak curvature `|Δu|/d`, curvature rate `|Δu|/d²`),
//! so its speed cap `v_b` is a few mm/s. Both ways stay within the tolerance (a stop
//! follows the programmed corner exactly); the planner takes the faster. Measured on two
//! 38/30 mm lines at 100 mm/s (factory limits, reserve 0): a 90° corner took 0.861 s
//! blended and 0.821 s stopped.
//!
//! Per side of the corner, against the stop, the blend
//! * crawls the transition's half `d` at `v_b` instead of running it in the stop's
//!   braking tail: `d/v_b − d/V` more (the tail is part of the braking both ways);
//! * brakes from the approach speed V to `v_b` instead of 0, which saves
//!   `T(V→0) − T(V→v_b)` of braking and `(X(V→0) − X(V→v_b))/V` of cruising (T, X: time
//!   and distance of the time-optimal jerk-limited speed change at the lines' limits);
//!
//! and the stop is taken where the crawl costs more than the braking saves. `v_b` is the
//! speed cap of the whole transition (`span::path_limits` over its derivative bounds:
//! `|p'_i| ≤ max(|u_A,i|, |u_B,i|)`, `|p''_i| ≤ |Δu_i|/d`, `|p'''_i| ≤ |Δu_i|/d²`), which
//! the planner's spans at the corner's middle allow at most; V the feed within the lines'
//! speed limits. With the factory limits, ε = 10 µm and 100 mm/s, corners of more than
//! about 30-45° stop (`tests`).

use super::blend::Junction;
use super::config::ValidPlannerConfig;
use super::fmath::{self, F32Ext};
use super::geometry::Piece;
use super::span::{path_limits, DerivBounds};

/// Whether the junction `j` between the lines `a` and `b` (the lower feed of the two
/// `feed_mm_s`) is faster as an exact stop.
pub(crate) fn stop_is_faster(
    j: &Junction,
    a: &Piece,
    b: &Piece,
    feed_mm_s: f32,
    s: &ValidPlannerConfig,
) -> bool {
    let d = j.d;
    if j.stop || j.mixed || a.is_curved() || b.is_curved() || !(d > 0.0) {
        return false;
    }
    let (ua, ub) = (a.derivs(a.len).d1, b.derivs(0.0).d1);
    let mut bounds = DerivBounds::default();
    for i in 0..3 {
        let du = j.du[i].abs();
        bounds.p1[i] = ua[i].abs().mx(ub[i].abs());
        bounds.p2[i] = du / d;
        bounds.p3[i] = du / (d * d);
    }
    let v_b = path_limits(&bounds, f32::INFINITY, f32::INFINITY, s).vel;
    // The lines' own limits: projected on each direction, the weaker line's.
    let (mut vel, mut acc, mut jerk) = (feed_mm_s, f32::INFINITY, f32::INFINITY);
    for u in [ua, ub] {
        for (i, c) in u.to_array().iter().map(|x| x.abs()).enumerate() {
            if c > 0.0 {
                vel = vel.mn(s.vel_max[i] / c);
                acc = acc.mn(s.acc_max[i] / c);
                jerk = jerk.mn(s.path_jerk_share * s.jerk_max[i] / c);
            }
        }
    }
    if !(acc.is_finite() && jerk.is_finite() && vel > v_b && v_b > 0.0) {
        return false;
    }
    let time = |dv: f32| speed_change_time(dv, acc, jerk);
    let saved_braking = time(vel) - time(vel - v_b);
    let saved_cruise = (0.5 * vel * time(vel) - 0.5 * (vel + v_b) * time(vel - v_b)) / vel;
    let crawl = d / v_b - d / vel;
    crawl > saved_braking + saved_cruise
}

/// Time of the time-optimal jerk-limited change of speed by `dv` between two states at
/// zero acceleration.
fn speed_change_time(dv: f32, acc: f32, jerk: f32) -> f32 {
    if dv * jerk >= acc * acc {
        dv / acc + acc / jerk
    } else {
        2.0 * fmath::sqrt(dv.mx(0.0) / jerk)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::planner::blend::plan_junction;
    use crate::motion::planner::blend::tests::line;
    use crate::motion::planner::config::GANTRY_PLANNER;

    fn stops(turn_deg: f32, reserve: f32, feed: f32) -> bool {
        let mut c = GANTRY_PLANNER;
        c.servo_reserve = reserve;
        let s = ValidPlannerConfig::new(&c).unwrap();
        let t = turn_deg.to_radians();
        let a = line([0.0; 3], [10.0, 0.0, 0.0]);
        let b = line(
            [10.0, 0.0, 0.0],
            [10.0 + 10.0 * t.cos(), 10.0 * t.sin(), 0.0],
        );
        let j = plan_junction(&a, &b, Some(0.01), &Junction::NONE, 10.0, 2e-5, 5e-4);
        stop_is_faster(&j, &a, &b, feed, &s)
    }

    #[test]
    fn sharp_corners_stop_and_gentle_ones_blend() {
        // Measured with cargo sim gcode on two lines at F6000 (docs/planner.md §9): the
        // blend is faster up to 10-20°, the stop from 45-60° on, at both reserves.
        for r in [0.0, 0.75] {
            for turn in [2.0, 5.0, 10.0] {
                assert!(!stops(turn, r, 100.0), "{turn}° at R {r}");
            }
            for turn in [60.0, 90.0, 120.0, 150.0, 179.0] {
                assert!(stops(turn, r, 100.0), "{turn}° at R {r}");
            }
        }
        // At a feed the blend allows there is nothing to brake for: the blend.
        assert!(!stops(90.0, 0.75, 1.0));
    }

    #[test]
    fn speed_change_time_is_continuous_at_the_regime_change() {
        let (a, j) = (2000.0f32, 1.0e5f32);
        let dv = a * a / j;
        let lo = speed_change_time(dv * (1.0 - 1e-4), a, j);
        let hi = speed_change_time(dv, a, j);
        assert!((hi - lo).abs() < 1e-5, "{lo} {hi}");
        assert!((hi - 0.04).abs() < 1e-6, "{hi}");
    }
}
