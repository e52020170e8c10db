//! The link's clock on the device: milliseconds of machine time, counted from control
//! periods.
//!
//! Every device end (the board's control interrupt, the QEMU link rig, the simulated
//! machine of `gantry --sim`) times its link — watchdog, retransmissions, timeouts — in
//! control periods, so the link keeps the machine's time whatever the emulator's or the
//! simulation's speed. [`LinkClock`] is that count in one place: after `n` periods at
//! `rate_hz` it reads ⌊n · 1000 / rate_hz⌋ ms, wrapping at 2³² ms like every link time.
//! It needs no division: each period carries 1000 into a remainder below the rate, which
//! suits the control interrupt.

/// Machine time in ms, advanced once per control period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkClock {
    rate_hz: u32,
    ms: u32,
    /// Periods' worth of ms beyond `ms`, times the rate (always below `rate_hz`).
    sub: u32,
}

impl LinkClock {
    /// A clock at 0 ms for control periods at `rate_hz` (0 is taken as 1 Hz).
    #[must_use]
    pub const fn new(rate_hz: u32) -> Self {
        Self {
            rate_hz: if rate_hz == 0 { 1 } else { rate_hz },
            ms: 0,
            sub: 0,
        }
    }

    /// One control period has run: the new time, ms.
    #[inline]
    pub fn period(&mut self) -> u32 {
        // 1000 ms per `rate_hz` periods, carried (at rates below 1 kHz a period is
        // several ms); `sub` stays below the rate, so the sum only wraps for rates
        // within 1000 of 2³², which no control loop runs at
        self.sub = self.sub.wrapping_add(1000);
        while self.sub >= self.rate_hz {
            self.sub -= self.rate_hz;
            self.ms = self.ms.wrapping_add(1);
        }
        self.ms
    }

    /// The time now, ms.
    #[must_use]
    pub const fn ms(&self) -> u32 {
        self.ms
    }
}

#[cfg(test)]
mod tests {
    use super::LinkClock;

    /// The carried count is the exact quotient, at rates above and below 1 kHz.
    #[test]
    fn counts_whole_ms_of_the_periods_run() {
        for rate_hz in [1, 100, 999, 1000, 1001, 7_919, 10_000, 20_000, 50_000] {
            let mut clock = LinkClock::new(rate_hz);
            for n in 1..=3 * u64::from(rate_hz) + 17 {
                let ms = clock.period();
                assert_eq!(u64::from(ms), n * 1000 / u64::from(rate_hz), "{rate_hz} Hz");
                assert_eq!(clock.ms(), ms);
            }
        }
        assert_eq!(LinkClock::new(0), LinkClock::new(1));
    }

    /// Past 2³² ms the time wraps, as every link time does.
    #[test]
    fn wraps_at_two_to_the_32_ms() {
        let mut clock = LinkClock {
            rate_hz: 1000,
            ms: u32::MAX,
            sub: 0,
        };
        assert_eq!(clock.period(), 0);
    }
}
