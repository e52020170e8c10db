//! Counts to positions in `f32` over a 24-hour run at the board's rate (the position's resolution must not decay with time).
//!
//! The servo step's positions are `count_to_real(n) · len` in `f32` (no `f64`: soft float
//! on the board), from wide counts `n` kept exactly in `i64` by [`WideCounter`]. Nothing
//! is accumulated in floating point: the position of a count is the same whenever it is
//! reached, so its error does not grow with the run's length. This test runs the board's
//! path for 24 hours of periods and checks that, and the stated bound.

use controller_core::estimator::{counts_to_position, CounterWidth, WideCounter};
use controller_core::presets::board::{servo_config, BOARD_RATE_HZ};

/// Largest distance from the arm position (the wide counts' origin) a machine position
/// can have: ±2 m, the envelope of the fixed-point range analysis (docs/fixed-point.md);
/// the gantry's screws are 300-800 mm long.
const ENVELOPE_MM: f64 = 2000.0;

/// The stated bound of the `f32` position error within the envelope, mm: half an ulp of
/// the position (the product rounds once; the count itself is exact below 2^24 counts,
/// 10.5 m) plus the count length's own rounding to `f32` (relative 2.2e-8 for
/// 1/1600 mm) times the position: 6.1e-5 + 4.5e-5 mm at 2 m, so 0.11 µm, under a
/// fifth of a count (0.625 µm).
const POSITION_F32_MAX_ERR_MM: f64 = 1.1e-4;

#[test]
fn counts_to_positions_over_24_hours_at_the_board_rate() {
    let cfg = servo_config(BOARD_RATE_HZ);
    let periods = 24 * 3600 * u64::from(BOARD_RATE_HZ);
    // X on a 32-bit timer, Z on a 16-bit one (wrapping every 41 mm)
    for axis in [0, 2] {
        let enc = cfg.encoders[axis];
        let len_f64 = enc.count_len().unwrap();
        let len = len_f64 as f32;
        let width = enc.counter;
        let mask = match width {
            CounterWidth::Bits16 => 0xFFFF,
            CounterWidth::Bits32 => u32::MAX,
        };
        let span = (ENVELOPE_MM / len_f64) as i64;
        let mut counter = WideCounter::new(width, 0, 0);
        // sweep the whole envelope back and forth at full speed (250 mm/s: 40 counts per
        // period at 1600 counts/mm and 10 kHz), one count slower every other sweep so
        // that the reversals fall on different counts
        let full = (250.0 / len_f64 / f64::from(BOARD_RATE_HZ)) as i64;
        let (mut n, mut v, mut worst, mut worst_at) = (0i64, full, 0.0f64, 0i64);
        let mut sweeps = 0u32;
        for _ in 0..periods {
            n += v;
            if n.abs() > span {
                n = n.signum() * span;
                sweeps += 1;
                v = -v.signum() * (full - i64::from(sweeps % 2));
            }
            let wide = counter.update((n as u32) & mask);
            let p = counts_to_position::<f32>(wide, len);
            let err = (f64::from(p) - n as f64 * len_f64).abs();
            if err > worst {
                (worst, worst_at) = (err, n);
            }
        }
        println!("axis {axis}: {periods} periods, {sweeps} sweeps, worst {worst:e} mm at count {worst_at}");
        // the wide count followed every period exactly, wraps included
        assert_eq!(counter.count(), n, "axis {axis}");
        assert!(sweeps > 1000, "{sweeps} sweeps");
        assert!(
            worst <= POSITION_F32_MAX_ERR_MM,
            "axis {axis}: {worst:e} mm at count {worst_at}"
        );
        // the bound is tight: the run reaches most of it
        assert!(
            worst > 0.6 * POSITION_F32_MAX_ERR_MM,
            "axis {axis}: {worst:e}"
        );
    }
}
