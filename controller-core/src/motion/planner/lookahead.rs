//! Look-ahead: the jerk of the next control period, chosen so that the machine goes as fast
//! as the current span allows while it can still meet every speed limit ahead and stop at
//! the end of the queue.
//!
//! The planner scans the spans ahead (up to the distance the slowest possible stop could
//! need) and collects
//! * **speed constraints** `(distance, w, A, J)`: the speed must be ≤ w at that point; A and
//!   J are the smallest path limits of the spans before it (where the braking happens).
//!   Only constraints below every cap before them are kept: a lower cap closer by already
//!   forces the speed below a later, higher one.
//! * **acceleration constraints** `(distance, A)`: entering a span whose acceleration limit
//!   is below the current acceleration needs the acceleration ramped down first.
//!
//! Each period [`choose_jerk`] takes the jerk of the time-optimal approach to the current
//! span's cap, checks that the state after one period can still brake in time for every
//! constraint (exact time-optimal jerk-limited braking distances, [`super::profile`]), and
//! otherwise bisects between that jerk and the jerk of maximal braking for the largest one
//! that passes. There are no per-junction speeds with zero acceleration at each junction
//! (the usual S-curve look-ahead), so a speed change can spread over any number of short
//! spans: that is what keeps the feed on thousands of short CAM segments.
//!
//! The choice is always within the current span's limits (|j| ≤ J, |a| ≤ A): the per-axis
//! limits hold by construction; only the speed caps ahead rely on the look-ahead, and
//! [`Choice::slipped`] reports the (never observed in the tests) case where even maximal
//! braking fails a check.

use super::profile::{braking_distance, integrate, ramp_down_distance, stop_jerk, track_jerk};

/// Most constraints kept per period; a longer staircase of ever lower caps is cut by
/// treating the last kept one as a stop (conservative).
pub(crate) const MAX_CONSTRAINTS: usize = 16;

/// Braking checks use the acceleration limits reduced by this factor, so that the
/// discrete per-period jerk can follow a continuous braking profile whose switch to
/// constant deceleration falls inside a period. (The jerk is not reduced: the ramp into
/// braking runs at full jerk, and a model with a lower jerk would see that as worse.)
const CHECK_DERATE: f32 = 1.0e-3;

/// Distance margin of the braking checks when choosing the jerk: 2 nm plus 2e-7 of the
/// distance (f32 rounding of span lengths and positions). The slip test uses none, so
/// that rounding on a state that rides the braking curve is no slip.
const CHECK_MARGIN_MM: f32 = 2.0e-6;
const CHECK_MARGIN_REL: f32 = 2.0e-7;

/// Bisection steps between the braking and the tracking jerk (resolution J·2⁻¹²).
const BISECT_STEPS: usize = 12;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SpeedConstraint {
    /// Distance from the current position (mm); ≤ 0 when inside or behind.
    pub dist: f32,
    /// Speed limit there (mm/s).
    pub w: f32,
    /// Acceleration and jerk limits for braking toward it.
    pub acc: f32,
    pub jerk: f32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct AccConstraint {
    pub dist: f32,
    pub acc: f32,
    pub jerk: f32,
}

/// What the scan found ahead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Ahead {
    pub speed: [SpeedConstraint; MAX_CONSTRAINTS],
    pub n_speed: usize,
    pub accel: [AccConstraint; MAX_CONSTRAINTS],
    pub n_accel: usize,
    /// Cap (speed target) of the current span.
    pub cap: f32,
    /// Limits of the spans the next period can touch.
    pub acc: f32,
    pub jerk: f32,
}

impl Ahead {
    pub fn new(cap: f32, acc: f32, jerk: f32) -> Self {
        Self {
            speed: [SpeedConstraint::default(); MAX_CONSTRAINTS],
            n_speed: 0,
            accel: [AccConstraint::default(); MAX_CONSTRAINTS],
            n_accel: 0,
            cap,
            acc,
            jerk,
        }
    }

    /// Adds a speed constraint; returns false when full (the caller then ends the scan
    /// with a stop at this point, which is conservative).
    pub fn push_speed(&mut self, c: SpeedConstraint) -> bool {
        if self.n_speed + 1 >= MAX_CONSTRAINTS && c.w > 0.0 {
            // Keep the last slot for a stop.
            if let Some(slot) = self.speed.get_mut(self.n_speed) {
                *slot = SpeedConstraint { w: 0.0, ..c };
                self.n_speed += 1;
            }
            return false;
        }
        if let Some(slot) = self.speed.get_mut(self.n_speed) {
            *slot = c;
            self.n_speed += 1;
            true
        } else {
            false
        }
    }

    pub fn push_accel(&mut self, c: AccConstraint) {
        if let Some(slot) = self.accel.get_mut(self.n_accel) {
            *slot = c;
            self.n_accel += 1;
        }
    }

    /// Whether the state reached by jerk `j` from `(v, a)` can still meet every
    /// constraint.
    fn feasible(&self, v: f32, a: f32, j: f32, t: f32, margin: f32) -> bool {
        let (ds, v1, a1) = integrate(v, a, j, t);
        if v1 < -1.0e-4 {
            return false;
        }
        let v1 = v1.max(0.0);
        let k = 1.0 - CHECK_DERATE;
        for c in self.speed.iter().take(self.n_speed) {
            let need = braking_distance(v1, a1, c.w, c.acc * k, c.jerk);
            let room = c.dist - ds;
            let m = margin * (1.0 + c.dist.abs() * (CHECK_MARGIN_REL / CHECK_MARGIN_MM));
            if room <= 0.0 {
                // Past the point: the speed must already be (and stay) below w.
                if v1 > c.w * (1.0 + 1.0e-6) + 1.0e-6 || need > 1.0e-6 {
                    return false;
                }
            } else if need > room - m {
                return false;
            }
        }
        for c in self.accel.iter().take(self.n_accel) {
            if a1 > c.acc {
                let need = ramp_down_distance(v1, a1, c.acc, c.jerk);
                if need > c.dist - ds - margin * (1.0 + c.dist.abs() * 0.1) {
                    return false;
                }
            }
        }
        true
    }
}

/// The jerk for the next period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Choice {
    pub jerk: f32,
    /// Even maximal braking failed a check (the look-ahead slipped).
    pub slipped: bool,
}

/// Chooses the jerk for the next period of length `t` from speed `v`, acceleration `a`.
pub(crate) fn choose_jerk(ahead: &Ahead, v: f32, a: f32, t: f32) -> Choice {
    let (amax, jmax) = (ahead.acc, ahead.jerk);
    let jt = jmax * t;
    // Hard bounds: jerk limit, acceleration limit (back inside at full jerk if outside).
    let mut j_max = ((amax - a) / t).min(jmax);
    let mut j_min = ((-amax - a) / t).max(-jmax);
    if a > amax {
        j_max = -jmax;
        j_min = -jmax;
    } else if a < -amax {
        j_min = jmax;
        j_max = jmax;
    }
    let j_hi = track_jerk(v, a, ahead.cap, amax, jmax, t).clamp(j_min, j_max);
    if ahead.feasible(v, a, j_hi, t, CHECK_MARGIN_MM) {
        return Choice {
            jerk: j_hi,
            slipped: false,
        };
    }
    let j_lo = stop_jerk(v, a, amax, jmax, t).clamp(j_min, j_hi);
    if !ahead.feasible(v, a, j_lo, t, CHECK_MARGIN_MM) {
        return Choice {
            jerk: j_lo,
            slipped: !ahead.feasible(v, a, j_lo, t, 0.0),
        };
    }
    let (mut lo, mut hi) = (j_lo, j_hi);
    for _ in 0..BISECT_STEPS {
        let mid = 0.5 * (lo + hi);
        if ahead.feasible(v, a, mid, t, CHECK_MARGIN_MM) {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1.0e-6 * jt.max(1.0) {
            break;
        }
    }
    Choice {
        jerk: lo,
        slipped: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f32 = 1.0e-4;

    /// Drives a single span of `len` with cap `cap` to its end: stops exactly there,
    /// never exceeds the cap, never slips.
    #[test]
    fn accelerates_cruises_and_stops_at_the_end() {
        let (amax, jmax, cap, len) = (2000.0f32, 1.0e5f32, 80.0f32, 20.0f32);
        let (mut s, mut v, mut a) = (0.0f32, 0.0f32, 0.0f32);
        let mut vmax_seen = 0.0f32;
        for _ in 0..200_000 {
            let mut ah = Ahead::new(cap, amax, jmax);
            ah.push_speed(SpeedConstraint {
                dist: len - s,
                w: 0.0,
                acc: amax,
                jerk: jmax,
            });
            let c = choose_jerk(&ah, v, a, T);
            assert!(!c.slipped, "slip at s {s} v {v} a {a}");
            let (ds, v1, a1) = integrate(v, a, c.jerk, T);
            s += ds;
            v = v1.max(0.0);
            a = a1;
            vmax_seen = vmax_seen.max(v);
            assert!(a.abs() <= amax * (1.0 + 1e-5));
            if v < 1e-4 && len - s < 1e-3 && s > 1.0 {
                break;
            }
        }
        assert!(s <= len + 1e-4 && s > len - 2e-3, "stopped at {s}");
        assert!(vmax_seen <= cap * (1.0 + 1e-5) && vmax_seen > cap * 0.999);
    }
}
