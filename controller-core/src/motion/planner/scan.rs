//! The look-ahead scan: which constraints ahead of the current position can bind, as
//! positions on the path (fixed-point path length, see [`super::ring`]), so that one scan
//! serves many periods.
//!
//! A scan collects, from the current span up to a horizon:
//! * speed constraints: the staircase of caps below the current span's cap (each lower
//!   than everything before it, from the ring's `next_cap` links), the hold's stop point,
//!   and the first stop at a span end (exact stop, dwell, end of the known path), which
//!   ends the scan. Braking toward each uses the lowest acceleration limit before it.
//! * acceleration constraints: spans whose acceleration limit lies below a threshold
//!   (the most the state's acceleration can reach), each lower than all before it.
//!
//! The result stays valid while the motion keeps within what it was scanned for (the
//! planner checks [`ScanCache::covers`] every period): the stopping distance from the
//! current state still ends before the scanned horizon, the acceleration stays below the
//! threshold, no span with a higher cap than the scanned one is entered, no stop point is
//! passed, and nothing that was scanned can change (spans up to the horizon are frozen;
//! an end of the known path is re-scanned once more path is known). The planner scans a
//! margin further than needed so that a scan lasts many periods.

use super::fmath::F32Ext;
use super::lookahead::{AccConstraint, Ahead, JerkDrop, SpeedConstraint, MAX_CONSTRAINTS};
use super::profile::braking_distance;
use super::ring::{cum_mm, to_cum, SpanRing};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct SpeedAt {
    pos: i64,
    w: f32,
    /// Lowest acceleration and jerk limits of the spans a braking toward it crosses.
    acc: f32,
    jerk: f32,
    soft: bool,
}

impl SpeedAt {
    const ZERO: Self = Self {
        pos: 0,
        w: 0.0,
        acc: 0.0,
        jerk: 0.0,
        soft: false,
    };
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct AccAt {
    pos: i64,
    acc: f32,
    /// Lowest jerk limit of the spans before it (where the acceleration is ramped down).
    jerk: f32,
}

impl AccAt {
    const ZERO: Self = Self {
        pos: 0,
        acc: 0.0,
        jerk: 0.0,
    };
}

/// A span whose jerk limit lies below every one before it (from the scan's span on).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct JerkAt {
    pos: i64,
    jerk: f32,
}

impl JerkAt {
    const ZERO: Self = Self { pos: 0, jerk: 0.0 };
}

/// What to scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ScanInput {
    /// Current span index and the last span the scan may use.
    pub idx: usize,
    /// Local σ on the current span (fixed point).
    pub sigma_cum: i64,
    pub scan_last: usize,
    /// The known path ends at the end of `scan_last` (queue end or channel full).
    pub end_stop: bool,
    /// Constraints starting beyond this position are left out (and `ScanCache::covers`
    /// fails once the stopping distance reaches it).
    pub horizon_end: i64,
    /// Cap of the current span (the staircase starts below it).
    pub cap0: f32,
    pub ovr: f32,
    /// Hold stop point (span sequence number, local σ).
    pub hold: Option<(u32, f32)>,
    /// Acceleration limits below this, starting before `acc_end`, are collected.
    pub acc_below: f32,
    pub acc_end: i64,
    /// Sequence number the next appended span will get (to notice new path).
    pub next_seq: u32,
    /// For the executor's own stop: the speed and acceleration it may start from (at
    /// most), and the period.
    pub stop_from: (f32, f32),
    pub period_s: f32,
}

/// A scan's result, reusable while [`ScanCache::covers`] holds.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ScanCache {
    pub valid: bool,
    speed: [SpeedAt; MAX_CONSTRAINTS],
    n_speed: usize,
    accel: [AccAt; MAX_CONSTRAINTS],
    n_accel: usize,
    drops: [JerkAt; MAX_CONSTRAINTS],
    n_drops: usize,
    cap_thr: f32,
    /// None: the scan ended at a stop point (nothing beyond it matters).
    horizon_end: Option<i64>,
    /// Acceleration limits below this were collected (the threshold or the scanned
    /// span's own limit, if lower).
    acc_start: f32,
    acc_end: i64,
    /// The nearest stop point and whether it is the end of the known path there.
    stop_pos: Option<i64>,
    stop_at_path_end: bool,
    soft_end: bool,
    next_seq: u32,
    /// `stop_acc` holds for states up to this speed.
    stop_v_max: f32,
    /// Lowest acceleration limit from the scan's span to the horizon (for the executor's
    /// own stop).
    pub stop_acc: f32,
    /// Lowest jerk limit from the scan's span to the end of the scan (the same stop).
    pub stop_jerk: f32,
    /// Lowest acceleration and jerk limits of the spans passed since the scan: while they
    /// are not below the current span's, every constraint's limits (the lowest over the
    /// spans from the scan's span on) are what a fresh scan would find.
    passed_acc: f32,
    passed_jerk: f32,
    /// Sequence number of the span at whose end the scan's stop lies.
    pub stop_seq: Option<u32>,
}

impl ScanCache {
    pub const fn new() -> Self {
        Self {
            valid: false,
            speed: [SpeedAt::ZERO; MAX_CONSTRAINTS],
            n_speed: 0,
            accel: [AccAt::ZERO; MAX_CONSTRAINTS],
            n_accel: 0,
            drops: [JerkAt::ZERO; MAX_CONSTRAINTS],
            n_drops: 0,
            cap_thr: 0.0,
            horizon_end: None,
            acc_start: 0.0,
            acc_end: 0,
            stop_pos: None,
            stop_at_path_end: false,
            soft_end: false,
            next_seq: 0,
            stop_v_max: 0.0,
            stop_acc: 0.0,
            stop_jerk: 0.0,
            passed_acc: f32::INFINITY,
            passed_jerk: f32::INFINITY,
            stop_seq: None,
        }
    }

    /// The look-ahead moved past a span with these limits.
    pub fn passed(&mut self, acc: f32, jerk: f32) {
        self.passed_acc = self.passed_acc.mn(acc);
        self.passed_jerk = self.passed_jerk.mn(jerk);
    }

    /// Whether this scan still covers the state at `pos` (speed up to `v_next`) whose
    /// stopping distance is
    /// `horizon`, acceleration bound `a1max` with ramp reach `reach`, on a span with cap
    /// `cap0`, acceleration limit `acc0` and jerk limit `jerk0`, with the next span
    /// sequence number `next_seq`.
    #[allow(clippy::too_many_arguments)]
    pub fn covers(
        &self,
        pos: i64,
        cur_cum: i64,
        v_next: f32,
        horizon: f32,
        a1max: f32,
        reach: f32,
        (cap0, acc0, jerk0): (f32, f32, f32),
        next_seq: u32,
    ) -> bool {
        if !self.valid || v_next > self.stop_v_max {
            return false;
        }
        if self.passed_acc < acc0 || self.passed_jerk < jerk0 {
            return false;
        }
        // Constraints of the current span and those before it (starting at or before
        // `cur_cum`) are dropped by `fill`: the current span's own cap is the tracking
        // target. What is left ahead is the staircase below the lowest of them (and the
        // scanned span's cap): right as long as the current span does not lie above it.
        let mut cap_thr = self.cap_thr;
        for c in self.speed.iter().take(self.n_speed) {
            if c.pos.wrapping_sub(cur_cum) > 0 {
                break;
            }
            cap_thr = cap_thr.mn(c.w);
        }
        if cap0 > cap_thr {
            return false;
        }
        // Likewise the acceleration limits: those below the lower of the next period's
        // reach and the current span's limit must all be there.
        let mut acc_thr = self.acc_start;
        for c in self.accel.iter().take(self.n_accel) {
            if c.pos.wrapping_sub(cur_cum) > 0 {
                break;
            }
            acc_thr = acc_thr.mn(c.acc);
        }
        if a1max.mn(acc0) > acc_thr {
            return false;
        }
        if self.soft_end && next_seq != self.next_seq {
            return false;
        }
        if let Some(sp) = self.stop_pos {
            if sp.wrapping_sub(pos) <= 0 {
                return false;
            }
        }
        if let Some(h) = self.horizon_end {
            if h.wrapping_sub(pos) < to_cum(horizon) {
                return false;
            }
        }
        self.acc_end.wrapping_sub(pos) >= to_cum(reach)
    }

    fn push_speed(&mut self, c: SpeedAt) {
        if let Some(slot) = self.speed.get_mut(self.n_speed) {
            *slot = c;
            self.n_speed += 1;
        } else if let Some(last) = self.speed.last_mut() {
            // Full: the last one takes the lower limit (conservative, it lies nearer).
            last.w = last.w.mn(c.w);
            last.acc = last.acc.mn(c.acc);
            last.jerk = last.jerk.mn(c.jerk);
            last.soft = last.soft && c.soft;
        }
    }

    fn push_accel(&mut self, c: AccAt) {
        if let Some(slot) = self.accel.get_mut(self.n_accel) {
            *slot = c;
            self.n_accel += 1;
        } else if let Some(last) = self.accel.last_mut() {
            last.acc = last.acc.mn(c.acc);
            last.jerk = last.jerk.mn(c.jerk);
        }
    }

    fn stop_at(&mut self, pos: i64, acc: f32, jerk: f32) {
        self.push_speed(SpeedAt {
            pos,
            w: 0.0,
            acc,
            jerk,
            soft: false,
        });
        let nearer = match self.stop_pos {
            Some(p) => pos.wrapping_sub(p) < 0,
            None => true,
        };
        if nearer {
            self.stop_pos = Some(pos);
        }
    }

    /// Scans `spans` as `inp` says.
    pub fn scan<const S: usize>(&mut self, spans: &SpanRing<S>, inp: &ScanInput) {
        self.valid = true;
        self.n_speed = 0;
        self.n_accel = 0;
        self.n_drops = 0;
        self.cap_thr = inp.cap0;
        self.horizon_end = Some(inp.horizon_end);
        self.acc_end = inp.acc_end;
        self.stop_pos = None;
        self.stop_at_path_end = false;
        self.soft_end = inp.end_stop;
        self.next_seq = inp.next_seq;
        self.stop_seq = None;
        self.passed_acc = f32::INFINITY;
        self.passed_jerk = f32::INFINITY;
        let Some(cur) = spans.get(inp.idx) else {
            self.valid = false;
            return;
        };
        self.stop_jerk = spans.min_jerk(inp.idx, inp.scan_last);
        self.stop_acc = self.stop_limit(spans, inp, cur.cum, cur.lim.acc);
        let (cur_seq, cur_cum, cur_acc, cur_next_cap) =
            (cur.span.seq, cur.cum, cur.lim.acc, cur.next_cap);
        let idx = inp.idx;

        // The hold's stop point on the current span.
        if let Some((hseq, hsigma)) = inp.hold {
            if hseq == cur_seq {
                self.stop_at(
                    cur_cum.wrapping_add(to_cum(hsigma)),
                    cur_acc,
                    spans.min_jerk(idx, idx),
                );
            }
        }
        let stop_ev = self.speed_events(spans, inp, cur_next_cap);

        // A stop at the end of the queue stops being one when more path arrives.
        self.soft_end = inp.end_stop || self.stop_at_path_end;

        self.accel_limits(spans, inp, (cur_cum, cur_acc, cur.lim.jerk), stop_ev);
    }

    /// The speed events of the scan in path order (at equal spans: cap, hold, then the
    /// stop at its end), from the current span's next cap `cur_next_cap` on; returns the
    /// span of the nearest stop, if any.
    fn speed_events<const S: usize>(
        &mut self,
        spans: &SpanRing<S>,
        inp: &ScanInput,
        cur_next_cap: Option<u32>,
    ) -> Option<usize> {
        let idx = inp.idx;
        let within = |i: usize| i <= inp.scan_last;
        let beyond = |p: i64| p.wrapping_sub(inp.horizon_end) > 0;
        // Speed events in path order; at equal spans: cap, hold, then the stop at its end.
        let mut c_ev = spans.link(cur_next_cap).filter(|&i| within(i));
        let mut h_ev = inp
            .hold
            .and_then(|(hseq, _)| spans.index_of(hseq))
            .filter(|&i| i > idx && within(i));
        let first_stop = spans.first_stop_from(idx).filter(|&i| within(i));
        let stop_ev = match (first_stop, inp.end_stop) {
            (Some(i), _) => Some(i),
            (None, true) => Some(inp.scan_last),
            (None, false) => None,
        };
        let mut caps = 0;
        loop {
            let k_start = match (c_ev, h_ev) {
                (Some(p), Some(q)) => Some(p.min(q)),
                (p, None) => p,
                (None, q) => q,
            };
            let k = match (k_start, stop_ev) {
                (Some(k), Some(st)) if k <= st => k,
                (Some(k), None) => k,
                (None, None) => break,
                (_, st) => {
                    if let Some((st, sp)) = st.and_then(|st| spans.get(st).map(|sp| (st, sp))) {
                        self.stop_at(
                            sp.cum_end(),
                            spans.min_acc(idx, st),
                            spans.min_jerk(idx, st),
                        );
                        self.stop_seq = Some(sp.span.seq);
                        self.stop_at_path_end = st + 1 >= spans.len();
                        // Nothing beyond a stop matters.
                        self.horizon_end = None;
                    }
                    break;
                }
            };
            let Some(sk) = spans.get(k) else {
                break;
            };
            if beyond(sk.cum) {
                break;
            }
            if c_ev == Some(k) {
                let acc = spans.min_acc(idx, k - 1);
                // (span k's own jerk too: a speed at the cap whose acceleration is ramped
                // out after the point is ramped out in span k)
                let jerk = spans.min_jerk(idx, k);
                if caps + 1 < CAP_EVENTS {
                    let cap_k = sk.cap(inp.ovr);
                    self.push_speed(SpeedAt {
                        pos: sk.cum,
                        w: cap_k,
                        acc,
                        jerk,
                        soft: cap_k < sk.lim.vel,
                    });
                    c_ev = spans.link(sk.next_cap).filter(|&i| within(i));
                } else {
                    // A long staircase (a spiral, a curve tightening over many spans):
                    // the rest in one, with its lowest cap, here (conservative).
                    let upto = stop_ev.unwrap_or(inp.scan_last);
                    self.push_speed(SpeedAt {
                        pos: sk.cum,
                        w: spans.min_cap(k, upto),
                        acc,
                        jerk: spans.min_jerk(idx, upto),
                        soft: false,
                    });
                    c_ev = None;
                }
                caps += 1;
            }
            if h_ev == Some(k) {
                if let Some((_, hsigma)) = inp.hold {
                    self.stop_at(
                        sk.cum.wrapping_add(to_cum(hsigma)),
                        spans.min_acc(idx, k),
                        spans.min_jerk(idx, k),
                    );
                }
                h_ev = None;
            }
        }
        stop_ev
    }

    /// The acceleration limits below the threshold and the jerk drops, in path order,
    /// before the nearest stop `stop_ev`; `cur` is the current span's start, acceleration
    /// and jerk limit.
    fn accel_limits<const S: usize>(
        &mut self,
        spans: &SpanRing<S>,
        inp: &ScanInput,
        cur: (i64, f32, f32),
        stop_ev: Option<usize>,
    ) {
        let idx = inp.idx;
        let (cur_cum, cur_acc, cur_jerk) = cur;
        // Acceleration limits below the threshold, in path order, before the nearest stop.
        let acc_last = spans
            .last_starting_within(idx, inp.acc_end.wrapping_sub(cur_cum))
            .min(stop_ev.unwrap_or(inp.scan_last))
            .min(inp.scan_last);
        let mut below = inp.acc_below.mn(cur_acc);
        self.acc_start = below;
        let mut from = idx + 1;
        for _ in 0..MAX_CONSTRAINTS {
            let Some(k) = spans.first_acc_below(from, acc_last, below) else {
                break;
            };
            let Some(sk) = spans.get(k) else {
                break;
            };
            self.push_accel(AccAt {
                pos: sk.cum,
                acc: sk.lim.acc,
                jerk: spans.min_jerk(idx, k - 1),
            });
            below = sk.lim.acc;
            from = k + 1;
        }
        // Where the jerk limit drops, over the same reach (any ramp-out of the
        // acceleration ends within it): a ramp-out is modelled span by span.
        let mut j_below = cur_jerk;
        let mut from_j = idx + 1;
        for _ in 0..MAX_CONSTRAINTS {
            let Some(k) = spans.first_jerk_below(from_j, acc_last, j_below) else {
                break;
            };
            let Some(sk) = spans.get(k) else {
                break;
            };
            if let Some(slot) = self.drops.get_mut(self.n_drops) {
                *slot = JerkAt {
                    pos: sk.cum,
                    jerk: sk.lim.jerk,
                };
                self.n_drops += 1;
            }
            j_below = sk.lim.jerk;
            from_j = k + 1;
        }
        let rest_j = spans.min_jerk(from_j, acc_last);
        if rest_j < j_below {
            if let Some(last) = self
                .n_drops
                .checked_sub(1)
                .and_then(|i| self.drops.get_mut(i))
            {
                last.jerk = last.jerk.mn(rest_j);
            }
        }

        // More than that: the lowest of the rest joins the last one (conservative).
        let rest = spans.min_acc(from, acc_last);
        if rest < below {
            let jerk = spans.min_jerk(idx, acc_last);
            if let Some(last) = self
                .n_accel
                .checked_sub(1)
                .and_then(|i| self.accel.get_mut(i))
            {
                last.acc = last.acc.mn(rest);
                last.jerk = last.jerk.mn(jerk);
            }
        }
    }

    /// The acceleration limit of the executor's own stop (underrun) from the state
    /// `inp.stop_from`: the weakest span it can reach, found where a stop with the limits
    /// so far ends before the next weaker span (a few steps; then the weakest up to the
    /// scan's end).
    fn stop_limit<const S: usize>(
        &mut self,
        spans: &SpanRing<S>,
        inp: &ScanInput,
        cur_cum: i64,
        cur_acc: f32,
    ) -> f32 {
        let (v, a) = inp.stop_from;
        self.stop_v_max = v;
        // Drops of a few percent (span-to-span noise of the limits) are taken in stride:
        // the stop brakes with 97 % of the limit so far, down to the next real drop.
        let mut acc_run = cur_acc;
        let mut from = inp.idx + 1;
        for _ in 0..STOP_LIMIT_STEPS {
            let lim = acc_run * (1.0 - STOP_ACC_SLACK);
            let Some(k) = spans.first_acc_below(from, inp.scan_last, lim) else {
                return lim;
            };
            let Some(sk) = spans.get(k) else {
                return lim;
            };
            let need = braking_distance(v, a, 0.0, lim, self.stop_jerk) + v * inp.period_s;
            if to_cum(need) < sk.cum.wrapping_sub(cur_cum).wrapping_sub(inp.sigma_cum) {
                return lim;
            }
            acc_run = sk.lim.acc;
            from = k + 1;
        }
        (acc_run * (1.0 - STOP_ACC_SLACK)).mn(spans.min_acc(from, inp.scan_last))
    }

    /// The constraints ahead of the current span (which starts at `cur_cum`), as seen
    /// from `pos` (+ the Kahan compensation `comp` of the position), into `ahead`; returns the distance to the nearest stop point (+∞ if
    /// none) and whether it is the end of the known path.
    pub fn fill(&self, ahead: &mut Ahead, pos: i64, cur_cum: i64, comp: f32) -> (f32, bool) {
        ahead.n_speed = 0;
        ahead.n_accel = 0;
        let ahead_of = |p: i64| p.wrapping_sub(cur_cum) > 0;
        for s in self
            .speed
            .iter()
            .take(self.n_speed)
            .filter(|s| ahead_of(s.pos))
        {
            ahead.push_speed(SpeedConstraint {
                dist: cum_mm(s.pos.wrapping_sub(pos)) + comp,
                w: s.w,
                acc: s.acc,
                jerk: s.jerk,
                soft: s.soft,
            });
        }
        for c in self
            .accel
            .iter()
            .take(self.n_accel)
            .filter(|c| ahead_of(c.pos))
        {
            ahead.push_accel(AccConstraint {
                dist: cum_mm(c.pos.wrapping_sub(pos)) + comp,
                acc: c.acc,
                jerk: c.jerk,
            });
        }
        ahead.n_drops = 0;
        for d in self.drops.iter().take(self.n_drops) {
            // (drops behind the position count from here: their span is being crossed)
            ahead.push_drop(JerkDrop {
                dist: (cum_mm(d.pos.wrapping_sub(pos)) + comp).mx(0.0),
                jerk: d.jerk,
            });
        }
        let stop = self
            .stop_pos
            .map(|p| cum_mm(p.wrapping_sub(pos)) + comp)
            .unwrap_or(f32::INFINITY);
        (stop, self.stop_at_path_end)
    }
}

/// Weaker spans the executor's stop limit looks through before taking the weakest.
const STOP_LIMIT_STEPS: usize = 4;
/// Fraction of the acceleration limit the executor's stop leaves unused (see
/// `ScanCache::stop_limit`).
pub(crate) const STOP_ACC_SLACK: f32 = 0.03;

/// Cap steps one scan keeps exactly; the rest of a longer staircase is represented by its
/// lowest cap at the last kept point (conservative).
const CAP_EVENTS: usize = 12;
