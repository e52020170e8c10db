//! How deep the stack has ever been: cortex-m-rt paints the whole stack region at reset
//! (feature `paint-stack`, the word `STACK_PAINT_VALUE`), and every word the program
//! has pushed is no longer paint. The telemetry task logs the high-water mark, so that
//! the margin the static RAM leaves (README-firmware "Size") is measured, not guessed:
//! a stack that overflows into the statics corrupts them silently.

extern "C" {
    /// Top of the stack (the end of RAM), from cortex-m-rt's linker script.
    static _stack_start: u32;
    /// Bottom of the stack (the end of the statics).
    static _stack_end: u32;
}

/// The stack's size and the most of it ever used, in bytes.
pub fn high_water() -> (u32, u32) {
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let size = top.saturating_sub(bottom);
    let mut p = bottom;
    // (from the bottom up: the words still painted were never reached; the scan stops at
    // the first one the stack wrote, far below the stack pointer of this task)
    while p < top {
        // SAFETY: `p` is a word-aligned address inside the stack region, below every
        // live frame while it is still paint; a volatile read of RAM has no side effects.
        let w = unsafe { core::ptr::read_volatile(p as *const u32) };
        if w != cortex_m_rt::STACK_PAINT_VALUE {
            break;
        }
        p += 4;
    }
    (size as u32, top.saturating_sub(p) as u32)
}
