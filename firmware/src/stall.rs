//! The control loop's stalls against what a 16-bit encoder counter can follow (board
//! review D6).
//!
//! While the core cannot run (a flash erase holds it for 2–4 s: it runs from flash), the
//! control interrupt reads no encoder. The servo step extends each reading by the signed
//! 16-bit difference to the last one (`WideCounter`), so an axis on a 16-bit timer (the
//! board's Z, TIM3) that moved more than half the counter's range, 32 768 counts, in the
//! meantime is off by a multiple of 65 536 counts without any sign of it. Z is the axis
//! that can: with its drive off it falls if its brake slips. The fastest it can move from
//! rest is free fall, which covers half the range (`d` mm) in `sqrt(2 d / g)`; a stall
//! longer than that (65 ms at the gantry's 1 600 counts/mm) makes Z's position unknown:
//! the control interrupt then has the servo forget Z's home (`Servo::forget_home`), so no
//! program runs until Z is homed again. The X and Y timers count in 32 bits (a stall
//! would have to last hours).
//!
//! The gap is measured between control interrupts with the DWT cycle counter (32 bits:
//! 25.6 s at 168 MHz, so a longer stall is measured modulo that; no stall the firmware
//! makes is longer than an erase).

use core::sync::atomic::AtomicU32;

use controller_core::Real;

/// Stalls that made the 16-bit axes' positions unknown since boot (stored by the control
/// interrupt, logged by the telemetry task).
pub static POSITION_STALLS: AtomicU32 = AtomicU32::new(0);

/// Standard gravity, m/s² (the free fall that bounds how fast an unpowered axis moves).
pub const GRAVITY_M_S2: f32 = 9.806_65;

/// Half the range of a 16-bit counter: the largest move its signed difference resolves.
pub const HALF_RANGE_16BIT_COUNTS: f32 = 32_768.0;

/// The longest stall, s, after which an axis of `counts_per_mm` on a 16-bit counter still
/// cannot have moved half the counter's range in free fall from rest. 0 for a scale that
/// is not a positive number (any stall then counts as too long).
pub fn alias_safe_s(counts_per_mm: f32) -> f32 {
    if !(counts_per_mm > 0.0) || !counts_per_mm.is_finite() {
        return 0.0;
    }
    let half_range_m = HALF_RANGE_16BIT_COUNTS / counts_per_mm * 1e-3;
    (2.0 * half_range_m / GRAVITY_M_S2).sqrt_pos()
}

/// The gaps between control interrupts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StallWatch {
    /// The cycle counter at the last entry (`None` before the first).
    last: Option<u32>,
    /// Stalls longer than the safe time so far.
    pub stalls: u32,
    /// The longest gap measured, cycles.
    pub longest_cycles: u32,
}

impl StallWatch {
    pub const fn new() -> Self {
        Self {
            last: None,
            stalls: 0,
            longest_cycles: 0,
        }
    }

    /// A control interrupt entered at `now_cycles`. Gaps up to `quick_cycles` (a few
    /// periods) are never stalls and cost a compare; a longer one is compared with
    /// `safe_cycles()` (computed only then). True: the gap was a stall longer than safe.
    #[inline]
    pub fn entry(
        &mut self,
        now_cycles: u32,
        quick_cycles: u32,
        safe_cycles: impl FnOnce() -> u32,
    ) -> bool {
        let last = self.last.replace(now_cycles);
        let Some(last) = last else {
            return false;
        };
        let gap = now_cycles.wrapping_sub(last);
        if gap <= quick_cycles {
            return false;
        }
        self.long_gap(gap, safe_cycles())
    }

    #[cold]
    #[inline(never)]
    fn long_gap(&mut self, gap: u32, safe: u32) -> bool {
        self.longest_cycles = self.longest_cycles.max(gap);
        if gap > safe {
            self.stalls = self.stalls.saturating_add(1);
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_fall_time_over_half_the_range() {
        // the gantry's Z: 1 600 counts/mm, 20.48 mm of half range: sqrt(2 * 0.02048 / g)
        let t = alias_safe_s(1600.0);
        assert!((t - 0.064_63).abs() < 1e-4, "{t}");
        assert_eq!(alias_safe_s(0.0), 0.0);
        assert_eq!(alias_safe_s(f32::NAN), 0.0);
        assert_eq!(alias_safe_s(-5.0), 0.0);
        assert_eq!(alias_safe_s(f32::INFINITY), 0.0);
    }

    #[test]
    fn only_a_gap_longer_than_safe_is_a_stall() {
        let mut w = StallWatch::new();
        let safe = || 10_000;
        assert!(!w.entry(u32::MAX - 50, 100, safe)); // first entry: nothing to compare
        assert!(!w.entry(49, 100, safe)); // 100 cycles, across the wrap
        assert!(!w.entry(5_049, 100, safe)); // long, but not past safe
        assert_eq!((w.stalls, w.longest_cycles), (0, 5_000));
        assert!(w.entry(25_050, 100, safe)); // 20 001 cycles
        assert_eq!((w.stalls, w.longest_cycles), (1, 20_001));
        assert!(!w.entry(25_150, 100, || panic!("not computed for a quick gap")));
    }
}
