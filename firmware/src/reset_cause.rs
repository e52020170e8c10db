//! Why the chip last reset, from RCC_CSR's reset flags (RM0090 6.3.21): read once at boot,
//! logged, cleared (RMVF) so the next boot reports its own cause.

/// RCC_CSR reset flags (bits 25..31).
const BORRSTF: u32 = 1 << 25;
const PINRSTF: u32 = 1 << 26;
const PORRSTF: u32 = 1 << 27;
const SFTRSTF: u32 = 1 << 28;
const IWDGRSTF: u32 = 1 << 29;
const WWDGRSTF: u32 = 1 << 30;
const LPWRRSTF: u32 = 1 << 31;

/// The cause of the last reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ResetCause {
    /// The independent watchdog expired: the control loop stopped feeding it.
    Watchdog,
    /// The window watchdog (the firmware does not use it).
    WindowWatchdog,
    /// Software: SYSRESETREQ (a probe's reset, a firmware-requested reset).
    Software,
    /// An illegal low-power entry.
    LowPower,
    /// The supply fell below the brown-out level.
    BrownOut,
    /// Power-on (the supply came up).
    PowerOn,
    /// The NRST pin (the reset button, a probe holding it).
    Pin,
    /// No flag set (the flags were cleared and nothing reset the chip since).
    Unknown,
}

impl ResetCause {
    /// The cause from RCC_CSR. Every internal reset also drives NRST, so PINRSTF comes
    /// with all of them and counts only alone; a brown-out comes with a power-on.
    pub fn from_csr(csr: u32) -> Self {
        if csr & IWDGRSTF != 0 {
            Self::Watchdog
        } else if csr & WWDGRSTF != 0 {
            Self::WindowWatchdog
        } else if csr & SFTRSTF != 0 {
            Self::Software
        } else if csr & LPWRRSTF != 0 {
            Self::LowPower
        } else if csr & PORRSTF != 0 {
            Self::PowerOn
        } else if csr & BORRSTF != 0 {
            Self::BrownOut
        } else if csr & PINRSTF != 0 {
            Self::Pin
        } else {
            Self::Unknown
        }
    }

    /// The name the boot log gives (`reset cause: <name>`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Watchdog => "watchdog",
            Self::WindowWatchdog => "window watchdog",
            Self::Software => "software",
            Self::LowPower => "low power",
            Self::BrownOut => "brown-out",
            Self::PowerOn => "power-on",
            Self::Pin => "reset pin",
            Self::Unknown => "unknown",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flags_a_reset_leaves_name_its_cause() {
        // RM0090: a power-on sets PORRSTF, BORRSTF and PINRSTF (0x0E00_0000, the reset value)
        assert_eq!(ResetCause::from_csr(0x0E00_0000), ResetCause::PowerOn);
        // the IWDG also pulls NRST
        assert_eq!(
            ResetCause::from_csr(IWDGRSTF | PINRSTF),
            ResetCause::Watchdog
        );
        assert_eq!(
            ResetCause::from_csr(SFTRSTF | PINRSTF),
            ResetCause::Software
        );
        assert_eq!(ResetCause::from_csr(PINRSTF), ResetCause::Pin);
        assert_eq!(
            ResetCause::from_csr(BORRSTF | PINRSTF),
            ResetCause::BrownOut
        );
        assert_eq!(ResetCause::from_csr(0), ResetCause::Unknown);
        assert_eq!(ResetCause::from_csr(IWDGRSTF | PINRSTF).name(), "watchdog");
    }
}
