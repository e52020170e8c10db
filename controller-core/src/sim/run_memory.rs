//! The memory of a scripted run's machine when it runs no program: a scope and no
//! planner ([`NoPlanner`]). A run that streams a program
//! ([`super::run::RunConfig::program`]) is given a machine memory with a real planner by
//! its caller instead (host-sim: the board's split planner, boxed; the QEMU rig: the
//! firmware's static one).

use core::ops::{Deref, DerefMut};

use crate::machine::scope::Scope;
use crate::machine::MachineMemory;
use crate::motion::planner::{
    ExecMode, Offer, PathSample, PlannerConfig, PlannerConfigError, PlannerHandle, RestartError,
    Segment, SegmentError,
};
use crate::Vec3;

/// The planner of a scripted run's machine: none. Such a run follows the servo's own
/// path (`Command::StartPath`) or holds; a program it is sent is refused segment by
/// segment, and it holds its start.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoPlanner {
    start_mm: [f32; 3],
}

impl PlannerHandle for NoPlanner {
    const OFFERS_PER_PERIOD: usize = 1;
    fn restart(&mut self, _: &PlannerConfig, start_mm: [f32; 3]) -> Result<(), RestartError> {
        self.start_mm = start_mm;
        Ok(())
    }
    fn offer(&mut self, _: &Segment) -> Offer {
        Offer::Refused(SegmentError::QueueFull)
    }
    fn hold(&mut self) {}
    fn resume(&mut self) {}
    fn abort(&mut self) {}
    fn set_feed_override(&mut self, _: f32) -> Result<(), PlannerConfigError> {
        Ok(())
    }
    fn free_slots(&self) -> usize {
        0
    }
    fn tick(&mut self) -> PathSample {
        PathSample {
            pos_mm: Vec3::from_array(self.start_mm),
            vel_mm_s: Vec3::zero(),
            acc_mm_s2: Vec3::zero(),
            tangent: Vec3::zero(),
            path_speed_mm_s: 0.0,
            path_acc_mm_s2: 0.0,
            feed_ratio: 0.0,
            tag: 0,
            mode: ExecMode::Idle,
        }
    }
    fn is_idle(&self) -> bool {
        true
    }
}

/// A scripted run's machine memory, held in the run: its scope (no planner).
pub struct RunMemory(MachineMemory<NoPlanner>);

impl RunMemory {
    pub const fn new() -> Self {
        Self(MachineMemory {
            planner: NoPlanner { start_mm: [0.0; 3] },
            scope: Scope::new(),
            comp: crate::motion::compensation::CompTables::NONE,
            comp_entry: crate::machine::CompEntry::NONE,
            response: crate::machine::ResponseRecord::EMPTY,
            shaper: crate::motion::shaper::ShaperStage::NONE,
            queue: crate::machine::RequestQueue::new(),
            next_settings: None,
            settings: crate::settings::FACTORY,
        })
    }
}

impl Default for RunMemory {
    fn default() -> Self {
        Self::new()
    }
}

impl Deref for RunMemory {
    type Target = MachineMemory<NoPlanner>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl DerefMut for RunMemory {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.0
    }
}
