//! Jerk-limited (S-curve) motion of the path parameter σ: exact integration over one period
//! under constant jerk, the time-optimal braking distance, and the two discrete control laws
//! built on it (approach a speed target and land on it with zero acceleration; stop).
//!
//! Every profile here is the classic 7-phase shape reduced to what one period needs: the
//! acceleration ramps at ±J, holds at ±A, ramps back. Nothing is precomputed per segment:
//! the look-ahead (`super::lookahead`) asks these functions every period whether the
//! state after a candidate jerk can still brake in time for every constraint ahead, which
//! is what lets the acceleration stay non-zero across any number of short spans.
//!
//! All inputs are checked for the degenerate cases (zero limits, zero period) so that no
//! division by zero and no NaN can come out; callers pass validated, positive limits.

/// Smallest limit used as a divisor (mm/s² or mm/s³); validated limits are far above.
use super::fmath::{self, F32Ext};

const TINY: f32 = 1.0e-12;

/// Exact motion over `t` seconds under constant jerk `j` from speed `v` and acceleration
/// `a`: returns `(Δσ, v', a')`.
#[inline]
pub fn integrate(v: f32, a: f32, j: f32, t: f32) -> (f32, f32, f32) {
    let t2 = t * t;
    let ds = v * t + 0.5 * a * t2 + j * t2 * t * (1.0 / 6.0);
    (ds, v + a * t + 0.5 * j * t2, a + j * t)
}

/// Distance to brake from `v` to `w` (both at zero acceleration, `v > w`) with acceleration
/// limit `amax` and jerk limit `jmax` (time-optimal: ramp, hold, ramp).
pub fn rest_to_rest_distance(v: f32, w: f32, amax: f32, jmax: f32) -> f32 {
    let dv = v - w;
    if !(dv > 0.0) {
        return 0.0;
    }
    let (amax, jmax) = (amax.mx(TINY), jmax.mx(TINY));
    if dv * jmax >= amax * amax {
        // Reaches amax: two ramps of amax/jmax plus a constant-deceleration phase.
        0.5 * (v + w) * (dv / amax + amax / jmax)
    } else {
        // Triangular acceleration: peak sqrt(jmax dv), total time 2 sqrt(dv/jmax).
        (v + w) * fmath::sqrt(dv / jmax)
    }
}

/// Distance the time-optimal braking from state `(v, a)` needs until the speed is at or
/// below `w` for good (the acceleration back at zero or the speed below `w` while it
/// ramps back). Zero when the speed never exceeds `w` again.
pub fn braking_distance(v: f32, a: f32, w: f32, amax: f32, jmax: f32) -> f32 {
    let (amax, jmax) = (amax.mx(TINY), jmax.mx(TINY));
    if a > 0.0 {
        // Bring the acceleration down first; the speed still rises to its peak.
        let t0 = a / jmax;
        let peak = v + 0.5 * a * a / jmax;
        if !(peak > w) {
            return 0.0;
        }
        let d0 = v * t0 + 0.5 * a * t0 * t0 - jmax * t0 * t0 * t0 * (1.0 / 6.0);
        return d0.mx(0.0) + rest_to_rest_distance(peak, w, amax, jmax);
    }
    if !(v > w) {
        return 0.0;
    }
    // Already braking (deceleration m ≥ 0); deceleration beyond this constraint's limit is
    // not counted on. Each phase's distance is summed directly (no difference of large
    // terms), so f32 keeps the result to a few ulps: the look-ahead rides this curve.
    let m = (-a).mn(amax);
    let j = jmax;
    if v - 0.5 * m * m / j < w {
        // Braking harder than needed: the speed passes `w` while the deceleration ramps out.
        let disc = (m * m - 2.0 * j * (v - w)).mx(0.0);
        let t = ((m - fmath::sqrt(disc)) / j).mx(0.0);
        return (v * t - 0.5 * m * t * t + j * t * t * t * (1.0 / 6.0)).mx(0.0);
    }
    // Peak deceleration of ramp-in (from m), possible hold, ramp-out ending at w.
    let ap2 = j * (v - w) + 0.5 * m * m;
    let (ap, hold) = if ap2 <= amax * amax {
        (fmath::sqrt(ap2), 0.0)
    } else {
        let v1 = v - 0.5 * (amax * amax - m * m) / j;
        let v3 = w + 0.5 * amax * amax / j;
        (amax, ((v1 - v3) * (v1 + v3) / (2.0 * amax)).mx(0.0))
    };
    let t1 = ((ap - m) / j).mx(0.0);
    let ramp_in = v * t1 - 0.5 * m * t1 * t1 - j * t1 * t1 * t1 * (1.0 / 6.0);
    let ramp_out = w * ap / j + ap * ap * ap / (6.0 * j * j);
    (ramp_in.mx(0.0) + hold + ramp_out).mx(0.0)
}

/// Distance covered while the acceleration ramps down from `a` to `a_to` (< `a`) at jerk
/// `jmax` starting at speed `v`.
pub fn ramp_down_distance(v: f32, a: f32, a_to: f32, jmax: f32) -> f32 {
    if !(a > a_to) {
        return 0.0;
    }
    let t = (a - a_to) / jmax.mx(TINY);
    (v * t + 0.5 * a * t * t - jmax * t * t * t * (1.0 / 6.0)).mx(0.0)
}

/// The jerk for the next period that approaches speed `target` as fast as `amax`/`jmax`
/// allow and lands on it with zero acceleration, from above or from below.
///
/// With `x` the acceleration at the end of the period, the speed then is
/// `v' = v + (a + x) T / 2`; ramping `x` back to zero at full jerk adds `x|x|/(2J)`. From
/// below the largest `x` whose peak `v' + x²/(2J)` stays ≤ target is taken, from above the
/// smallest whose trough stays ≥ target: both are roots of a quadratic, so the approach
/// needs no iteration and ends exactly on the target (up to `J T²/8` of the last period).
pub fn track_jerk(v: f32, a: f32, target: f32, amax: f32, jmax: f32, t: f32) -> f32 {
    track_jerk_landing(v, a, target, amax, jmax, jmax, t)
}

/// As [`track_jerk`], with the landing (the acceleration ramped out after this period)
/// modelled at jerk `j_land` ≤ `jmax`: the ramp-out may reach spans that allow less jerk
/// than the one this period runs on.
pub fn track_jerk_landing(
    v: f32,
    a: f32,
    target: f32,
    amax: f32,
    jmax: f32,
    j_land: f32,
    t: f32,
) -> f32 {
    if !(t > 0.0) {
        return 0.0;
    }
    let (amax, jmax) = (amax.mx(TINY), jmax.mx(TINY));
    // (the quadratic below models the ramp-out at this jerk; the result is clamped to
    // ±jmax)
    let jm = j_land.mn(jmax).mx(TINY);
    let jt = jm * t;
    let projected = v + 0.5 * a * a.abs() / jm;
    let x = if projected <= target {
        let c = target - v - 0.5 * a * t;
        let disc = 0.25 * jt * jt + 2.0 * jm * c;
        // No real root: the speed is above the target while the acceleration is so
        // negative that the trough lies below it anyway; raise it as fast as allowed.
        let root = if disc >= 0.0 {
            -0.5 * jt + fmath::sqrt(disc)
        } else {
            f32::INFINITY
        };
        if root > 0.0 {
            root
        } else {
            (2.0 * c / t).mn(0.0)
        }
    } else {
        let c = v + 0.5 * a * t - target;
        let disc = 0.25 * jt * jt + 2.0 * jm * c;
        // No real root: below the target while accelerating so hard that the peak
        // overshoots anyway; lower the acceleration as fast as allowed.
        let root = if disc >= 0.0 {
            0.5 * jt - fmath::sqrt(disc)
        } else {
            f32::NEG_INFINITY
        };
        if root < 0.0 {
            root
        } else {
            (-2.0 * c / t).mx(0.0)
        }
    };
    // The jerk itself is clamped (not the end acceleration): (x − a)/T loses the jerk's
    // precision when |a| ≫ J·T, and a braking profile ridden at slightly less than J
    // falls behind its own model.
    let j = if x.is_finite() {
        (x - a) / t
    } else if x > 0.0 {
        jmax
    } else {
        -jmax
    };
    let j = j.clampf(-jmax, jmax);
    // End acceleration within ±amax; from outside (limits just dropped) back at full jerk.
    let j_up = if a <= amax { (amax - a) / t } else { -jmax };
    let j_dn = if a >= -amax { (-amax - a) / t } else { jmax };
    j.mn(j_up.mx(-jmax)).mx(j_dn.mn(jmax))
}

/// The jerk of the time-optimal stop (target speed zero) for the next period.
#[inline]
pub fn stop_jerk(v: f32, a: f32, amax: f32, jmax: f32, t: f32) -> f32 {
    track_jerk(v, a, 0.0, amax, jmax, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f32 = 1.0e-4;

    /// Simulates the stop law from (v, a) and returns (distance, max |a|, max |j|, periods).
    fn simulate_stop(v0: f32, a0: f32, amax: f32, jmax: f32) -> (f32, f32, f32, usize) {
        let (mut v, mut a, mut s) = (v0, a0, 0.0f32);
        let (mut amx, mut jmx) = (a.abs(), 0.0f32);
        for n in 0..1_000_000 {
            if v <= 1e-6 && a.abs() <= jmax * T {
                return (s, amx, jmx, n);
            }
            let j = stop_jerk(v, a, amax, jmax, T);
            let (ds, v1, a1) = integrate(v, a, j, T);
            s += ds;
            v = v1.mx(0.0);
            a = a1;
            amx = amx.mx(a.abs());
            jmx = jmx.mx(j.abs());
        }
        (s, amx, jmx, usize::MAX)
    }

    #[test]
    fn stop_law_matches_braking_distance_and_limits() {
        for &(v0, a0) in &[
            (100.0, 0.0),
            (100.0, 1500.0),
            (100.0, -1500.0),
            (3.0, 0.0),
            (3.0, -700.0),
            (0.5, 900.0),
        ] {
            let (amax, jmax) = (2000.0, 1.0e5);
            let d = braking_distance(v0, a0, 0.0, amax, jmax);
            let (s, amx, jmx, n) = simulate_stop(v0, a0, amax, jmax);
            assert!(n < usize::MAX, "stop did not finish from ({v0}, {a0})");
            assert!(amx <= amax.mx(a0.abs()) * (1.0 + 1e-5), "|a| {amx}");
            assert!(jmx <= jmax * (1.0 + 1e-4), "|j| {jmx}");
            // The discrete stop follows the continuous one within a period's travel.
            assert!(
                (s - d).abs() <= v0 * T + 1e-4,
                "({v0},{a0}): sim {s} vs {d}"
            );
        }
    }

    #[test]
    fn rest_to_rest_both_regimes() {
        // Reaches amax: 100 -> 0 with A = 1000, J = 1e5: (100/2)(0.1 + 0.01) = 5.5 mm.
        assert!((rest_to_rest_distance(100.0, 0.0, 1000.0, 1e5) - 5.5).abs() < 1e-4);
        // Triangular: 1 -> 0: (1)(sqrt(1e-5)) = 3.162e-3 mm.
        let d = rest_to_rest_distance(1.0, 0.0, 1000.0, 1e5);
        assert!((d - 3.1623e-3).abs() < 1e-6, "{d}");
        assert_eq!(rest_to_rest_distance(1.0, 2.0, 1000.0, 1e5), 0.0);
    }

    #[test]
    fn tracker_lands_on_target_without_overshoot() {
        let (amax, jmax) = (2000.0, 1.0e5);
        for &(v0, a0, target) in &[(0.0, 0.0, 50.0), (80.0, 0.0, 20.0), (10.0, 300.0, 12.0)] {
            let (mut v, mut a) = (v0, a0);
            let mut peak = v;
            let mut trough = v;
            for _ in 0..20_000 {
                let j = track_jerk(v, a, target, amax, jmax, T);
                assert!(j.abs() <= jmax * (1.0 + 1e-4));
                let (_, v1, a1) = integrate(v, a, j, T);
                v = v1;
                a = a1;
                assert!(a.abs() <= amax * (1.0 + 1e-5));
                peak = peak.mx(v);
                trough = trough.mn(v);
            }
            assert!((v - target).abs() < 1e-3, "{v0}->{target}: ended at {v}");
            assert!(a.abs() < 1.0, "a {a}");
            if v0 < target {
                assert!(peak <= target + 1e-3, "overshoot {peak}");
            } else {
                assert!(trough >= target - 1e-3, "undershoot {trough}");
            }
        }
    }

    #[test]
    fn braking_distance_is_monotone_in_speed_and_acceleration() {
        let (amax, jmax) = (1500.0, 4.0e4);
        let mut last = 0.0;
        for i in 0..200 {
            let v = i as f32;
            let d = braking_distance(v, 0.0, 10.0, amax, jmax);
            assert!(d >= last - 1e-5, "v {v}: {d} < {last}");
            last = d;
        }
        let mut last = 0.0;
        for i in -150..150 {
            let a = i as f32 * 10.0;
            let d = braking_distance(60.0, a, 10.0, amax, jmax);
            assert!(d >= last - 1e-4, "a {a}: {d} < {last}");
            last = d;
        }
    }
}
