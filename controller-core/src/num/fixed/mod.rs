//! Saturating fixed-point numbers for the control laws.
//!
//! [`Fx`] wraps a type of the `fixed` crate and implements [`Real`], so PID, SMC, DSMC,
//! the contour error and the cross-coupling run in fixed point from the same generic code
//! as `f32`. Every arithmetic operator saturates at the format's bounds: nothing wraps,
//! nothing panics (the `fixed` crate's own operators would panic or wrap on overflow,
//! which is why the newtype exists).
//!
//! Two formats are provided; the range analysis behind them is in `docs/fixed-point.md`:
//! - [`FxQ16`] = Q16.16 in an `i32`: ±32768 with 1.5e-5 resolution. Every multiply is one
//!   `SMULL` on the Cortex-M4. Covers the paper's normalised helix and a real axis in mm
//!   except the squared tangent norm `|v|²` above 181 mm/s (see the docs).
//! - [`FxQ32`] = Q32.32 in an `i64`: ±2.1e9 with 2.3e-10 resolution. Covers every signal
//!   of a ±2 m, 1 m/s gantry in mm with margin; a multiply is ~40 instructions on the M4.
//!
//! Products truncate toward −∞ (arithmetic shift). Division, cube roots and the
//! trigonometric functions use integer-only algorithms (`crate::powers`, [`trig`]).

pub mod trig;

use crate::num::powers::{cbrt_raw, div_by_raw, div_raw, inv_cbrt_raw, RawDivisor};
use crate::{Exponent, Real};
use core::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};
use fixed::types::{I16F16, I32F32};

/// Relative error bound of one fixed-point root (cube root, inverse cube root) and of
/// [`Real::div_or`]'s reciprocal, before the format's own rounding: see `crate::powers`.
pub const FX_ROOT_MAX_REL_ERR: f64 = crate::num::powers::CBRT_NORM_MAX_REL_ERR;

/// Relative error bound of [`Real::pow_abs`] in fixed point for den ∈ {1, 3, 9} and
/// |num| <= 5, before rounding: a den-9 root is two roots (4/3 of one root's error) and
/// the integer power multiplies the root's error by |num|: 5 · 4/3 · 1e-8 ≈ 7e-8.
pub const FX_POW_MAX_REL_ERR: f64 = 7.0e-8;

/// Rounding allowance of the fixed-point routines, in LSB of the format: each root and
/// quotient rounds once to the format (0.5 LSB) and the den-9 path rounds twice; the
/// integer power's multiplications truncate (1 LSB each, at most three for |num| <= 5).
pub const FX_ROUTINE_MAX_LSB: f64 = 4.0;

/// A saturating fixed-point number (newtype over a `fixed` crate type).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Fx<F>(pub F);

/// Q16.16: the cheap format (one `SMULL` per multiply).
pub type FxQ16 = Fx<I16F16>;
/// Q32.32: the wide format (covers a 2 m, 1 m/s gantry in mm throughout).
pub type FxQ32 = Fx<I32F32>;

macro_rules! impl_fx {
    ($F:ty, $raw:ty, $mul:path, $frac:expr) => {
        impl Fx<$F> {
            /// Fractional bits of the format.
            pub const FRAC: u32 = $frac;
            pub const MAX: Self = Fx(<$F>::MAX);
            pub const MIN: Self = Fx(<$F>::MIN);
            /// The smallest positive value (one LSB).
            pub const DELTA: Self = Fx(<$F>::DELTA);

            pub const fn from_bits(b: $raw) -> Self {
                Fx(<$F>::from_bits(b))
            }

            pub const fn to_bits(self) -> $raw {
                self.0.to_bits()
            }

            /// Saturate a magnitude (as produced by the integer routines) to the positive
            /// range, then apply the sign.
            #[inline(always)]
            fn from_mag(m: u64, negative: bool) -> Self {
                let m = if m > <$raw>::MAX as u64 {
                    <$raw>::MAX
                } else {
                    m as $raw
                };
                Self::from_bits(if negative { -m } else { m })
            }

            #[inline(always)]
            fn mag(self) -> u64 {
                self.to_bits().unsigned_abs() as u64
            }

            /// `|self|^(1/den)` for den 3 or 9 (`inverse`: `|self|^(-1/den)`), or `None`
            /// for other denominators.
            #[inline(always)]
            fn root(m: u64, den: i16, inverse: bool) -> Option<u64> {
                match (den, inverse) {
                    (1, false) => Some(m),
                    (3, false) => Some(cbrt_raw(m, $frac)),
                    (3, true) => Some(inv_cbrt_raw(m, $frac)),
                    (9, false) => Some(cbrt_raw(cbrt_raw(m, $frac), $frac)),
                    // x^(-1/9) = cbrt(x^(-1/3)): no division
                    (9, true) => Some(cbrt_raw(inv_cbrt_raw(m, $frac), $frac)),
                    _ => None,
                }
            }
        }

        impl Add for Fx<$F> {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                Fx(self.0.saturating_add(o.0))
            }
        }

        impl Sub for Fx<$F> {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                Fx(self.0.saturating_sub(o.0))
            }
        }

        impl Mul for Fx<$F> {
            type Output = Self;
            /// Full-width product, truncated toward −∞, saturated.
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                Self::from_bits($mul(self.to_bits(), o.to_bits()))
            }
        }

        impl Neg for Fx<$F> {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                Fx(self.0.saturating_neg())
            }
        }

        impl AddAssign for Fx<$F> {
            #[inline(always)]
            fn add_assign(&mut self, o: Self) {
                *self = *self + o;
            }
        }

        impl SubAssign for Fx<$F> {
            #[inline(always)]
            fn sub_assign(&mut self, o: Self) {
                *self = *self - o;
            }
        }

        impl Real for Fx<$F> {
            const ZERO: Self = Fx(<$F>::ZERO);
            const ONE: Self = Fx(<$F>::ONE);

            /// Saturating; NaN maps to 0.
            fn from_f32(x: f32) -> Self {
                if x.is_nan() {
                    Self::ZERO
                } else {
                    Fx(<$F>::saturating_from_num(x))
                }
            }

            fn from_f64(x: f64) -> Self {
                if x.is_nan() {
                    Self::ZERO
                } else {
                    Fx(<$F>::saturating_from_num(x))
                }
            }

            fn to_f32(self) -> f32 {
                self.0.to_num::<f32>()
            }

            fn to_f64(self) -> f64 {
                self.0.to_num::<f64>()
            }

            fn div_or(self, d: Self, fallback: Self) -> Self {
                let negative = (self.to_bits() < 0) != (d.to_bits() < 0);
                match div_raw(self.mag(), d.mag(), $frac) {
                    Some(q) if q <= <$raw>::MAX as u64 => Self::from_mag(q, negative),
                    _ => fallback,
                }
            }

            /// One reciprocal of `d` for both quotients: exactly two `div_or` calls.
            fn div2_or(a: Self, b: Self, d: Self, fallback: Self) -> (Self, Self) {
                let Some(div) = RawDivisor::new(d.mag()) else {
                    return (fallback, fallback);
                };
                let q = |x: Self| {
                    let negative = (x.to_bits() < 0) != (d.to_bits() < 0);
                    match div_by_raw(x.mag(), &div, $frac) {
                        Some(q) if q <= <$raw>::MAX as u64 => Self::from_mag(q, negative),
                        _ => fallback,
                    }
                };
                (q(a), q(b))
            }

            fn cbrt(self) -> Self {
                Self::from_mag(cbrt_raw(self.mag(), $frac), self.to_bits() < 0)
            }

            fn sqrt_pos(self) -> Self {
                if self.to_bits() > 0 {
                    Fx(self.0.sqrt())
                } else {
                    Self::ZERO
                }
            }

            fn pow_abs(self, e: Exponent, floor: Self) -> Self {
                let mut m = self.mag();
                if e.num < 0 {
                    let fl = floor.mag().max(1);
                    if m < fl {
                        m = fl;
                    }
                } else if e.num == 0 {
                    return Self::ONE;
                } else if m == 0 {
                    return Self::ZERO;
                }
                let n = e.num.unsigned_abs();
                match Self::root(m, e.den, e.num < 0) {
                    Some(r) => {
                        let r = Self::from_mag(r, false);
                        let mut acc = if n & 1 == 1 { r } else { Self::ONE };
                        let mut b = r;
                        let mut k = n >> 1;
                        while k > 0 {
                            b = b * b;
                            if k & 1 == 1 {
                                acc = acc * b;
                            }
                            k >>= 1;
                        }
                        if e.den == 1 && e.num < 0 {
                            Self::ONE.div_or(acc, Self::MAX)
                        } else {
                            acc
                        }
                    }
                    // Any other denominator: through the f32 reference (not used by the
                    // paper's laws, kept so the trait stays total).
                    None => {
                        let v = libm::powf(Self::from_mag(m, false).to_f32(), e.as_f32());
                        if v.is_finite() {
                            Self::from_f32(v)
                        } else {
                            Self::MAX
                        }
                    }
                }
            }

            fn sin_cos(self) -> (Self, Self) {
                let (s, c) = trig::sin_cos_q31(self.to_bits() as i64, $frac);
                (
                    Self::from_bits(trig::q31_to(s, $frac) as $raw),
                    Self::from_bits(trig::q31_to(c, $frac) as $raw),
                )
            }

            fn is_finite(self) -> bool {
                true
            }
        }
    };
}

/// Q16.16 product `a b 2^-16`, floored, saturated: one SMULL and the range check.
#[inline(always)]
fn mul_q16(a: i32, b: i32) -> i32 {
    let p = (a as i64 * b as i64) >> 16;
    if p > i32::MAX as i64 {
        i32::MAX
    } else if p < i32::MIN as i64 {
        i32::MIN
    } else {
        p as i32
    }
}

/// Q32.32 product `a b 2^-32`, floored, saturated. Written on magnitudes as four
/// 32 x 32 -> 64 partial products (UMULL/UMLAL on the Cortex-M4) instead of a generic
/// 128-bit multiply, which LLVM expands to about twice the instructions.
#[inline(always)]
fn mul_q32(a: i64, b: i64) -> i64 {
    let neg = (a ^ b) < 0;
    let (ua, ub) = (a.unsigned_abs(), b.unsigned_abs());
    let (al, ah) = (ua & 0xFFFF_FFFF, ua >> 32);
    let (bl, bh) = (ub & 0xFFFF_FFFF, ub >> 32);
    let ll = al * bl;
    // none of these sums can overflow u64: each product is below (2^32 - 1)^2
    let m1 = (ll >> 32) + al * bh;
    let m2 = (m1 & 0xFFFF_FFFF) + ah * bl;
    let hi = ah * bh + (m1 >> 32) + (m2 >> 32); // bits 64.. of |a b|
    if hi >= 1 << 31 {
        return if neg { i64::MIN } else { i64::MAX };
    }
    let mag = (hi << 32) | (m2 & 0xFFFF_FFFF); // bits 32..95 of |a b|, below 2^63
    if neg {
        // floor for negative results: round the magnitude up when bits were dropped
        (mag + ((ll & 0xFFFF_FFFF) != 0) as u64).wrapping_neg() as i64
    } else {
        mag as i64
    }
}

impl_fx!(I16F16, i32, mul_q16, 16);
impl_fx!(I32F32, i64, mul_q32, 32);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operators_saturate() {
        let big = FxQ16::from_f32(30_000.0);
        assert_eq!(big + big, FxQ16::MAX);
        assert_eq!(-big - big, FxQ16::MIN);
        assert_eq!(big * big, FxQ16::MAX);
        assert_eq!(big * -big, FxQ16::MIN);
        assert_eq!(-FxQ16::MIN, FxQ16::MAX);
        assert_eq!(FxQ32::from_f64(1e12), FxQ32::MAX);
        assert_eq!(FxQ32::from_f32(f32::NAN), FxQ32::ZERO);
        let h = FxQ32::from_f64(1.5);
        assert_eq!((h * h).to_f64(), 2.25);
    }

    #[test]
    fn division_and_fallback() {
        let a = FxQ16::from_f32(3.0);
        let b = FxQ16::from_f32(-4.0);
        assert_eq!(a.div_or(b, FxQ16::ONE).to_f32(), -0.75);
        assert_eq!(a.div_or(FxQ16::ZERO, FxQ16::ONE), FxQ16::ONE);
        // quotient not representable → fallback
        assert_eq!(
            FxQ16::from_f32(1000.0).div_or(FxQ16::DELTA, FxQ16::ZERO),
            FxQ16::ZERO
        );
    }

    #[test]
    fn paper_powers_in_fixed_point() {
        let e59 = Exponent { num: 5, den: 9 };
        let m49 = Exponent { num: -4, den: 9 };
        let x = FxQ32::from_f64(0.3);
        let v = x.sig_pow(e59, FxQ32::ZERO).to_f64();
        assert!((v - 0.3f64.powf(5.0 / 9.0)).abs() < 1e-8, "{v}");
        let w = (-x).sig_pow(e59, FxQ32::ZERO).to_f64();
        assert_eq!(w, -v);
        let fl = FxQ16::from_f32(1e-4);
        assert_eq!(
            FxQ16::ZERO.pow_abs(m49, fl),
            fl.pow_abs(m49, fl),
            "negative exponent floors the base"
        );
        assert_eq!(FxQ16::from_f32(-27.0).cbrt().to_f32(), -3.0);
    }

    proptest::proptest! {
        /// One shared reciprocal gives exactly the two guarded divisions (any bits).
        #[test]
        fn shared_divisor_is_bit_identical_q32(a: i64, b: i64, d: i64, fb: i64) {
            let f = FxQ32::from_bits;
            let (qa, qb) = FxQ32::div2_or(f(a), f(b), f(d), f(fb));
            proptest::prop_assert_eq!(qa, f(a).div_or(f(d), f(fb)));
            proptest::prop_assert_eq!(qb, f(b).div_or(f(d), f(fb)));
        }

        #[test]
        fn shared_divisor_is_bit_identical_q16(a: i32, b: i32, d: i32, fb: i32) {
            let f = FxQ16::from_bits;
            let (qa, qb) = FxQ16::div2_or(f(a), f(b), f(d), f(fb));
            proptest::prop_assert_eq!(qa, f(a).div_or(f(d), f(fb)));
            proptest::prop_assert_eq!(qb, f(b).div_or(f(d), f(fb)));
        }

        /// ... and for the divisors of the coupling (|d|² of a path direction).
        #[test]
        fn shared_divisor_is_bit_identical_small(a in -1.0e6f64..1.0e6, d in 1.0e-9f64..1.0e7) {
            let (x, n2) = (FxQ32::from_f64(a), FxQ32::from_f64(d));
            let (q, _) = FxQ32::div2_or(x, x, n2, FxQ32::ZERO);
            proptest::prop_assert_eq!(q, x.div_or(n2, FxQ32::ZERO));
        }
    }
}
