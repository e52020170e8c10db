//! Where the firmware keeps the machine (controller-core `machine::Machine`) and its
//! planning task's half. The large parts live in statics: the scope's buffer and the
//! executor's half (`MachineMemory`, 8.7 KiB) and the planning half
//! (`MachineTaskPlanner`, 61 KiB, in the CCM RAM) zero-filled and made blank in place at
//! build (`firmware::blank_static`: no image of them in flash), and the queues between
//! the two halves (`PlannerChannels`, 10 KiB); the rest of the machine (6 KiB) is in a
//! slot the caller owns. None of them is ever copied through the stack, which could not
//! hold them.

use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

use controller_core::machine::{
    Machine, MachineError, MachineMemory, MachineTaskPlanner, MACHINE_SEGMENTS, MACHINE_SPANS,
};
use controller_core::motion::planner::{PlannerChannels, SplitExecutor, SplitPlanner};
use controller_core::settings::Settings;
use firmware::blank_static;

/// The control interrupt's half of the planner.
pub type Executor = SplitExecutor<'static>;

/// The machine as the firmware holds it: the planner's executor in the control interrupt.
pub type FwMachine = Machine<&'static mut MachineMemory<Executor>, Executor>;

/// QEMU's rig: the machine in a simulated run (controller-core `SimRun`) against the
/// simulated world, its memory the same statics (the planning half is the `plan` task's).
#[cfg(feature = "qemu")]
pub type FwRun =
    controller_core::sim::run::SimRun<f32, &'static mut MachineMemory<Executor>, Executor>;

/// The planning half, run by the `plan` task after every control period.
pub type PlanTask = SplitPlanner<'static, MACHINE_SEGMENTS, MACHINE_SPANS>;

// Zero-filled, made blank in place by `build` (`firmware::blank_static`): no initial
// image in flash. `MEMORY` is in `.bss`; `PLANNER` in the CCM RAM (core-coupled,
// otherwise unused: the look-ahead's queue is most of it), `NOLOAD` (memory.x).
static mut MEMORY: MaybeUninit<MachineMemory<Executor>> = MaybeUninit::uninit();
#[cfg_attr(target_os = "none", link_section = ".ccmbss")]
static mut PLANNER: MaybeUninit<MachineTaskPlanner> = MaybeUninit::uninit();
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

/// The machine's memory (the scope and the executor's half, connected to the planning
/// half, which waits for [`take_plan_task`]), once.
pub fn memory() -> Result<&'static mut MachineMemory<Executor>, BuildError> {
    if MEMORY_TAKEN.swap(true, Ordering::AcqRel) {
        return Err(BuildError::Twice);
    }
    // SAFETY: the flag above hands out the only references to `MEMORY`, `PLANNER`,
    // `CHANNELS` and `TASK` (before `take_plan_task` can see it), once.
    let (memory, planner, channels, task) = unsafe {
        (
            blank_static::memory(core::ptr::addr_of_mut!(MEMORY)),
            blank_static::planner(core::ptr::addr_of_mut!(PLANNER)),
            &mut *core::ptr::addr_of_mut!(CHANNELS),
            &mut *core::ptr::addr_of_mut!(TASK),
        )
    };
    let (executor_ends, planner_ends) = channels.split();
    memory.planner.attach(executor_ends);
    *task = Some(SplitPlanner::new(planner, planner_ends));
    Ok(memory)
}

/// Build the machine into `slot`: `settings` at `rate_hz`, the encoders' registers now
/// `raw` standing for wide counts `counts`. Its planning half waits for
/// [`take_plan_task`].
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub fn build(
    slot: &'static mut Option<FwMachine>,
    settings: &Settings,
    rate_hz: u32,
    raw: [u32; 3],
    counts: [i64; 3],
) -> Result<&'static mut FwMachine, BuildError> {
    let m = Machine::new(settings, rate_hz, raw, counts, memory()?).map_err(BuildError::Machine)?;
    Ok(slot.insert(m))
}

/// The planning half of the machine whose [`memory`] was taken, once (none before).
pub fn take_plan_task() -> Option<PlanTask> {
    if !MEMORY_TAKEN.load(Ordering::Acquire) || TASK_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: `build` and this run in `init` only (one thread, one after the other);
    // `build` no longer holds its reference, and the flag above hands this one out once.
    unsafe { (*core::ptr::addr_of_mut!(TASK)).take() }
}
