//! The few f32 functions the planner needs, in f32 arithmetic only and without library
//! calls on the Cortex-M4F: `libm::sqrtf` is a software routine there (about 100
//! instructions), `libm::cbrtf`/`sinf`/`cosf` evaluate in soft `f64` (thousands), and
//! `f32::min`/`max` become calls to `fminf`/`fmaxf` (no VMINNM before ARMv8).
//!
//! `min`/`max` here follow IEEE maxNum like `f32::max` (a NaN operand yields the other
//! one), so `x.mx(0.0)` still turns NaN into 0.

/// Relative error bound of [`sqrt`] (tested over many decades: about 1 ulp).
pub const SQRT_MAX_REL_ERR: f32 = 2.5e-7;

/// Branchy min/max/clamp for f32 (NaN-ignoring like `f32::min`/`max`, never panics).
pub trait F32Ext: Copy {
    fn mn(self, o: Self) -> Self;
    fn mx(self, o: Self) -> Self;
    /// `self` limited to `[lo, hi]` (no panic for `lo > hi`: then `hi` wins).
    fn clampf(self, lo: Self, hi: Self) -> Self;
}

impl F32Ext for f32 {
    #[inline(always)]
    fn mn(self, o: f32) -> f32 {
        if self < o || o.is_nan() {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn mx(self, o: f32) -> f32 {
        if self > o || o.is_nan() {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    fn clampf(self, lo: f32, hi: f32) -> f32 {
        self.mx(lo).mn(hi)
    }
}

/// `1/√x` for `x > 0` finite and normal: bit-trick seed, three Newton steps.
#[inline(always)]
fn rsqrt_normal(x: f32) -> f32 {
    let mut y = f32::from_bits(0x5f37_5a86_u32.wrapping_sub(x.to_bits() >> 1));
    let hx = 0.5 * x;
    y *= 1.5 - hx * y * y;
    y *= 1.5 - hx * y * y;
    y *= 1.5 - hx * y * y;
    y
}

/// `√x`; 0 for `x ≤ 0` and NaN, +∞ for +∞. About 1 ulp ([`SQRT_MAX_REL_ERR`]).
#[inline]
pub fn sqrt(x: f32) -> f32 {
    if !(x > 0.0) {
        return 0.0;
    }
    if !(x <= f32::MAX) {
        return x;
    }
    // Subnormal: scale by 2^64 (root 2^32).
    let (x, back) = if x < f32::MIN_POSITIVE {
        (x * 1.844_674_4e19, 2.328_306_4e-10)
    } else {
        (x, 1.0)
    };
    let y = rsqrt_normal(x);
    let s = x * y;
    // One Newton step on the root itself, with the residual x − s² (nearly exact).
    (s + 0.5 * y * (x - s * s)) * back
}

/// `1/√x` for `x > 0` (+∞ for `x ≤ 0`, which callers exclude).
#[inline]
pub fn rsqrt(x: f32) -> f32 {
    if !(x >= f32::MIN_POSITIVE) || !(x <= f32::MAX) {
        return 1.0 / sqrt(x);
    }
    let y = rsqrt_normal(x);
    // Newton step with the full residual.
    y + 0.5 * y * (1.0 - x * y * y)
}

/// Half-width of the window around 1 where [`rsqrt_near_one`] uses its series.
pub const NEAR_ONE: f32 = 1.0 / 128.0;
/// Relative error of [`rsqrt_near_one`] inside the window: the series' remainder
/// (5/16 e³ ≤ 1.5e-7) plus rounding (`rsqrt_near_one_is_within_its_bound`).
pub const RSQRT_NEAR_ONE_MAX_REL_ERR: f32 = 3.0e-7;

/// `1/√x` for `x` near 1 by the series `1 − e/2 + 3e²/8` (`e = x − 1`, within
/// [`RSQRT_NEAR_ONE_MAX_REL_ERR`] while `|e| ≤ NEAR_ONE`), [`rsqrt`] elsewhere. The
/// planner's path derivative is a unit vector up to the span fit, so its squared norm is
/// that close to 1 almost always: 6 instructions instead of 25 in the control interrupt.
#[inline]
pub fn rsqrt_near_one(x: f32) -> f32 {
    let e = x - 1.0;
    if e.abs() <= NEAR_ONE {
        1.0 + e * (-0.5 + 0.375 * e)
    } else {
        rsqrt(x)
    }
}

/// `√(a² + b²)` (lengths in mm: no overflow concern below 1e18).
#[inline]
pub fn hypot(a: f32, b: f32) -> f32 {
    sqrt(a * a + b * b)
}

/// `(sin x, cos x)`, f32 only.
#[inline]
pub fn sin_cos(x: f32) -> (f32, f32) {
    crate::num::powers::sin_cos_f32(x)
}

/// Real cube root, f32 only.
#[inline]
pub fn cbrt(x: f32) -> f32 {
    crate::num::powers::cbrt_f32(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rsqrt_near_one_is_within_its_bound() {
        // every f32 in the window, and beyond it on both sides (where rsqrt takes over)
        let (lo, hi) = (1.0 - 2.0 * NEAR_ONE, 1.0 + 2.0 * NEAR_ONE);
        let (mut worst_in, mut x) = (0.0f64, lo);
        while x <= hi {
            let exact = 1.0 / (x as f64).sqrt();
            let rel = ((rsqrt_near_one(x) as f64 - exact) / exact).abs();
            if (x - 1.0).abs() <= NEAR_ONE {
                worst_in = worst_in.max(rel);
            } else {
                assert!(rel < 1e-6, "{x}: {rel}");
            }
            x = f32::from_bits(x.to_bits() + 1);
        }
        assert!(
            worst_in <= f64::from(RSQRT_NEAR_ONE_MAX_REL_ERR),
            "{worst_in}"
        );
        // the bound is not loose by more than 2x
        assert!(
            worst_in > f64::from(RSQRT_NEAR_ONE_MAX_REL_ERR) / 2.0,
            "{worst_in}"
        );
        // far from 1 and at the edges of f32 it is rsqrt
        for x in [1e-30f32, 0.25, 4.0, 1e30] {
            assert_eq!(rsqrt_near_one(x), rsqrt(x));
        }
    }

    #[test]
    fn sqrt_is_within_an_ulp_over_many_decades() {
        let mut worst = 0.0f64;
        let mut x = 1.0e-40f32;
        while x < 1.0e38 {
            for k in 0..97 {
                let v = x * (1.0 + k as f32 / 97.0);
                let exact = (v as f64).sqrt();
                let rel = ((sqrt(v) as f64 - exact) / exact).abs();
                worst = worst.max(rel);
                let r_exact = 1.0 / exact;
                if v >= f32::MIN_POSITIVE {
                    let rr = ((rsqrt(v) as f64 - r_exact) / r_exact).abs();
                    worst = worst.max(rr);
                }
            }
            x *= 3.7;
        }
        assert!(worst <= SQRT_MAX_REL_ERR as f64, "{worst:e}");
        assert_eq!(sqrt(0.0), 0.0);
        assert_eq!(sqrt(-1.0), 0.0);
        assert_eq!(sqrt(f32::NAN), 0.0);
        assert_eq!(sqrt(f32::INFINITY), f32::INFINITY);
        assert_eq!(sqrt(4.0), 2.0);
        assert_eq!(sqrt(9.0), 3.0);
    }

    #[test]
    fn min_max_ignore_nan_like_std() {
        for &(a, b) in &[
            (1.0f32, 2.0f32),
            (2.0, 1.0),
            (f32::NAN, 1.0),
            (1.0, f32::NAN),
            (-0.5, -0.5),
        ] {
            assert_eq!(a.mn(b).to_bits(), a.min(b).to_bits(), "{a} {b}");
            assert_eq!(a.mx(b).to_bits(), a.max(b).to_bits(), "{a} {b}");
        }
        assert_eq!(5.0f32.clampf(0.0, 1.0), 1.0);
        assert_eq!(f32::NAN.clampf(0.0, 1.0), 0.0);
        assert_eq!(0.5f32.clampf(1.0, 0.0), 0.0);
    }
}
