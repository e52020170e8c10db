//! The machine's large statics without an initial image: the planning half (62 KiB, in
//! the CCM RAM) and the machine memory (the scope's buffer and the executor, 8.7 KiB)
//! are zero-filled statics (`.bss`, and the CCM's `NOLOAD` `.ccmbss`, firmware/memory.x)
//! made blank in place at boot, field by field. As initialised statics their images
//! cost 71 KiB of flash and a copy at every boot; as constants
//! written whole they would be copied through the stack, which cannot hold them.
//!
//! Zero bytes are a valid planner, executor, scope, request queue, compensation tables and
//! input shaper (switched off) (numbers, bools, heapless queues'
//! indices over uninitialised storage, `None` references, enums with a variant at
//! zero); each is then set to its blank value with the core's in-place `blank`
//! (`Planner::blank`, `Scope::blank`) or, for the small executor, a plain write. The host
//! tests below start from garbage, as an SRAM after a reset holds, and compare with the
//! constants.

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use controller_core::machine::{MachineMemory, MachineTaskPlanner};
use controller_core::motion::planner::SplitExecutor;

/// Makes `*p` [`MachineTaskPlanner::BLANK`] in place and returns it.
///
/// # Safety
/// `p` is valid for writes and nothing else refers to it while the reference lives.
pub unsafe fn planner<'a>(p: *mut MaybeUninit<MachineTaskPlanner>) -> &'a mut MachineTaskPlanner {
    p.write_bytes(0, 1);
    // SAFETY: zero bytes are a valid planner (module docs); the caller's exclusivity
    let planner = &mut *p.cast::<MachineTaskPlanner>();
    planner.blank();
    planner
}

/// Makes `*p` the machine memory of a fresh machine (`SplitExecutor::DETACHED` and
/// `Scope::new()`) in place and returns it.
///
/// # Safety
/// As for [`planner`].
pub unsafe fn memory<'a>(
    p: *mut MaybeUninit<MachineMemory<SplitExecutor<'a>>>,
) -> &'a mut MachineMemory<SplitExecutor<'a>> {
    p.write_bytes(0, 1);
    let m = p.cast::<MachineMemory<SplitExecutor<'a>>>();
    // (the executor is small: written whole; nothing in the zero bytes is dropped)
    addr_of_mut!((*m).planner).write(SplitExecutor::DETACHED);
    // (an `Option<PreparedSettings>` is not `None` as zero bytes, nor a settings tree valid)
    addr_of_mut!((*m).next_settings).write(None);
    addr_of_mut!((*m).settings).write(controller_core::settings::FACTORY);
    // SAFETY: zero bytes are a valid scope (module docs), the executor was just written
    let m = &mut *m;
    m.scope.blank();
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::machine::scope::ScopeState;
    use controller_core::motion::planner::GANTRY_PLANNER;

    /// A static's storage after a reset: whatever the last run left (here 0xa5).
    fn garbage<T>() -> Box<MaybeUninit<T>> {
        let mut b = Box::<T>::new_uninit();
        // SAFETY: a byte pattern written into the box's own storage
        unsafe {
            b.as_mut_ptr()
                .cast::<u8>()
                .write_bytes(0xa5, core::mem::size_of::<T>())
        };
        b
    }

    #[test]
    fn the_planning_half_is_blank_and_plans() {
        let mut b = garbage::<MachineTaskPlanner>();
        // SAFETY: the box's storage, borrowed for this test only
        let p = unsafe { planner(&mut *b) };
        assert!(*p == MachineTaskPlanner::BLANK);
        // and it restarts and takes a program like a planner built from `new`
        p.restart(&GANTRY_PLANNER, [0.0; 3]).unwrap();
        let fresh = MachineTaskPlanner::new(&GANTRY_PLANNER, [0.0; 3]).unwrap();
        assert!(*p == fresh);
    }

    #[test]
    fn the_machine_memory_is_a_fresh_machines() {
        let mut b = garbage::<MachineMemory<SplitExecutor<'static>>>();
        // SAFETY: as above
        let m = unsafe { memory(&mut *b) };
        assert_eq!(m.scope.state(), ScopeState::Off);
        assert!(m.scope.read(0).is_err(), "a blank scope has no capture");
        assert_eq!(*m.planner.report(), *SplitExecutor::DETACHED.report());
        assert!(m.next_settings.is_none());
        assert!(m.queue.is_empty());
        assert!(!m.shaper.active());
    }
}
