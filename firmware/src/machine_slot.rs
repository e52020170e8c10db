//! Where the firmware keeps the machine (controller-core `machine::Machine`): its
//! large parts (`MachineMemory`: the planner, 40 KiB, and the scope's buffer, 8 KiB) in a
//! static initialised at reset from a constant, the rest (6 KiB)
//! in a slot the caller owns. Neither is ever copied through the stack, which could not
//! hold two of them.

use core::sync::atomic::{AtomicBool, Ordering};

use controller_core::machine::{Machine, MachineError, MachineMemory};
use controller_core::settings::Settings;

/// The machine as the firmware holds it.
pub type FwMachine = Machine<&'static mut MachineMemory>;

static mut MEMORY: MachineMemory = MachineMemory::BLANK;
static MEMORY_TAKEN: AtomicBool = AtomicBool::new(false);

/// Why the machine could not be built.
#[derive(Debug)]
pub enum BuildError {
    /// Built once already (its memory is taken).
    Twice,
    Machine(#[allow(dead_code)] MachineError),
}

/// Build the machine into `slot`: `settings` at `rate_hz`, the encoders' registers now
/// `raw` standing for wide counts `counts`.
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
    // SAFETY: the flag above hands out the only reference to `MEMORY`, once.
    let memory = unsafe { &mut *core::ptr::addr_of_mut!(MEMORY) };
    let m = Machine::new(settings, rate_hz, raw, counts, memory).map_err(BuildError::Machine)?;
    Ok(slot.insert(m))
}
