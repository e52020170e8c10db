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
        let kr = self.iwdg.kr();
        kr.write(|w| w.key().unlock());
        // SAFETY: any 3-bit value is a valid prescaler (6 and 7 both divide by 256).
        self.iwdg
            .pr()
            .write(|w| unsafe { w.pr().bits(setting.pr & 0b111) });
        self.iwdg.rlr().write(|w| w.rl().set(setting.reload));
        kr.write(|w| w.key().start());
        kr.write(|w| w.key().feed());
    }

    /// Reloads the counter.
    #[inline(always)]
    pub fn feed(&mut self) {
        self.iwdg.kr().write(|w| w.key().feed());
    }
}
