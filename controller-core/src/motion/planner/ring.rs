//! The planner's span ring with the indexes the look-ahead needs, so that one period's
//! scan costs O(number of constraints) instead of O(spans within the stopping distance)
//! (hundreds of spans on short CAM segments at speed).
//!
//! Per span, besides the span itself:
//! * `cum`: path length from a fixed origin to the span start, fixed point 2⁻⁴⁰ mm in a
//!   wrapping `i64`. An f32 span length converts exactly (for lengths ≥ 2⁻¹⁷ mm), so the
//!   distance between any two spans is their exact f32 length sum, rounded once when
//!   converted back (relative 6e-8), however long the program.
//! * `next_cap`: the first later span with a strictly lower speed cap. Following it from
//!   the current span visits exactly the "staircase" of caps ahead that can bind (each
//!   lower than everything before it).
//! * `prev_cap`: the last earlier span with a cap ≤ this one. From the newest span this
//!   chain lists the spans still waiting for their `next_cap` (the suffix minima), which is
//!   what appending and truncating maintain (a monotone stack without the stack:
//!   amortized O(1) per span).
//!
//! Min segment trees ([`MinTree`]) over the caps, the acceleration and the jerk limits
//! answer "lowest value over these spans" and "first span below x" in O(log S).
//!
//! Caps depend on the feed override; changing it re-links the ring (O(S), once).
//! Exact stops (and dwells) are kept in a sorted side list of sequence numbers.

use heapless::Deque;

use super::fmath::F32Ext;
use super::mintree::MinTree;
use super::span::{PathLimits, Span};

/// Fixed-point scale of `cum`: 2⁴⁰ units per mm.
const CUM_SCALE: f32 = 1_099_511_627_776.0;
const CUM_UNIT_MM: f32 = 1.0 / CUM_SCALE;

/// `len_mm` in cum units (exact for 2⁻¹⁷ ≤ len < 2¹⁶ mm; shorter lengths truncate to
/// within 2⁻⁴⁰ mm; negative and NaN give 0, longer saturate). In two 32-bit halves: the
/// f32 → i64 conversion is a library routine on the Cortex-M4, f32 → u32 one instruction.
#[inline]
pub(crate) fn to_cum(len_mm: f32) -> i64 {
    let x = len_mm.clampf(0.0, 65_536.0) * CUM_SCALE;
    // x < 2⁵⁶: the high part has at most 24 bits and x − hi·2³² is exact.
    let hi = (x * (1.0 / 4_294_967_296.0)) as u32;
    let lo = (x - hi as f32 * 4_294_967_296.0) as u32;
    ((hi as i64) << 32) | lo as i64
}

/// A cum difference in mm: `d = hi·2³² + lo` with a signed low half (|lo| ≤ 2³¹), each
/// converted by one instruction; small differences are exact up to the final rounding.
#[inline]
pub(crate) fn cum_mm(d: i64) -> f32 {
    let lo = d as i32;
    let hi = (d.wrapping_sub(lo as i64) >> 32) as i32;
    (hi as f32 * 4_294_967_296.0 + lo as f32) * CUM_UNIT_MM
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SpanSlot {
    pub span: Span,
    pub piece_id: u32,
    /// Piece-local σ at the span start.
    pub sigma0: f32,
    pub lim: PathLimits,
    pub feed: f32,
    pub rapid: bool,
    /// The machine stops at the end of this span (exact-stop junction).
    pub stop_after: bool,
    pub dwell_periods: u32,
    pub sent: bool,
    /// Index fields, maintained by [`SpanRing`].
    pub cum: i64,
    pub next_cap: Option<u32>,
    pub prev_cap: Option<u32>,
}

impl SpanSlot {
    /// Whether the motion must come to rest at the end of this span.
    #[inline]
    pub fn stops(&self) -> bool {
        self.stop_after || self.dwell_periods > 0
    }

    /// Speed cap under feed override `ovr`.
    #[inline]
    pub fn cap(&self, ovr: f32) -> f32 {
        if self.rapid {
            self.lim.vel * ovr.mn(1.0)
        } else {
            self.lim.vel.mn(self.feed * ovr)
        }
    }

    /// cum at the span end.
    #[inline]
    pub fn cum_end(&self) -> i64 {
        self.cum.wrapping_add(to_cum(self.span.len_mm))
    }
}

/// Span ring of capacity `S` with the look-ahead indexes.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SpanRing<const S: usize> {
    slots: Deque<SpanSlot, S>,
    /// Sequence numbers of the spans that stop at their end, ascending.
    stops: Deque<u32, S>,
    /// Feed override the cap links were built for.
    ovr: f32,
    /// Caps, acceleration and jerk limits by sequence number (mod S).
    caps: MinTree<S>,
    accs: MinTree<S>,
    jerks: MinTree<S>,
}

impl<const S: usize> SpanRing<S> {
    pub const fn new() -> Self {
        Self {
            slots: Deque::new(),
            stops: Deque::new(),
            ovr: 1.0,
            caps: MinTree::new(),
            accs: MinTree::new(),
            jerks: MinTree::new(),
        }
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    #[inline]
    pub fn is_full(&self) -> bool {
        self.slots.is_full()
    }

    #[inline]
    pub fn front(&self) -> Option<&SpanSlot> {
        self.slots.front()
    }

    #[inline]
    pub fn back(&self) -> Option<&SpanSlot> {
        self.slots.back()
    }

    #[inline]
    pub fn get(&self, i: usize) -> Option<&SpanSlot> {
        self.slots.get(i)
    }

    /// Index of the span with sequence number `seq`, if held.
    #[inline]
    pub fn index_of(&self, seq: u32) -> Option<usize> {
        let front = self.slots.front()?.span.seq;
        let i = seq.wrapping_sub(front) as usize;
        (i < self.slots.len()).then_some(i)
    }

    /// Index of a link, if it points at a held span.
    #[inline]
    pub fn link(&self, l: Option<u32>) -> Option<usize> {
        l.and_then(|s| self.index_of(s))
    }

    pub fn mark_sent(&mut self, i: usize) {
        if let Some(s) = self.slots.get_mut(i) {
            s.sent = true;
        }
    }

    /// Makes the newest span an exact stop (its end is a G61 junction).
    pub fn set_stop_back(&mut self) {
        let Some(s) = self.slots.back_mut() else {
            return;
        };
        if !s.stop_after {
            s.stop_after = true;
            if s.dwell_periods == 0 {
                // Newest span: the list stays sorted.
                let _ = self.stops.push_back(s.span.seq);
            }
        }
    }

    /// Appends a span (its index fields are filled in here); false when full.
    pub fn push_back(&mut self, mut slot: SpanSlot) -> bool {
        slot.cum = self.slots.back().map(|b| b.cum_end()).unwrap_or(0);
        slot.next_cap = None;
        slot.prev_cap = None;
        let stops = slot.stops();
        let seq = slot.span.seq;
        if self.slots.push_back(slot).is_err() {
            return false;
        }
        if stops {
            let _ = self.stops.push_back(seq);
        }
        self.caps.set(seq as usize, slot.cap(self.ovr));
        self.accs.set(seq as usize, slot.lim.acc);
        self.jerks.set(seq as usize, slot.lim.jerk);
        self.link_cap(self.slots.len() - 1);
        true
    }

    /// Removes the newest span.
    pub fn pop_back(&mut self) -> Option<SpanSlot> {
        let s = self.slots.pop_back()?;
        if self.stops.back() == Some(&s.span.seq) {
            self.stops.pop_back();
        }
        self.unlink_tail();
        Some(s)
    }

    /// Removes the oldest span.
    pub fn pop_front(&mut self) -> Option<SpanSlot> {
        let s = self.slots.pop_front()?;
        while let Some(&q) = self.stops.front() {
            if self.index_of(q).is_none() {
                self.stops.pop_front();
            } else {
                break;
            }
        }
        Some(s)
    }

    pub fn clear(&mut self) {
        self.slots.clear();
        self.stops.clear();
    }

    /// As [`SpanRing::new`], in place (the ring is large).
    pub fn reset(&mut self) {
        self.clear();
        self.ovr = 1.0;
        self.caps = MinTree::new();
        self.accs = MinTree::new();
        self.jerks = MinTree::new();
    }

    /// The first span at index ≥ `from` that stops at its end.
    pub fn first_stop_from(&self, from: usize) -> Option<usize> {
        self.stops
            .iter()
            .filter_map(|&q| self.index_of(q))
            .find(|&i| i >= from)
    }

    /// Re-links the caps for a new feed override.
    pub fn set_override(&mut self, ovr: f32) {
        if ovr == self.ovr {
            return;
        }
        self.ovr = ovr;
        for i in 0..self.slots.len() {
            if let Some(s) = self.slots.get_mut(i) {
                s.next_cap = None;
                s.prev_cap = None;
            }
        }
        for i in 0..self.slots.len() {
            self.link_cap(i);
            if let Some(sl) = self.slots.get(i) {
                self.caps.set_raw(sl.span.seq as usize, sl.cap(ovr));
            }
        }
        self.caps.rebuild();
    }

    /// Sequence number of index `i` (as a tree slot).
    #[inline]
    fn slot_of(&self, i: usize) -> usize {
        self.slots
            .front()
            .map(|f| f.span.seq.wrapping_add(i as u32) as usize)
            .unwrap_or(0)
    }

    /// Lowest acceleration limit of the spans `i..=k` (+∞ if empty).
    #[inline]
    pub fn min_acc(&self, i: usize, k: usize) -> f32 {
        if k < i || k >= self.slots.len() {
            return f32::INFINITY;
        }
        self.accs.min_run(self.slot_of(i), k - i + 1)
    }

    /// Lowest jerk limit of the spans `i..=k` (+∞ if empty).
    #[inline]
    pub fn min_jerk(&self, i: usize, k: usize) -> f32 {
        if k < i || k >= self.slots.len() {
            return f32::INFINITY;
        }
        self.jerks.min_run(self.slot_of(i), k - i + 1)
    }

    /// Lowest speed cap of the spans `i..=k` (+∞ if empty).
    #[inline]
    pub fn min_cap(&self, i: usize, k: usize) -> f32 {
        if k < i || k >= self.slots.len() {
            return f32::INFINITY;
        }
        self.caps.min_run(self.slot_of(i), k - i + 1)
    }

    /// First index in `i..=k` whose span's acceleration limit is below `x`.
    #[inline]
    pub fn first_acc_below(&self, i: usize, k: usize, x: f32) -> Option<usize> {
        if k < i || k >= self.slots.len() {
            return None;
        }
        self.accs
            .first_below_run(self.slot_of(i), k - i + 1, x)
            .map(|o| i + o)
    }

    /// First index in `i..=k` whose span's jerk limit is below `x`.
    #[inline]
    pub fn first_jerk_below(&self, i: usize, k: usize, x: f32) -> Option<usize> {
        if k < i || k >= self.slots.len() {
            return None;
        }
        self.jerks
            .first_below_run(self.slot_of(i), k - i + 1, x)
            .map(|o| i + o)
    }

    /// Links span `m` (all before it linked, none after it): pending spans with a higher
    /// cap get `m` as their next lower one, `m` its previous lower-or-equal one.
    fn link_cap(&mut self, m: usize) {
        let ovr = self.ovr;
        let Some(sm) = self.slots.get(m) else {
            return;
        };
        let (seq_m, cap_m) = (sm.span.seq, sm.cap(ovr));
        let mut j = m.checked_sub(1);
        while let Some(jj) = j {
            let Some(sj) = self.slots.get_mut(jj) else {
                break;
            };
            if sj.cap(ovr) > cap_m {
                sj.next_cap = Some(seq_m);
                let p = sj.prev_cap;
                j = self.link(p).filter(|&p| p < jj);
            } else {
                break;
            }
        }
        let prev = j.and_then(|jj| self.slots.get(jj)).map(|s| s.span.seq);
        if let Some(sm) = self.slots.get_mut(m) {
            sm.prev_cap = prev;
        }
    }

    /// After the newest span was dropped: the spans that pointed at it wait again (they
    /// are suffix minima, found backwards through the `prev_*` links; the first one that
    /// does not point at it ends the walk).
    fn unlink_tail(&mut self) {
        let Some(last) = self.slots.len().checked_sub(1) else {
            return;
        };
        let gone = |l: Option<u32>, ring: &Self| l.is_some() && ring.link(l).is_none();
        let mut j = Some(last);
        while let Some(jj) = j {
            let (nc, pc) = match self.slots.get(jj) {
                Some(s) => (s.next_cap, s.prev_cap),
                None => break,
            };
            if !gone(nc, self) {
                break;
            }
            if let Some(s) = self.slots.get_mut(jj) {
                s.next_cap = None;
            }
            j = self.link(pc).filter(|&p| p < jj);
        }
    }

    /// The last index `k ≥ from` whose span starts at most `d` (cum units) after the
    /// start of span `from` (binary search).
    pub fn last_starting_within(&self, from: usize, d: i64) -> usize {
        let Some(base) = self.slots.get(from).map(|s| s.cum) else {
            return from;
        };
        let (mut lo, mut hi) = (from, self.slots.len().saturating_sub(1).max(from));
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            let c = self
                .slots
                .get(mid)
                .map(|s| s.cum.wrapping_sub(base))
                .unwrap_or(i64::MAX);
            if c <= d {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        lo
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slot(seq: u32, len: f32, vel: f32, acc: f32, jerk: f32) -> SpanSlot {
        SpanSlot {
            span: Span {
                seq,
                path_gen: 0,
                run: 0,
                tag: 0,
                len_mm: len,
                inv_len: 1.0 / len,
                inv_feed: 0.0,
                coef: [[0.0; 8]; 3],
            },
            piece_id: 0,
            sigma0: 0.0,
            lim: PathLimits { vel, acc, jerk },
            feed: 1.0e9,
            rapid: false,
            stop_after: false,
            dwell_periods: 0,
            sent: false,
            cum: 0,
            next_cap: None,
            prev_cap: None,
        }
    }

    /// The links must equal a brute-force scan after any sequence of appends, tail
    /// truncations and front releases.
    fn check(r: &SpanRing<64>) {
        let n = r.len();
        for i in 0..n {
            let s = r.get(i).unwrap();
            let want_next = (i + 1..n)
                .find(|&k| r.get(k).unwrap().cap(r.ovr) < s.cap(r.ovr))
                .map(|k| r.get(k).unwrap().span.seq);
            assert_eq!(s.next_cap, want_next, "next_cap of {i}");
            for k in i..n {
                let accs = (i..=k).map(|q| r.get(q).unwrap().lim.acc);
                let jerks = (i..=k).map(|q| r.get(q).unwrap().lim.jerk);
                let caps = (i..=k).map(|q| r.get(q).unwrap().cap(r.ovr));
                assert_eq!(r.min_acc(i, k), accs.fold(f32::INFINITY, f32::min));
                assert_eq!(r.min_jerk(i, k), jerks.fold(f32::INFINITY, f32::min));
                assert_eq!(r.min_cap(i, k), caps.fold(f32::INFINITY, f32::min));
                let x = 260.0;
                let want = (i..=k).find(|&q| r.get(q).unwrap().lim.acc < x);
                assert_eq!(r.first_acc_below(i, k, x), want);
            }
            if i > 0 {
                let c = r.get(i - 1).unwrap().cum_end();
                assert_eq!(s.cum, c);
            }
        }
    }

    #[test]
    fn links_match_brute_force_under_appends_truncations_and_releases() {
        let mut r: SpanRing<64> = SpanRing::new();
        let mut seq = 1u32;
        // Deterministic pseudo-random caps from a small set (ties included).
        let mut x = 12345u32;
        let mut rnd = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        for step in 0..3000 {
            let op = rnd() % 10;
            if op < 6 && !r.is_full() {
                let v = (rnd() % 7) as f32 * 10.0 + 5.0;
                let a = (rnd() % 5) as f32 * 100.0 + 50.0;
                let j = (rnd() % 4) as f32 * 1.0e4 + 2.0e4;
                let len = 0.01 + (rnd() % 100) as f32 * 0.013;
                assert!(r.push_back(slot(seq, len, v, a, j)));
                seq += 1;
            } else if op < 8 {
                if r.pop_back().is_some() {
                    seq -= 1;
                }
            } else {
                r.pop_front();
            }
            if step % 500 == 250 {
                r.set_override(0.5 + (rnd() % 4) as f32 * 0.3);
            }
            check(&r);
        }
    }

    #[test]
    fn fixed_point_conversions_are_exact() {
        for &x in &[
            0.0f32, 1.0e-9, 3.0e-6, 0.05, 0.1, 1.0, 12.345_678, 64.0, 1000.5, 65_535.9,
        ] {
            let want = (x as f64 * 1_099_511_627_776.0).trunc() as i64;
            assert_eq!(to_cum(x), want, "{x}");
            let back = cum_mm(want) as f64;
            assert!(
                (back - x as f64).abs() <= 1.0e-7 * x as f64 + 1.0e-12,
                "{x}"
            );
        }
        assert_eq!(to_cum(-1.0), 0);
        assert_eq!(to_cum(f32::NAN), 0);
        for d in [-5_000_000_000_000i64, -1, 0, 1, 123_456_789_012_345] {
            let back = cum_mm(d) as f64;
            let want = d as f64 / 1_099_511_627_776.0;
            assert!((back - want).abs() <= 1.0e-7 * want.abs() + 1.0e-15, "{d}");
        }
    }

    #[test]
    fn cum_is_exact_and_search_finds_the_span() {
        let mut r: SpanRing<64> = SpanRing::new();
        for k in 0..10 {
            r.push_back(slot(k + 1, 0.1, 1.0, 1.0, 1.0));
        }
        let d = r.get(7).unwrap().cum - r.get(2).unwrap().cum;
        assert_eq!(d, 5 * to_cum(0.1));
        assert!((cum_mm(d) - 0.5).abs() < 1e-7);
        assert_eq!(r.last_starting_within(2, to_cum(0.25)), 4);
        assert_eq!(r.last_starting_within(2, to_cum(100.0)), 9);
        assert_eq!(r.last_starting_within(2, -1), 2);
    }
}
