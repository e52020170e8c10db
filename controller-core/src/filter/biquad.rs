//! One biquad section in the control period's number type: coefficients designed in
//! `f64` ([`super::cookbook`]) and stored as [`Real`] values, a two-value state, and the
//! exact frequency response of the stored (rounded) coefficients.
//!
//! **Form: transposed direct form II** (J. O. Smith, "Introduction to Digital Filters",
//! "Transposed Direct-Forms"):
//!
//! ```text
//! y  = b0 x + s1
//! s1 = b1 x - a1 y + s2
//! s2 = b2 x - a2 y
//! ```
//!
//! Why this form:
//! - **Two states**, against four for direct form I: the period loads and stores two
//!   values per section instead of four (the cost kernel `filters3_f32`).
//! - **No internal gain.** Plain direct form II keeps `w = x / A(z)`, whose DC gain is
//!   `1/(1 + a1 + a2) ≈ 1/w0²` (2000 for a 35 Hz notch at 10 kHz): an overflow in fixed
//!   point and a loss of resolution in any type. The transposed form's states are sums of
//!   coefficient × signal terms, `|s2| <= |b2||x| + |a2||y|`,
//!   `|s1| <= |b1||x| + |a1||y| + |s2|`: at most about 6 times the larger of `|x|`, `|y|`
//!   (the coefficients are at most 2 in magnitude, `|y|` is within the filter's peak
//!   gain, 1 for the notch and the low-pass at `Q <= 1/√2`). In Q32.32 (±2.1e9) that
//!   leaves the effort signals (at most 1e5 in any unit the axes use) eight orders of
//!   magnitude of headroom; the fixed-point operators saturate beyond it.
//! - **Floating point**: the form's rounding errors enter at the states, whose noise gain
//!   is the recursion's `1/A(z)`, as in direct form I; no form of five multiplies avoids
//!   that at low `f0/fs`. The test `f32_and_q32_follow_f64` measures what it costs on a
//!   52 Hz notch and a 400 Hz low-pass at 10 kHz under white noise: `f32` stays within
//!   4.3e-5 (RMS, relative) of `f64`, a fifth of the amplifier's 12-bit command quantum
//!   (2.4e-4 of full scale); Q32.32 (32 fractional bits, coefficients within 2.3e-10)
//!   within 1e-7.
//!
//! The coefficients near 2 (`a1 = -2 cos w0 / a0`) need the integer part: Q32.32 has 31
//! integer bits, so they are exact to 2.3e-10; Q16.16 would round them to 1.5e-5, which
//! moves a low-frequency notch's poles by as much as its width: use `f32` or Q32.32.

use super::cookbook::Coefficients;
use super::response::{FrequencyResponse, C64};
use crate::Real;
use core::f64::consts::PI;

/// A biquad section (coefficients only; the state is a `[R; 2]` kept by the caller).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad<R> {
    b0: R,
    b1: R,
    b2: R,
    a1: R,
    a2: R,
    /// DC gain of the stored coefficients: the steady state of [`Self::steady_state`].
    dc_gain: R,
    /// Sample period, for [`Self::response`].
    period_s: f32,
}

impl<R: Real> Biquad<R> {
    /// The section with coefficients `c` (rounded to `R`) at sample period `period_s`
    /// (validated by the caller: positive and finite).
    pub fn new(c: &Coefficients, period_s: f32) -> Self {
        let [b0, b1, b2] = c.b.map(R::from_f64);
        let [a1, a2] = c.a.map(R::from_f64);
        let mut s = Self {
            b0,
            b1,
            b2,
            a1,
            a2,
            dc_gain: R::ONE,
            period_s,
        };
        s.dc_gain = R::from_f64(s.stored().dc_gain());
        s
    }

    /// `H(z) = 1`.
    pub fn identity(period_s: f32) -> Self {
        Self::new(&Coefficients::IDENTITY, period_s)
    }

    /// The stored coefficients, back in `f64`: the filter that actually runs.
    pub fn stored(&self) -> Coefficients {
        Coefficients {
            b: [self.b0.to_f64(), self.b1.to_f64(), self.b2.to_f64()],
            a: [self.a1.to_f64(), self.a2.to_f64()],
        }
    }

    /// One sample through the section (transposed direct form II).
    #[inline(always)]
    pub fn process(&self, s: &mut [R; 2], x: R) -> R {
        let y = self.b0 * x + s[0];
        s[0] = self.b1 * x - self.a1 * y + s[1];
        s[1] = self.b2 * x - self.a2 * y;
        y
    }

    /// The state and output of the section at rest under the constant input `level`
    /// (output `H(1)·level`): a section reset to it and fed `level` outputs `H(1)·level`
    /// from the first sample on, so enabling a filter under a held effort kicks nothing.
    pub fn steady_state(&self, level: R) -> ([R; 2], R) {
        let y = self.dc_gain * level;
        let s2 = self.b2 * level - self.a2 * y;
        let s1 = self.b1 * level - self.a1 * y + s2;
        ([s1, s2], y)
    }

    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// Complex gain of the stored section at `freq_hz`, in `f64`.
    pub fn response_c64(&self, freq_hz: f32) -> C64 {
        let c = self.stored();
        let w = 2.0 * PI * freq_hz as f64 * self.period_s as f64;
        let z1 = C64::unit(-w);
        let z2 = C64::unit(-2.0 * w);
        let num = C64::new(c.b[0], 0.0)
            .plus(z1.scale(c.b[1]))
            .plus(z2.scale(c.b[2]));
        let den = C64::ONE.plus(z1.scale(c.a[0])).plus(z2.scale(c.a[1]));
        num.over(den)
    }
}

impl<R: Real> FrequencyResponse for Biquad<R> {
    /// The discrete section's gain `H(e^{jωT})` at `freq_hz`, from the stored coefficients.
    fn response(&self, freq_hz: f32) -> (f32, f32) {
        self.response_c64(freq_hz).to_pair()
    }
}

#[cfg(test)]
mod tests {
    use super::super::cookbook::{low_pass, notch};
    use super::*;
    use crate::num::fixed::FxQ32;

    const FS: f64 = 1.0e4;
    const T: f32 = 1.0e-4;

    /// Steady-state amplitude of the section's output for a unit sine at `f`: run 2 s to
    /// settle, then correlate over a whole number of cycles.
    fn sine_amplitude<R: Real>(bq: &Biquad<R>, f: f64) -> f64 {
        let mut s = [R::ZERO; 2];
        let w = 2.0 * PI * f / FS;
        let settle = (2.0 * FS) as usize;
        let cycles = (f * 1.0).ceil().max(1.0);
        let n = libm::round(cycles * FS / f) as usize;
        let (mut re, mut im) = (0.0, 0.0);
        for k in 0..settle + n {
            let y = bq
                .process(&mut s, R::from_f64(libm::sin(w * k as f64)))
                .to_f64();
            if k >= settle {
                let (sn, cs) = libm::sincos(w * k as f64);
                re += y * sn;
                im += y * cs;
            }
        }
        2.0 * libm::hypot(re, im) / n as f64
    }

    #[test]
    fn response_matches_simulated_sines() {
        let sections = [
            notch(35.0, 8.0, 20.0, FS),
            notch(250.0, 60.0, 12.0, FS),
            low_pass(400.0, core::f64::consts::FRAC_1_SQRT_2, FS),
        ];
        let mut worst = 0.0f64;
        for c in &sections {
            let bq = Biquad::<f64>::new(c, T);
            let bq32 = Biquad::<f32>::new(c, T);
            for f in [5.0, 20.0, 31.0, 35.0, 40.0, 120.0, 250.0, 400.0, 1500.0] {
                let expect = bq.response_c64(f as f32).abs();
                for got in [sine_amplitude(&bq, f), sine_amplitude(&bq32, f)] {
                    let rel = (got - expect).abs() / expect;
                    worst = worst.max(rel);
                    assert!(rel < 5e-3, "{c:?} at {f} Hz: {got} vs {expect}");
                }
            }
        }
        assert!(worst > 0.0);
    }

    #[test]
    fn steady_state_is_kick_free() {
        let c = notch(35.0, 8.0, 20.0, FS);
        for level in [0.0, 1.0, -37.5, 1234.0] {
            let bq = Biquad::<f32>::new(&c, T);
            let (mut s, y0) = bq.steady_state(level);
            assert!((y0 - level).abs() <= 1e-3 * level.abs());
            for _ in 0..1000 {
                let y = bq.process(&mut s, level);
                assert!((y - y0).abs() <= 2e-6 * level.abs(), "{level}: {y} vs {y0}");
            }
            let fx = Biquad::<FxQ32>::new(&c, T);
            let l = FxQ32::from_f32(level);
            let (mut s, y0) = fx.steady_state(l);
            for _ in 0..1000 {
                let y = fx.process(&mut s, l);
                assert!((y - y0).abs().to_f64() <= 1e-7 * (1.0 + level.abs() as f64));
            }
        }
        // without the reset, the same step kicks: the test can tell the difference
        let bq = Biquad::<f32>::new(&low_pass(400.0, core::f64::consts::FRAC_1_SQRT_2, FS), T);
        let mut s = [0.0; 2];
        assert!((bq.process(&mut s, 100.0) - 100.0).abs() > 50.0);
    }

    #[test]
    fn identity_passes_through() {
        let bq = Biquad::<f32>::identity(T);
        let mut s = [0.0; 2];
        for x in [0.0, -0.0, 1.5, -3.25e7, 1e-40] {
            assert_eq!(bq.process(&mut s, x).to_bits(), (x + 0.0).to_bits());
        }
        assert_eq!(bq.response(123.0), (1.0, 0.0));
    }
}
