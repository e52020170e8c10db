//! The number trait every law is written against.
//!
//! A law is written once over [`Real`]; `f32` is what the firmware runs, `f64` is the
//! host's reference precision, and a saturating fixed-point type implements the same
//! trait. Operations that can fail on real hardware are total here: division by (near)
//! zero returns a caller-chosen fallback, roots of negative numbers follow the real odd
//! root convention, and nothing returns NaN for finite input.

use super::exponent::Exponent;
use core::fmt::Debug;
use core::ops::{Add, AddAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// The arithmetic the control laws need. Implementations must be total: no panic, no
/// wrap-around, and no NaN or infinity produced from finite inputs.
pub trait Real:
    Copy
    + Debug
    + Default
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
{
    const ZERO: Self;
    const ONE: Self;

    fn from_f32(x: f32) -> Self;
    fn from_f64(x: f64) -> Self;
    fn to_f32(self) -> f32;
    fn to_f64(self) -> f64;

    /// `self / d`, or `fallback` when `|d|` is too small for the quotient to be
    /// representable (zero for floats; the type's resolution for fixed point).
    fn div_or(self, d: Self, fallback: Self) -> Self;

    /// `(a / d, b / d)`, each with [`Self::div_or`]'s guard. The default is two
    /// [`Self::div_or`]; floats multiply by one reciprocal instead (one division: each
    /// quotient within 1.5 ulp of the divided one; the fallback when `1/d` overflows,
    /// `|d|` below 2^-128 in `f32`, or the product does), fixed point shares the
    /// reciprocal (bit-identical to the default).
    fn div2_or(a: Self, b: Self, d: Self, fallback: Self) -> (Self, Self) {
        (a.div_or(d, fallback), b.div_or(d, fallback))
    }

    /// Real cube root, odd: `cbrt(-8) = -2`.
    fn cbrt(self) -> Self;

    /// Square root of `max(self, 0)`.
    fn sqrt_pos(self) -> Self;

    /// `|self|^e`. For `e < 0` the base is floored at `floor` (> 0) so the result stays
    /// bounded; for `e >= 0`, `0^e` is 0 (or 1 when e == 0).
    fn pow_abs(self, e: Exponent, floor: Self) -> Self;

    fn sin_cos(self) -> (Self, Self);

    fn is_finite(self) -> bool;

    /// `|self|^(1/den)` for a positive odd `den` (the shared roots of the sliding-mode
    /// laws); the default is [`Self::pow_abs`], types with a faster root override it.
    fn root_abs(self, den: i16) -> Self {
        self.pow_abs(Exponent { num: 1, den }, Self::ZERO)
    }

    fn abs(self) -> Self {
        if self < Self::ZERO {
            -self
        } else {
            self
        }
    }

    /// -1, 0 or 1 (0 exactly at zero, as the reaching laws need).
    fn sign(self) -> Self {
        if self > Self::ZERO {
            Self::ONE
        } else if self < Self::ZERO {
            -Self::ONE
        } else {
            Self::ZERO
        }
    }

    /// `self` with the sign of `s`: `-self` where `s < 0`, else `self`. For a magnitude
    /// `self >= 0` that is 0 where `s` is (`|s|^e`, e > 0) this is `sign(s) · self`, with
    /// one comparison instead of the sign's two and a multiplication (the same value:
    /// `(β·sign(s))·x` and `β·(-x)` round alike).
    fn with_sign_of(self, s: Self) -> Self {
        if s < Self::ZERO {
            -self
        } else {
            self
        }
    }

    fn min_of(self, o: Self) -> Self {
        if o < self {
            o
        } else {
            self
        }
    }

    fn max_of(self, o: Self) -> Self {
        if o > self {
            o
        } else {
            self
        }
    }

    /// Clamp to `[-limit, limit]` (`limit >= 0`).
    fn clamp_sym(self, limit: Self) -> Self {
        self.max_of(-limit).min_of(limit)
    }

    /// Finite and within `[-limit, limit]`: [`Self::clamp_sym`] and
    /// [`Self::clamp_finite`] leave such a value unchanged (the test the fast paths use).
    fn in_range(self, limit: Self) -> bool {
        self.is_finite() && self >= -limit && self <= limit
    }

    /// [`Self::finite_or_zero`], then [`Self::clamp_sym`]: a state or an output that must
    /// stay finite and within `±limit` (`limit >= 0`, possibly infinite).
    fn clamp_finite(self, limit: Self) -> Self {
        if self.in_range(limit) {
            self
        } else {
            self.finite_or_zero().clamp_sym(limit)
        }
    }

    /// `sig(x)^e = sign(x) |x|^e`.
    fn sig_pow(self, e: Exponent, floor: Self) -> Self {
        self.sign() * self.pow_abs(e, floor)
    }

    /// Replace a non-finite value by zero: the last line of defence before an output.
    fn finite_or_zero(self) -> Self {
        if self.is_finite() {
            self
        } else {
            Self::ZERO
        }
    }
}

macro_rules! impl_float_real {
    ($t:ty, $cbrt:path, $sqrt:path, $pow_abs:path, $sin_cos:path $(, $root_abs:path)?) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;

            fn from_f32(x: f32) -> Self {
                x as $t
            }
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            fn to_f32(self) -> f32 {
                self as f32
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            /// A zero `d` gives an infinite or NaN quotient: one finiteness test covers it.
            #[inline]
            fn div_or(self, d: Self, fallback: Self) -> Self {
                let q = self / d;
                if q.is_finite() {
                    q
                } else {
                    fallback
                }
            }
            /// `a · (1/d)`: a quotient that is not finite (`d` zero or NaN, `1/d`
            /// overflowing, the product overflowing) is the fallback.
            #[inline(always)]
            fn div2_or(a: Self, b: Self, d: Self, fallback: Self) -> (Self, Self) {
                let r = 1.0 / d;
                let q = |x: Self| {
                    let q = x * r;
                    if q.is_finite() {
                        q
                    } else {
                        fallback
                    }
                };
                (q(a), q(b))
            }
            fn cbrt(self) -> Self {
                $cbrt(self)
            }
            fn sqrt_pos(self) -> Self {
                if self > 0.0 {
                    $sqrt(self)
                } else {
                    0.0
                }
            }
            fn pow_abs(self, e: Exponent, floor: Self) -> Self {
                $pow_abs(self, e, floor)
            }
            #[inline(always)]
            fn sin_cos(self) -> (Self, Self) {
                $sin_cos(self)
            }
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            /// The hardware absolute value (`VABS`, clears the sign bit): `|-0.0| = +0.0`,
            /// which no law can tell from the default's `-0.0`.
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            /// The in-range case (the common one) first: one `VABS` and one comparison;
            /// the result is the default's for every input.
            #[inline(always)]
            fn clamp_sym(self, limit: Self) -> Self {
                if <$t>::abs(self) <= limit {
                    self
                } else {
                    self.max_of(-limit).min_of(limit)
                }
            }
            /// `|x| <= limit` and `|x| <= MAX` (NaN fails both): finite and in range.
            #[inline(always)]
            fn in_range(self, limit: Self) -> bool {
                let a = <$t>::abs(self);
                a <= limit && a <= <$t>::MAX
            }
            $(
                #[inline(always)]
                fn root_abs(self, den: i16) -> Self {
                    $root_abs(self, den)
                }
            )?
        }
    };
}

// f32, the firmware's type, takes the cube-root fast path for den ∈ {1, 3, 9} and an
// f32-only sin/cos (libm's `sincosf` works in f64, soft-float on the Cortex-M4F); see
// `powers`.
impl_float_real!(
    f32,
    crate::num::powers::cbrt_f32,
    libm::sqrtf,
    crate::num::powers::pow_abs_f32,
    crate::num::powers::sin_cos_f32,
    crate::num::powers::root_abs_f32
);
impl_float_real!(
    f64,
    libm::cbrt,
    libm::sqrt,
    crate::num::powers::pow_abs_f64,
    libm::sincos
);

/// `f32` with libm's generic `powf` and `cbrtf` for every fractional power: the reference
/// the fast powers are compared with, and the `dsmc3_f32_libm` cost kernel. Identical to
/// `f32` in everything else (including sin/cos), so the two kernels differ by the powers
/// alone.
#[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
pub struct LibmF32(pub f32);

macro_rules! libm_f32_binop {
    ($tr:ident, $f:ident, $op:tt, $tra:ident, $fa:ident) => {
        impl $tr for LibmF32 {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                LibmF32(self.0 $op o.0)
            }
        }
        impl $tra for LibmF32 {
            #[inline(always)]
            fn $fa(&mut self, o: Self) {
                self.0 = self.0 $op o.0;
            }
        }
    };
}
libm_f32_binop!(Add, add, +, AddAssign, add_assign);
libm_f32_binop!(Sub, sub, -, SubAssign, sub_assign);
libm_f32_binop!(Mul, mul, *, MulAssign, mul_assign);

impl Neg for LibmF32 {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        LibmF32(-self.0)
    }
}

impl Real for LibmF32 {
    const ZERO: Self = LibmF32(0.0);
    const ONE: Self = LibmF32(1.0);
    fn from_f32(x: f32) -> Self {
        LibmF32(x)
    }
    fn from_f64(x: f64) -> Self {
        LibmF32(x as f32)
    }
    fn to_f32(self) -> f32 {
        self.0
    }
    fn to_f64(self) -> f64 {
        self.0 as f64
    }
    fn div_or(self, d: Self, fallback: Self) -> Self {
        LibmF32(self.0.div_or(d.0, fallback.0))
    }
    fn div2_or(a: Self, b: Self, d: Self, fallback: Self) -> (Self, Self) {
        let (x, y) = f32::div2_or(a.0, b.0, d.0, fallback.0);
        (LibmF32(x), LibmF32(y))
    }
    fn cbrt(self) -> Self {
        LibmF32(libm::cbrtf(self.0))
    }
    fn sqrt_pos(self) -> Self {
        LibmF32(self.0.sqrt_pos())
    }
    fn pow_abs(self, e: Exponent, floor: Self) -> Self {
        LibmF32(crate::num::powers::pow_abs_f32_libm(self.0, e, floor.0))
    }
    fn sin_cos(self) -> (Self, Self) {
        // same sin/cos as f32: this type differs from f32 in the powers only
        let (s, c) = crate::num::powers::sin_cos_f32(self.0);
        (LibmF32(s), LibmF32(c))
    }
    fn is_finite(self) -> bool {
        self.0.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const E59: Exponent = Exponent { num: 5, den: 9 };

    #[test]
    fn odd_root_of_negative_is_negative() {
        assert_eq!((-8.0f64).cbrt(), -2.0);
        let v = (-1.0f64).sig_pow(E59, 1e-9);
        assert!((v + 1.0).abs() < 1e-12);
    }

    #[test]
    fn negative_exponent_is_floored() {
        let m49 = E59.minus_one();
        assert_eq!(m49, Exponent { num: -4, den: 9 });
        let at_zero = 0.0f32.pow_abs(m49, 1e-4);
        let at_floor = 1e-4f32.pow_abs(m49, 1e-4);
        assert_eq!(at_zero, at_floor);
        assert!((at_floor - libm::powf(1e-4, -4.0 / 9.0)).abs() < 1e-3);
    }

    #[test]
    fn guarded_division() {
        assert_eq!(1.0f32.div_or(0.0, 7.0), 7.0);
        assert_eq!(1.0f32.div_or(1e-45, 7.0), 7.0);
        assert_eq!(6.0f64.div_or(3.0, 7.0), 2.0);
        assert_eq!(f32::NAN.finite_or_zero(), 0.0);
    }

    /// Values where the float fast paths could part from the general definitions.
    const SPECIAL: [f32; 17] = [
        0.0,
        -0.0,
        1.0e-45,
        -1.0e-45,
        1.0,
        -1.0,
        2.5,
        -2.5,
        3.0,
        -3.0,
        3.000_000_2,
        -3.000_000_2,
        f32::MAX,
        -f32::MAX,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
    ];

    /// Same value, NaN equal to NaN, -0.0 distinct from +0.0.
    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    #[test]
    fn float_fast_paths_equal_the_general_definitions() {
        // the trait's general definitions, written out
        let clamp_ref = |x: f32, l: f32| x.max_of(-l).min_of(l);
        let in_range_ref = |x: f32, l: f32| x.is_finite() && x >= -l && x <= l;
        let mut checked = 0;
        for x in SPECIAL {
            for l in [0.0, 1.0, 3.0, f32::MAX, f32::INFINITY] {
                assert!(same(x.clamp_sym(l), clamp_ref(x, l)), "clamp_sym({x}, {l})");
                assert_eq!(x.in_range(l), in_range_ref(x, l), "in_range({x}, {l})");
                let cf = clamp_ref(x.finite_or_zero(), l);
                assert!(same(x.clamp_finite(l), cf), "clamp_finite({x}, {l})");
                checked += 1;
            }
            // with_sign_of is sign(s)·|x|^e (0 where s is 0)
            for e in [Exponent { num: 1, den: 3 }, Exponent { num: 5, den: 9 }] {
                let m = x.pow_abs(e, 0.0);
                if x.is_finite() {
                    assert_eq!(m.with_sign_of(x), x.sign() * m, "{x}");
                    assert_eq!(2.5 * m.with_sign_of(x), 2.5 * x.sign() * m, "{x}");
                }
            }
        }
        assert_eq!(checked, SPECIAL.len() * 5);
        // the fast paths keep the general results on either side of the limit
        assert_eq!(3.000_000_2f32.clamp_sym(3.0), 3.0);
        assert_eq!(f32::INFINITY.clamp_finite(f32::INFINITY), 0.0);
        assert!(!f32::INFINITY.in_range(f32::INFINITY));
    }

    #[test]
    fn one_reciprocal_for_two_quotients() {
        // floats: within 1.5 ulp of the divided quotients; the fallback where a quotient
        // is not finite
        let mut worst = 0.0f64;
        let mut d = 1.0e-6f32;
        while d < 1.0e6 {
            for a in [1.0f32, -3.7, 1234.5, 1.0e-3, 0.0] {
                let (q, q2) = f32::div2_or(a, -a, d, 9.0);
                let exact = a as f64 / d as f64;
                let ulp = (exact.abs() as f32).max(f32::MIN_POSITIVE) * f32::EPSILON;
                worst = worst.max((q as f64 - exact).abs() / ulp as f64);
                assert_eq!(q2, -q);
            }
            d *= 1.37;
        }
        assert!(worst <= 1.5, "{worst} ulp");
        assert!(
            worst > 0.0,
            "the reciprocal must round differently somewhere"
        );
        assert_eq!(f32::div2_or(1.0, 2.0, 0.0, 7.0), (7.0, 7.0));
        assert_eq!(f32::div2_or(0.0, 2.0, 0.0, 7.0), (7.0, 7.0));
        assert_eq!(f32::div2_or(1.0, 2.0, f32::NAN, 7.0), (7.0, 7.0));
        assert_eq!(f32::div2_or(f32::MAX, 1.0, 0.5, 7.0), (7.0, 2.0));
        // LibmF32 differs from f32 in the powers only
        let (a, b) = LibmF32::div2_or(LibmF32(3.0), LibmF32(-6.1), LibmF32(7.0), LibmF32(0.0));
        assert_eq!((a.0, b.0), f32::div2_or(3.0, -6.1, 7.0, 0.0));
    }

    #[test]
    fn exponent_requires_odd_denominator() {
        assert!(Exponent::new(1, 2).is_none());
        assert!(Exponent::new(5, 9).is_some());
        assert_eq!(
            Exponent::new(9, 5).unwrap().two_minus(),
            Exponent { num: 1, den: 5 }
        );
    }
}
