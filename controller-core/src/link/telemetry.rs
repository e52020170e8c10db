//! Unreliable telemetry channel: the device numbers frames, the host counts what it lost.
//!
//! Telemetry is never acknowledged or retransmitted (a late sample is worth less than
//! the next one, and retransmission would steal bandwidth from it: Klipper does the
//! same MCU → host). [`TelemetryReceiver`] classifies each frame by its [`Seq`] against
//! the newest one seen and a 32-frame history bitmap:
//!
//! - next in order: delivered;
//! - a jump of `d` ahead: `d - 1` frames counted lost;
//! - behind the newest but inside the history and not seen yet: late (reordered); it
//!   was counted lost when the jump happened, so the lost count is corrected;
//! - seen already: duplicate;
//! - further behind than the history: stale (cannot tell late from duplicate).

use super::seq::Seq;

/// Frames remembered behind the newest for reorder/duplicate detection.
pub const TELEMETRY_HISTORY: u16 = 32;

/// Device side: numbers telemetry frames.
#[derive(Clone, Copy, Debug, Default)]
pub struct TelemetrySender {
    next: Seq,
}

impl TelemetrySender {
    /// Numbering starts at `first`.
    #[must_use]
    pub const fn new(first: Seq) -> Self {
        Self { next: first }
    }

    /// Number for the next frame (advances).
    pub fn next_seq(&mut self) -> Seq {
        let s = self.next;
        self.next = s.next();
        s
    }
}

/// How a received telemetry frame relates to the ones before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arrival {
    /// The first frame seen, or the next in order.
    InOrder,
    /// Ahead of the next expected: `lost` frames were skipped (counted lost).
    Gap {
        /// Frames missing before this one.
        lost: u16,
    },
    /// Behind the newest, not seen before: arrived late (reordered).
    Late,
    /// Seen before.
    Duplicate,
    /// Further behind than [`TELEMETRY_HISTORY`] frames: cannot be classified.
    Stale,
}

impl Arrival {
    /// True for frames worth handing to the application (new data).
    #[must_use]
    pub const fn is_new(self) -> bool {
        matches!(self, Self::InOrder | Self::Gap { .. } | Self::Late)
    }
}

/// Host counters of the telemetry channel (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TelemetryStats {
    /// Distinct frames received.
    pub received: u32,
    /// Frames never received (gaps net of late arrivals).
    pub lost: u32,
    /// Frames that arrived behind a newer one.
    pub late: u32,
    /// Duplicates.
    pub duplicates: u32,
    /// Stale frames (further behind than the history).
    pub stale: u32,
}

/// Host side: gap, reorder and duplicate accounting.
#[derive(Clone, Copy, Debug, Default)]
pub struct TelemetryReceiver {
    newest: Option<Seq>,
    /// Bit `i` set: frame `newest - i` was received (bit 0 is `newest` itself).
    seen: u32,
    stats: TelemetryStats,
}

impl TelemetryReceiver {
    /// Nothing seen yet.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            newest: None,
            seen: 0,
            stats: TelemetryStats {
                received: 0,
                lost: 0,
                late: 0,
                duplicates: 0,
                stale: 0,
            },
        }
    }

    /// Counters.
    #[must_use]
    pub const fn stats(&self) -> TelemetryStats {
        self.stats
    }

    /// Forget the sequence history (new session: the device may restart its numbering).
    /// Counters stay.
    pub fn resync(&mut self) {
        self.newest = None;
        self.seen = 0;
    }

    /// Classify frame `seq` and update the counters.
    pub fn on_frame(&mut self, seq: Seq) -> Arrival {
        let Some(newest) = self.newest else {
            self.newest = Some(seq);
            self.seen = 1;
            self.stats.received = self.stats.received.saturating_add(1);
            return Arrival::InOrder;
        };
        let d = seq.diff(newest);
        if d > 0 {
            let ahead = d.unsigned_abs();
            self.seen = if u32::from(ahead) < u32::BITS {
                (self.seen << ahead) | 1
            } else {
                1
            };
            self.newest = Some(seq);
            self.stats.received = self.stats.received.saturating_add(1);
            let lost = ahead - 1;
            self.stats.lost = self.stats.lost.saturating_add(u32::from(lost));
            return if lost == 0 {
                Arrival::InOrder
            } else {
                Arrival::Gap { lost }
            };
        }
        let behind = d.unsigned_abs();
        if behind >= TELEMETRY_HISTORY {
            self.stats.stale = self.stats.stale.saturating_add(1);
            return Arrival::Stale;
        }
        let bit = 1u32 << behind;
        if self.seen & bit != 0 {
            self.stats.duplicates = self.stats.duplicates.saturating_add(1);
            Arrival::Duplicate
        } else {
            self.seen |= bit;
            self.stats.received = self.stats.received.saturating_add(1);
            self.stats.late = self.stats.late.saturating_add(1);
            self.stats.lost = self.stats.lost.saturating_sub(1);
            Arrival::Late
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feed(seqs: &[u16]) -> (TelemetryReceiver, [Arrival; 8]) {
        let mut r = TelemetryReceiver::new();
        let mut out = [Arrival::Stale; 8];
        for (o, &s) in out.iter_mut().zip(seqs) {
            *o = r.on_frame(Seq(s));
        }
        (r, out)
    }

    #[test]
    fn gaps_are_counted_as_lost() {
        let (r, a) = feed(&[10, 11, 14, 15, 20]);
        assert_eq!(a[2], Arrival::Gap { lost: 2 });
        assert_eq!(a[4], Arrival::Gap { lost: 4 });
        assert_eq!(r.stats().lost, 6);
        assert_eq!(r.stats().received, 5);
    }

    #[test]
    fn late_frames_correct_the_lost_count_and_duplicates_are_flagged() {
        let (r, a) = feed(&[1, 2, 5, 3, 3, 4, 5, 6]);
        assert_eq!(a[2], Arrival::Gap { lost: 2 });
        assert_eq!(a[3], Arrival::Late);
        assert_eq!(a[4], Arrival::Duplicate);
        assert_eq!(a[5], Arrival::Late);
        assert_eq!(a[6], Arrival::Duplicate);
        assert_eq!(a[7], Arrival::InOrder);
        let s = r.stats();
        assert_eq!((s.received, s.lost, s.late, s.duplicates), (6, 0, 2, 2));
    }

    #[test]
    fn counting_works_across_the_wrap() {
        let (r, a) = feed(&[65533, 65534, 1, 65535, 0, 2]);
        assert_eq!(a[2], Arrival::Gap { lost: 2 });
        assert_eq!(a[3], Arrival::Late);
        assert_eq!(a[4], Arrival::Late);
        assert_eq!(a[5], Arrival::InOrder);
        assert_eq!(r.stats().lost, 0);
        assert_eq!(r.stats().received, 6);
    }

    #[test]
    fn frames_beyond_the_history_are_stale() {
        let (r, a) = feed(&[100, 200, 150, 168, 169]);
        assert_eq!(a[1], Arrival::Gap { lost: 99 });
        assert_eq!(a[2], Arrival::Stale); // 50 behind
        assert_eq!(a[3], Arrival::Stale); // 32 behind: just outside the history
        assert_eq!(a[4], Arrival::Late); // 31 behind: the oldest frame inside it
        assert_eq!(r.stats().stale, 2);
        assert_eq!(r.stats().lost, 98);
    }
}
