//! Both halves wired together for one thread (host-sim, tests): each period the planner
//! syncs with the executor, tops up the step buffer, then the executor samples. On the
//! board the same two calls run in two tasks (see the module docs of [`super`]).

use heapless::Deque;

use super::config::{PlannerConfig, PlannerConfigError};
use super::executor::{ExecMode, Executor, ExecutorStatus, PathSample, Step};
use super::handle::{Offer, PlannerHandle, RestartError};
use super::planner::{Planner, PlannerState, PlannerStatus};
use super::segment::{Segment, SegmentError};
use super::span::Span;

/// Planner + executor in one value: `N` segment slots, `S` spans in the planner's ring,
/// `C` spans in the executor's channel, `B` steps buffered (`B` periods of latency for
/// feed override; hold acts within one period).
#[derive(Clone, Debug)]
pub struct MotionPlanner<
    const N: usize = 64,
    const S: usize = 256,
    const C: usize = 128,
    const B: usize = 32,
> {
    planner: Planner<N, S>,
    executor: Executor,
    spans: Deque<Span, C>,
    steps: Deque<Step, B>,
}

impl<const N: usize, const S: usize, const C: usize, const B: usize> MotionPlanner<N, S, C, B> {
    pub fn new(cfg: &PlannerConfig, start_mm: [f32; 3]) -> Result<Self, PlannerConfigError> {
        let planner = Planner::new(cfg, start_mm)?;
        let executor = Executor::new(planner.settings().period_s, start_mm);
        Ok(Self {
            planner,
            executor,
            spans: Deque::new(),
            steps: Deque::new(),
        })
    }

    /// A planner with no configuration, to be [`MotionPlanner::restart`]ed before use: a
    /// constant, so a static can hold one without a copy on the stack (the firmware).
    pub const BLANK: Self = Self {
        planner: Planner::BLANK,
        executor: Executor::new(0.0, [0.0; 3]),
        spans: Deque::new(),
        steps: Deque::new(),
    };

    /// As [`MotionPlanner::new`], in place (no copy of the planner on the stack: the
    /// firmware restarts it in the control interrupt). Nothing changes on an error.
    pub fn restart(
        &mut self,
        cfg: &PlannerConfig,
        start_mm: [f32; 3],
    ) -> Result<(), PlannerConfigError> {
        self.planner.restart(cfg, start_mm)?;
        self.executor = Executor::new(self.planner.settings().period_s, start_mm);
        self.spans.clear();
        self.steps.clear();
        Ok(())
    }

    /// Queues a segment (see [`Planner::push`]).
    pub fn push(&mut self, seg: &Segment) -> Result<(), SegmentError> {
        self.planner.push(seg)
    }

    /// One control period: plan ahead, then sample the reference.
    pub fn tick(&mut self) -> PathSample {
        self.plan();
        self.sample()
    }

    /// The interrupt part of [`MotionPlanner::tick`] alone: one executor sample.
    pub fn sample(&mut self) -> PathSample {
        self.executor.sample(&mut self.spans, &mut self.steps)
    }

    /// The planning part of [`MotionPlanner::tick`] alone.
    pub fn plan(&mut self) {
        let st = self.executor.status();
        self.planner.sync(&st);
        self.planner.produce(&mut self.spans, &mut self.steps, B);
    }

    /// Feed hold (see [`Planner::hold`]).
    pub fn hold(&mut self) {
        self.planner.hold();
    }

    pub fn resume(&mut self) {
        self.planner.resume();
    }

    /// Stop on the path, then clear the queue; new segments start where it stopped
    /// ([`MotionPlanner::end_position_mm`] once [`MotionPlanner::is_idle`]).
    pub fn abort(&mut self) {
        self.planner.abort();
    }

    pub fn set_feed_override(&mut self, ratio: f32) -> Result<(), PlannerConfigError> {
        self.planner.set_feed_override(ratio)
    }

    pub fn free_slots(&self) -> usize {
        self.planner.free_slots()
    }

    pub fn end_position_mm(&self) -> [f32; 3] {
        self.planner.end_position_mm()
    }

    pub fn planner(&self) -> &Planner<N, S> {
        &self.planner
    }

    pub fn planner_status(&self) -> PlannerStatus {
        self.planner.status()
    }

    pub fn executor_status(&self) -> ExecutorStatus {
        self.executor.status()
    }

    /// At rest with no motion pending (the program ended, or held, or aborted).
    pub fn is_idle(&self) -> bool {
        self.executor.mode() == ExecMode::Idle
            && self.steps.is_empty()
            && matches!(
                self.planner.status().state,
                PlannerState::Idle | PlannerState::Held
            )
    }
}

/// Both halves in the period: a segment is planned when it is offered, so at most one is
/// offered per period (one segment's look-ahead, `cargo insns` `planner_segment`).
impl<const N: usize, const S: usize, const C: usize, const B: usize> PlannerHandle
    for MotionPlanner<N, S, C, B>
{
    const OFFERS_PER_PERIOD: usize = 1;

    fn restart(&mut self, cfg: &PlannerConfig, start_mm: [f32; 3]) -> Result<(), RestartError> {
        MotionPlanner::restart(self, cfg, start_mm).map_err(RestartError::Config)
    }

    fn offer(&mut self, seg: &Segment) -> Offer {
        if self.free_slots() == 0 {
            return Offer::Later;
        }
        match self.push(seg) {
            Ok(()) => Offer::Taken,
            Err(e) => Offer::Refused(e),
        }
    }

    fn hold(&mut self) {
        MotionPlanner::hold(self);
    }

    fn resume(&mut self) {
        MotionPlanner::resume(self);
    }

    fn abort(&mut self) {
        MotionPlanner::abort(self);
    }

    fn set_feed_override(&mut self, ratio: f32) -> Result<(), PlannerConfigError> {
        MotionPlanner::set_feed_override(self, ratio)
    }

    fn free_slots(&self) -> usize {
        MotionPlanner::free_slots(self)
    }

    fn tick(&mut self) -> PathSample {
        MotionPlanner::tick(self)
    }

    fn is_idle(&self) -> bool {
        MotionPlanner::is_idle(self)
    }
}
