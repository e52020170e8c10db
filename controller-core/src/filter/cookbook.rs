//! Biquad coefficients of the output filters, designed in `f64` at configuration time.
//!
//! The designs are R. Bristow-Johnson's "Cookbook formulae for audio EQ biquad filter
//! coefficients" (the Audio EQ Cookbook, W3C Audio WG note, 2005/2016): the bilinear
//! transform of an analog prototype, pre-warped so that the prototype's characteristic
//! frequency lands exactly on the digital `w0 = 2π f0 / fs`.
//!
//! - [`notch`]: the cookbook's *peaking EQ* with a negative gain, i.e. a notch of finite
//!   depth: `H(s) = (s² + s·A/Q + 1) / (s² + s/(A·Q) + 1)`, `A = 10^(-depth_dB/40)`. Its
//!   gain at the centre is exactly `A² = -depth_dB` (also in the digital filter), it is 1 at
//!   DC and at Nyquist, and its width is given in Hz between the two frequencies where the
//!   attenuation is half the depth in dB (the cookbook's definition of the peaking EQ's
//!   bandwidth). For that width `W` the cookbook's `α = sin(w0)/(2Q)` is exactly
//!   `α = tan(π W / fs)`: the prototype's half-gain points satisfy `|1 - u²| = u/Q`, so in
//!   the pre-warped variable `Ω = tan(w/2)` they are `Ω_lo Ω_hi = Ω0²`,
//!   `Ω_hi - Ω_lo = Ω0/Q`, whence `tan((w_hi - w_lo)/2) = (Ω0/Q)/(1 + Ω0²) = α` (the
//!   classic digital notch bandwidth relation, e.g. Mitra, "Digital Signal Processing",
//!   §7.2). The width is therefore exact in the digital domain, at any `f0/fs`.
//! - [`low_pass`]: the cookbook's LPF, `H(s) = 1 / (s² + s/Q + 1)`, `α = sin(w0)/(2Q)`;
//!   its gain at the cutoff is exactly `Q` (-3.01 dB for the Butterworth `Q = 1/√2`).
//!
//! `1 - cos(w0)` is written `2 sin²(w0/2)`: no cancellation at low `f0/fs`.

use core::f64::consts::PI;

/// A biquad's coefficients normalised to `a0 = 1`:
/// `H(z) = (b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    pub b: [f64; 3],
    pub a: [f64; 2],
}

impl Coefficients {
    /// `H(z) = 1`.
    pub const IDENTITY: Self = Self {
        b: [1.0, 0.0, 0.0],
        a: [0.0, 0.0],
    };

    /// Divide by `a0` (the cookbook's formulas give an unnormalised `a0`). `a0 >= 1` for
    /// every design here (`1 + α` or `1 + α/A`, `α > 0`), so the division is safe.
    fn normalised(b: [f64; 3], a0: f64, a: [f64; 2]) -> Self {
        let r = 1.0 / a0;
        Self {
            b: [b[0] * r, b[1] * r, b[2] * r],
            a: [a[0] * r, a[1] * r],
        }
    }

    /// Gain at DC, `H(1)`.
    pub fn dc_gain(&self) -> f64 {
        let den = 1.0 + self.a[0] + self.a[1];
        let num = self.b[0] + self.b[1] + self.b[2];
        if den.abs() > f64::MIN_POSITIVE {
            num / den
        } else {
            0.0
        }
    }
}

/// The notch of finite depth at `freq_hz`, `width_hz` wide between its half-depth
/// frequencies, `depth_db` (> 0) deep at the centre, for the sample rate `sample_hz`.
/// The arguments are validated by the caller (`design`): `0 < freq, width < fs/2`.
pub fn notch(freq_hz: f64, width_hz: f64, depth_db: f64, sample_hz: f64) -> Coefficients {
    let w0 = 2.0 * PI * freq_hz / sample_hz;
    let alpha = libm::tan(PI * width_hz / sample_hz);
    let a = libm::pow(10.0, -depth_db / 40.0);
    let c = libm::cos(w0);
    Coefficients::normalised(
        [1.0 + alpha * a, -2.0 * c, 1.0 - alpha * a],
        1.0 + alpha / a,
        [-2.0 * c, 1.0 - alpha / a],
    )
}

/// The second-order low-pass at `cutoff_hz` with quality `q` (gain `q` at the cutoff).
pub fn low_pass(cutoff_hz: f64, q: f64, sample_hz: f64) -> Coefficients {
    let w0 = 2.0 * PI * cutoff_hz / sample_hz;
    let (s, c) = libm::sincos(w0);
    let alpha = s / (2.0 * q);
    let half = libm::sin(0.5 * w0);
    let one_minus_cos = 2.0 * half * half;
    Coefficients::normalised(
        [0.5 * one_minus_cos, one_minus_cos, 0.5 * one_minus_cos],
        1.0 + alpha,
        [-2.0 * c, 1.0 - alpha],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unity_at_dc_and_normalised() {
        for c in [notch(35.0, 8.0, 20.0, 1e4), low_pass(500.0, 0.5, 1e4)] {
            assert!((c.dc_gain() - 1.0).abs() < 1e-12, "{c:?}");
        }
        // the notch's numerator and denominator share b1 = a1 (peaking EQ)
        let n = notch(35.0, 8.0, 20.0, 1e4);
        assert_eq!(n.b[1], n.a[0]);
        assert_eq!(Coefficients::IDENTITY.dc_gain(), 1.0);
    }
}
