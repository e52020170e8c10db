//! The independent watchdog (IWDG), board build only (QEMU does not model it).
//!
//! Started at the end of `init` with the timeout of `firmware::watchdog::iwdg_setting`
//! for the control rate (2.0 ms at the fastest LSI, 3.0 ms typical, 5.6 ms at the slowest
//! at 10 kHz); fed only by the control interrupt, at the end of every period it completes.
//! Once started the IWDG cannot be stopped; it also runs while a debugger halts the core
//! (DBGMCU's DBG_IWDG_STOP is left clear), so a breakpoint resets the board within the
//! timeout: the outputs cannot stay on under a halted core.
//!
//! The keys are RM0090 21.4.1's (0x5555 unlock, 0xCCCC start, 0xAAAA feed). Hand-written rather than the HAL's `IndependentWatchdog`, whose timeouts are whole
//! milliseconds computed for the typical 32 kHz LSI.

use stm32f4xx_hal::pac;

use firmware::watchdog::IwdgSetting;

/// The IWDG, owned by the control task.
pub struct Watchdog {
    iwdg: pac::IWDG,
}

impl Watchdog {
    pub fn new(iwdg: pac::IWDG) -> Self {
        Self { iwdg }
    }

    /// Programs `setting` and starts the watchdog (for good). The prescaler and reload
    /// registers take up to five LSI cycles to update (SR.PVU/RVU, up to 0.3 ms at the
    /// slowest LSI); until then the previous values hold, which are the reset ones (the
    /// longest timeout, 0.5 s) at boot, so nothing waits for it here. A feed writes the
    /// new reload value into the counter once it is in.
    pub fn start(&mut self, setting: IwdgSetting) {
        write_setting(&self.iwdg, setting);
        let kr = self.iwdg.kr();
        kr.write(|w| w.key().start());
        kr.write(|w| w.key().feed());
    }

    /// Reloads the counter.
    #[inline(always)]
    pub fn feed(&mut self) {
        self.iwdg.kr().write(|w| w.key().feed());
    }
}

/// Unlock PR and RLR and write `setting` into them (they stay unlocked until the next key).
fn write_setting(iwdg: &pac::IWDG, setting: IwdgSetting) {
    iwdg.kr().write(|w| w.key().unlock());
    // SAFETY: any 3-bit value is a valid prescaler (6 and 7 both divide by 256).
    iwdg.pr()
        .write(|w| unsafe { w.pr().bits(setting.pr & 0b111) });
    iwdg.rlr().write(|w| w.rl().set(setting.reload));
}

/// Polls of IWDG_SR before giving up on a register update (each poll is a few cycles; an
/// update takes up to 5 LSI cycles, 0.3 ms at the slowest LSI, ~50,000 cycles at 168 MHz).
const UPDATE_POLLS: u32 = 1_000_000;

/// The link task's hold on the IWDG's timeout, for a settings save: the flash erase
/// stalls the CPU for seconds and nobody can feed the watchdog then. The control task
/// keeps feeding through [`Watchdog`]; this only reprograms the prescaler and reload.
///
/// Sharing the peripheral is sound because the control task only ever writes the feed
/// key to IWDG_KR, and a reprogramming here (unlock key, PR, RLR) runs with interrupts
/// off, so a feed (which locks PR and RLR again) cannot fall between the unlock and the
/// writes.
pub struct WatchdogStretch {
    iwdg: pac::IWDG,
    normal: IwdgSetting,
    long: IwdgSetting,
}

impl WatchdogStretch {
    /// # Safety
    /// The only other user of the IWDG must be a [`Watchdog`] (feeds only).
    pub unsafe fn new(normal: IwdgSetting, long: IwdgSetting) -> Self {
        Self {
            // SAFETY: see the type's docs (the caller's contract)
            iwdg: unsafe { pac::IWDG::steal() },
            normal,
            long,
        }
    }

    /// Switch to the long timeout and wait until it is in force (a feed loads it).
    /// `false`: the IWDG did not take it (its registers stayed busy), do not erase.
    pub fn stretch(&mut self) -> bool {
        self.program(self.long)
    }

    /// Back to the control rate's timeout.
    pub fn restore(&mut self) -> bool {
        self.program(self.normal)
    }

    fn program(&mut self, setting: IwdgSetting) -> bool {
        // PR and RLR can be written only while no update of them is pending
        if !self.settled() {
            return false;
        }
        cortex_m::interrupt::free(|_| {
            write_setting(&self.iwdg, setting);
            // (the feed key also write-protects PR and RLR again)
            self.iwdg.kr().write(|w| w.key().feed());
        });
        if !self.settled() {
            return false;
        }
        // the counter restarts from the new reload
        self.iwdg.kr().write(|w| w.key().feed());
        true
    }

    /// No prescaler or reload update pending (bounded wait).
    fn settled(&self) -> bool {
        settled(&self.iwdg)
    }
}

/// No prescaler or reload update pending (bounded wait).
fn settled(iwdg: &pac::iwdg::RegisterBlock) -> bool {
    for _ in 0..UPDATE_POLLS {
        let sr = iwdg.sr().read();
        if !sr.pvu().bit_is_set() && !sr.rvu().bit_is_set() {
            return true;
        }
    }
    false
}

/// The prescaler and reload written at start have reached the IWDG (bounded wait): PR and
/// RLR then read back what was written (the boot self-check reads them).
pub fn updates_settled() -> bool {
    // SAFETY: only the status register is read (no side effects); the writers of PR/RLR
    // (start, the save stretch) are not running during `init`.
    settled(unsafe { &*pac::IWDG::ptr() })
}
