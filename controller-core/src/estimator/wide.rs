//! Wrap-extension of hardware encoder counters.
//!
//! STM32 timers in encoder mode count in 16 bits (TIM3/TIM4) or 32 bits (TIM2/TIM5) and
//! wrap silently. The estimators take *wide* counts (`i64`, which no axis can overflow:
//! 2^63 counts of 0.625 µm is 5.8e9 km), so the wrap is undone here, once, by adding the
//! signed difference between successive raw readings. This is exact as long as the axis
//! moves less than half the counter range between two readings (32768 counts = 20 mm per
//! period for a 16-bit timer at 0.625 µm/count, far beyond any real axis).

/// Width of the hardware counter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum CounterWidth {
    Bits16,
    Bits32,
}

/// Turns successive raw counter readings into a wide, never-wrapping count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WideCounter {
    /// `32 - width`: the reading is kept in the top bits of a `u32`, so the difference of
    /// two readings wraps at the counter's width whatever it is (one code path, no
    /// per-reading dispatch on the width).
    shift: u32,
    /// The last reading shifted left by `shift` (a 16-bit timer's upper register bits fall
    /// off).
    last: u32,
    total: i64,
    /// The change of the wide count at the last reading: the counter's signed delta,
    /// within ±2^31 (half a 32-bit counter's range), so an exact `i32`.
    step: i32,
    /// The counter counts down when the axis moves forward (an encoder wired or mounted
    /// the other way round: the setting `axis.<a>.encoder.invert`): every delta is negated.
    inverted: bool,
}

impl WideCounter {
    /// Start at wide count `start` with the counter currently reading `raw` (a 16-bit
    /// counter's reading is taken modulo 2^16).
    pub fn new(width: CounterWidth, raw: u32, start: i64) -> Self {
        let shift = match width {
            CounterWidth::Bits16 => 16,
            CounterWidth::Bits32 => 0,
        };
        Self {
            shift,
            last: raw << shift,
            total: start,
            step: 0,
            inverted: false,
        }
    }

    /// Count the other way from the next reading on (the count so far stays: the count
    /// is continuous, its direction flips).
    pub fn set_inverted(&mut self, inverted: bool) {
        self.inverted = inverted;
    }

    pub fn inverted(&self) -> bool {
        self.inverted
    }

    /// Take a new raw reading; returns the wide count.
    #[inline]
    pub fn update(&mut self, raw: u32) -> i64 {
        // The signed difference modulo the counter width: a wrap between readings becomes
        // a small step of the right sign. In the top bits of a u32 the subtraction wraps
        // at the counter's width; the arithmetic shift back sign-extends it (for 16 bits:
        // `(raw - last) as u16 as i16`).
        let shifted = raw << self.shift;
        let delta = (shifted.wrapping_sub(self.last) as i32) >> self.shift;
        // (wrapping: a 32-bit counter's half-range step, i32::MIN, is ambiguous either way)
        let delta = if self.inverted {
            delta.wrapping_neg()
        } else {
            delta
        };
        self.last = shifted;
        // saturating (a wide count never wraps), the rare case kept off the common path
        match self.total.checked_add(i64::from(delta)) {
            Some(t) => {
                self.total = t;
                self.step = delta;
            }
            None => self.saturate(delta),
        }
        self.total
    }

    /// The wide count beyond `i64` (never on a machine: 2^63 counts of 0.625 µm are
    /// 5.8e9 km): it stays at the limit, and the step is what it actually moved.
    #[cold]
    #[inline(never)]
    fn saturate(&mut self, delta: i32) {
        let t = self.total.saturating_add(i64::from(delta));
        self.step = t.saturating_sub(self.total) as i32;
        self.total = t;
    }

    /// The change of the wide count at the last reading (0 before the first): the
    /// encoder's step over the last period, counts. Exact (`i32` holds any counter delta).
    pub fn step(&self) -> i32 {
        self.step
    }

    /// The wide count after the last reading.
    /// The wide count a register value `raw` read just after the last update stands for
    /// (an index pulse's captured count), without changing the counter.
    pub fn extend(&self, raw: u32) -> i64 {
        let mut probe = *self;
        probe.update(raw)
    }

    pub fn count(&self) -> i64 {
        self.total
    }

    /// Move the count's origin: the count becomes `count - shift` (homing re-bases an
    /// axis); the steps between readings are unchanged.
    pub fn rebase(&mut self, shift: i64) {
        self.total = self.total.saturating_sub(shift);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sixteen_bit_wrap_both_directions() {
        let mut w = WideCounter::new(CounterWidth::Bits16, 65530, 0);
        assert_eq!(w.update(3), 9); // 65530 -> 65535 -> 0 -> 3
        assert_eq!(w.update(65534), 4); // back down across zero by 5
                                        // upper bits of a 32-bit register read are ignored for a 16-bit timer
        assert_eq!(w.update(0xABCD_FFFE), 4);
    }

    #[test]
    fn an_inverted_counter_counts_the_other_way_across_the_wraps_and_flips_without_a_jump() {
        let mut w = WideCounter::new(CounterWidth::Bits16, 65530, 100);
        w.set_inverted(true);
        assert_eq!(w.update(3), 91); // +9 counts of the register: 9 down
        assert_eq!(w.step(), -9);
        assert_eq!(w.update(65534), 96); // back 5 across zero: 5 up
        assert_eq!(w.extend(65530), 100); // a captured value, the same way
        w.set_inverted(false);
        assert_eq!(w.update(65534), 96); // no reading change, no jump
        assert_eq!(w.update(2), 100);
        let mut w = WideCounter::new(CounterWidth::Bits32, u32::MAX - 1, 0);
        w.set_inverted(true);
        assert_eq!(w.update(2), -4);
    }

    #[test]
    fn thirty_two_bit_wrap() {
        let mut w = WideCounter::new(CounterWidth::Bits32, u32::MAX - 1, 1_000);
        assert_eq!(w.update(2), 1_004);
        assert_eq!(w.step(), 4);
        assert_eq!(w.update(u32::MAX), 1_001);
        assert_eq!(w.step(), -3);
        // the largest delta a 32-bit counter can show, both signs
        assert_eq!(w.update(u32::MAX - 0x8000_0000), 1_001 - 0x8000_0000);
        assert_eq!(w.step(), i32::MIN);
        assert_eq!(w.update(u32::MAX - 1), 1_000);
        assert_eq!(w.step(), i32::MAX);
    }

    #[test]
    fn the_wide_count_saturates_and_its_step_is_what_it_moved() {
        let mut w = WideCounter::new(CounterWidth::Bits16, 0, i64::MAX - 2);
        assert_eq!(w.update(5), i64::MAX);
        assert_eq!(w.step(), 2);
        assert_eq!(w.update(3), i64::MAX - 2);
        assert_eq!(w.step(), -2);
        let mut w = WideCounter::new(CounterWidth::Bits32, 10, i64::MIN + 1);
        assert_eq!(w.update(0), i64::MIN);
        assert_eq!(w.step(), -1);
    }

    /// The wrap extension as it was written with a per-reading dispatch on the width.
    struct General {
        width: CounterWidth,
        last: u32,
        total: i64,
    }

    impl General {
        fn update(&mut self, raw: u32) -> i64 {
            let raw = match self.width {
                CounterWidth::Bits16 => raw & 0xFFFF,
                CounterWidth::Bits32 => raw,
            };
            let delta = match self.width {
                CounterWidth::Bits16 => {
                    i64::from((raw as u16).wrapping_sub(self.last as u16) as i16)
                }
                CounterWidth::Bits32 => i64::from(raw.wrapping_sub(self.last) as i32),
            };
            self.last = raw;
            self.total = self.total.saturating_add(delta);
            self.total
        }
    }

    proptest::proptest! {
        /// One code path for both widths, the same wide counts (upper register bits of a
        /// 16-bit timer included), and the step is the count's change.
        #[test]
        fn one_path_for_both_widths(
            start in proptest::num::i64::ANY,
            first in proptest::num::u32::ANY,
            raws in proptest::collection::vec(proptest::num::u32::ANY, 1..40),
            w16 in proptest::bool::ANY,
        ) {
            let width = if w16 { CounterWidth::Bits16 } else { CounterWidth::Bits32 };
            let mut w = WideCounter::new(width, first, start);
            let mut g = General {
                width,
                last: if w16 { first & 0xFFFF } else { first },
                total: start,
            };
            for r in raws {
                let before = w.count();
                let n = w.update(r);
                proptest::prop_assert_eq!(n, g.update(r));
                proptest::prop_assert_eq!(i64::from(w.step()), n - before);
            }
        }
    }
}
