//! A machine memory with the planner split as the firmware splits it: the executor's
//! half in the machine ([`SplitExecutor`]), the planning half beside it ([`PlanTask`]),
//! run by the caller once after every period as the board's `plan` task runs when
//! nothing preempts it. A program run in discrete mode (and so `qemu-verdict`) and the
//! machine replay plan exactly as the board and its QEMU rig do.

use controller_core::machine::scope::Scope;
use controller_core::machine::{
    MachineMemory, MachineTaskPlanner, MACHINE_SEGMENTS, MACHINE_SPANS,
};
use controller_core::motion::planner::{PlannerChannels, SplitExecutor, SplitPlanner};

/// The planning half.
pub type PlanTask<'a> = SplitPlanner<'a, MACHINE_SEGMENTS, MACHINE_SPANS>;

/// The parts the two halves borrow: the queues between them and the planning half's
/// look-ahead (61 KiB), boxed.
pub struct SplitParts {
    channels: Box<PlannerChannels>,
    planner: Box<MachineTaskPlanner>,
}

impl SplitParts {
    pub fn new() -> Self {
        Self {
            channels: Box::new(PlannerChannels::new()),
            planner: Box::new(MachineTaskPlanner::BLANK),
        }
    }

    /// The machine's memory (the executor's half, connected, and a scope) and the
    /// planning half, both borrowing these parts.
    pub fn split(&mut self) -> (Box<MachineMemory<SplitExecutor<'_>>>, PlanTask<'_>) {
        let (ex, pl) = self.channels.split();
        let mut exec = SplitExecutor::DETACHED;
        exec.attach(ex);
        let memory = Box::new(MachineMemory {
            planner: exec,
            scope: Scope::new(),
            comp: controller_core::motion::compensation::CompTables::NONE,
            comp_entry: controller_core::machine::CompEntry::NONE,
            response: controller_core::machine::ResponseRecord::EMPTY,
            shaper: controller_core::motion::shaper::ShaperStage::NONE,
            queue: controller_core::machine::RequestQueue::new(),
            next_settings: None,
            settings: controller_core::settings::FACTORY,
        });
        (memory, SplitPlanner::new(&mut self.planner, pl))
    }
}

impl Default for SplitParts {
    fn default() -> Self {
        Self::new()
    }
}
