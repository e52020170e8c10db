//! The clock tree and its failure handling.
//!
//! - Start-up: the 8 MHz crystal (HSE) is started here with a bounded wait
//!   ([`HSE_STARTUP_TIMEOUT_MS`]) before the HAL's clock setup runs (the HAL waits for
//!   HSERDY forever). If it does not start, the same 168 MHz tree is built from the
//!   internal 16 MHz RC oscillator (HSI, PLL) and [`ClockStart::HsiFallback`] is reported:
//!   `init` latches `FaultKind::ClockFault` in the servo, which then never enables the
//!   outputs (the HSI's ±1 % at 25 °C, worse over temperature, makes every rate and time
//!   in the controller untrustworthy).
//! - Running: the clock security system (RCC CR.CSSON) watches the HSE. On a failure the
//!   hardware switches SYSCLK to the HSI, stops the HSE, sends a break event to TIM1 (PWM
//!   off in hardware) and raises the NMI; [`NonMaskableInt`] switches the outputs off,
//!   clears the interrupt and flags the fault for the control task, which latches
//!   `ClockFault` in its next period ([`take_css_fault`]).
//!
//! The QEMU build has no RCC model: it stays on the HSI (`Config::hsi()`) and none of this
//! runs there.
// (The QEMU build compiles the board's clock code but never runs it.)
#![cfg_attr(feature = "qemu", allow(dead_code, unused_imports))]

use core::sync::atomic::{AtomicBool, Ordering};

use stm32f4xx_hal::{
    pac,
    prelude::*,
    rcc::{Config, Rcc},
};

/// SYSCLK the firmware runs at (the QEMU build's core also runs at 168 MHz, whatever the
/// clock tree registers say).
pub const SYSCLK_HZ: u32 = 168_000_000;

/// How long the crystal may take to start, ms: ST's own HAL uses 100 ms
/// (`HSE_STARTUP_TIMEOUT`); an 8 MHz crystal typically starts in 2 ms (DS8626, tSU(HSE)).
pub const HSE_STARTUP_TIMEOUT_MS: u32 = 100;

/// Core clock while waiting for the crystal: the HSI, 16 MHz.
const HSI_HZ: u32 = 16_000_000;

/// [`HSE_STARTUP_TIMEOUT_MS`] in DWT cycles at the HSI.
const HSE_STARTUP_TIMEOUT_CYCLES: u32 = HSI_HZ / 1000 * HSE_STARTUP_TIMEOUT_MS;

/// Which oscillator the clock tree runs from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum ClockStart {
    /// The crystal started; the clock security system watches it.
    Hse,
    /// The crystal did not start within the timeout: the internal RC oscillator runs the
    /// PLL (a clock fault).
    HsiFallback,
}

/// The 168 MHz tree from `source`: SYSCLK = HCLK 168 MHz, APB1 42 MHz (timers 84 MHz),
/// APB2 84 MHz (timers 168 MHz); the PLL input is the 8 MHz crystal or the 16 MHz HSI.
fn tree(source: ClockStart) -> Config {
    let cfg = match source {
        ClockStart::Hse => Config::hse(8.MHz()),
        ClockStart::HsiFallback => Config::hsi(),
    };
    cfg.sysclk(SYSCLK_HZ.Hz())
        .hclk(SYSCLK_HZ.Hz())
        .pclk1(42.MHz())
        .pclk2(84.MHz())
}

/// Starts the crystal and waits for it at most [`HSE_STARTUP_TIMEOUT_MS`] (measured with
/// the DWT cycle counter, which `init` enables first; an iteration cap bounds the loop
/// should the counter not run), then sets up the clock tree and, on the crystal, the
/// clock security system.
#[cfg(not(feature = "qemu"))]
pub fn setup(rcc: Rcc) -> (Rcc, ClockStart) {
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    let start = cortex_m::peripheral::DWT::cycle_count();
    let mut ready = false;
    // every iteration takes at least one cycle, so the cap is never shorter than the
    // timeout; it only matters if the cycle counter does not count
    for _ in 0..HSE_STARTUP_TIMEOUT_CYCLES {
        if rcc.cr().read().hserdy().bit_is_set() {
            ready = true;
            break;
        }
        let elapsed = cortex_m::peripheral::DWT::cycle_count().wrapping_sub(start);
        if elapsed >= HSE_STARTUP_TIMEOUT_CYCLES {
            break;
        }
    }
    let source = if ready {
        ClockStart::Hse
    } else {
        rcc.cr().modify(|_, w| w.hseon().clear_bit());
        ClockStart::HsiFallback
    };
    let rcc = rcc.freeze(tree(source));
    if source == ClockStart::Hse {
        rcc.cr().modify(|_, w| w.csson().set_bit());
    }
    (rcc, source)
}

/// QEMU does not model the RCC (the crystal start-up would time out): stay on the 16 MHz
/// HSI; the emulated core runs at its own speed anyway.
#[cfg(feature = "qemu")]
pub fn setup(rcc: Rcc) -> (Rcc, ClockStart) {
    let _ = tree;
    (rcc.freeze(Config::hsi()), ClockStart::Hse)
}

/// Set by the NMI when the clock security system saw the crystal fail.
static CSS_FAULT: AtomicBool = AtomicBool::new(false);

/// True once after the clock security system tripped (the control task latches the
/// clock fault).
#[inline]
pub fn take_css_fault() -> bool {
    CSS_FAULT.swap(false, Ordering::Relaxed)
}

/// The NMI: on the STM32F4 only the clock security system raises it. Outputs off first,
/// then acknowledge (CSSC; otherwise the NMI re-enters forever) and flag the fault. The
/// hardware has already moved SYSCLK to the HSI and sent TIM1 a break.
#[cfg(not(feature = "qemu"))]
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    super::shutdown::outputs_off_raw();
    // SAFETY: CIR is only written here (the firmware enables no other RCC interrupt, so
    // writing the other enable bits as 0 changes nothing).
    let rcc = unsafe { &*pac::RCC::ptr() };
    rcc.cir().write(|w| w.cssc().set_bit());
    CSS_FAULT.store(true, Ordering::Relaxed);
}
