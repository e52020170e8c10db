//! Heartbeat watchdog: notices a silent link.
//!
//! Fed by every valid frame from the other end (a frame that passed CRC and parsing; a
//! stream of garbage does not keep it alive). On an idle link the host sends a
//! [`super::ToDevice::Heartbeat`] every [`Watchdog::heartbeat_interval_ms`], a quarter of
//! the timeout, so three heartbeats in a row can be lost before it expires.
//!
//! The watchdog only reports ([`Watchdog::expired`]); the device's supervisor turns expiry
//! into a controlled stop and a `LinkLost` fault (every controller in the comparison added
//! stop-on-comm-loss after users asked for it). It is armed when a session starts: a board
//! nobody has talked to yet is not "lost".

use super::LinkConfigError;

/// Watchdog settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct WatchdogConfig {
    /// Silence after which the link counts as lost (ms), in `MIN..=MAX` below.
    pub timeout_ms: u32,
}

/// 500 ms: long enough for a host hiccup (a USB-serial stall, a GC pause in a GUI) with
/// heartbeats every 125 ms, short enough that an axis at 100 mm/s moves at most 50 mm
/// before the controlled stop starts (ODrive's watchdog is user-set, often 0.1-1 s).
pub const DEFAULT_WATCHDOG_CONFIG: WatchdogConfig = WatchdogConfig { timeout_ms: 500 };

/// Shortest accepted timeout: 4 heartbeat intervals must each cover a worst-case frame
/// (2.9 ms) plus scheduling jitter.
pub const MIN_WATCHDOG_TIMEOUT_MS: u32 = 20;
/// Longest accepted timeout (1 minute).
pub const MAX_WATCHDOG_TIMEOUT_MS: u32 = 60_000;

impl WatchdogConfig {
    /// Check the settings.
    ///
    /// # Errors
    /// [`LinkConfigError`] when `timeout_ms` is outside the accepted range.
    pub const fn validate(&self) -> Result<(), LinkConfigError> {
        if self.timeout_ms < MIN_WATCHDOG_TIMEOUT_MS || self.timeout_ms > MAX_WATCHDOG_TIMEOUT_MS {
            return Err(LinkConfigError::OutOfRange("watchdog.timeout_ms"));
        }
        Ok(())
    }
}

/// The watchdog state.
#[derive(Clone, Copy, Debug)]
pub struct Watchdog {
    timeout_ms: u32,
    /// Time of the last feed; `None` while disarmed.
    last_fed_ms: Option<u32>,
}

impl Watchdog {
    /// A disarmed watchdog.
    ///
    /// # Errors
    /// [`LinkConfigError`] for a bad config.
    pub const fn new(config: &WatchdogConfig) -> Result<Self, LinkConfigError> {
        if let Err(e) = config.validate() {
            return Err(e);
        }
        Ok(Self {
            timeout_ms: config.timeout_ms,
            last_fed_ms: None,
        })
    }

    /// Start watching at `now_ms` (same as a feed).
    pub fn arm(&mut self, now_ms: u32) {
        self.last_fed_ms = Some(now_ms);
    }

    /// Stop watching (session ended).
    pub fn disarm(&mut self) {
        self.last_fed_ms = None;
    }

    /// True while armed.
    #[must_use]
    pub const fn is_armed(&self) -> bool {
        self.last_fed_ms.is_some()
    }

    /// A valid frame arrived at `now_ms`. Does nothing while disarmed.
    pub fn feed(&mut self, now_ms: u32) {
        if self.last_fed_ms.is_some() {
            self.last_fed_ms = Some(now_ms);
        }
    }

    /// True when armed and nothing fed it for `timeout_ms` or longer. Wrapping time:
    /// correct as long as it is polled at least once every 24 days.
    #[must_use]
    pub const fn expired(&self, now_ms: u32) -> bool {
        match self.last_fed_ms {
            Some(t) => now_ms.wrapping_sub(t) >= self.timeout_ms,
            None => false,
        }
    }

    /// The configured timeout (ms).
    #[must_use]
    pub const fn timeout_ms(&self) -> u32 {
        self.timeout_ms
    }

    /// How often the host sends heartbeats on an idle link: a quarter of the timeout.
    #[must_use]
    pub const fn heartbeat_interval_ms(&self) -> u32 {
        self.timeout_ms / 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expires_exactly_at_the_timeout_and_only_when_armed() {
        let mut w = Watchdog::new(&WatchdogConfig { timeout_ms: 100 }).unwrap();
        assert!(!w.expired(1_000_000));
        w.feed(0);
        assert!(!w.is_armed());
        w.arm(10);
        assert!(!w.expired(109));
        assert!(w.expired(110));
        w.feed(105);
        assert!(!w.expired(204));
        assert!(w.expired(205));
        w.disarm();
        assert!(!w.expired(10_000));
        assert_eq!(w.heartbeat_interval_ms(), 25);
    }

    #[test]
    fn works_across_the_millisecond_wrap() {
        let mut w = Watchdog::new(&WatchdogConfig { timeout_ms: 100 }).unwrap();
        w.arm(u32::MAX - 40);
        assert!(!w.expired(58));
        assert!(w.expired(59));
    }

    #[test]
    fn timeout_range_is_checked() {
        for (t, ok) in [(19, false), (20, true), (60_000, true), (60_001, false)] {
            assert_eq!(
                Watchdog::new(&WatchdogConfig { timeout_ms: t }).is_ok(),
                ok,
                "{t}"
            );
        }
    }
}
