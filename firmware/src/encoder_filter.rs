//! The digital input filter of the encoder timers (TIMx_CCMR1 IC1F/IC2F), and what it
//! costs in counting speed.
//!
//! The filter passes a new level of a channel only after it was sampled `N` times in a
//! row at `f_SAMPLING` (RM0090, TIMx_CCMR1 ICxF). A glitch shorter than `N` samples is
//! dropped; a genuine level must last at least `N + 1` samples (one sample of phase
//! uncertainty) to pass. In quadrature at a count rate of `C` counts/s (×4 decoding),
//! each channel's level lasts `2 / C` nominally, so the highest count rate the filter
//! passes is `2 f_SAMPLING / (N + 1)`. Both channels are delayed alike, so the order of
//! their edges (the direction) is kept as long as the edges are more than one sample
//! apart.
//!
//! The encoder timers TIM2/TIM3/TIM5 run at 84 MHz (APB1 timers) with CKD = 1
//! (`f_DTS` = 84 MHz). The chosen code `0b0111` (`f_DTS / 4` = 21 MHz, `N` = 8) rejects
//! glitches up to 381 ns and passes up to 4.67 M counts/s (2.9 m/s at 1600 counts/mm):
//! 11.7 times the 400 k counts/s of the gantry's 250 mm/s maximum speed, 10.6 times at the
//! overspeed trip (1.1 × 250 mm/s), so an encoder whose duty cycle or quadrature phase is
//! far off (a channel level at half its nominal length) still counts at five times the
//! maximum speed.

/// Kernel clock of the encoder timers (APB1 timer clock at 168 MHz SYSCLK), Hz.
pub const ENCODER_TIMER_CLOCK_HZ: u32 = 84_000_000;

/// TIMx_CCMR1 IC1F and IC2F of every encoder timer: `f_DTS / 4`, `N = 8`.
pub const ENCODER_IC_FILTER: u8 = 0b0111;

/// Sampling divider of `f_DTS` and the number of samples `N` of an ICxF code (RM0090);
/// code 0 (no filter) is `(1, 1)`: one sample at the timer clock.
pub const fn ic_filter(code: u8) -> (u32, u32) {
    match code & 0xF {
        0b0000 => (1, 1),
        0b0001 => (1, 2),
        0b0010 => (1, 4),
        0b0011 => (1, 8),
        0b0100 => (2, 6),
        0b0101 => (2, 8),
        0b0110 => (4, 6),
        0b0111 => (4, 8),
        0b1000 => (8, 6),
        0b1001 => (8, 8),
        0b1010 => (16, 5),
        0b1011 => (16, 6),
        0b1100 => (16, 8),
        0b1101 => (32, 5),
        0b1110 => (32, 6),
        _ => (32, 8),
    }
}

/// Longest glitch the filter `code` drops at timer clock `clock_hz`, ns.
pub fn glitch_rejected_ns(code: u8, clock_hz: u32) -> f64 {
    let (div, n) = ic_filter(code);
    f64::from(n) * f64::from(div) * 1e9 / f64::from(clock_hz)
}

/// Highest quadrature count rate (×4 decoding) the filter `code` passes at timer clock
/// `clock_hz`, counts/s.
pub fn max_count_rate(code: u8, clock_hz: u32) -> f64 {
    let (div, n) = ic_filter(code);
    let f_sampling = f64::from(clock_hz) / f64::from(div);
    2.0 * f_sampling / f64::from(n + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SERVO;

    #[test]
    fn filter_rejects_glitches_and_passes_the_gantrys_top_speed_tenfold() {
        let glitch = glitch_rejected_ns(ENCODER_IC_FILTER, ENCODER_TIMER_CLOCK_HZ);
        assert!((glitch - 380.95).abs() < 0.01, "{glitch}");
        let max = max_count_rate(ENCODER_IC_FILTER, ENCODER_TIMER_CLOCK_HZ);
        assert!((max - 4_666_666.7).abs() < 1.0, "{max}");
        // the gantry's fastest axis at its overspeed trip, counts/s (x4 decoding)
        let gantry_max = 250.0 * 1600.0 * 1.1;
        assert!(max >= 10.0 * gantry_max, "{max} vs {gantry_max}");
        // and the board's own configuration: every axis' speed limit (where finite)
        for i in 0..3 {
            let a = SERVO.safety.axes[i];
            let rate = f64::from(a.vel_max_mm_s)
                * f64::from(SERVO.encoders[i].counts_per_mm)
                * f64::from(SERVO.safety.overspeed_ratio);
            if rate.is_finite() {
                assert!(max >= 4.0 * rate, "axis {i}: {rate} counts/s");
            }
        }
    }

    #[test]
    fn the_filter_table_is_monotonic_in_length() {
        let mut last = 0.0;
        for code in 0..16u8 {
            let g = glitch_rejected_ns(code, ENCODER_TIMER_CLOCK_HZ);
            assert!(g >= last, "code {code}");
            last = g;
        }
        assert_eq!(ic_filter(0b1111), (32, 8));
    }
}
