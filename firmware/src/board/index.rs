//! The encoders' index (Z channel) inputs: the counter value at each index pulse, for
//! homing on the index and the core's index-pulse checks ([`IndexInputs::read`] is the
//! board's `ServoIo::read_index`, called in the control interrupt).
//!
//! | axis | pin | how the count is captured |
//! | --- | --- | --- |
//! | X | PB10 | TIM2_CH3 (AF1): input capture of TI3, latches TIM2_CNT in TIM2_CCR3 in hardware |
//! | Y | PB1 | EXTI1 (rising edge): the `y_index` task, RTIC's highest priority, reads TIM5_CNT |
//! | Z | PB0 | TIM3_CH3 (AF2): input capture of TI3, latches TIM3_CNT in TIM3_CCR3 in hardware |
//!
//! Wiring: a differential encoder's Z/Z̄ pair through the line receiver, like A/B. The
//! inputs have the internal pull-down, so an unwired index input gives no edges (a line
//! receiver's fail-safe output, high on an open cable, gives none either).
//!
//! **X and Z** (TIMx_CCMR2 CC3S = 01: IC3 mapped on TI3; IC3PSC = 00, every edge; IC3F =
//! the A/B filter `ENCODER_IC_FILTER`; TIMx_CCER CC3P = CC3NP = 0: rising edge; CC3E = 1).
//! The timer keeps counting in encoder mode; channel 3 is not part of the encoder
//! interface, so capturing on it changes nothing of the count. The index edge passes the
//! same filter as A and B, so it is delayed as much as the count (8 samples at 21 MHz)
//! and the capture is exact to the count, at any speed. CC3IF says a capture came; reading
//! CCR3 clears it. Two captures between reads: CCR3 holds the newer one (CC3OF is set
//! and left so: nothing needs it).
//!
//! **Y.** TIM5's channels 3 and 4 are on PA2/PA3 (the host link's USART2) or PH12
//! and PI0 (not on the LQFP100 package), and TIM5 has no ETR input; so the capture is
//! done in software: PB1's rising edge (EXTI line 1, SYSCFG_EXTICR1 EXTI1 = port B; no
//! other pin uses line 1 as an interrupt, and PB1's timer functions TIM1_CH3N, TIM3_CH4,
//! TIM8_CH3N are unused) raises EXTI1, whose task reads TIM5_CNT first, then clears the
//! EXTI_PR pending bit and hands the value over. Its priority is 6, above the host UART
//! (5) and the control tick (4), so no RTIC task delays it: an RTIC lock of a lower
//! task raises BASEPRI at most to its ceiling (5), and the handler shares nothing (its
//! handoff to the control task is `firmware::index_capture::IndexMailbox`, lock-free;
//! an RTIC resource shared with the control task would make the control task's read a
//! BASEPRI lock that holds off this very interrupt). RTIC allows priorities up to
//! 2^NVIC_PRIO_BITS = 16 on the STM32F4 (4 priority bits).
//!
//! Latency of Y's capture: EXTI edge detection, a few cycles; exception entry, 12 cycles
//! at 168 MHz (a few more when the vector fetch misses the ART accelerator's cache at 5
//! flash wait states); then the handler's first instructions (in the release build the
//! TIM5_CNT load is its 7th: a 4-register push, the register addresses, RTIC's BASEPRI
//! read, about 11 cycles) and the load itself across the APB1 bridge (42 MHz: a few
//! cycles). That is about 30 cycles, at most about 40: 0.18-0.24 µs, against 2.5 µs per count at
//! the gantry's top speed (250 mm/s × 1600 counts/mm = 400 k counts/s): under 0.1 count.
//! (And the A/B count itself lags the encoder by the input filter's 0.38-0.43 µs, while
//! EXTI has no filter, so the two delays largely cancel.) Homing on the index runs far
//! slower (at 5 mm/s a count lasts 125 µs), where the latency is immaterial. What can
//! delay it more: the SysTick handler (RTIC's monotonic, at the NVIC's highest priority:
//! board review D8), a PRIMASK critical section (a few µs at most), a flash erase (the
//! CPU stalls, with the outputs off) — each then makes the capture a count or two late
//! at top speed.
//!
//! EXTI has no digital filter: an index line that is noise (floating, ringing) would
//! raise this highest-priority interrupt as fast as it toggles and starve the control
//! task. `firmware::index_capture::StormGuard` masks EXTI line 1 (EXTI_IMR MR1) after 8
//! captures in a row each less than 10 µs after the previous one (real index pulses are
//! at least 18 ms apart); until the next reset Y then reports no index (homing on it
//! cannot complete, the rest runs on). Slower noise costs at most one short interrupt
//! per 10 µs.
//!
//! Not built for the QEMU rig (QEMU models no GPIO or EXTI; it reads the simulated
//! machine instead).

use stm32f4xx_hal::gpio::{Alternate, Edge, ExtiPin, Input, Pin, PB0, PB1, PB10};
use stm32f4xx_hal::{pac, syscfg::SysCfg};

use controller_core::axes::AXES;
use firmware::encoder_filter::ENCODER_IC_FILTER;
use firmware::index_capture::{IndexMailbox, IndexReader, StormGuard};

/// Y's index captures: written by [`on_y_index`] (the EXTI1 task), read by
/// [`IndexInputs::read`] (the control task, which EXTI1 preempts: the mailbox's contract).
static Y_INDEX: IndexMailbox = IndexMailbox::new();

/// EXTI line of Y's index input (PB1).
const Y_EXTI_LINE: u32 = 1;

/// The three index inputs, configured; owns their pins.
pub struct IndexInputs {
    _x: Pin<'B', 10, Alternate<1>>,
    _y: Pin<'B', 1, Input>,
    _z: Pin<'B', 0, Alternate<2>>,
    /// Y's captures taken so far.
    y: IndexReader,
}

impl IndexInputs {
    /// Pins, TIM2/TIM3 channel 3 capture, EXTI line 1. After the encoder timers are in
    /// encoder mode (the HAL's setup writes their CCER whole); before interrupts are
    /// enabled (RTIC unmasks EXTI1 at the end of init).
    pub fn new(x: PB10, y: PB1, z: PB0, syscfg: &mut SysCfg, exti: &mut pac::EXTI) -> Self {
        let x = x.into_alternate::<1>().internal_pull_down(true);
        let z = z.into_alternate::<2>().internal_pull_down(true);
        let mut y = y.into_pull_down_input();

        // SAFETY: CCMR2, CCER and SR of TIM2 and TIM3 are written only here, once, in
        // `init` (the HAL's `Qei` reads only CNT afterwards, and nothing else uses
        // channel 3); `read` only reads SR and CCR3 later. The channel is configured
        // before it is enabled (CC3S is writable only while CC3E = 0).
        unsafe {
            let tim2 = &*pac::TIM2::ptr();
            tim2.ccmr2_input().modify(|_, w| {
                w.cc3s()
                    .ti3()
                    .ic3psc()
                    .bits(0)
                    .ic3f()
                    .bits(ENCODER_IC_FILTER)
            });
            tim2.ccer()
                .modify(|_, w| w.cc3p().clear_bit().cc3np().clear_bit().cc3e().set_bit());
            // no capture before this point counts (rc_w0: only these two bits clear)
            tim2.sr()
                .write(|w| w.cc3if().clear_bit().cc3of().clear_bit());

            let tim3 = &*pac::TIM3::ptr();
            tim3.ccmr2_input().modify(|_, w| {
                w.cc3s()
                    .ti3()
                    .ic3psc()
                    .bits(0)
                    .ic3f()
                    .bits(ENCODER_IC_FILTER)
            });
            tim3.ccer()
                .modify(|_, w| w.cc3p().clear_bit().cc3np().clear_bit().cc3e().set_bit());
            tim3.sr()
                .write(|w| w.cc3if().clear_bit().cc3of().clear_bit());
        }

        // Y: PB1 on EXTI line 1, rising edge, unmasked (SYSCFG's clock is on: `SysCfg`).
        y.make_interrupt_source(syscfg);
        y.trigger_on_edge(exti, Edge::Rising);
        y.clear_interrupt_pending_bit();
        y.enable_interrupt(exti);

        Self {
            _x: x,
            _y: y,
            _z: z,
            y: IndexReader::new(),
        }
    }

    /// Per axis the counter value captured at the newest index pulse since the last call,
    /// in the timer's width (Z: 16 bits), like `Encoders::read_raw`. A few register and
    /// memory loads; never waits.
    #[inline]
    pub fn read(&mut self) -> [Option<u32>; AXES] {
        // SAFETY: reads of TIM2/TIM3 SR and CCR3. The only side effect, reading CCR3
        // clearing CC3IF, is this function's own (the control task is their one reader;
        // `new` wrote them before any task ran). Reading SR first, then CCR3: a capture
        // landing in between gives the newer value, one after CCR3's read sets CC3IF
        // again for the next call, so none is lost.
        let (x, z) = unsafe {
            let tim2 = &*pac::TIM2::ptr();
            let tim3 = &*pac::TIM3::ptr();
            let x = tim2
                .sr()
                .read()
                .cc3if()
                .bit_is_set()
                .then(|| tim2.ccr3().read().bits());
            let z = tim3
                .sr()
                .read()
                .cc3if()
                .bit_is_set()
                .then(|| tim3.ccr3().read().bits() & 0xFFFF);
            (x, z)
        };
        [x, self.y.take(&Y_INDEX), z]
    }
}

/// The EXTI1 task's body: Y's index edge. TIM5_CNT is read first (its latency is the
/// capture's error, see the module doc), then the pending bit is cleared and the value
/// handed over. A call without the pending bit (a spurious re-entry) does nothing.
#[inline(always)]
pub fn on_y_index(guard: &mut StormGuard) {
    // SAFETY: TIM5_CNT and EXTI_PR are read without side effects. EXTI_PR is rc_w1:
    // writing only PR1's bit clears only line 1's pending bit, nobody else's. EXTI_IMR
    // is read-modify-written only here at run time (by the highest-priority interrupt,
    // which nothing that writes EXTI_IMR can preempt) and in `init`, before interrupts.
    unsafe {
        let count = (*pac::TIM5::ptr()).cnt().read().bits();
        let exti = &*pac::EXTI::ptr();
        if exti.pr().read().bits() & (1 << Y_EXTI_LINE) == 0 {
            return;
        }
        exti.pr().write(|w| w.pr1().clear_bit_by_one());
        if guard.on_capture(cortex_m::peripheral::DWT::cycle_count()) {
            exti.imr().modify(|_, w| w.mr1().clear_bit());
        }
        Y_INDEX.publish(count);
        // The pending bit's clear must reach EXTI before the exception returns, or the
        // NVIC can see the line still pending and enter again (a spurious entry that the
        // check above would drop): a read on the same bus completes after the write.
        let _ = exti.pr().read().bits();
    }
}
