//! Execution-time measurement of the control task (the board's cycle counter).
//!
//! On the board: the DWT cycle counter (core cycles at 168 MHz).
//!
//! In QEMU the DWT is not modelled (it reads 0). There, with `-icount shift=0` every
//! emulated instruction advances the virtual clock by exactly 1 ns, and SysTick counts
//! that virtual clock at 168 MHz; the SysTick down-counter difference, scaled by 1e9/168e6,
//! is therefore the number of *instructions* executed (resolution about 6). It is not a
//! cycle count: QEMU does not model pipeline or memory timing.

/// An opaque start mark.
#[derive(Clone, Copy)]
pub struct Mark(u32);

/// Starts a measurement.
#[inline(always)]
pub fn start() -> Mark {
    #[cfg(not(feature = "qemu"))]
    {
        Mark(cortex_m::peripheral::DWT::cycle_count())
    }
    #[cfg(feature = "qemu")]
    {
        Mark(cortex_m::peripheral::SYST::get_current())
    }
}

/// Cycles (board) or emulated instructions (QEMU) since `mark`.
#[inline(always)]
pub fn since(mark: Mark) -> u32 {
    #[cfg(not(feature = "qemu"))]
    {
        cortex_m::peripheral::DWT::cycle_count().wrapping_sub(mark.0)
    }
    #[cfg(feature = "qemu")]
    {
        // SysTick counts down from its reload value and wraps to it.
        let now = cortex_m::peripheral::SYST::get_current();
        let reload = cortex_m::peripheral::SYST::get_reload() + 1;
        let ticks = if now <= mark.0 {
            mark.0 - now
        } else {
            mark.0 + reload - now
        };
        // 1e9 / 168e6 = 125 / 21 instructions per SysTick tick.
        ((u64::from(ticks) * 125) / 21) as u32
    }
}
