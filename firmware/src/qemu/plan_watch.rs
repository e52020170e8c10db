//! Whether the machine's planning half (the `plan` task, spawned by every control period)
//! ran exactly once between two control periods, as host-sim's runs assume: the `plan`
//! task counts its runs ([`plan_started`], [`plan_finished`]) and the rig's control
//! period reads the count ([`PlanWatch::since_last`]). A scenario's program run fails when
//! it did not (the run would not be the one host-sim computes); the link rig records it
//! for the replay.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// Runs of the planning half completed (the `plan` task, after each).
static PLAN_RUNS: AtomicU32 = AtomicU32::new(0);
/// The planning half is running (a control period that finds it so preempted it).
static PLAN_BUSY: AtomicBool = AtomicBool::new(false);

/// The `plan` task starts a run of the planning half.
pub fn plan_started() {
    PLAN_BUSY.store(true, Ordering::Release);
}

/// The `plan` task finished a run.
pub fn plan_finished() {
    PLAN_RUNS.fetch_add(1, Ordering::AcqRel);
    PLAN_BUSY.store(false, Ordering::Release);
}

/// The control period's view of the planning half's runs.
pub struct PlanWatch {
    /// Runs seen so far.
    seen: u32,
}

impl PlanWatch {
    pub const fn new() -> Self {
        Self { seen: 0 }
    }

    /// The runs of the planning half since the last call, and whether one is running now
    /// (this control period preempted it).
    pub fn since_last(&mut self) -> (u32, bool) {
        let runs = PLAN_RUNS.load(Ordering::Acquire);
        let busy = PLAN_BUSY.load(Ordering::Acquire);
        let ran = runs.wrapping_sub(self.seen);
        self.seen = runs;
        (ran, busy)
    }
}
