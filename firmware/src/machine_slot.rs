//! Where the firmware keeps the machine (controller-core `machine::Machine`) and its
//! planning task's half. The large parts live in statics initialised at reset from
//! constants: the scope's buffer and the executor's half (`MachineMemory`, 8 KiB), the
//! planning half (`MachineTaskPlanner`, 32 KiB) and the queues between the two halves
//! (`PlannerChannels`, 10 KiB); the rest of the machine (6 KiB) is in a slot the caller
//! owns. None of them is ever copied through the stack, which could not hold them.

use core::sync::atomic::{AtomicBool, Ordering};

use controller_core::machine::scope::Scope;
use controller_core::machine::{
    Machine, MachineError, MachineMemory, MachineTaskPlanner, MACHINE_SEGMENTS, MACHINE_SPANS,
};
use controller_core::motion::planner::{PlannerChannels, SplitExecutor, SplitPlanner};
use controller_core::settings::Settings;

/// The control interrupt's half of the planner.
type Executor = SplitExecutor<'static>;

/// The machine as the firmware holds it: the planner's executor in the control interrupt.
pub type FwMachine = Machine<&'static mut MachineMemory<Executor>, Executor>;

/// The planning half, run by the `plan` task after every control period.
pub type PlanTask = SplitPlanner<'static, MACHINE_SEGMENTS, MACHINE_SPANS>;

static mut MEMORY: MachineMemory<Executor> = MachineMemory {
    planner: SplitExecutor::DETACHED,
    scope: Scope::new(),
};
/// The planning half in the CCM RAM (core-coupled, otherwise unused: the look-ahead's
/// queue is most of it). Its initial image is copied there by [`init_ccm`].
#[cfg_attr(target_os = "none", link_section = ".ccmdata")]
static mut PLANNER: MachineTaskPlanner = MachineTaskPlanner::BLANK;
static mut CHANNELS: PlannerChannels = PlannerChannels::new();
static mut TASK: Option<PlanTask> = None;
static MEMORY_TAKEN: AtomicBool = AtomicBool::new(false);
static TASK_TAKEN: AtomicBool = AtomicBool::new(false);

/// Why the machine could not be built.
#[derive(Debug)]
pub enum BuildError {
    /// Built once already (its memory is taken).
    Twice,
    Machine(#[allow(dead_code)] MachineError),
}

/// Build the machine into `slot`: `settings` at `rate_hz`, the encoders' registers now
/// `raw` standing for wide counts `counts`. Its planning half waits for
/// [`take_plan_task`].
pub fn build(
    slot: &'static mut Option<FwMachine>,
    settings: &Settings,
    rate_hz: u32,
    raw: [u32; 3],
    counts: [i64; 3],
) -> Result<&'static mut FwMachine, BuildError> {
    if MEMORY_TAKEN.swap(true, Ordering::AcqRel) {
        return Err(BuildError::Twice);
    }
    // SAFETY: the first and only build, before anything has a reference to a CCM static.
    unsafe { init_ccm() };
    // SAFETY: the flag above hands out the only references to `MEMORY`, `PLANNER`,
    // `CHANNELS` and `TASK` (before `take_plan_task` can see it), once.
    let (memory, planner, channels, task) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(MEMORY),
            &mut *core::ptr::addr_of_mut!(PLANNER),
            &mut *core::ptr::addr_of_mut!(CHANNELS),
            &mut *core::ptr::addr_of_mut!(TASK),
        )
    };
    let (executor_ends, planner_ends) = channels.split();
    memory.planner.attach(executor_ends);
    *task = Some(SplitPlanner::new(planner, planner_ends));
    let m = Machine::new(settings, rate_hz, raw, counts, memory).map_err(BuildError::Machine)?;
    Ok(slot.insert(m))
}

/// The planning half of the machine built by [`build`], once (none before a build).
pub fn take_plan_task() -> Option<PlanTask> {
    if !MEMORY_TAKEN.load(Ordering::Acquire) || TASK_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: `build` and this run in `init` only (one thread, one after the other);
    // `build` no longer holds its reference, and the flag above hands this one out once.
    unsafe { (*core::ptr::addr_of_mut!(TASK)).take() }
}

/// Copies the initial image of the `.ccmdata` statics from flash into the CCM RAM
/// (memory.x): cortex-m-rt initialises `.data` only.
///
/// # Safety
/// Once, before any reference to a `.ccmdata` static exists (`build` calls it first).
#[cfg(target_os = "none")]
unsafe fn init_ccm() {
    extern "C" {
        static mut __sccmdata: u32;
        static __eccmdata: u32;
        static __siccmdata: u32;
    }
    let start = core::ptr::addr_of_mut!(__sccmdata);
    let end = core::ptr::addr_of!(__eccmdata);
    let words = (end as usize - start as usize) / 4;
    // word by word from the flash image (both 4-aligned by the linker script)
    core::ptr::copy_nonoverlapping(core::ptr::addr_of!(__siccmdata), start, words);
}

/// On the host (unit tests) the statics are ordinary ones, already initialised.
#[cfg(not(target_os = "none"))]
unsafe fn init_ccm() {}
