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

use super::fmath::F32Ext;
use heapless::Deque;

use super::blend::{plan_junction, Jet, Junction};
use super::channel::Sink;
use super::config::{PlannerConfig, PlannerConfigError, ValidPlannerConfig};
use super::corner::stop_is_faster;
use super::executor::{ExecMode, ExecutorStatus, Step};
use super::geometry::{Piece, V3};
use super::lookahead::{choose_jerk, Ahead};
use super::profile::{braking_distance, integrate};
use super::ring::{to_cum, SpanRing, SpanSlot};
use super::scan::{ScanCache, ScanInput, STOP_ACC_SLACK};
use super::segment::{prepare, PieceAttr, Segment, SegmentError};
use super::span::{
    derivative_bounds, fit, offset_at, path_limits, PathLimits, Span, FIT_TOL_MM, SPANS_PER_PERIOD,
};

/// Feed override range (1 % to 200 %).
pub const FEED_OVERRIDE_MIN: f32 = 0.01;
pub const FEED_OVERRIDE_MAX: f32 = 2.0;

/// A feed override ratio is finite and within [`FEED_OVERRIDE_MIN`]..=[`FEED_OVERRIDE_MAX`].
pub fn check_feed_override(ratio: f32) -> Result<(), PlannerConfigError> {
    if !ratio.is_finite() {
        return Err(PlannerConfigError::NotFinite("feed_override"));
    }
    if !(FEED_OVERRIDE_MIN..=FEED_OVERRIDE_MAX).contains(&ratio) {
        return Err(PlannerConfigError::OutOfRange("feed_override"));
    }
    Ok(())
}

/// Stop points closer than this (mm) at speeds below [`SNAP_SPEED_MM_S`] are taken as
/// reached: ends the asymptotic creep of the discrete braking onto a stop point.
const SNAP_MM: f32 = 2.0e-5;
const SNAP_SPEED_MM_S: f32 = 2.0e-3;

/// Halvings of a span whose fit misses the exact curve by more than [`FIT_TOL_MM`].
const MAX_FIT_HALVINGS: usize = 12;

/// A look-ahead scan reaches this factor (and [`SCAN_MARGIN_MM`]) beyond what the current
/// state needs, so that it serves the following periods too.
const SCAN_MARGIN: f32 = 1.25;
const SCAN_MARGIN_MM: f32 = 0.5;

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
    const fn at(seq: u32, sigma: f32) -> Self {
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
    set: ValidPlannerConfig,
    pieces: Deque<PieceEntry, N>,
    front_piece_id: u32,
    spans: SpanRing<S>,
    next_seq: u32,
    /// Spans with a lower sequence number have been handed to the executor.
    sent_end: u32,
    gen: GenState,
    epoch: u16,
    path_gen: u16,
    /// Program run: stamped on every span and step (see [`super::split`]).
    run_id: u16,
    feed_override: f32,
    run: RunState,
    hold_point: Option<HoldPoint>,
    exec_mode: ExecMode,
    end_pos: V3,
    slips: u32,
    /// The look-ahead's scan (reused while it covers the state) and its constraints.
    scan: ScanCache,
    ahead: Ahead,
}

impl<const N: usize, const S: usize> Planner<N, S> {
    /// A planner at rest at `start_mm`.
    pub fn new(cfg: &PlannerConfig, start_mm: [f32; 3]) -> Result<Self, PlannerConfigError> {
        let mut p = Self::BLANK;
        p.restart(cfg, start_mm)?;
        Ok(p)
    }

    /// A planner with no configuration, to be [`Planner::restart`]ed before use: a
    /// constant, so a static can hold one without a copy on the stack (the firmware).
    pub const BLANK: Self = Self {
        set: ValidPlannerConfig::BLANK,
        pieces: Deque::new(),
        front_piece_id: 0,
        spans: SpanRing::new(),
        next_seq: 1,
        sent_end: 1,
        gen: GenState::at(1, 0.0),
        epoch: 0,
        path_gen: 0,
        run_id: 0,
        feed_override: 1.0,
        run: RunState::Run,
        hold_point: None,
        exec_mode: ExecMode::Idle,
        end_pos: V3::new(0.0, 0.0, 0.0),
        slips: 0,
        scan: ScanCache::new(),
        ahead: Ahead::new(0.0, 0.0, 0.0),
    };

    /// As [`Planner::new`], in place (a planner is large: no copy of it on the stack).
    /// Nothing changes on an error.
    pub fn restart(
        &mut self,
        cfg: &PlannerConfig,
        start_mm: [f32; 3],
    ) -> Result<(), PlannerConfigError> {
        self.restart_run(cfg, start_mm, 0)
    }

    /// As [`Planner::restart`], for program run `run` (its spans and steps carry it: an
    /// executor restarted for the same run drops what an earlier run left in the
    /// channels, [`super::split`]).
    pub fn restart_run(
        &mut self,
        cfg: &PlannerConfig,
        start_mm: [f32; 3],
        run: u16,
    ) -> Result<(), PlannerConfigError> {
        let set = ValidPlannerConfig::new(cfg)?;
        for x in start_mm {
            if !x.is_finite() {
                return Err(PlannerConfigError::NotFinite("start_mm"));
            }
        }
        self.blank();
        self.set = set;
        self.run_id = run;
        self.end_pos = V3::from_array(start_mm);
        Ok(())
    }

    /// Makes this planner [`Planner::BLANK`] in place, field by field: no image of the
    /// planner is copied, on the stack or from flash. The firmware keeps its planning
    /// half in a zero-filled static (no initial image in flash) and calls this at boot;
    /// `tests::blank_in_place_equals_blank` checks that it leaves exactly `BLANK`.
    pub fn blank(&mut self) {
        self.set = ValidPlannerConfig::BLANK;
        self.pieces.clear();
        self.front_piece_id = 0;
        self.spans.reset();
        self.next_seq = 1;
        self.sent_end = 1;
        self.gen = GenState::at(1, 0.0);
        self.epoch = 0;
        self.path_gen = 0;
        self.run_id = 0;
        self.feed_override = 1.0;
        self.run = RunState::Run;
        self.hold_point = None;
        self.exec_mode = ExecMode::Idle;
        self.end_pos = V3::new(0.0, 0.0, 0.0);
        self.slips = 0;
        self.scan = ScanCache::new();
        self.ahead = Ahead::new(0.0, 0.0, 0.0);
    }

    pub fn settings(&self) -> &ValidPlannerConfig {
        &self.set
    }

    /// Program run its spans and steps carry ([`Planner::restart_run`]).
    pub fn run_id(&self) -> u16 {
        self.run_id
    }

    /// Free segment slots (flow control: an arc of n extra turns needs n + 1).
    pub fn free_slots(&self) -> usize {
        N - self.pieces.len()
    }

    /// Where the queued path ends (the start of the next segment), mm.
    pub fn end_position_mm(&self) -> [f32; 3] {
        self.end_pos.to_array()
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
            self.scan.valid = false;
        }
    }

    /// Continue after a hold, from the stop point (continuous: the profile simply
    /// accelerates again from rest).
    pub fn resume(&mut self) {
        if self.run == RunState::Hold {
            self.run = RunState::Run;
            self.hold_point = None;
            self.scan.valid = false;
        }
    }

    /// Feed override as a ratio (0.01..=2.0); applied by the look-ahead from the next
    /// generated step on, within the jerk and acceleration limits.
    pub fn set_feed_override(&mut self, ratio: f32) -> Result<(), PlannerConfigError> {
        check_feed_override(ratio)?;
        self.feed_override = ratio;
        self.spans.set_override(ratio);
        self.scan.valid = false;
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
        self.scan.valid = false;
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
                // An exact stop (G61.1) ends its segment at rest even where the next one
                // continues in the same direction: `plan_junction` passes smooth junctions
                // in every mode, which is right between the pieces of one segment.
                let next = prep.piece(0);
                let j = if last.attr.tol_after.is_none() {
                    Junction::STOP
                } else {
                    let j = plan_junction(
                        &last.piece,
                        &next,
                        last.attr.tol_after,
                        &last.j_in,
                        free,
                        FIT_TOL_MM,
                        self.set.min_span_mm(),
                    );
                    // A sharp corner is passed faster at rest than along its blend.
                    let feed = last.attr.feed.mn(prep.attr.feed);
                    if stop_is_faster(&j, &last.piece, &next, feed, &self.set) {
                        Junction::STOP
                    } else {
                        j
                    }
                };
                last.j_out = j;
                last.closed = true;
                j_in = j;
                if last.done
                    && j.stop
                    && matches!(self.spans.back(), Some(slot) if slot.piece_id == last_id)
                {
                    // The whole piece is already cut (and with the executor): the stop goes
                    // on its last span.
                    self.spans.set_stop_back();
                }
            }
        }
        let mut piece = prep.piece(0);
        for k in 0..prep.n {
            let next = if k + 1 < prep.n {
                prep.piece(k + 1)
            } else {
                piece
            };
            let closed = k + 1 < prep.n;
            let j_out = if closed {
                plan_junction(
                    &piece,
                    &next,
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
            piece = next;
        }
        self.end_pos = piece.end;
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
        if st.run != self.run_id {
            // the executor's status of another program run (it was restarted before or
            // after this planner): nothing in it concerns this run
            return;
        }
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
            self.scan.valid = false;
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
            e.j_in.d.mn(len)
        } else {
            0.0
        };
        if len - b_in < lmin {
            b_in = len;
        }
        let mut b_out = if e.closed && e.j_out.d > 0.0 {
            (len - e.j_out.d).mx(0.0)
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
                let x = s.mn(e.j_in.d);
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
                let x = (s - len).clampf(-e.j_out.d, 0.0);
                j.add(&e.j_out.correction(&e.piece, &next.piece, x, right));
            }
        }
        j
    }

    /// Cuts the next span of piece `k`.
    fn generate_one(&mut self, k: usize) {
        let Some(e) = self.pieces.get(k) else {
            return;
        };
        let piece_id = self.front_piece_id.wrapping_add(k as u32);
        let len = e.piece.len;
        let sa = e.cursor;
        if e.piece.is_dwell() {
            self.generate_dwell(k, piece_id);
            return;
        }
        if !(sa < len) {
            if let Some(m) = self.pieces.get_mut(k) {
                m.done = true;
            }
            return;
        }
        let lmin = self.set.min_span_mm();
        let (b_in, b_out) = self.breakpoints(e);
        let mut sb = len.mn(sa + e.piece.max_span_len());
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
                    worst = worst.mx((got[i] + j0.p[i] - exact[i]).abs());
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
            run: self.run_id,
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
            cum: 0,
            next_cap: None,
            prev_cap: None,
        });
        if let Some(m) = self.pieces.get_mut(k) {
            m.cursor = sb;
            m.done = at_end;
        }
    }

    /// The one span of the dwell piece `k`: zero length, a stop, held `dwell_periods`.
    fn generate_dwell(&mut self, k: usize, piece_id: u32) {
        let Some(e) = self.pieces.get(k) else {
            return;
        };
        let len = e.piece.len;
        let span = Span {
            seq: self.next_seq,
            path_gen: self.path_gen,
            run: self.run_id,
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
            cum: 0,
            next_cap: None,
            prev_cap: None,
        });
        if let Some(m) = self.pieces.get_mut(k) {
            m.cursor = len;
            m.done = true;
        }
    }

    fn push_slot(&mut self, slot: SpanSlot) {
        if self.spans.push_back(slot) {
            self.next_seq = self.next_seq.wrapping_add(1);
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
            let Some(slot) = self.spans.get(i) else {
                return false;
            };
            if out.try_send(slot.span).is_err() {
                return false;
            }
            self.spans.mark_sent(i);
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
        match self.dwell(idx, out)? {
            Ok(next) => idx = next,
            Err(step) => return Some(step),
        }
        let (v, a) = (self.gen.vel, self.gen.acc);
        let cur = self.spans.get(idx)?;
        let ovr = self.feed_override;
        let (len0, lim0, cum0, stop0) = (cur.span.len_mm, cur.lim, cur.cum, cur.stops());
        let cap0 = cur.cap(ovr);
        let floor_a = self.set.acc_floor;
        let floor_j = self.set.jerk_floor;
        // No period's jerk exceeds the current span's: the speed bound of the next period.
        let v_next = v + a.mx(0.0) * t + 0.5 * lim0.jerk * t * t;
        // The spans the next period can touch bound its acceleration and jerk (not beyond
        // an exact stop: the motion rests there before it enters the next span).
        let pos_here = cum0.wrapping_add(to_cum(self.gen.sigma));
        let (acc_touch, jerk) = self.touched_limits(idx, pos_here, v_next, lim0, stop0);
        // Scan as far as any braking could need: to a stop with the weakest limits of the
        // spans held (any braking runs on them; the end of what is held is a stop), plus
        // the most that braking to a low speed w instead of zero can add (it ends with a
        // ramp-out at w: (v+w)τ/2 − w²/2A grows until w = Aτ/2, by A³/8J² at most). The
        // acceleration with the slack the executor's own stop may brake with
        // (`scan::STOP_ACC_SLACK`), so that its stop too ends within what is sent.
        let horizon = self.braking_horizon(idx, v_next, a, lim0.jerk);
        // Acceleration limits matter up to the most the acceleration can reach next period
        // and within the distance a ramp from there needs (at the floor jerk: the spans
        // ahead may have less than this one; plus two periods at the speed it ends with).
        let a1max = a.abs() + lim0.jerk * t;
        let reach = |a1: f32| reach_mm(v_next, a1, floor_j, t);
        // Position on the path (fixed point) plus the Kahan compensation of σ: on a long
        // span f32 σ alone is only good to its ulp (1.9e-6 mm at 20 mm), which would make
        // the constraints jitter.
        let pos = pos_here;
        let comp = self.gen.comp;
        let steady = self.run == RunState::Run && self.hold_point.is_none();
        if !(steady
            && self.scan.covers(
                pos,
                cum0,
                v_next,
                horizon,
                a1max,
                reach(a1max),
                (cap0, lim0.acc, lim0.jerk),
                self.next_seq,
            ))
        {
            self.refresh_scan(
                &ScanNeed {
                    idx,
                    front_seq,
                    pos,
                    cum0,
                    stop0,
                    cap0,
                    lim0,
                    ovr,
                    steady,
                    v_next,
                    horizon,
                    a1max,
                },
                out,
            );
        }
        let (stop_dist, at_path_end) = self.scan.fill(&mut self.ahead, pos, cum0, comp);
        self.ahead.cap = cap0;
        self.ahead.cap_soft = cap0 < lim0.vel;
        self.ahead.acc = acc_touch;
        self.ahead.jerk = jerk;
        self.ahead.jerk0 = lim0.jerk;
        self.ahead.stop_dist = stop_dist;
        let (stop_acc, stop_jerk) = (
            self.scan.stop_acc.mx(floor_a),
            self.scan.stop_jerk.mn(jerk).mx(floor_j),
        );

        // At rest on a stop point with nothing to wait for: idle.
        if v == 0.0 && a == 0.0 && stop_dist <= SNAP_MM && at_path_end {
            self.gen.sigma = len0;
            return None;
        }

        self.advance(idx, pos, horizon, stop_dist, jerk);
        self.pass_finished_spans(&mut idx, out);
        Some(Step {
            epoch: self.epoch,
            path_gen: self.path_gen,
            run: self.run_id,
            span_seq: self.gen.seq,
            sigma_mm: self.gen.sigma,
            vel_mm_s: self.gen.vel,
            acc_mm_s2: self.gen.acc,
            stop_acc_mm_s2: stop_acc,
            stop_jerk_mm_s3: stop_jerk,
        })
    }

    /// The acceleration and jerk limits of the spans the next period can touch from
    /// `pos_here` at speeds up to `v_next`, starting with the current span's `lim0`.
    fn touched_limits(
        &self,
        idx: usize,
        pos_here: i64,
        v_next: f32,
        lim0: PathLimits,
        stop0: bool,
    ) -> (f32, f32) {
        let t = self.set.period_s;
        let touch = to_cum(v_next * t + 1.0e-6);
        let (mut acc_touch, mut jerk) = (lim0.acc, lim0.jerk);
        let mut stops_before = stop0;
        for k in idx + 1..idx + 1 + SPANS_PER_PERIOD + 2 {
            match self.spans.get(k) {
                Some(s) if !stops_before && s.cum.wrapping_sub(pos_here) < touch => {
                    acc_touch = acc_touch.mn(s.lim.acc);
                    jerk = jerk.mn(s.lim.jerk);
                    stops_before = s.stops();
                }
                _ => break,
            }
        }
        (acc_touch, jerk)
    }

    /// How far any braking from `v_next` (acceleration `a`, the current span's jerk
    /// `jerk0`) could need, with the weakest limits of the spans held (mm).
    fn braking_horizon(&self, idx: usize, v_next: f32, a: f32, jerk0: f32) -> f32 {
        let t = self.set.period_s;
        let (floor_a, floor_j) = (self.set.acc_floor, self.set.jerk_floor);
        let last_idx = self.spans.len() - 1;
        let weak_a = (self.spans.min_acc(idx, last_idx) * (1.0 - STOP_ACC_SLACK)).mx(floor_a);
        let weak_j = self.spans.min_jerk(idx, last_idx).mx(floor_j);
        braking_distance(v_next, a.mx(0.0) + jerk0 * t, 0.0, weak_a, weak_j)
            + weak_a * weak_a * weak_a / (8.0 * weak_j * weak_j)
            + 2.0 * v_next * t
            + 1.0e-3
    }

    /// On a dwell span (or a zero-length stop): `Err` with the step of a period still
    /// waiting, `Ok` with the index of the span to go on with, `None` when the next span
    /// cannot be handed over yet.
    fn dwell(&mut self, idx: usize, out: &mut impl Sink<Span>) -> Option<Result<usize, Step>> {
        let mut idx = idx;
        let slot = self.spans.get(idx)?;
        if slot.dwell_periods > 0 || (slot.span.len_mm == 0.0 && slot.stop_after) {
            let (periods, lim) = (slot.dwell_periods, slot.lim);
            if !self.gen.dwell_started {
                self.gen.dwell_started = true;
                self.gen.dwell_left = periods;
            }
            if self.gen.dwell_left > 0 {
                self.gen.dwell_left -= 1;
                return Some(Err(self.step_here(lim.acc, lim.jerk)));
            }
            if idx + 1 < self.spans.len() && self.ensure_sent(idx + 1, out) {
                idx += 1;
                self.gen = GenState::at(self.gen.seq.wrapping_add(1), 0.0);
            } else {
                return None;
            }
        }
        Some(Ok(idx))
    }

    /// Scans the path ahead again (see [`ScanNeed`]), a margin further than needed now so
    /// that the scan lasts.
    fn refresh_scan(&mut self, need: &ScanNeed, out: &mut impl Sink<Span>) {
        let ScanNeed {
            idx,
            front_seq,
            pos,
            cum0,
            stop0,
            cap0,
            lim0,
            ovr,
            steady,
            v_next,
            horizon,
            a1max,
        } = *need;
        let t = self.set.period_s;
        let a = self.gen.acc;
        let floor_j = self.set.jerk_floor;
        let reach = |a1: f32| reach_mm(v_next, a1, floor_j, t);
        // Scan a margin further than needed now, so that the scan lasts.
        let horizon_s = horizon * SCAN_MARGIN + SCAN_MARGIN_MM;
        let acc_below = if steady {
            a1max + (SCAN_MARGIN - 1.0) * lim0.acc
        } else {
            a1max
        };
        let reach_s = reach(acc_below) * SCAN_MARGIN + SCAN_MARGIN_MM;
        // The spans the scan may rely on: those starting within the horizon. They are
        // handed over (frozen) first; if the channel is full, the known path ends
        // there.
        let last = self.spans.len() - 1;
        let rel = to_cum(self.gen.sigma).wrapping_add(to_cum(horizon_s));
        let mut scan_last = if stop0 {
            idx
        } else {
            self.spans.last_starting_within(idx, rel)
        };
        let mut end_stop = false;
        let mut channel_full = false;
        if !self.ensure_sent(scan_last, out) {
            let sent = self.sent_end.wrapping_sub(front_seq) as usize;
            scan_last = sent.saturating_sub(1).max(idx);
            end_stop = true;
            channel_full = true;
        } else if scan_last == last {
            let end = self.spans.get(last).map(|s| s.cum_end()).unwrap_or(cum0);
            end_stop = end.wrapping_sub(pos) <= to_cum(horizon_s);
        }
        let input = ScanInput {
            idx,
            sigma_cum: to_cum(self.gen.sigma),
            scan_last,
            end_stop,
            horizon_end: pos.wrapping_add(to_cum(horizon_s)),
            cap0,
            ovr,
            hold: self.hold_point.map(|h| (h.seq, h.sigma)),
            acc_below,
            acc_end: pos.wrapping_add(to_cum(reach_s)),
            next_seq: self.next_seq,
            stop_from: (
                if steady { v_next * SCAN_MARGIN } else { v_next },
                a.mx(0.0) + lim0.jerk * t,
            ),
            period_s: t,
        };
        self.scan.scan(&self.spans, &input);
        if channel_full || !steady {
            // Good for this period only.
            self.scan.valid = false;
        }
    }

    /// One period of motion along the path: lands on a stop point reached at (almost) zero
    /// speed, or applies the jerk [`choose_jerk`] picks.
    fn advance(&mut self, idx: usize, pos: i64, horizon: f32, stop_dist: f32, jerk: f32) {
        // (the index, position and horizon are for the tests' cross-check only)
        #[cfg(not(test))]
        let _ = (idx, pos, horizon);
        let t = self.set.period_s;
        let (v, a) = (self.gen.vel, self.gen.acc);
        // Land on a stop point reached at (almost) zero speed: this period brings the
        // acceleration to zero (|Δa| ≤ J·T, so the jerk stays within the limit) and ends
        // the asymptotic creep of the discrete braking.
        if stop_dist <= SNAP_MM + v * t && v <= SNAP_SPEED_MM_S && a.abs() <= jerk * t {
            self.gen.sigma += stop_dist.mx(0.0);
            self.gen.comp = 0.0;
            self.gen.vel = 0.0;
            self.gen.acc = 0.0;
            self.gen.vel_comp = 0.0;
            self.gen.acc_comp = 0.0;
        } else {
            let choice = choose_jerk(&self.ahead, v, a, t);
            #[cfg(test)]
            self.cross_check(idx, pos, v, a, horizon, choice.jerk);
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
    }

    /// Moves onto the following spans once the current one is passed.
    fn pass_finished_spans(&mut self, idx: &mut usize, out: &mut impl Sink<Span>) {
        while let Some(cur) = self.spans.get(*idx) {
            let (len, lim) = (cur.span.len_mm, cur.lim);
            // A dwell span is left by the dwell logic once its time is up.
            if self.gen.sigma < len || cur.dwell_periods > 0 {
                break;
            }
            let can_pass = *idx + 1 < self.spans.len()
                && (!cur.stop_after || self.gen.vel == 0.0)
                && self.ensure_sent(*idx + 1, out);
            if !can_pass {
                self.gen.sigma = len;
                break;
            }
            self.scan.passed(lim.acc, lim.jerk);
            self.gen.sigma -= len;
            self.gen.seq = self.gen.seq.wrapping_add(1);
            self.gen.dwell_started = false;
            *idx += 1;
        }
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
            acc_run = acc_run.mn(s.lim.acc);
            jerk_run = jerk_run.mn(s.lim.jerk);
            let d = braking_distance(v, a, 0.0, acc_run, jerk_run) + 2.0 * v * t + 1.0e-5;
            let end = start + s.span.len_mm;
            if d <= end || s.stop_after || k + 1 >= self.spans.len() {
                let lo = if k == idx { self.gen.sigma } else { 0.0 };
                self.hold_point = Some(HoldPoint {
                    seq: s.span.seq,
                    sigma: (d - start).clampf(lo, s.span.len_mm.mx(lo)),
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
        self.scan.valid = false;
    }

    fn step_here(&self, acc: f32, jerk: f32) -> Step {
        Step {
            epoch: self.epoch,
            path_gen: self.path_gen,
            run: self.run_id,
            span_seq: self.gen.seq,
            sigma_mm: self.gen.sigma,
            vel_mm_s: 0.0,
            acc_mm_s2: 0.0,
            stop_acc_mm_s2: acc.mx(self.set.acc_floor),
            stop_jerk_mm_s3: jerk.mx(self.set.jerk_floor),
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

/// What a scan of the path ahead must cover, from one period of [`Planner::gen_step`].
#[derive(Clone, Copy)]
struct ScanNeed {
    /// The current span (index in the queue) and the first queued span's sequence number.
    idx: usize,
    front_seq: u32,
    /// Position on the path and the current span's start (fixed point).
    pos: i64,
    cum0: i64,
    /// The current span ends in a stop.
    stop0: bool,
    /// The current span's speed cap (with the override) and limits.
    cap0: f32,
    lim0: PathLimits,
    ovr: f32,
    /// Running, no hold: the scan may serve later periods too.
    steady: bool,
    /// The speed bound of the next period (mm/s).
    v_next: f32,
    /// How far braking could need (mm).
    horizon: f32,
    /// The most the acceleration can reach next period (mm/s²).
    a1max: f32,
}

/// Distance within which acceleration limits matter for an acceleration `a1`: a ramp
/// from there at the floor jerk `floor_j`, plus three periods `t` at the speed it ends
/// with (mm).
fn reach_mm(v_next: f32, a1: f32, floor_j: f32, t: f32) -> f32 {
    let tau = a1 / floor_j;
    v_next * tau + 0.5 * a1 * tau * tau + 3.0 * t * (v_next + 0.5 * a1 * tau) + 1.0e-3
}

fn constant_coef(p: V3) -> [[f32; 8]; 3] {
    let mut c = [[0.0f32; 8]; 3];
    for i in 0..3 {
        c[i][0] = p[i];
    }
    c
}

/// Test-only check of the scan cache: every period, a fresh scan (no margins, no reuse)
/// must lead to the same jerk as the cached one.
#[cfg(test)]
pub(crate) mod cache_check {
    use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
    pub static ON: AtomicBool = AtomicBool::new(false);
    pub static CHECKS: AtomicU32 = AtomicU32::new(0);
    pub static MISMATCHES: AtomicU32 = AtomicU32::new(0);
    pub fn on() -> bool {
        ON.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
impl<const N: usize, const S: usize> Planner<N, S> {
    fn cross_check(&self, idx: usize, pos: i64, v: f32, a: f32, horizon: f32, j: f32) {
        use core::sync::atomic::Ordering::Relaxed;
        if !(cache_check::on() && self.run == RunState::Run && self.hold_point.is_none()) {
            return;
        }
        let t = self.set.period_s;
        let Some(cur) = self.spans.get(idx) else {
            return;
        };
        let jerk = cur.lim.jerk;
        let a1max = a.abs() + jerk * t;
        let v_next = v + a.mx(0.0) * t + 0.5 * jerk * t * t;
        let tau = a1max / self.set.jerk_floor;
        let reach = v_next * tau
            + 0.5 * a1max * tau * tau
            + 3.0 * t * (v_next + 0.5 * a1max * tau)
            + 1.0e-3;
        let front = self.spans.front().map(|f| f.span.seq).unwrap_or(0);
        let sent_last = (self.sent_end.wrapping_sub(front) as usize).saturating_sub(1);
        let mut scan_last = if cur.stops() {
            idx
        } else {
            self.spans
                .last_starting_within(idx, to_cum(self.gen.sigma).wrapping_add(to_cum(horizon)))
        };
        let mut end_stop = false;
        if scan_last > sent_last {
            scan_last = sent_last.max(idx);
            end_stop = true;
        } else if scan_last + 1 == self.spans.len() {
            let end = self.spans.get(scan_last).map(|s| s.cum_end()).unwrap_or(0);
            end_stop = end.wrapping_sub(pos) <= to_cum(horizon);
        }
        let input = ScanInput {
            idx,
            sigma_cum: to_cum(self.gen.sigma),
            scan_last,
            end_stop,
            horizon_end: pos.wrapping_add(to_cum(horizon)),
            cap0: cur.cap(self.feed_override),
            ovr: self.feed_override,
            hold: None,
            acc_below: a1max,
            acc_end: pos.wrapping_add(to_cum(reach)),
            next_seq: self.next_seq,
            stop_from: (v_next, a.mx(0.0) + jerk * t),
            period_s: t,
        };
        let mut fresh = ScanCache::new();
        fresh.scan(&self.spans, &input);
        let mut ahead = self.ahead;
        fresh.fill(&mut ahead, pos, cur.cum, self.gen.comp);
        let jf = choose_jerk(&ahead, v, a, t).jerk;
        cache_check::CHECKS.fetch_add(1, Relaxed);
        // Safe for the fresh constraints, and as good as the fresh choice: the same jerk
        // (to 1e-3 J), or one that leaves no more than the search's tolerance of room.
        use super::lookahead::{CHECK_MARGIN_MM, SLACK_TIGHT_MM};
        let sf = ahead.slack(v, a, j, t, CHECK_MARGIN_MM, true);
        let same = (jf - j).abs() <= 1.0e-3 * jerk;
        let good = sf >= 0.0 && (j >= jf - 1.0e-3 * jerk || sf <= 2.0 * SLACK_TIGHT_MM);
        if !(same || good) {
            let n = cache_check::MISMATCHES.fetch_add(1, Relaxed);
            if n < 5 {
                extern crate std;
                std::println!(
                    "cache mismatch: seq {} v {v} a {a} j cached {j} fresh {jf} slack {sf}\n cached {:?} {:?}\n fresh {:?} {:?}",
                    self.gen.seq,
                    &self.ahead.speed[..self.ahead.n_speed],
                    &self.ahead.accel[..self.ahead.n_accel],
                    &ahead.speed[..ahead.n_speed],
                    &ahead.accel[..ahead.n_accel]
                );
            }
        }
    }
}

#[cfg(test)]
mod cache_tests {
    extern crate std;
    use super::*;
    use crate::motion::planner::{Blend, Executor, Plane, GANTRY_PLANNER};
    use core::sync::atomic::Ordering::Relaxed;
    use heapless::spsc::Queue;
    use std::vec::Vec;

    fn run(segs: &[Segment], start: [f32; 3], starve: Option<(usize, usize)>, periods: usize) {
        let cfg = GANTRY_PLANNER;
        let mut spans_q: Queue<Span, 129> = Queue::new();
        let mut steps_q: Queue<Step, 33> = Queue::new();
        let (mut span_tx, mut span_rx) = spans_q.split();
        let (mut step_tx, mut step_rx) = steps_q.split();
        let mut planner: Planner<64, 256> = Planner::new(&cfg, start).unwrap();
        let mut exec = Executor::new(cfg.period_s, start);
        let mut next = 0;
        for n in 0..periods {
            while next < segs.len() && planner.push(&segs[next]).is_ok() {
                next += 1;
            }
            if !starve.is_some_and(|(a, b)| (a..b).contains(&n)) {
                planner.sync(&exec.status());
                planner.produce(&mut span_tx, &mut step_tx, 32);
            }
            exec.sample(&mut span_rx, &mut step_rx);
        }
    }

    /// The cached look-ahead decides exactly like a fresh scan every period.
    #[test]
    fn scan_cache_decides_like_a_fresh_scan() {
        cache_check::ON.store(true, Relaxed);
        let pts = [
            [0.0f32, 0.0, 0.0],
            [20.0, 0.0, 0.0],
            [20.0, 20.0, 0.0],
            [0.0, 20.0, 5.0],
            [0.0, 0.0, 0.0],
        ];
        let square: Vec<Segment> = pts
            .windows(2)
            .enumerate()
            .map(|(k, w)| Segment::line(w[1], 80.0, k as u32 + 1))
            .collect();
        run(&square, [0.0; 3], None, 40_000);
        run(&square, [0.0; 3], Some((2000, 3500)), 40_000);
        // Chords of a circle, a spiral of shrinking arcs, exact stops, rapids.
        let chords: Vec<Segment> = (1..2000u32)
            .map(|k| {
                let phi = 0.05 / 20.0 * k as f32;
                Segment::line(
                    [20.0 * libm::cosf(phi), 20.0 * libm::sinf(phi), 0.0],
                    150.0,
                    k,
                )
            })
            .collect();
        run(&chords, [20.0, 0.0, 0.0], None, 30_000);
        let mut spiral = Vec::new();
        let mut r = 20.0f32;
        let mut p = [20.0f32, 0.0, 0.0];
        for k in 0..40u32 {
            let phi = (k + 1) as f32 * 0.7;
            r *= 0.93;
            let e = [r * libm::cosf(phi), r * libm::sinf(phi), 0.02 * k as f32];
            let c = [0.0, 0.0, p[2]];
            let rr = libm::hypotf(p[0], p[1]);
            let e2 = [e[0] * rr / r, e[1] * rr / r, e[2]];
            spiral.push(
                Segment::arc(e2, c, Plane::XY, false, 0, 120.0, k)
                    .with_blend(Blend::Tolerance(0.02)),
            );
            p = e2;
        }
        run(&spiral, [20.0, 0.0, 0.0], None, 60_000);
        let mixed = [
            Segment::line([10.0, 0.0, 0.0], 60.0, 1).with_blend(Blend::ExactStop),
            Segment::rapid([10.0, 30.0, 5.0], 2),
            Segment::line([0.0, 30.0, 5.0], 100.0, 3),
            Segment::dwell(0.01, 4),
            Segment::line([0.0, 0.0, 0.0], 100.0, 5),
        ];
        run(&mixed, [0.0; 3], None, 60_000);
        cache_check::ON.store(false, Relaxed);
        let (c, m) = (
            cache_check::CHECKS.load(Relaxed),
            cache_check::MISMATCHES.load(Relaxed),
        );
        assert!(c > 100_000, "{c} checks");
        assert_eq!(m, 0, "{m} of {c} periods decided differently");
    }
}

#[cfg(test)]
mod blank_tests {
    use super::*;
    use crate::machine::MachineTaskPlanner;
    use crate::motion::planner::GANTRY_PLANNER;

    /// `blank` leaves exactly `BLANK`, whatever the planner held: every field it must
    /// reset is moved away from `BLANK` first. (The firmware's zero-filled static is
    /// checked in firmware/src/machine_slot.rs: this crate has no unsafe code to make one.)
    #[test]
    fn blank_in_place_equals_blank() {
        let mut p = MachineTaskPlanner::BLANK;
        p.restart_run(&GANTRY_PLANNER, [1.0, 2.0, 3.0], 7).unwrap();
        for k in 0..40u32 {
            let x = 1.0 + 0.5 * (k + 1) as f32;
            let y = if k % 2 == 0 { 2.0 } else { 2.5 };
            if p.push(&Segment::line([x, y, 3.0], 20.0, k)).is_err() {
                break;
            }
        }
        p.set_feed_override(0.5).unwrap();
        assert!(p != MachineTaskPlanner::BLANK);
        p.blank();
        assert!(p == MachineTaskPlanner::BLANK);
    }
}
