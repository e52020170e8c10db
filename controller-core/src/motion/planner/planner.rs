//! The planning half (lower-priority task): segment queue, junction blends, span
//! generation, and the look-ahead that turns the spans into one [`Step`] per control
//! period for the executor.
//!
//! Pipeline of one segment: `push` validates it ([`super::segment`]), chooses the blend at
//! the junction with the previous segment ([`super::blend`]) and queues its pieces;
//! `produce` cuts queued pieces into spans ([`super::span`]) as room allows, hands spans to
//! the executor as the profile approaches them, and generates steps ([`super::lookahead`]).
//!
//! **Frozen path.** A span handed to the executor never changes. The planner always hands
//! over every span within the stopping distance of the newest step, so that a hold (or a
//! starved planner) can stop on known geometry. The last queued segment is *tentative*:
//! its spans assume the path ends there; when the next segment arrives the tentative spans
//! not yet handed over are regenerated with the new blend, whose width is limited to the
//! part of the segment not yet handed over.

use heapless::Deque;

use super::blend::{plan_junction, Jet, Junction};
use super::channel::Sink;
use super::config::{PlannerConfig, PlannerConfigError, Settings};
use super::executor::{ExecMode, ExecutorStatus, Step};
use super::geometry::{Piece, V3};
use super::lookahead::{choose_jerk, AccConstraint, Ahead, SpeedConstraint};
use super::profile::{braking_distance, integrate};
use super::segment::{prepare, PieceAttr, Segment, SegmentError};
use super::span::{derivative_bounds, fit, offset_at, path_limits, PathLimits, Span, FIT_TOL_MM};

/// Feed override range (1 % to 200 %).
pub const FEED_OVERRIDE_MIN: f32 = 0.01;
pub const FEED_OVERRIDE_MAX: f32 = 2.0;

/// Stop points closer than this (mm) at speeds below [`SNAP_SPEED_MM_S`] are taken as
/// reached: ends the asymptotic creep of the discrete braking onto a stop point.
const SNAP_MM: f32 = 2.0e-5;
const SNAP_SPEED_MM_S: f32 = 2.0e-3;

/// Halvings of a span whose fit misses the exact curve by more than [`FIT_TOL_MM`].
const MAX_FIT_HALVINGS: usize = 12;

#[derive(Clone, Copy, Debug, PartialEq)]
struct PieceEntry {
    piece: Piece,
    attr: PieceAttr,
    /// Blend at the piece start (fixed when the piece was queued).
    j_in: Junction,
    /// Blend at the piece end; final once `closed`.
    j_out: Junction,
    closed: bool,
    /// Spans exist for local σ below this.
    cursor: f32,
    /// Every span of the piece exists (tentative ones if not `closed`).
    done: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct SpanSlot {
    span: Span,
    piece_id: u32,
    /// Piece-local σ at the span start.
    sigma0: f32,
    lim: PathLimits,
    feed: f32,
    rapid: bool,
    /// The machine stops at the end of this span (exact-stop junction).
    stop_after: bool,
    dwell_periods: u32,
    sent: bool,
}

/// Profile state of the look-ahead (the newest generated step).
#[derive(Clone, Copy, Debug, PartialEq)]
struct GenState {
    seq: u32,
    sigma: f32,
    /// Kahan compensation of `sigma`, `vel`, `acc`: the state is a running sum of tiny
    /// increments; uncompensated f32 rounding drifts it off the braking curve it rides.
    comp: f32,
    vel: f32,
    vel_comp: f32,
    acc: f32,
    acc_comp: f32,
    dwell_left: u32,
    dwell_started: bool,
}

impl GenState {
    fn at(seq: u32, sigma: f32) -> Self {
        Self {
            seq,
            sigma,
            comp: 0.0,
            vel: 0.0,
            vel_comp: 0.0,
            acc: 0.0,
            acc_comp: 0.0,
            dwell_left: 0,
            dwell_started: false,
        }
    }
}

/// What the planner is doing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlannerState {
    /// At rest, nothing queued beyond the current position.
    #[default]
    Idle,
    /// Generating motion.
    Running,
    /// Feed hold requested, still stopping.
    Holding,
    /// Stopped by a feed hold; `resume` continues.
    Held,
    /// Abort requested, stopping; the queue is cleared once stopped.
    Aborting,
}

/// Requested run state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RunState {
    Run,
    Hold,
    Abort,
}

/// Where a hold stops: span sequence number and local σ.
#[derive(Clone, Copy, Debug, PartialEq)]
struct HoldPoint {
    seq: u32,
    sigma: f32,
}

/// Queue and look-ahead figures.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlannerStatus {
    pub state: PlannerState,
    /// Segments (pieces) queued and not yet cut into spans.
    pub queued_segments: usize,
    /// Spans held (executor position to generation frontier).
    pub queued_spans: usize,
    pub free_slots: usize,
    /// Periods where even maximal braking failed a look-ahead check (expected 0).
    pub slips: u32,
    /// Tag of the segment the newest step lies on.
    pub tag: u32,
}

/// The planning half: owns the segment queue (capacity `N` segments) and the span ring
/// (capacity `S` spans).
#[derive(Clone, Debug, PartialEq)]
pub struct Planner<const N: usize, const S: usize> {
    set: Settings,
    pieces: Deque<PieceEntry, N>,
    front_piece_id: u32,
    spans: Deque<SpanSlot, S>,
    next_seq: u32,
    /// Spans with a lower sequence number have been handed to the executor.
    sent_end: u32,
    gen: GenState,
    epoch: u16,
    path_gen: u16,
    feed_override: f32,
    run: RunState,
    hold_point: Option<HoldPoint>,
    exec_mode: ExecMode,
    end_pos: V3,
    slips: u32,
}

impl<const N: usize, const S: usize> Planner<N, S> {
    /// A planner at rest at `start_mm`.
    pub fn new(cfg: &PlannerConfig, start_mm: [f32; 3]) -> Result<Self, PlannerConfigError> {
        let set = Settings::new(cfg)?;
        for x in start_mm {
            if !x.is_finite() {
                return Err(PlannerConfigError::NotFinite("start_mm"));
            }
        }
        Ok(Self {
            set,
            pieces: Deque::new(),
            front_piece_id: 0,
            spans: Deque::new(),
            next_seq: 1,
            sent_end: 1,
            gen: GenState::at(1, 0.0),
            epoch: 0,
            path_gen: 0,
            feed_override: 1.0,
            run: RunState::Run,
            hold_point: None,
            exec_mode: ExecMode::Idle,
            end_pos: start_mm,
            slips: 0,
        })
    }

    pub fn settings(&self) -> &Settings {
        &self.set
    }

    /// Free segment slots (flow control: an arc of n extra turns needs n + 1).
    pub fn free_slots(&self) -> usize {
        N - self.pieces.len()
    }

    /// Where the queued path ends (the start of the next segment), mm.
    pub fn end_position_mm(&self) -> [f32; 3] {
        self.end_pos
    }

    pub fn status(&self) -> PlannerStatus {
        let at_rest = self.gen.vel == 0.0 && self.gen.acc == 0.0;
        let state = match self.run {
            RunState::Abort => PlannerState::Aborting,
            RunState::Hold if at_rest => PlannerState::Held,
            RunState::Hold => PlannerState::Holding,
            RunState::Run if at_rest && self.at_path_end() => PlannerState::Idle,
            RunState::Run => PlannerState::Running,
        };
        let tag = self
            .gen
            .seq
            .checked_sub(self.spans.front().map(|s| s.span.seq).unwrap_or(0))
            .and_then(|i| self.spans.get(i as usize))
            .map(|s| s.span.tag)
            .unwrap_or(0);
        PlannerStatus {
            state,
            queued_segments: self.pieces.len(),
            queued_spans: self.spans.len(),
            free_slots: self.free_slots(),
            slips: self.slips,
            tag,
        }
    }

    /// Whether the look-ahead is at the end of everything queued.
    fn at_path_end(&self) -> bool {
        let Some(front) = self.spans.front() else {
            return true;
        };
        let idx = self.gen.seq.wrapping_sub(front.span.seq) as usize;
        match self.spans.get(idx) {
            None => true,
            Some(s) => {
                idx + 1 >= self.spans.len()
                    && self.gen.sigma >= s.span.len_mm
                    && self.pieces.iter().all(|e| e.done)
            }
        }
    }

    /// Feed hold: stop on the path as fast as the limits allow (within the look-ahead,
    /// so every span's limits hold while stopping), then wait for [`Planner::resume`].
    /// Acts on the next generated step: the executor sees it after the steps already
    /// buffered between the two halves.
    pub fn hold(&mut self) {
        if self.run == RunState::Run {
            self.run = RunState::Hold;
            self.hold_point = None;
        }
    }

    /// Continue after a hold, from the stop point (continuous: the profile simply
    /// accelerates again from rest).
    pub fn resume(&mut self) {
        if self.run == RunState::Hold {
            self.run = RunState::Run;
            self.hold_point = None;
        }
    }

    /// Feed override as a ratio (0.01..=2.0); applied by the look-ahead from the next
    /// generated step on, within the jerk and acceleration limits.
    pub fn set_feed_override(&mut self, ratio: f32) -> Result<(), PlannerConfigError> {
        if !ratio.is_finite() {
            return Err(PlannerConfigError::NotFinite("feed_override"));
        }
        if !(FEED_OVERRIDE_MIN..=FEED_OVERRIDE_MAX).contains(&ratio) {
            return Err(PlannerConfigError::OutOfRange("feed_override"));
        }
        self.feed_override = ratio;
        Ok(())
    }

    pub fn feed_override(&self) -> f32 {
        self.feed_override
    }

    /// Abort: stop on the path like a hold, then clear the queue; new segments start at
    /// the stop point ([`Planner::end_position_mm`]). Pushes are refused meanwhile.
    pub fn abort(&mut self) {
        if self.run == RunState::Run {
            self.hold_point = None;
        }
        self.run = RunState::Abort;
    }

    /// Queues one segment. On error nothing changes. A line shorter than
    /// `min_segment_mm` is accepted and skipped.
    pub fn push(&mut self, seg: &Segment) -> Result<(), SegmentError> {
        if self.run == RunState::Abort {
            return Err(SegmentError::Aborting);
        }
        let prep = prepare(seg, self.end_pos, &self.set)?;
        if prep.n == 0 {
            return Ok(());
        }
        if self.free_slots() < prep.n {
            return Err(SegmentError::QueueFull);
        }
        let mut j_in = Junction::NONE;
        if !self.pieces.is_empty() {
            self.reopen_tail();
            let last_id = self.front_piece_id + self.pieces.len() as u32 - 1;
            if let Some(last) = self.pieces.back_mut() {
                let free = last.piece.len - last.cursor;
                let j = plan_junction(
                    &last.piece,
                    &prep.pieces[0],
                    last.attr.tol_after,
                    &last.j_in,
                    free,
                    FIT_TOL_MM,
                    self.set.min_span_mm(),
                );
                last.j_out = j;
                last.closed = true;
                j_in = j;
                if last.done && j.stop {
                    // The whole piece is already with the executor: the stop goes on its
                    // last span.
                    if let Some(slot) = self.spans.back_mut() {
                        if slot.piece_id == last_id {
                            slot.stop_after = true;
                        }
                    }
                }
            }
        }
        for k in 0..prep.n {
            let piece = prep.pieces[k];
            let closed = k + 1 < prep.n;
            let j_out = if closed {
                plan_junction(
                    &piece,
                    &prep.pieces[k + 1],
                    prep.attr.tol_after,
                    &j_in,
                    piece.len,
                    FIT_TOL_MM,
                    self.set.min_span_mm(),
                )
            } else {
                Junction::NONE
            };
            let entry = PieceEntry {
                piece,
                attr: prep.attr,
                j_in,
                j_out,
                closed,
                cursor: 0.0,
                done: false,
            };
            // Capacity was checked above.
            let _ = self.pieces.push_back(entry);
            j_in = j_out;
        }
        self.end_pos = prep.pieces[prep.n - 1].end;
        Ok(())
    }

    /// Removes the not yet handed over spans of the tentative last piece, so that it can be
    /// regenerated with its end blend.
    fn reopen_tail(&mut self) {
        let Some(last_idx) = self.pieces.len().checked_sub(1) else {
            return;
        };
        let last_id = self.front_piece_id + last_idx as u32;
        while let Some(slot) = self.spans.back() {
            if slot.piece_id == last_id && !slot.sent {
                self.spans.pop_back();
                self.next_seq = self.next_seq.wrapping_sub(1);
            } else {
                break;
            }
        }
        let kept = matches!(self.spans.back(), Some(slot) if slot.piece_id == last_id);
        let cursor = match self.spans.back() {
            Some(slot) if kept => slot.sigma0 + slot.span.len_mm,
            _ => 0.0,
        };
        if let Some(last) = self.pieces.back_mut() {
            last.cursor = cursor;
            // A dwell is one zero-length span: done if it is still there.
            last.done = if last.piece.is_dwell() {
                kept
            } else {
                !(cursor < last.piece.len)
            };
        }
    }

    /// Takes the executor's latest status (call before [`Planner::produce`]).
    pub fn sync(&mut self, st: &ExecutorStatus) {
        self.exec_mode = st.mode;
        // Release spans the executor has passed (and the look-ahead too).
        while let Some(front) = self.spans.front() {
            if front.span.seq < st.span_seq && front.span.seq < self.gen.seq && front.sent {
                self.spans.pop_front();
            } else {
                break;
            }
        }
        if st.epoch != self.epoch {
            // The executor stopped by itself (underrun): restart the profile at its stop.
            self.epoch = st.epoch;
            let front_seq = self
                .spans
                .front()
                .map(|s| s.span.seq)
                .unwrap_or(self.next_seq);
            self.gen =
                if st.span_seq >= front_seq && st.span_seq != 0 && st.path_gen == self.path_gen {
                    GenState::at(st.span_seq, st.sigma_mm)
                } else {
                    GenState::at(front_seq, 0.0)
                };
            self.hold_point = None;
        }
    }

    /// Cuts queued pieces into spans while there is room, hands spans over as the profile
    /// needs them, and generates up to `max_steps` steps into `steps`. Returns the number
    /// of steps generated.
    pub fn produce(
        &mut self,
        spans: &mut impl Sink<Span>,
        steps: &mut impl Sink<Step>,
        max_steps: usize,
    ) -> usize {
        self.fill_spans();
        self.release_pieces();
        if self.exec_mode == ExecMode::Stopping {
            return 0;
        }
        let mut n = 0;
        while n < max_steps && steps.free() > 0 {
            match self.gen_step(spans) {
                Some(s) => {
                    if steps.try_send(s).is_err() {
                        break;
                    }
                    n += 1;
                }
                None => break,
            }
        }
        n
    }

    /// Generates spans until the ring is full or every queued piece is cut.
    pub fn fill_spans(&mut self) {
        while !self.spans.is_full() {
            let Some(k) = self.pieces.iter().position(|e| !e.done) else {
                return;
            };
            self.generate_one(k);
        }
    }

    /// Drops pieces whose spans are all generated and final and whose geometry the next
    /// piece's blend no longer needs.
    fn release_pieces(&mut self) {
        while self.pieces.len() >= 2 {
            let (Some(a), Some(b)) = (self.pieces.get(0), self.pieces.get(1)) else {
                return;
            };
            if a.done && a.closed && b.closed && b.cursor >= a.j_out.d {
                self.pieces.pop_front();
                self.front_piece_id = self.front_piece_id.wrapping_add(1);
            } else {
                return;
            }
        }
    }

    /// Where the transitions of piece `k` start and end on it: the incoming one is active
    /// on `[0, b_in]`, the outgoing one on `[b_out, len]`. Breakpoints closer than the
    /// shortest span to each other or to a piece end are moved onto it (there the kernels
    /// are zero up to the third derivative), so that every breakpoint is a span end and
    /// adjacent spans see the same jets.
    fn breakpoints(&self, e: &PieceEntry) -> (f32, f32) {
        let lmin = self.set.min_span_mm();
        let len = e.piece.len;
        let mut b_in = if e.j_in.d > 0.0 {
            e.j_in.d.min(len)
        } else {
            0.0
        };
        if len - b_in < lmin {
            b_in = len;
        }
        let mut b_out = if e.closed && e.j_out.d > 0.0 {
            (len - e.j_out.d).max(0.0)
        } else {
            len
        };
        if b_out < lmin {
            b_out = 0.0;
        }
        if b_out > 0.0 && b_out < len && b_in > 0.0 && b_in < len && (b_out - b_in).abs() < lmin {
            b_out = b_in;
        }
        (b_in, b_out)
    }

    /// Exact commanded curve on piece `k` at local `s` (offset from the programmed point
    /// at `s_ref`), one-sided at breakpoints: `right` means the span lies to the right of
    /// `s`.
    fn jet(&self, k: usize, s: f32, s_ref: f32, right: bool) -> Jet {
        let Some(e) = self.pieces.get(k) else {
            return Jet::default();
        };
        let (b_in, b_out) = self.breakpoints(e);
        let d = e.piece.derivs(s);
        let mut j = Jet {
            p: e.piece.delta(s_ref, s),
            d1: d.d1,
            d2: d.d2,
            d3: d.d3,
        };
        let in_active = if right {
            s < b_in
        } else {
            s <= b_in && b_in > 0.0
        };
        if in_active {
            if let Some(prev) = k.checked_sub(1).and_then(|i| self.pieces.get(i)) {
                let x = s.min(e.j_in.d);
                j.add(&e.j_in.correction(&prev.piece, &e.piece, x, right));
            }
        }
        let len = e.piece.len;
        let out_active = if right {
            s >= b_out && b_out < len
        } else {
            s > b_out
        };
        if out_active && e.closed {
            if let Some(next) = self.pieces.get(k + 1) {
                let x = (s - len).clamp(-e.j_out.d, 0.0);
                j.add(&e.j_out.correction(&e.piece, &next.piece, x, right));
            }
        }
        j
    }

    /// Cuts the next span of piece `k`.
    fn generate_one(&mut self, k: usize) {
        let Some(e) = self.pieces.get(k).copied() else {
            return;
        };
        let piece_id = self.front_piece_id.wrapping_add(k as u32);
        let len = e.piece.len;
        let sa = e.cursor;
        if e.piece.is_dwell() {
            let span = Span {
                seq: self.next_seq,
                path_gen: self.path_gen,
                tag: e.attr.tag,
                len_mm: 0.0,
                inv_len: 0.0,
                inv_feed: 0.0,
                coef: constant_coef(e.piece.start),
            };
            self.push_slot(SpanSlot {
                span,
                piece_id,
                sigma0: 0.0,
                lim: PathLimits {
                    vel: 0.0,
                    acc: self.set.acc_floor,
                    jerk: self.set.jerk_floor,
                },
                feed: 0.0,
                rapid: false,
                stop_after: true,
                dwell_periods: e.attr.dwell_periods,
                sent: false,
            });
            if let Some(m) = self.pieces.get_mut(k) {
                m.cursor = len;
                m.done = true;
            }
            return;
        }
        if !(sa < len) {
            if let Some(m) = self.pieces.get_mut(k) {
                m.done = true;
            }
            return;
        }
        let lmin = self.set.min_span_mm();
        let (b_in, b_out) = self.breakpoints(&e);
        let mut sb = len.min(sa + e.piece.max_span_len());
        if len - sb < lmin {
            sb = len;
        }
        for b in [b_in, b_out] {
            if b > sa && b < sb {
                sb = b;
            }
        }
        let needs_check = e.piece.is_curved()
            || (e.j_in.mixed && sa < b_in)
            || (e.closed && e.j_out.mixed && sb > b_out);
        let origin = e.piece.position(sa);
        let j0 = self.jet(k, sa, sa, true);
        let mut coef;
        let mut halvings = 0;
        loop {
            let j1 = self.jet(k, sb, sa, false);
            let h = sb - sa;
            coef = fit(&j0, &j1, h, origin);
            if !needs_check || halvings >= MAX_FIT_HALVINGS || h < 2.0 * lmin {
                break;
            }
            let mut worst = 0.0f32;
            for u in [0.25f32, 0.5, 0.75] {
                let exact = self.jet(k, sa + u * h, sa, true).p;
                let got = offset_at(&coef, u);
                for i in 0..3 {
                    worst = worst.max((got[i] + j0.p[i] - exact[i]).abs());
                }
            }
            if worst <= FIT_TOL_MM {
                break;
            }
            sb = sa + 0.5 * h;
            halvings += 1;
        }
        let h = sb - sa;
        let bounds = derivative_bounds(&coef, h);
        let v_design = e.attr.feed * FEED_OVERRIDE_MAX;
        let lim = path_limits(&bounds, h, v_design, &self.set);
        let inv_feed = if e.attr.rapid || !e.attr.feed.is_finite() {
            0.0
        } else {
            1.0 / e.attr.feed
        };
        let span = Span {
            seq: self.next_seq,
            path_gen: self.path_gen,
            tag: e.attr.tag,
            len_mm: h,
            inv_len: if h > 0.0 { 1.0 / h } else { 0.0 },
            inv_feed,
            coef,
        };
        let at_end = !(sb < len);
        self.push_slot(SpanSlot {
            span,
            piece_id,
            sigma0: sa,
            lim,
            feed: e.attr.feed,
            rapid: e.attr.rapid,
            stop_after: at_end && e.closed && e.j_out.stop,
            dwell_periods: 0,
            sent: false,
        });
        if let Some(m) = self.pieces.get_mut(k) {
            m.cursor = sb;
            m.done = at_end;
        }
    }

    fn push_slot(&mut self, slot: SpanSlot) {
        if self.spans.push_back(slot).is_ok() {
            self.next_seq = self.next_seq.wrapping_add(1);
        }
    }

    /// Speed cap of a span under the current feed override.
    fn cap(&self, s: &SpanSlot) -> f32 {
        if s.rapid {
            s.lim.vel * self.feed_override.min(1.0)
        } else {
            s.lim.vel.min(s.feed * self.feed_override)
        }
    }

    /// Hands spans `..=idx` to the executor (in order); false when the channel is full.
    fn ensure_sent(&mut self, idx: usize, out: &mut impl Sink<Span>) -> bool {
        let Some(front_seq) = self.spans.front().map(|s| s.span.seq) else {
            return false;
        };
        if idx >= self.spans.len() {
            return false;
        }
        let target = front_seq.wrapping_add(idx as u32);
        while self.sent_end <= target {
            let i = self.sent_end.wrapping_sub(front_seq) as usize;
            let Some(slot) = self.spans.get_mut(i) else {
                return false;
            };
            if out.try_send(slot.span).is_err() {
                return false;
            }
            slot.sent = true;
            self.sent_end = self.sent_end.wrapping_add(1);
        }
        true
    }

    /// One control period of the look-ahead; `None` when there is nothing to do (at rest
    /// at the end of the queue, or waiting for geometry/channel room).
    fn gen_step(&mut self, out: &mut impl Sink<Span>) -> Option<Step> {
        let t = self.set.period_s;
        let front_seq = self.spans.front()?.span.seq;
        let mut idx = self.gen.seq.checked_sub(front_seq)? as usize;
        if !self.ensure_sent(idx, out) {
            return None;
        }
        if self.run != RunState::Run {
            if self.gen.vel == 0.0 && self.gen.acc == 0.0 {
                // Stopped: held until resumed, or the abort completes.
                if self.run == RunState::Abort {
                    self.finish_abort(idx);
                }
                return None;
            }
            if self.hold_point.is_none() {
                self.place_hold_point(idx);
            }
        }
        // Dwell spans: wait, then move on.
        let slot = *self.spans.get(idx)?;
        if slot.dwell_periods > 0 || (slot.span.len_mm == 0.0 && slot.stop_after) {
            if !self.gen.dwell_started {
                self.gen.dwell_started = true;
                self.gen.dwell_left = slot.dwell_periods;
            }
            if self.gen.dwell_left > 0 {
                self.gen.dwell_left -= 1;
                return Some(self.step_here(slot.lim.acc, slot.lim.jerk));
            }
            if idx + 1 < self.spans.len() && self.ensure_sent(idx + 1, out) {
                idx += 1;
                self.gen = GenState::at(self.gen.seq.wrapping_add(1), 0.0);
            } else {
                return None;
            }
        }
        let slot = *self.spans.get(idx)?;
        let (v, a) = (self.gen.vel, self.gen.acc);
        let floor_a = self.set.acc_floor;
        let floor_j = self.set.jerk_floor;
        let v_next = v + a.max(0.0) * t + 0.5 * slot.lim.jerk * t * t;
        // Scan as far as any braking could need: to a stop at the floor limits, plus the
        // most that braking to a low speed w instead of zero can add (it ends with a
        // ramp-out at w: (v+w)τ/2 − w²/2A grows until w = Aτ/2, by A³/8J² at most).
        let horizon = braking_distance(
            v_next,
            a.max(0.0) + slot.lim.jerk * t,
            0.0,
            floor_a,
            floor_j,
        ) + floor_a * floor_a * floor_a / (8.0 * floor_j * floor_j)
            + 2.0 * v_next * t
            + 1.0e-3;
        let touch = v_next * t + 1.0e-6;

        let cap0 = self.cap(&slot);
        let mut ahead = Ahead::new(cap0, slot.lim.acc, slot.lim.jerk);
        // Distances from the compensated σ: on a long span f32 σ alone is only good to its
        // ulp (1.9e-6 mm at 20 mm), which would make the constraints jitter.
        let mut dist = (slot.span.len_mm - self.gen.sigma) + self.gen.comp;
        // The current span's own cap and acceleration limit do not dominate later ones:
        // the motion can speed up in a following span with higher limits (and a lower
        // jerk there changes what the current state can still meet).
        let (mut cap_min, mut acc_run, mut jerk_run, mut acc_seen) =
            (f32::INFINITY, slot.lim.acc, slot.lim.jerk, f32::INFINITY);
        // Last acceleration constraint (distance, limit) and the lowest jerk since it.
        let mut last_acc: Option<(f32, f32)> = None;
        let mut jerk_since = f32::INFINITY;
        let mut prev_stop = slot.stop_after;
        let mut stop_dist = f32::INFINITY;
        // Limits for the executor's own stop (hold, underrun): the weakest span it can
        // reach, found where a stop with the limits so far ends before the next weaker span.
        let mut stop_limits: Option<(f32, f32)> = None;
        let hold = self.hold_point;
        // The hold's stop point only adds a constraint: those near it still count (braking
        // to a low speed can need more room than braking to zero), so the scan goes on.
        if let Some(h) = hold.filter(|h| h.seq == slot.span.seq) {
            let d = (h.sigma - self.gen.sigma) + self.gen.comp;
            ahead.push_speed(SpeedConstraint {
                dist: d,
                w: 0.0,
                acc: acc_run,
                jerk: jerk_run,
                soft: false,
            });
            stop_dist = d;
        }
        let mut k = idx + 1;
        loop {
            if prev_stop {
                ahead.push_speed(SpeedConstraint {
                    dist,
                    w: 0.0,
                    acc: acc_run,
                    jerk: jerk_run,
                    soft: false,
                });
                stop_dist = stop_dist.min(dist);
                break;
            }
            if dist > horizon {
                break;
            }
            if k >= self.spans.len() || !self.ensure_sent(k, out) {
                // End of the known (or handed over) path: stop there.
                ahead.push_speed(SpeedConstraint {
                    dist,
                    w: 0.0,
                    acc: acc_run,
                    jerk: jerk_run,
                    soft: false,
                });
                stop_dist = stop_dist.min(dist);
                break;
            }
            let Some(s) = self.spans.get(k).copied() else {
                break;
            };
            let cap_k = self.cap(&s);
            if stop_limits.is_none()
                && (s.lim.acc < acc_run || s.lim.jerk < jerk_run)
                && braking_distance(v_next, a, 0.0, acc_run, jerk_run) + v_next * t < dist
            {
                stop_limits = Some((acc_run, jerk_run));
            }
            if dist < touch {
                ahead.acc = ahead.acc.min(s.lim.acc);
                ahead.jerk = ahead.jerk.min(s.lim.jerk);
            }
            if cap_k < cap_min {
                let c = SpeedConstraint {
                    dist,
                    w: cap_k,
                    acc: acc_run,
                    jerk: jerk_run,
                    soft: cap_k < s.lim.vel,
                };
                if !ahead.push_speed(c) {
                    stop_dist = dist;
                    break;
                }
            }
            if s.lim.acc < acc_seen {
                // Implied by the previous acceleration constraint when the rest of the
                // reduction fits between the two at the spans' jerk and the running cap.
                let implied = last_acc.is_some_and(|(d_p, a_p)| {
                    cap_min.min(cap_k) * (a_p - s.lim.acc) / jerk_since.max(1.0) <= dist - d_p
                });
                if !implied {
                    ahead.push_accel(AccConstraint {
                        dist,
                        acc: s.lim.acc,
                        jerk: jerk_run,
                        v_ref: cap_k,
                    });
                }
                acc_seen = s.lim.acc;
                last_acc = Some((dist, s.lim.acc));
                jerk_since = f32::INFINITY;
            }
            jerk_since = jerk_since.min(s.lim.jerk);
            cap_min = cap_min.min(cap_k);
            acc_run = acc_run.min(s.lim.acc);
            jerk_run = jerk_run.min(s.lim.jerk);
            if let Some(h) = hold.filter(|h| h.seq == s.span.seq) {
                // The hold's stop point lies on this span.
                ahead.push_speed(SpeedConstraint {
                    dist: dist + h.sigma,
                    w: 0.0,
                    acc: acc_run,
                    jerk: jerk_run,
                    soft: false,
                });
                stop_dist = stop_dist.min(dist + h.sigma);
            }
            prev_stop = s.stop_after || s.dwell_periods > 0;
            dist += s.span.len_mm;
            k += 1;
        }
        let (stop_acc, stop_jerk) = stop_limits.unwrap_or((acc_run, jerk_run));
        let (stop_acc, stop_jerk) = (stop_acc.max(floor_a), stop_jerk.max(floor_j));

        // At rest on a stop point with nothing to wait for: idle.
        if v == 0.0 && a == 0.0 && stop_dist <= SNAP_MM && k >= self.spans.len() {
            self.gen.sigma = slot.span.len_mm;
            return None;
        }

        // Land on a stop point reached at (almost) zero speed: this period brings the
        // acceleration to zero (|Δa| ≤ J·T, so the jerk stays within the limit) and ends
        // the asymptotic creep of the discrete braking.
        if stop_dist <= SNAP_MM + v * t && v <= SNAP_SPEED_MM_S && a.abs() <= ahead.jerk * t {
            self.gen.sigma += stop_dist.max(0.0);
            self.gen.comp = 0.0;
            self.gen.vel = 0.0;
            self.gen.acc = 0.0;
            self.gen.vel_comp = 0.0;
            self.gen.acc_comp = 0.0;
        } else {
            let choice = choose_jerk(&ahead, v, a, t);
            if choice.slipped {
                self.slips = self.slips.saturating_add(1);
            }
            // Increments computed apart from the state, then added with compensation.
            let j = choice.jerk;
            let (ds, _, _) = integrate(v, a, j, t);
            let dv = a * t + 0.5 * j * t * t;
            let da = j * t;
            let g = &mut self.gen;
            g.sigma = kahan(g.sigma, ds, &mut g.comp);
            let v1c = kahan(v, dv, &mut g.vel_comp);
            let a1c = kahan(a, da, &mut g.acc_comp);
            if v1c < 0.0 {
                // The speed crossed zero inside the period (the last ramp-out period of a
                // stop): rest now, the acceleration goes to zero next period (snap), so no
                // period changes it by more than J·T.
                g.vel = 0.0;
                g.acc = a1c;
                g.vel_comp = 0.0;
                g.acc_comp = 0.0;
            } else {
                g.vel = v1c;
                g.acc = a1c;
            }
        }
        // Move onto the following spans.
        while let Some(cur) = self.spans.get(idx) {
            let len = cur.span.len_mm;
            // A dwell span is left by the dwell logic once its time is up.
            if self.gen.sigma < len || cur.dwell_periods > 0 {
                break;
            }
            let can_pass = idx + 1 < self.spans.len()
                && (!cur.stop_after || self.gen.vel == 0.0)
                && self.ensure_sent(idx + 1, out);
            if !can_pass {
                self.gen.sigma = len;
                break;
            }
            self.gen.sigma -= len;
            self.gen.seq = self.gen.seq.wrapping_add(1);
            self.gen.dwell_started = false;
            idx += 1;
        }
        Some(Step {
            epoch: self.epoch,
            path_gen: self.path_gen,
            span_seq: self.gen.seq,
            sigma_mm: self.gen.sigma,
            vel_mm_s: self.gen.vel,
            acc_mm_s2: self.gen.acc,
            stop_acc_mm_s2: stop_acc,
            stop_jerk_mm_s3: stop_jerk,
        })
    }

    /// Puts the hold's stop point where the time-optimal stop from the newest state ends,
    /// braking with the weakest limits of the spans up to there (or at the next stop, or
    /// at the end of the queue, if sooner).
    fn place_hold_point(&mut self, idx: usize) {
        let (v, a) = (self.gen.vel, self.gen.acc);
        let t = self.set.period_s;
        let mut start = self.gen.comp - self.gen.sigma;
        let (mut acc_run, mut jerk_run) = (f32::INFINITY, f32::INFINITY);
        let mut k = idx;
        while let Some(s) = self.spans.get(k) {
            acc_run = acc_run.min(s.lim.acc);
            jerk_run = jerk_run.min(s.lim.jerk);
            let d = braking_distance(v, a, 0.0, acc_run, jerk_run) + 2.0 * v * t + 1.0e-5;
            let end = start + s.span.len_mm;
            if d <= end || s.stop_after || k + 1 >= self.spans.len() {
                let lo = if k == idx { self.gen.sigma } else { 0.0 };
                self.hold_point = Some(HoldPoint {
                    seq: s.span.seq,
                    sigma: (d - start).clamp(lo, s.span.len_mm.max(lo)),
                });
                return;
            }
            start = end;
            k += 1;
        }
    }

    /// The abort has stopped the look-ahead: drop the program, keep the stop point as the
    /// start of the next one. Spans already with the executor stay valid up to the stop;
    /// the new program's spans and steps carry a new path generation.
    fn finish_abort(&mut self, idx: usize) {
        let pos = self
            .spans
            .get(idx)
            .map(|s| s.span.eval(self.gen.sigma).pos)
            .unwrap_or(self.end_pos);
        self.pieces.clear();
        self.spans.clear();
        self.front_piece_id = self.front_piece_id.wrapping_add(N as u32);
        self.path_gen = self.path_gen.wrapping_add(1);
        self.sent_end = self.next_seq;
        self.gen = GenState::at(self.next_seq, 0.0);
        self.end_pos = pos;
        self.run = RunState::Run;
        self.hold_point = None;
    }

    fn step_here(&self, acc: f32, jerk: f32) -> Step {
        Step {
            epoch: self.epoch,
            path_gen: self.path_gen,
            span_seq: self.gen.seq,
            sigma_mm: self.gen.sigma,
            vel_mm_s: 0.0,
            acc_mm_s2: 0.0,
            stop_acc_mm_s2: acc.max(self.set.acc_floor),
            stop_jerk_mm_s3: jerk.max(self.set.jerk_floor),
        }
    }
}

/// `sum + add` with Kahan compensation `comp`.
#[inline]
fn kahan(sum: f32, add: f32, comp: &mut f32) -> f32 {
    let y = add - *comp;
    let t = sum + y;
    *comp = (t - sum) - y;
    t
}

fn constant_coef(p: V3) -> [[f32; 8]; 3] {
    let mut c = [[0.0f32; 8]; 3];
    for i in 0..3 {
        c[i][0] = p[i];
    }
    c
}
