//! Encoder index captures taken in an interrupt and read by the control period: the
//! board's Y axis, whose encoder timer (TIM5) has no free capture channel, so an EXTI
//! interrupt reads TIM5_CNT at the index edge (`board::index` in the binary).
//!
//! - [`IndexMailbox`]: the lock-free handoff from that interrupt (the only writer) to the
//!   control task (the only reader), which never blocks either side and never loses the
//!   newest capture.
//! - [`StormGuard`]: decides, from the gaps between captures, when the index line is
//!   noise rather than an encoder (an interrupt storm at the highest priority would starve
//!   the control task), so that the interrupt can mask its line.
//!
//! Why atomics rather than an RTIC shared resource: the writer runs at the highest
//! priority to keep its capture latency short; a shared resource would make the control
//! task's access a lock that raises BASEPRI to the writer's priority, delaying the very
//! capture whose latency matters (by little, but for nothing: a sequence count makes the
//! handoff exact without any masking).

use core::sync::atomic::{AtomicU32, Ordering};

/// The newest index capture, handed from one interrupt (writer) to one task (reader).
///
/// Contract (what makes it exact; breaking it is no memory-safety issue, the reader could
/// only get a value of a different capture): one writer context, one reader context, and
/// the writer preempts the reader, never the other way round (the writer is an interrupt
/// of a higher priority than the reader's; single core).
///
/// The writer stores the value, then increments the capture count (`published`). The
/// reader takes a value only if the count did not change while it read the value (a
/// sequence lock whose writer can never be interrupted by the reader, so it never waits).
pub struct IndexMailbox {
    /// Captures published so far (wrapping); written last by [`Self::publish`].
    published: AtomicU32,
    /// The newest capture's counter value.
    value: AtomicU32,
}

impl IndexMailbox {
    /// No capture yet.
    pub const fn new() -> Self {
        Self {
            published: AtomicU32::new(0),
            value: AtomicU32::new(0),
        }
    }

    /// The writer: a capture of `raw` (the counter register at the index edge). Two plain
    /// stores (value, then count with release ordering, so the value is written first).
    #[inline(always)]
    pub fn publish(&self, raw: u32) {
        self.value.store(raw, Ordering::Relaxed);
        // only this context writes `published`: a load and a store need no
        // read-modify-write instruction
        let n = self.published.load(Ordering::Relaxed).wrapping_add(1);
        self.published.store(n, Ordering::Release);
    }
}

impl Default for IndexMailbox {
    fn default() -> Self {
        Self::new()
    }
}

/// The reader's side of an [`IndexMailbox`]: which capture it took last.
pub struct IndexReader {
    /// `published` as of the last capture taken.
    taken: u32,
}

/// Where [`IndexReader::take_with`] lets a test run the writer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadStep {
    /// After a load of the capture count.
    Count,
    /// After the load of the value, before the count is loaded again.
    Value,
}

impl IndexReader {
    /// Nothing taken yet (a mailbox starts with no capture).
    pub const fn new() -> Self {
        Self { taken: 0 }
    }

    /// The newest capture published since the last `take`, if any.
    ///
    /// Bounded and lock-free: at most two attempts. An attempt fails only if the writer
    /// published again between its two loads of the count (two index edges within a few
    /// cycles: noise); after two failures it returns `None` and the capture is taken by
    /// the next call instead, with its value intact.
    #[inline(always)]
    pub fn take(&mut self, mailbox: &IndexMailbox) -> Option<u32> {
        self.take_with(mailbox, |_| {})
    }

    /// [`Self::take`] with `between` called at each point where the writer may preempt
    /// the reader (a no-op in the firmware; tests publish there).
    #[inline(always)]
    pub fn take_with(
        &mut self,
        mailbox: &IndexMailbox,
        mut between: impl FnMut(ReadStep),
    ) -> Option<u32> {
        // Acquire loads keep the three loads in program order: the value is read after
        // the first count and before the second.
        let mut count = mailbox.published.load(Ordering::Acquire);
        between(ReadStep::Count);
        for _ in 0..2 {
            if count == self.taken {
                return None;
            }
            let value = mailbox.value.load(Ordering::Acquire);
            between(ReadStep::Value);
            let again = mailbox.published.load(Ordering::Acquire);
            between(ReadStep::Count);
            if again == count {
                // no publish between the loads: `value` is capture `count`'s
                self.taken = count;
                return Some(value);
            }
            count = again;
        }
        None
    }
}

impl Default for IndexReader {
    fn default() -> Self {
        Self::new()
    }
}

/// Gap below which two index captures are noise, µs. An encoder's index comes once per
/// revolution: 8000 counts (a 2000-line encoder read ×4, 5 mm of lead), 20 ms apart at the
/// gantry's top speed (250 mm/s × 1600 counts/mm = 400 k counts/s), 18 ms at the
/// overspeed trip; 10 µs is 1800 times shorter.
pub const STORM_GAP_US: u32 = 10;

/// Captures in a row, each closer than [`STORM_GAP_US`] to the one before, that make the
/// line noise: the interrupt then masks it.
pub const STORM_STRIKES: u32 = 8;

/// Detects an index line that is noise (a floating or ringing input), from the gaps
/// between its captures, so the interrupt can mask its line before it starves the control
/// task. Bounded cost either way: until [`STORM_STRIKES`] close captures in a row, every
/// capture costs one interrupt; captures further apart than the gap cost at most one
/// interrupt (well under a microsecond) per [`STORM_GAP_US`], a few per cent of the CPU.
pub struct StormGuard {
    /// [`STORM_GAP_US`] in the clock of `now` (core cycles on the board).
    gap: u32,
    /// The previous capture's time, if any.
    last: Option<u32>,
    /// Close captures in a row.
    strikes: u32,
}

impl StormGuard {
    /// A guard for a clock of `clock_hz` (the time passed to [`Self::on_capture`]).
    pub const fn new(clock_hz: u32) -> Self {
        Self {
            gap: (clock_hz / 1_000_000).saturating_mul(STORM_GAP_US),
            last: None,
            strikes: 0,
        }
    }

    /// A capture at `now` (a free-running wrapping counter, e.g. DWT_CYCCNT); `true` when
    /// the line is to be masked (the [`STORM_STRIKES`]th close capture in a row).
    #[inline(always)]
    pub fn on_capture(&mut self, now: u32) -> bool {
        let close = matches!(self.last, Some(last) if now.wrapping_sub(last) < self.gap);
        self.last = Some(now);
        self.strikes = if close {
            self.strikes.saturating_add(1)
        } else {
            0
        };
        self.strikes >= STORM_STRIKES
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_capture_is_taken_once() {
        let m = IndexMailbox::new();
        let mut r = IndexReader::new();
        assert_eq!(r.take(&m), None);
        m.publish(1234);
        assert_eq!(r.take(&m), Some(1234));
        assert_eq!(r.take(&m), None);
        m.publish(0);
        assert_eq!(r.take(&m), Some(0), "a capture at count 0 is a capture");
        assert_eq!(r.take(&m), None);
    }

    #[test]
    fn two_captures_between_takes_give_the_newest() {
        let m = IndexMailbox::new();
        let mut r = IndexReader::new();
        m.publish(10);
        m.publish(8010);
        assert_eq!(r.take(&m), Some(8010));
        assert_eq!(r.take(&m), None);
    }

    #[test]
    fn the_same_value_captured_again_is_a_new_capture() {
        // an axis going back and forth over its index captures the same count
        let m = IndexMailbox::new();
        let mut r = IndexReader::new();
        m.publish(u32::MAX);
        assert_eq!(r.take(&m), Some(u32::MAX));
        m.publish(u32::MAX);
        assert_eq!(r.take(&m), Some(u32::MAX));
    }

    #[test]
    fn the_capture_count_wraps() {
        let m = IndexMailbox::new();
        m.published.store(u32::MAX - 1, Ordering::Relaxed);
        let mut r = IndexReader {
            taken: u32::MAX - 1,
        };
        for v in 0..4 {
            m.publish(v);
            assert_eq!(r.take(&m), Some(v));
            assert_eq!(r.take(&m), None);
        }
    }

    /// The writer preempting the reader at every point, once: nothing lost, nothing
    /// twice, never an old value with a new count.
    #[test]
    fn a_publish_preempting_the_reader_anywhere_is_neither_lost_nor_doubled() {
        for at in 0..5 {
            for before in [false, true] {
                let m = IndexMailbox::new();
                let mut r = IndexReader::new();
                if before {
                    m.publish(100);
                }
                let mut point = 0;
                let got = r.take_with(&m, |_| {
                    if point == at {
                        m.publish(200);
                    }
                    point += 1;
                });
                if point <= at {
                    // the take was over before that point: the publish comes after it
                    m.publish(200);
                }
                // whatever this take returned, the next one returns the rest, and then
                // nothing: the newest (200) is seen exactly once, last
                let next = r.take(&m);
                assert_eq!(r.take(&m), None, "at {at}, before {before}");
                match (got, next) {
                    (Some(200), None) | (Some(100), Some(200)) => {}
                    (None, Some(200)) if !before => {}
                    other => panic!("at {at}, before {before}: {other:?}"),
                }
                if !before {
                    assert_ne!(got, Some(100));
                }
            }
        }
    }

    #[test]
    fn a_reader_preempted_on_every_load_gives_up_and_the_next_take_gets_the_newest() {
        let m = IndexMailbox::new();
        let mut r = IndexReader::new();
        m.publish(1);
        let mut v = 1;
        let got = r.take_with(&m, |step| {
            if step == ReadStep::Value {
                v += 1;
                m.publish(v);
            }
        });
        assert_eq!(got, None, "two attempts, both torn");
        assert_eq!(r.take(&m), Some(v));
        assert_eq!(r.take(&m), None);
    }

    #[test]
    fn index_pulses_never_trip_the_storm_guard() {
        const CLOCK: u32 = 168_000_000;
        let mut g = StormGuard::new(CLOCK);
        // one revolution per 18 ms (the overspeed trip), for a while, across the wrap
        let mut now = u32::MAX - 10 * 3_024_000;
        for _ in 0..1000 {
            assert!(!g.on_capture(now));
            now = now.wrapping_add(3_024_000);
        }
        // nor a double edge (a bounce) now and then
        for _ in 0..100 {
            assert!(!g.on_capture(now));
            assert!(!g.on_capture(now.wrapping_add(100)));
            now = now.wrapping_add(3_024_000);
        }
    }

    #[test]
    fn noise_on_the_index_line_trips_the_storm_guard_after_the_strikes() {
        const CLOCK: u32 = 168_000_000;
        let gap = CLOCK / 1_000_000 * STORM_GAP_US;
        let mut g = StormGuard::new(CLOCK);
        let mut now = 5;
        assert!(!g.on_capture(now));
        for i in 1..=STORM_STRIKES {
            now = now.wrapping_add(gap - 1);
            assert_eq!(g.on_capture(now), i == STORM_STRIKES, "strike {i}");
        }
        // one capture at exactly the gap is no strike
        let mut g = StormGuard::new(CLOCK);
        for k in 0..100 {
            assert!(!g.on_capture(k * gap));
        }
    }
}
