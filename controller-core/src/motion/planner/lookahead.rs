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

use super::fmath::{self, F32Ext};
use super::profile::{
    braking_distance, integrate, ramp_down_distance, rest_to_rest_distance, track_jerk_landing,
};

/// Most constraints of each kind kept per period; further ones tighten the last one
/// (conservative).
pub(crate) const MAX_CONSTRAINTS: usize = 16;

/// Distance margin of the braking checks when choosing the jerk: 2 nm plus 2e-6 of the
/// distance (f32 rounding of span lengths and positions), plus the lag of the discrete
/// follower (see `feasible`). The slip test allows the same amount the other way, so that
/// rounding on a state that rides the braking curve is no slip.
pub(crate) const CHECK_MARGIN_MM: f32 = 2.0e-6;
const CHECK_MARGIN_REL: f32 = 2.0e-6;

/// How far the last ramp-out period may carry the motion past a stop point (mm) before
/// the planner snaps it onto the point: the discrete landing cannot hit the point with
/// zero speed and acceleration at a period boundary exactly.
const STOP_OVERSHOOT_MM: f32 = 5.0e-6;

/// Search steps between the braking and the tracking jerk (enough for 2⁻¹² of the bracket
/// with every other step a bisection).
const SEARCH_STEPS: usize = 24;

/// The search stops once the chosen state is this close (mm) to its binding constraint.
pub(crate) const SLACK_TIGHT_MM: f32 = 2.0e-7;

/// Bisection steps locating where a ramp-out reaches a jerk drop (2⁻²⁴ of the ramp time:
/// f32 resolution).
const RAMP_BISECTIONS: usize = 24;

/// Slack of a failed check without a distance scale.
const FAIL: f32 = -1.0e6;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SpeedConstraint {
    /// Distance from the current position (mm); ≤ 0 when inside or behind.
    pub dist: f32,
    /// Speed limit there (mm/s).
    pub w: f32,
    /// Acceleration and jerk limits for braking toward it.
    pub acc: f32,
    pub jerk: f32,
    /// The limit is the programmed feed × override, not the geometry: after the override
    /// is lowered it may be out of reach; the look-ahead then brakes as hard as allowed
    /// toward it instead of counting a slip.
    pub soft: bool,
}

impl SpeedConstraint {
    pub const ZERO: Self = Self {
        dist: 0.0,
        w: 0.0,
        acc: 0.0,
        jerk: 0.0,
        soft: false,
    };
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct AccConstraint {
    pub dist: f32,
    pub acc: f32,
    pub jerk: f32,
}

impl AccConstraint {
    pub const ZERO: Self = Self {
        dist: 0.0,
        acc: 0.0,
        jerk: 0.0,
    };
}

/// Where the jerk limit drops ahead: from `dist` on (mm from the current position) the
/// spans allow at most `jerk` (each lower than everything before it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct JerkDrop {
    pub dist: f32,
    pub jerk: f32,
}

impl JerkDrop {
    pub const ZERO: Self = Self {
        dist: 0.0,
        jerk: 0.0,
    };
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
    /// The cap is the programmed feed (× override), not the geometry: a speed above it
    /// after the override was lowered is no slip.
    pub cap_soft: bool,
    /// Limits of the spans the next period can touch.
    pub acc: f32,
    pub jerk: f32,
    /// The current span's jerk limit and where it drops ahead (within the reach of any
    /// ramp-out of the acceleration): a ramp-out is modelled span by span, so that a
    /// lower limit ahead counts only where the ramp gets to it.
    pub jerk0: f32,
    pub drops: [JerkDrop; MAX_CONSTRAINTS],
    pub n_drops: usize,
    /// Distance to the nearest stop point (+∞ if none): the motion rests there, so no
    /// ramp-out reaches beyond it.
    pub stop_dist: f32,
}

impl Ahead {
    pub const fn new(cap: f32, acc: f32, jerk: f32) -> Self {
        Self {
            speed: [SpeedConstraint::ZERO; MAX_CONSTRAINTS],
            n_speed: 0,
            accel: [AccConstraint::ZERO; MAX_CONSTRAINTS],
            n_accel: 0,
            cap,
            cap_soft: false,
            acc,
            jerk,
            jerk0: jerk,
            drops: [JerkDrop::ZERO; MAX_CONSTRAINTS],
            n_drops: 0,
            stop_dist: f32::INFINITY,
        }
    }

    /// Adds a jerk drop (in order of distance); when full, the last one takes the lower
    /// limit (conservative: it lies nearer).
    pub fn push_drop(&mut self, c: JerkDrop) {
        if let Some(slot) = self.drops.get_mut(self.n_drops) {
            *slot = c;
            self.n_drops += 1;
        } else if let Some(last) = self.drops.last_mut() {
            last.jerk = last.jerk.mn(c.jerk);
        }
    }

    /// One period's travel at most during a ramp-out from `(v, a)` (the highest speed it
    /// reaches, at the lowest jerk ahead): how early a jerk drop counts.
    pub(crate) fn ramp_lead(&self, v: f32, a: f32, t: f32) -> f32 {
        let a = a.mx(0.0);
        let j_min = self
            .drops
            .iter()
            .take(self.n_drops)
            .fold(self.jerk0, |j, d| j.mn(d.jerk))
            .mx(1.0);
        (v + 0.5 * a * a / j_min) * t + 1.0e-6
    }

    /// Ramps the acceleration `a` out to zero at full jerk from speed `v`, at the jerk of
    /// the spans the ramp crosses (the current span's, then each drop's from where it
    /// lies): the distance the ramp takes and the speed at its end (the peak for `a > 0`;
    /// below zero for `a < 0` when the motion would reverse first). The ramp starts `s0`
    /// ahead of the current position; a period runs at the lowest jerk of the spans it
    /// touches, so each drop counts one period's travel (at most `lead` mm) early.
    pub(crate) fn ramp_out(&self, v: f32, a: f32, s0: f32, lead: f32) -> (f32, f32) {
        let mut j = self.jerk0.mx(1.0);
        let (mut v, mut a, mut s) = (v, a, s0);
        let sg = if a < 0.0 { -1.0 } else { 1.0 };
        for d0 in self.drops.iter().take(self.n_drops) {
            if d0.dist > self.stop_dist {
                break;
            }
            let d = JerkDrop {
                dist: d0.dist - lead,
                jerk: d0.jerk,
            };
            let tr = a.abs() / j;
            // distance of the whole ramp from here: v t + a t²/2 − sg j t³/6
            let dist = |t: f32| v * t + 0.5 * a * t * t - sg * j * t * t * t * (1.0 / 6.0);
            let dr = dist(tr);
            let v_end = v + 0.5 * a * tr;
            // (a drop behind: taken from here on)
            if !(d.dist > s) || d.jerk >= j {
                j = j.mn(d.jerk.mx(1.0));
                continue;
            }
            if s + dr <= d.dist || v_end < 0.0 {
                return (s - s0 + dr.mx(0.0), v_end);
            }
            // The ramp reaches the drop: where (bisection; the distance is monotone while
            // the speed stays positive, which `v_end ≥ 0` guarantees), then on at its jerk.
            let rem = d.dist - s;
            let (mut lo, mut hi) = (0.0f32, tr);
            for _ in 0..RAMP_BISECTIONS {
                let mid = 0.5 * (lo + hi);
                if dist(mid) < rem {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let t1 = lo;
            v += a * t1 - sg * 0.5 * j * t1 * t1;
            a -= sg * j * t1;
            s = d.dist;
            j = d.jerk.mx(1.0);
        }
        let tr = a.abs() / j;
        let dr = v * tr + 0.5 * a * tr * tr - sg * j * tr * tr * tr * (1.0 / 6.0);
        (s - s0 + dr.mx(0.0), v + 0.5 * a * tr)
    }

    /// Adds a speed constraint (in order of distance). When full, the last one is
    /// tightened instead: the lower limit at the nearer point (conservative).
    pub fn push_speed(&mut self, c: SpeedConstraint) {
        if let Some(slot) = self.speed.get_mut(self.n_speed) {
            *slot = c;
            self.n_speed += 1;
        } else if let Some(last) = self.speed.last_mut() {
            last.w = last.w.mn(c.w);
            last.acc = last.acc.mn(c.acc);
            last.jerk = last.jerk.mn(c.jerk);
            last.soft = last.soft && c.soft;
        }
    }

    /// Adds an acceleration constraint (in order of distance); when full, the last one
    /// is tightened (the lower limit at the nearer point).
    pub fn push_accel(&mut self, c: AccConstraint) {
        if let Some(slot) = self.accel.get_mut(self.n_accel) {
            *slot = c;
            self.n_accel += 1;
        } else if let Some(last) = self.accel.last_mut() {
            last.acc = last.acc.mn(c.acc);
            last.jerk = last.jerk.mn(c.jerk);
        }
    }

    /// Whether the state reached by jerk `j` from `(v, a)` can still meet every
    /// constraint.
    fn feasible(&self, v: f32, a: f32, j: f32, t: f32, margin: f32, soft: bool) -> bool {
        self.slack(v, a, j, t, margin, soft) >= 0.0
    }

    /// How much room (mm) the state reached by jerk `j` from `(v, a)` has left on the
    /// tightest constraint: ≥ 0 when every one can still be met, [`FAIL`] for a check
    /// that has no distance scale (past a point, reversal).
    pub(crate) fn slack(&self, v: f32, a: f32, j: f32, t: f32, margin: f32, soft: bool) -> f32 {
        let (ds, v1, a1) = integrate(v, a, j, t);
        // The last period of a stop may end slightly below zero speed (the planner rests
        // there and zeroes the acceleration next period); more is a real undershoot.
        if v1 < -self.jerk * t * t {
            return FAIL;
        }
        let mut slack = f32::INFINITY;
        let v1 = v1.mx(0.0);
        // The acceleration's ramp-out from the new state, span by span.
        let lead = self.ramp_lead(v1, a1, t);
        let (d_ramp, v_ramp) = if a1 != 0.0 {
            self.ramp_out(v1, a1, ds, lead)
        } else {
            (0.0, v1)
        };
        if a1 < 0.0 && v_ramp < -self.jerk * t * t && ds + 2.0 * (d_ramp + lead) < self.stop_dist {
            // ramping the deceleration out where the jerk drops would reverse the motion
            // (toward a stop point within the ramp that is the stop, braked for as such)
            return FAIL;
        }
        // The current span's cap from below: the ramp-out must not carry the speed above
        // it (up to the tracker's landing error, J·T²/8), whatever the spans after allow
        // (a lower cap among those is a constraint of its own).
        if a1 > 0.0 && (soft || !self.cap_soft) && v1 <= self.cap {
            let tol = 0.125 * self.jerk * t * t
                + 1.0e-6 * self.cap
                + if margin < 0.0 {
                    1.0e-5 * (1.0 + self.cap)
                } else {
                    0.0
                };
            let over = v_ramp - (self.cap + tol);
            if over > 0.0 {
                slack = slack.mn(-over * (a1 / self.jerk0.mx(1.0) + t));
            }
        }
        for c in self
            .speed
            .iter()
            .take(self.n_speed)
            .filter(|c| soft || !c.soft)
        {
            // Speed hysteresis on caps: a state that lands exactly on a cap (peak = w)
            // must not flip to "needs braking" by rounding in the next period.
            let w = if c.w > 0.0 {
                c.w - (1.0e-5 * (1.0 + c.w)).copysign(margin)
            } else {
                0.0
            };
            // Never above w again (the peak after ramping the acceleration out, span by
            // span): nothing to brake for, wherever the point lies.
            let peak = if a1 > 0.0 { v_ramp } else { v1 };
            if peak <= w {
                continue;
            }
            // A positive acceleration is ramped out first (as modelled above), then the
            // braking crosses every span up to the point (its lowest limits).
            let need = if a1 > 0.0 {
                d_ramp + rest_to_rest_distance(peak, w, c.acc, c.jerk)
            } else {
                braking_distance(v1, a1, w, c.acc, c.jerk)
            };
            let room = c.dist - ds;
            // A continuous braking profile reaches its constant deceleration inside a
            // period; the per-period jerk only at a period end, which costs up to J·T²/8 of
            // speed and so v·J·T²/(8A) of distance once per braking: kept in reserve (×2).
            let lag = v1 * c.jerk * t * t / (4.0 * c.acc.mx(1.0));
            let m = margin * (1.0 + c.dist.abs() * (CHECK_MARGIN_REL / CHECK_MARGIN_MM))
                + lag.copysign(margin);
            if room <= 0.0 {
                // Past the point: the speed must already be (and stay) below w, up to what
                // the discrete landing cannot resolve: J·T²/8 on a cap (the tracker's
                // landing error), a few nm of ramp-out past a stop point (snapped back).
                if c.w > 0.0 {
                    let tol_v = 0.125 * c.jerk * t * t + 1.0e-6 * c.w;
                    if v1 > c.w + tol_v || need > 1.0e-6 + tol_v * t {
                        return FAIL;
                    }
                } else if need > room + STOP_OVERSHOOT_MM {
                    return FAIL;
                }
            } else {
                slack = slack.mn(room - m - need);
            }
        }
        for c in self.accel.iter().take(self.n_accel) {
            if a1 > c.acc {
                // Plus two periods at the speed the ramp ends with (at most v + a²/2J): the
                // period that reaches the span already runs under its limit.
                let v_end = v1 + 0.5 * a1 * a1 / c.jerk.mx(1.0);
                let need = ramp_down_distance(v1, a1, c.acc, c.jerk) + 2.0 * v_end * t;
                slack = slack.mn(c.dist - ds - margin * (1.0 + c.dist.abs() * 0.1) - need);
            }
        }
        slack
    }
}

/// The strongest deceleration (most negative acceleration) from which the acceleration
/// can be brought back up to `-acc` at jerk `jmax`, starting at speed `v`, and end three
/// periods `t` (at the speed then) before a point `avail` mm ahead. The speed falls during
/// the ramp, which the distance accounts for.
fn decel_floor(v: f32, acc: f32, jmax: f32, avail: f32, t: f32) -> f32 {
    let dist = |a1: f32| {
        let tr = ((-acc - a1) / jmax).mx(0.0);
        let v_end = v + a1 * tr + 0.5 * jmax * tr * tr;
        v * tr + 0.5 * a1 * tr * tr + jmax * tr * tr * tr * (1.0 / 6.0) + 3.0 * t * v_end.mx(0.0)
    };
    if !(avail > 0.0) {
        return -acc;
    }
    // Lower end: the strongest deceleration whose ramp back to -acc ends before the speed
    // does (speed lost in the ramp: (a1² − acc²)/2J ≤ v); the distance is monotone above.
    let mut lo = -fmath::sqrt(2.0 * jmax * v.mx(0.0) + acc * acc);
    if dist(lo) <= avail {
        return lo;
    }
    let mut hi = -acc;
    for _ in 0..20 {
        let mid = 0.5 * (lo + hi);
        if dist(mid) <= avail {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
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
    // Hard bounds: jerk limit, acceleration limit. An acceleration just outside ±amax
    // (rounding) is brought back within this period; one further out (limits dropped)
    // moves back at full jerk.
    let mut j_max = ((amax - a) / t).mn(jmax);
    let mut j_min = ((-amax - a) / t).mx(-jmax);
    if j_min > j_max {
        let j = if a > 0.0 { -jmax } else { jmax };
        j_min = j;
        j_max = j;
    }
    // Deceleration entering a span with a lower acceleration limit must be reducible to
    // that limit before it (at the jerk of the spans before, three periods at the speed
    // then early: the period that crosses runs at the lower limits already). A braking
    // toward that span's own speed cap ends at zero acceleration there and never meets
    // this bound.
    // (Not beyond a stop point: the motion never gets there, and braking for the stop may
    // need more deceleration than such a span allows.)
    let stop_at = ahead.stop_dist;
    for c in ahead.accel.iter().take(ahead.n_accel) {
        if c.acc < amax && v > 0.0 && c.dist < stop_at {
            let a_lo = decel_floor(v, c.acc, c.jerk, c.dist - v * t, t);
            j_min = j_min.mx(((a_lo - a) / t).mn(j_max));
        }
    }
    // Never brake so hard that ramping the deceleration out at full jerk would reverse
    // the motion (speed lost a²/2J ≤ v): the most negative end acceleration x with
    // v + (a + x)T/2 − x²/2J ≥ 0.
    let c0 = v + 0.5 * a * t;
    let disc = 0.25 * jt * jt + 2.0 * jmax * c0;
    if disc >= 0.0 {
        let x_lo = 0.5 * jt - fmath::sqrt(disc);
        j_min = j_min.mx(((x_lo - a) / t).mn(j_max));
    }
    // The landing on the cap is modelled at the jerk the current ramp-out would see on
    // average (lower where the jerk drops ahead); `slack` checks the result span by span.
    let j_land = if a > 0.0 {
        let (_, peak) = ahead.ramp_out(v, a, 0.0, ahead.ramp_lead(v, a, t));
        let rise = peak - v;
        if rise > 0.0 {
            (0.5 * a * a / rise).mn(jmax)
        } else {
            jmax
        }
    } else {
        jmax
    };
    // (max/min rather than clamp: no panic path even for a non-finite input.)
    let j_hi = track_jerk_landing(v, a, ahead.cap, amax, jmax, j_land, t)
        .mx(j_min)
        .mn(j_max);
    let mut f_hi = ahead.slack(v, a, j_hi, t, CHECK_MARGIN_MM, true);
    if f_hi >= 0.0 {
        return Choice {
            jerk: j_hi,
            slipped: false,
        };
    }
    // The most braking that keeps the speed ≥ 0 at the end of the period (within the
    // landing tolerance of `feasible`).
    let j_vzero = -2.0 * (v + a * t - jmax * t * t) / (t * t);
    let j_lo = j_min.mx(j_vzero).mn(j_hi);
    let mut f_lo = ahead.slack(v, a, j_lo, t, CHECK_MARGIN_MM, true);
    if !(f_lo >= 0.0) {
        return Choice {
            jerk: j_lo,
            // Riding the braking curve exactly, f32 rounding can exceed it by a few nm:
            // that is no slip; nor is a feed limit out of reach after an override change.
            slipped: !ahead.feasible(v, a, j_lo, t, -CHECK_MARGIN_MM, false),
        };
    }
    // The largest feasible jerk in [j_lo, j_hi]: the slack is monotone in the jerk, so
    // regula falsi (Illinois variant, each step kept 2 % inside the bracket) on it; a step
    // that did not halve the bracket is followed by a bisection step (the slack is only
    // piecewise smooth), so the bracket shrinks at least as fast as by bisection every
    // other step. Done when the bracket is below J·2⁻¹² or the feasible end lies within
    // a fraction of a nanometre of its constraint.
    let (mut lo, mut hi) = (j_lo, j_hi);
    let resolution = (j_hi - j_lo) * (1.0 / 4096.0);
    let mut tight = f_lo;
    let mut side = 0i8;
    let mut bisect_next = false;
    for _ in 0..SEARCH_STEPS {
        let w = hi - lo;
        if !(w > resolution) || tight <= SLACK_TIGHT_MM {
            break;
        }
        let secant = !bisect_next && f_hi > FAIL && f_lo.is_finite() && f_lo - f_hi > 0.0;
        let mid = if secant {
            (hi - f_hi * w / (f_hi - f_lo)).clampf(lo + 0.02 * w, hi - 0.02 * w)
        } else {
            lo + 0.5 * w
        };
        let f = ahead.slack(v, a, mid, t, CHECK_MARGIN_MM, true);
        if f >= 0.0 {
            lo = mid;
            f_lo = f;
            tight = f;
            if side > 0 {
                f_hi *= 0.5;
            }
            side = 1;
        } else {
            hi = mid;
            f_hi = f;
            if side < 0 {
                f_lo *= 0.5;
            }
            side = -1;
        }
        bisect_next = secant && hi - lo > 0.5 * w;
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
        let (mut cs, mut cv, mut ca) = (0.0f32, 0.0f32, 0.0f32);
        let kahan = |sum: f32, add: f32, c: &mut f32| {
            let y = add - *c;
            let t = sum + y;
            *c = (t - sum) - y;
            t
        };
        let mut vmax_seen = 0.0f32;
        for _ in 0..200_000 {
            let mut ah = Ahead::new(cap, amax, jmax);
            ah.push_speed(SpeedConstraint {
                dist: len - s,
                w: 0.0,
                acc: amax,
                jerk: jmax,
                soft: false,
            });
            let c = choose_jerk(&ah, v, a, T);
            assert!(!c.slipped, "slip at s {s} v {v} a {a}");
            // Increments added with Kahan compensation, as the planner does: a plain f32
            // running sum drifts off the braking curve the state rides.
            let (ds, _, _) = integrate(v, a, c.jerk, T);
            let dv = a * T + 0.5 * c.jerk * T * T;
            s = kahan(s, ds, &mut cs);
            v = kahan(v, dv, &mut cv).mx(0.0);
            a = kahan(a, c.jerk * T, &mut ca);
            vmax_seen = vmax_seen.mx(v);
            assert!(a.abs() <= amax * (1.0 + 1e-5));
            if v < 1e-4 && len - s < 1e-3 && s > 1.0 {
                break;
            }
        }
        assert!(s <= len + 1e-4 && s > len - 2e-3, "stopped at {s}");
        assert!(vmax_seen <= cap * (1.0 + 1e-5) && vmax_seen > cap * 0.999);
    }
}
