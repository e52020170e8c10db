//! [`PlannerHandle`]: what the control period asks of a motion planner, whether both
//! halves run in the period ([`super::MotionPlanner`]: host-sim, tests) or the planning
//! half runs in a task of its own ([`super::split::SplitExecutor`]: the board). The
//! machine (`crate::machine`) is written against this trait only, so the supervisor,
//! its request order and its refusals are the same in both.

use super::config::{PlannerConfig, PlannerConfigError};
use super::executor::PathSample;
use super::segment::{Segment, SegmentError};

/// What became of a segment offered to the planner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Offer {
    /// Queued.
    Taken,
    /// Not yet: no room, or its result is not known yet. Offer the same segment again
    /// next period (nothing else may be offered meanwhile).
    Later,
    /// Refused; nothing was queued.
    Refused(SegmentError),
}

/// Why a program could not be started.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RestartError {
    Config(PlannerConfigError),
    /// The planning half is not connected (a split planner before its channels are
    /// attached).
    Detached,
}

/// The control period's view of a motion planner (see the module docs).
pub trait PlannerHandle {
    /// Segments offered per control period at most: a bound on the planning work the
    /// period does when the planning half runs inside it.
    const OFFERS_PER_PERIOD: usize;
    /// A new program at rest at `start_mm`: what an earlier one left is dropped.
    fn restart(&mut self, cfg: &PlannerConfig, start_mm: [f32; 3]) -> Result<(), RestartError>;
    /// Offer the next segment of the program (see [`Offer`]).
    fn offer(&mut self, seg: &Segment) -> Offer;
    /// Feed hold: a jerk-limited stop on the path.
    fn hold(&mut self);
    /// Continue on the path after a hold.
    fn resume(&mut self);
    /// Stop on the path, then clear the queue.
    fn abort(&mut self);
    /// Feed override ratio (`FEED_OVERRIDE_MIN..=FEED_OVERRIDE_MAX`); refused outside.
    fn set_feed_override(&mut self, ratio: f32) -> Result<(), PlannerConfigError>;
    /// Segment slots free (what the host's program may still send ahead).
    fn free_slots(&self) -> usize;
    /// This control period's reference.
    fn tick(&mut self) -> PathSample;
    /// At rest with nothing pending: the program ended (or is held, or was aborted).
    fn is_idle(&self) -> bool;
}
