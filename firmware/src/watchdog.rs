//! Timing of the independent watchdog (IWDG): the prescaler and reload value the board
//! programs, chosen from the control rate and the tolerance of the IWDG's clock.
//!
//! The IWDG counts the LSI RC oscillator, which the STM32F407 datasheet (DS8626, "LSI
//! oscillator characteristics") specifies as 17 kHz min, 32 kHz typ, 47 kHz max over
//! voltage and temperature. The control interrupt feeds the watchdog at the end of every
//! period that ran on time ([`crate::telemetry`] counts the others), so the watchdog
//! bites when the control interrupt stops running, or keeps missing its deadline, for
//! longer than the timeout.
//!
//! The timeout must not bite on an occasional late period (the servo's overrun monitor
//! handles those: a deadline-overrun fault after 3 overruns within 100 ms), so it is at
//! least [`MIN_TIMEOUT_PERIODS`] control periods and at least [`MIN_TIMEOUT_US`], both
//! counted at the *fastest* LSI. Shorter is better otherwise: that is how long PWM and
//! drive enables can stay as they were after the CPU stops running the control
//! interrupt (with TIM1's break input and the drives' own enable chain as the hardware
//! layers below). At the 10 kHz default the result is 2.0 ms at 47 kHz, 3.0 ms at the
//! typical 32 kHz and 5.6 ms at 17 kHz.

/// Slowest LSI the datasheet allows, Hz.
pub const LSI_MIN_HZ: u32 = 17_000;
/// Typical LSI, Hz.
pub const LSI_TYP_HZ: u32 = 32_000;
/// Fastest LSI the datasheet allows, Hz.
pub const LSI_MAX_HZ: u32 = 47_000;

/// The timeout is at least this long at the fastest LSI, µs: room for the longest
/// interrupt-disabled stretch outside the control task (RTIC's ceiling locks around plain
/// copies, a few µs) and start-up, with a wide margin.
pub const MIN_TIMEOUT_US: u32 = 2_000;

/// The timeout spans at least this many control periods at the fastest LSI, so a single
/// late period (which skips one feed) never resets the board.
pub const MIN_TIMEOUT_PERIODS: u32 = 5;

/// Largest reload value (IWDG_RLR is 12 bits).
pub const RELOAD_MAX: u16 = 0x0FFF;

/// A prescaler and reload setting of the IWDG.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IwdgSetting {
    /// IWDG_PR code: the LSI is divided by `4 << pr` (0..=6).
    pub pr: u8,
    /// IWDG_RLR: the counter counts `reload + 1` prescaled ticks down to zero.
    pub reload: u16,
}

impl IwdgSetting {
    /// LSI divider of the prescaler code.
    pub const fn divider(&self) -> u32 {
        4 << self.pr
    }

    /// Timeout with the LSI at `lsi_hz`, µs (rounded down).
    pub const fn timeout_us(&self, lsi_hz: u32) -> u32 {
        let ticks = (self.reload as u64 + 1) * self.divider() as u64;
        (ticks * 1_000_000 / lsi_hz as u64) as u32
    }
}

/// The timeout while a settings save writes the flash, at least this long at the fastest
/// LSI, µs: twice the worst erase of a 128 KiB sector (4 s, DS8626), during which the
/// CPU stalls and nothing can feed the watchdog. (At the slowest LSI it is 22.1 s.)
pub const SAVE_TIMEOUT_US: u32 = 8_000_000;

/// The shortest timeout that is at least `max(MIN_TIMEOUT_US, MIN_TIMEOUT_PERIODS
/// periods)` at the fastest LSI, for a control rate of `control_hz` (100..=50 000 Hz).
pub const fn iwdg_setting(control_hz: u32) -> IwdgSetting {
    let hz = if control_hz == 0 { 1 } else { control_hz };
    let periods_us = MIN_TIMEOUT_PERIODS as u64 * 1_000_000 / hz as u64;
    let need_us = if periods_us > MIN_TIMEOUT_US as u64 {
        periods_us
    } else {
        MIN_TIMEOUT_US as u64
    };
    shortest_setting(need_us)
}

/// The timeout the board switches to around a settings save (outputs off): at least
/// [`SAVE_TIMEOUT_US`] at the fastest LSI.
pub const fn iwdg_save_setting() -> IwdgSetting {
    shortest_setting(SAVE_TIMEOUT_US as u64)
}

/// The shortest setting whose timeout is at least `need_us` at the fastest LSI (the
/// longest setting when none is).
const fn shortest_setting(need_us: u64) -> IwdgSetting {
    let mut pr = 0u8;
    while pr <= 6 {
        let div = 4u64 << pr;
        // prescaled ticks at the fastest LSI, rounded up
        let ticks = (need_us * LSI_MAX_HZ as u64).div_ceil(div * 1_000_000);
        if ticks <= RELOAD_MAX as u64 + 1 {
            let reload = if ticks == 0 { 0 } else { ticks - 1 };
            return IwdgSetting {
                pr,
                reload: reload as u16,
            };
        }
        pr += 1;
    }
    IwdgSetting {
        pr: 6,
        reload: RELOAD_MAX,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_rate_gives_two_to_six_ms() {
        let s = iwdg_setting(10_000);
        assert_eq!(s, IwdgSetting { pr: 0, reload: 23 });
        assert_eq!(s.timeout_us(LSI_MAX_HZ), 2_042);
        assert_eq!(s.timeout_us(LSI_TYP_HZ), 3_000);
        assert_eq!(s.timeout_us(LSI_MIN_HZ), 5_647);
    }

    #[test]
    fn every_rate_keeps_the_bounds_and_is_shortest() {
        for hz in (100..=50_000).step_by(100) {
            let s = iwdg_setting(hz);
            let period_us = 1_000_000 / hz;
            let fastest = s.timeout_us(LSI_MAX_HZ);
            assert!(fastest >= MIN_TIMEOUT_US, "{hz} Hz: {fastest} us");
            assert!(fastest >= MIN_TIMEOUT_PERIODS * period_us, "{hz} Hz");
            // one tick less would be too short: the setting is the shortest that fits
            if s.reload > 0 {
                let shorter = IwdgSetting {
                    reload: s.reload - 1,
                    ..s
                };
                let t = shorter.timeout_us(LSI_MAX_HZ);
                assert!(t < MIN_TIMEOUT_US.max(MIN_TIMEOUT_PERIODS * period_us));
            }
            assert!(s.pr <= 6 && s.reload <= RELOAD_MAX);
        }
        // the slowest rate: 5 periods of 10 ms = 50 ms, still well inside the range
        let s = iwdg_setting(100);
        assert_eq!(s.timeout_us(LSI_MAX_HZ), 50_042);
        assert_eq!(s.timeout_us(LSI_MIN_HZ), 138_352);
    }

    #[test]
    fn the_save_timeout_outlasts_two_worst_sector_erases() {
        let s = iwdg_save_setting();
        assert_eq!(
            s,
            IwdgSetting {
                pr: 5,
                reload: 2937
            }
        );
        let fastest = s.timeout_us(LSI_MAX_HZ);
        assert!(
            (SAVE_TIMEOUT_US..SAVE_TIMEOUT_US + 10_000).contains(&fastest),
            "{fastest}"
        );
        assert_eq!(s.timeout_us(LSI_MIN_HZ), 22_121_411);
    }
}
