//! The executor: the half of the planner that runs in the control interrupt. Each period it
//! takes one precomputed step (span, σ, σ̇, σ̈) and evaluates the span polynomial into the
//! reference position, velocity, acceleration and tangent. It never loops over the queue:
//! the work per call is one polynomial evaluation plus a bounded number of channel pops.
//!
//! Feed hold, resume, abort and the feed override are the planner's business (its
//! look-ahead respects every span's limits while it stops, see [`super::Planner::hold`]);
//! they reach the executor as ordinary steps, a few periods later (the steps buffered
//! between the two halves).
//!
//! The executor's own logic is for an **underrun** only (no step while moving: the
//! planner task starved): it stops along the path with the time-optimal jerk-limited
//! profile from its current speed and acceleration, with the braking limits the planner
//! attached to the last step, then starts a new *epoch*: steps of the old epoch still in
//! the channel are dropped, and the planner, seeing the new epoch in [`ExecutorStatus`],
//! restarts its profile at the reported stop point.

use super::channel::Source;
use super::fmath::{self, F32Ext};
use super::geometry::V3;
use super::profile::{integrate, stop_jerk};
use super::span::Span;
use crate::Vec3;

/// One control period of the planned feed profile.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Step {
    /// Profile epoch (see the module docs).
    pub epoch: u16,
    /// Path generation of the span (incremented by every abort).
    pub path_gen: u16,
    /// Program run (see [`Span::run`]).
    pub run: u16,
    /// Span the state lies on.
    pub span_seq: u32,
    /// Local path parameter on that span (mm).
    pub sigma_mm: f32,
    /// Path speed σ̇ (mm/s) and acceleration σ̈ (mm/s²).
    pub vel_mm_s: f32,
    pub acc_mm_s2: f32,
    /// Path acceleration and jerk limits a stop from this state may use.
    pub stop_acc_mm_s2: f32,
    pub stop_jerk_mm_s3: f32,
}

/// Executor state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExecMode {
    /// At rest with nothing to do.
    #[default]
    Idle,
    /// Following the planner's steps.
    Running,
    /// Stopping on its own after an underrun.
    Stopping,
}

/// What the planner needs to know of the executor; published every period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExecutorStatus {
    pub epoch: u16,
    pub path_gen: u16,
    /// Program run the executor follows (see [`Span::run`]).
    pub run: u16,
    pub span_seq: u32,
    pub sigma_mm: f32,
    pub mode: ExecMode,
    /// Underruns so far (each one a stop of its own).
    pub underruns: u32,
    /// Reference position of the last sample (mm).
    pub pos_mm: [f32; 3],
    /// Tag of the segment being executed.
    pub tag: u32,
}

/// The reference for one control period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathSample {
    pub pos_mm: Vec3<f32>,
    pub vel_mm_s: Vec3<f32>,
    pub acc_mm_s2: Vec3<f32>,
    /// Unit tangent of the path (direction of motion for positive σ̇), from the span
    /// polynomial: defined at rest too.
    pub tangent: Vec3<f32>,
    /// Speed along the programmed path σ̇ (mm/s) and its derivative.
    pub path_speed_mm_s: f32,
    pub path_acc_mm_s2: f32,
    /// σ̇ / programmed feed of the current segment (0 on rapids and dwells).
    pub feed_ratio: f32,
    /// Tag of the current segment.
    pub tag: u32,
    pub mode: ExecMode,
}

/// Steps of an old epoch dropped per period at most.
const DRAIN_PER_PERIOD: usize = 8;
/// Spans pulled per period at most (the planner caps span speeds so that at most
/// `SPANS_PER_PERIOD` spans are crossed per period; the rest is for stale spans).
const SPAN_PULLS_PER_PERIOD: usize = 8;

/// The interrupt half of the planner.
///
/// The span being sampled stays at the front of the span channel (sampled in place, no
/// copy): the executor drops a span from the channel only when it has passed it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Executor {
    period_s: f32,
    mode: ExecMode,
    underruns: u32,
    epoch: u16,
    path_gen: u16,
    /// Program run: spans and steps of another run are dropped.
    run: u16,
    /// The front of the span channel is the current span (sequence number `seq`).
    on_span: bool,
    seq: u32,
    tag: u32,
    sigma: f32,
    vel: f32,
    acc: f32,
    stop_acc: f32,
    stop_jerk: f32,
    /// Position of the last sample (the rest position before the first span).
    pos: V3,
    tangent: V3,
    /// A step taken from the channel but not used yet.
    pending: Option<Step>,
}

/// `a` comes before `b` in the wrapping sequence order.
#[inline]
fn seq_before(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) < 0
}

impl Executor {
    /// At rest at `start_mm`; `period_s` is the control period (validated by the planner's
    /// settings: use `Planner::settings().period_s`).
    pub const fn new(period_s: f32, start_mm: [f32; 3]) -> Self {
        Self::for_run(period_s, start_mm, 0)
    }

    /// As [`Executor::new`], following program run `run` only (the planner restarted
    /// with `Planner::restart_run` for the same run).
    pub const fn for_run(period_s: f32, start_mm: [f32; 3], run: u16) -> Self {
        Self {
            period_s,
            mode: ExecMode::Idle,
            underruns: 0,
            epoch: 0,
            path_gen: 0,
            run,
            on_span: false,
            seq: 0,
            tag: 0,
            sigma: 0.0,
            vel: 0.0,
            acc: 0.0,
            stop_acc: 1.0,
            stop_jerk: 1.0,
            pos: V3::new(start_mm[0], start_mm[1], start_mm[2]),
            tangent: V3::new(1.0, 0.0, 0.0),
            pending: None,
        }
    }

    pub fn mode(&self) -> ExecMode {
        self.mode
    }

    pub fn status(&self) -> ExecutorStatus {
        ExecutorStatus {
            epoch: self.epoch,
            path_gen: self.path_gen,
            run: self.run,
            span_seq: self.seq,
            sigma_mm: self.sigma,
            mode: self.mode,
            underruns: self.underruns,
            pos_mm: self.pos.to_array(),
            tag: self.tag,
        }
    }

    /// Drops passed (and stale) spans until the front is span `seq` (bounded); false if
    /// it is not available yet.
    fn advance_to(&mut self, spans: &mut impl Source<Span>, seq: u32) -> bool {
        if self.on_span && self.seq == seq {
            return true;
        }
        for _ in 0..SPAN_PULLS_PER_PERIOD {
            let Some(f) = spans.peek() else {
                return false;
            };
            if f.run != self.run {
                // an earlier program run's span (its planner was restarted)
                spans.drop_front();
                self.on_span = false;
                continue;
            }
            if f.path_gen == self.path_gen && f.seq == seq {
                self.on_span = true;
                self.seq = seq;
                self.tag = f.tag;
                return true;
            }
            if f.path_gen == self.path_gen && !seq_before(f.seq, seq) {
                // The front lies beyond: not ours (cannot happen with a consistent planner).
                return false;
            }
            spans.drop_front();
            self.on_span = false;
        }
        false
    }

    /// Moves σ onto the following spans while it is past the end of the current one.
    fn carry_over(&mut self, spans: &mut impl Source<Span>) {
        for _ in 0..SPAN_PULLS_PER_PERIOD {
            let Some(len) = spans.peek().map(|f| f.len_mm) else {
                return;
            };
            if !(self.sigma > len) {
                return;
            }
            if spans.waiting() < 2 {
                // No geometry beyond (cannot happen while the planner keeps the stop
                // horizon frozen): end here at rest.
                self.sigma = len;
                self.vel = 0.0;
                self.acc = 0.0;
                return;
            }
            spans.drop_front();
            match spans.peek() {
                Some(f) if f.path_gen == self.path_gen && f.run == self.run => {
                    self.sigma -= len;
                    self.seq = f.seq;
                    self.tag = f.tag;
                }
                _ => {
                    // A new program's span: the old path ended; rest where the last
                    // sample was.
                    self.on_span = false;
                    self.vel = 0.0;
                    self.acc = 0.0;
                    return;
                }
            }
        }
    }

    fn start_stop(&mut self) {
        self.mode = ExecMode::Stopping;
        self.underruns = self.underruns.saturating_add(1);
    }

    /// One period of the executor's own jerk-limited stop.
    fn stop_step(&mut self, spans: &mut impl Source<Span>) {
        let t = self.period_s;
        // Braking harder than a ramp-out at the attached jerk could end before zero speed
        // (the planner was braking in a stronger span): ramp out with the jerk that lands
        // on zero instead of reversing.
        let mut jmax = self.stop_jerk;
        if self.acc < 0.0 && self.vel > 0.0 {
            jmax = jmax.mx(self.acc * self.acc / (2.0 * self.vel));
        }
        if self.vel <= 1.0e-5 && self.acc.abs() <= jmax * t {
            // Landed: this period takes the acceleration to zero (|Δa| ≤ J·T).
            self.vel = 0.0;
            self.acc = 0.0;
            self.epoch = self.epoch.wrapping_add(1);
            self.mode = ExecMode::Idle;
            return;
        }
        let amax = self.stop_acc.mx(-self.acc);
        let j = stop_jerk(self.vel, self.acc, amax, jmax, t);
        let (ds, v1, a1) = integrate(self.vel, self.acc, j, t);
        self.sigma += ds.mx(0.0);
        // The speed may cross zero inside the last ramp-out period: rest there, the
        // remaining acceleration goes next period.
        self.vel = v1.mx(0.0);
        self.acc = a1;
        if self.on_span {
            self.carry_over(spans);
        }
    }

    /// Takes the next step of the current epoch (dropping stale ones, a bounded number).
    fn next_step(&mut self, steps: &mut impl Source<Step>) -> Option<Step> {
        if let Some(s) = self.pending.take() {
            if s.epoch == self.epoch && s.run == self.run {
                return Some(s);
            }
        }
        for _ in 0..DRAIN_PER_PERIOD {
            match steps.try_recv() {
                Some(s) if s.epoch == self.epoch && s.run == self.run => return Some(s),
                Some(_) => {}
                None => return None,
            }
        }
        None
    }

    /// One control period: the reference for this period.
    pub fn sample(
        &mut self,
        spans: &mut impl Source<Span>,
        steps: &mut impl Source<Step>,
    ) -> PathSample {
        match self.mode {
            ExecMode::Stopping => self.stop_step(spans),
            ExecMode::Idle | ExecMode::Running => {
                if let Some(s) = self.next_step(steps) {
                    if s.path_gen != self.path_gen && self.vel == 0.0 {
                        // A new program after an abort: its spans replace the old ones.
                        self.path_gen = s.path_gen;
                        self.on_span = false;
                    }
                    if self.advance_to(spans, s.span_seq) {
                        self.sigma = s.sigma_mm;
                        self.vel = s.vel_mm_s;
                        self.acc = s.acc_mm_s2;
                        self.stop_acc = s.stop_acc_mm_s2;
                        self.stop_jerk = s.stop_jerk_mm_s3;
                        self.mode = ExecMode::Running;
                    } else {
                        // Geometry not there yet: keep the step, stop if moving.
                        self.pending = Some(s);
                        if self.vel > 0.0 {
                            self.start_stop();
                            self.stop_step(spans);
                        }
                    }
                } else if self.vel > 0.0 || self.acc != 0.0 {
                    self.start_stop();
                    self.stop_step(spans);
                } else {
                    self.mode = ExecMode::Idle;
                }
            }
        }
        self.output(spans)
    }

    fn output(&mut self, spans: &impl Source<Span>) -> PathSample {
        let span = if self.on_span { spans.peek() } else { None };
        let Some(span) = span else {
            return PathSample {
                pos_mm: self.pos,
                vel_mm_s: Vec3::from_array([0.0; 3]),
                acc_mm_s2: Vec3::from_array([0.0; 3]),
                tangent: self.tangent,
                path_speed_mm_s: self.vel,
                path_acc_mm_s2: self.acc,
                feed_ratio: 0.0,
                tag: self.tag,
                mode: self.mode,
            };
        };
        let p = span.eval(self.sigma);
        let (v, a) = (self.vel, self.acc);
        let v2 = v * v;
        // Tangent from p' (|p'| ≈ 1); at a reversal cusp p' = 0 and p'' points the new way.
        let n1 = p.d1[0] * p.d1[0] + p.d1[1] * p.d1[1] + p.d1[2] * p.d1[2];
        if n1 > 1.0e-8 {
            let k = fmath::rsqrt_near_one(n1);
            self.tangent = V3::new(p.d1[0] * k, p.d1[1] * k, p.d1[2] * k);
        } else {
            let n2 = p.d2[0] * p.d2[0] + p.d2[1] * p.d2[1] + p.d2[2] * p.d2[2];
            if n2 > 1.0e-8 {
                let k = fmath::rsqrt(n2);
                self.tangent = V3::new(p.d2[0] * k, p.d2[1] * k, p.d2[2] * k);
            }
        }
        self.pos = p.pos;
        PathSample {
            pos_mm: p.pos,
            vel_mm_s: Vec3::from_array([p.d1[0] * v, p.d1[1] * v, p.d1[2] * v]),
            acc_mm_s2: Vec3::from_array([
                p.d2[0] * v2 + p.d1[0] * a,
                p.d2[1] * v2 + p.d1[1] * a,
                p.d2[2] * v2 + p.d1[2] * a,
            ]),
            tangent: self.tangent,
            path_speed_mm_s: v,
            path_acc_mm_s2: a,
            feed_ratio: v * span.inv_feed,
            tag: span.tag,
            mode: self.mode,
        }
    }
}
