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
    width: CounterWidth,
    last_raw: u32,
    total: i64,
}

impl WideCounter {
    /// Start at wide count `start` with the counter currently reading `raw` (a 16-bit
    /// counter's reading is taken modulo 2^16).
    pub fn new(width: CounterWidth, raw: u32, start: i64) -> Self {
        Self {
            width,
            last_raw: Self::mask(width, raw),
            total: start,
        }
    }

    fn mask(width: CounterWidth, raw: u32) -> u32 {
        match width {
            CounterWidth::Bits16 => raw & 0xFFFF,
            CounterWidth::Bits32 => raw,
        }
    }

    /// Take a new raw reading; returns the wide count.
    pub fn update(&mut self, raw: u32) -> i64 {
        let raw = Self::mask(self.width, raw);
        // The signed difference modulo the counter width: a wrap between readings becomes
        // a small step of the right sign.
        let delta = match self.width {
            CounterWidth::Bits16 => {
                i64::from((raw as u16).wrapping_sub(self.last_raw as u16) as i16)
            }
            CounterWidth::Bits32 => i64::from(raw.wrapping_sub(self.last_raw) as i32),
        };
        self.last_raw = raw;
        // saturating (a wide count never wraps), the rare case kept off the common path
        self.total = match self.total.checked_add(delta) {
            Some(t) => t,
            None if delta > 0 => i64::MAX,
            None => i64::MIN,
        };
        self.total
    }

    /// The wide count after the last reading.
    pub fn count(&self) -> i64 {
        self.total
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
    fn thirty_two_bit_wrap() {
        let mut w = WideCounter::new(CounterWidth::Bits32, u32::MAX - 1, 1_000);
        assert_eq!(w.update(2), 1_004);
        assert_eq!(w.update(u32::MAX), 1_001);
    }
}
