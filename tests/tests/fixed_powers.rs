//! Accuracy of the fast fractional powers, cube roots, division and sine/cosine against
//! `f64`, over the ranges the laws use, for `f32` and both fixed-point formats. The bounds
//! are the documented constants of `controller_core::num::powers` and `controller_core::num::fixed`.

use controller_core::num::fixed::{
    FxQ16, FxQ32, FX_POW_MAX_REL_ERR, FX_ROOT_MAX_REL_ERR, FX_ROUTINE_MAX_LSB,
};
use controller_core::num::powers::{pow_abs_f32, POW_F32_MAX_REL_ERR};
use controller_core::{Exponent, Real};
use proptest::prelude::*;

/// The paper's exponents and their derived ones (5/9, -4/9, 1/3, 5/3) plus a few more
/// with the same denominators.
const EXPONENTS: [(i16, i16); 8] = [
    (5, 9),
    (-4, 9),
    (1, 3),
    (5, 3),
    (2, 3),
    (-1, 3),
    (1, 9),
    (2, 1),
];

fn exact(x: f64, e: Exponent) -> f64 {
    x.abs().powf(e.num as f64 / e.den as f64)
}

/// Error of a fixed-point result against the exact value, in units of the allowed error:
/// `FX_POW_MAX_REL_ERR · |exact| + FX_ROUTINE_MAX_LSB · lsb · (1 + |n|·|d ln r|)`, i.e. the
/// relative error of the root core plus the format's rounding propagated through the
/// integer power. Below 1 passes.
fn fx_err(got: f64, want: f64, lsb: f64, e: Exponent, root: f64) -> f64 {
    let n = e.num.unsigned_abs() as f64;
    // rounding of the root (1 LSB) grows by n · root^(n-1) through the integer power
    let prop = n * root.powf(n - 1.0).max(1.0) * lsb;
    let allowed = FX_POW_MAX_REL_ERR * want.abs() + FX_ROUTINE_MAX_LSB * (lsb + prop);
    (got - want).abs() / allowed
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn f32_powers_within_bound(l in -20.0f64..20.0, k in 0usize..EXPONENTS.len()) {
        let x = 10f64.powf(l) as f32;
        let e = Exponent { num: EXPONENTS[k].0, den: EXPONENTS[k].1 };
        let got = pow_abs_f32(x, e, 0.0) as f64;
        let want = exact(x as f64, e);
        if want < 1e37 && want > 1e-37 {
            prop_assert!(((got - want) / want).abs() <= POW_F32_MAX_REL_ERR as f64,
                "{}^{}/{}: {} vs {}", x, e.num, e.den, got, want);
        }
    }

    #[test]
    fn q32_powers_within_bound(l in -9.0f64..9.0, k in 0usize..EXPONENTS.len()) {
        let x = FxQ32::from_f64(10f64.powf(l));
        let e = Exponent { num: EXPONENTS[k].0, den: EXPONENTS[k].1 };
        let xv = x.to_f64();
        prop_assume!(xv > 0.0);
        let want = exact(xv, e);
        prop_assume!(want < 2.0e9);
        let got = x.pow_abs(e, FxQ32::ZERO).to_f64();
        let root = xv.powf(1.0 / e.den as f64 * e.num.signum() as f64);
        let r = fx_err(got, want, 1.0 / 4294967296.0, e, root);
        prop_assert!(r <= 1.0, "{}^{}/{}: {} vs {} ({:.2} of the bound)", xv, e.num, e.den, got, want, r);
    }

    #[test]
    fn q16_powers_within_bound(l in -4.5f64..4.5, k in 0usize..EXPONENTS.len()) {
        let x = FxQ16::from_f64(10f64.powf(l));
        let e = Exponent { num: EXPONENTS[k].0, den: EXPONENTS[k].1 };
        let xv = x.to_f64();
        prop_assume!(xv > 0.0);
        let want = exact(xv, e);
        prop_assume!(want < 32000.0);
        let got = x.pow_abs(e, FxQ16::ZERO).to_f64();
        let root = xv.powf(1.0 / e.den as f64 * e.num.signum() as f64);
        let r = fx_err(got, want, 1.0 / 65536.0, e, root);
        prop_assert!(r <= 1.0, "{}^{}/{}: {} vs {} ({:.2} of the bound)", xv, e.num, e.den, got, want, r);
    }

    #[test]
    fn fixed_division_within_bound(a in -1.0e6f64..1.0e6, b in -1.0e6f64..1.0e6) {
        let (x, y) = (FxQ32::from_f64(a), FxQ32::from_f64(b));
        prop_assume!(y != FxQ32::ZERO);
        let want = x.to_f64() / y.to_f64();
        let got = x.div_or(y, FxQ32::MAX);
        if want.abs() < 2.0e9 {
            let tol = FX_ROOT_MAX_REL_ERR * want.abs() + FX_ROUTINE_MAX_LSB / 4294967296.0;
            prop_assert!((got.to_f64() - want).abs() <= tol, "{} / {}: {} vs {}", a, b, got.to_f64(), want);
        } else {
            prop_assert_eq!(got, FxQ32::MAX, "unrepresentable quotient takes the fallback");
        }
    }

    #[test]
    fn fixed_sin_cos_within_bound(t in -20_000.0f64..20_000.0) {
        let x = FxQ32::from_f64(t);
        let (s, c) = x.sin_cos();
        let xv = x.to_f64();
        // Q31 polynomial error (4 LSB of Q31) plus truncation to Q32 output
        let tol = 4.0 / 2147483648.0 + 1.0 / 4294967296.0;
        prop_assert!((s.to_f64() - xv.sin()).abs() <= tol);
        prop_assert!((c.to_f64() - xv.cos()).abs() <= tol);
        let y = FxQ16::from_f64(t.clamp(-32000.0, 32000.0));
        let (s, c) = y.sin_cos();
        let yv = y.to_f64();
        prop_assert!((s.to_f64() - yv.sin()).abs() <= 2.0 / 65536.0);
        prop_assert!((c.to_f64() - yv.cos()).abs() <= 2.0 / 65536.0);
    }
}

#[test]
fn negative_exponents_are_floored_and_odd_powers_keep_the_sign() {
    let m49 = Exponent { num: -4, den: 9 };
    let e59 = Exponent { num: 5, den: 9 };
    let floor = FxQ32::from_f64(1e-4);
    let at_floor = floor.pow_abs(m49, floor).to_f64();
    let want = floor.to_f64().powf(-4.0 / 9.0);
    assert!((at_floor - want).abs() < 1e-6, "{at_floor} vs {want}");
    assert_eq!(FxQ32::ZERO.pow_abs(m49, floor).to_f64(), at_floor);
    let x = FxQ32::from_f64(0.0123);
    assert_eq!(
        (-x).sig_pow(e59, FxQ32::ZERO),
        -(x.sig_pow(e59, FxQ32::ZERO))
    );
    // den 5 is outside the fast path: the f32 fallback still answers
    let e15 = Exponent { num: 1, den: 5 };
    let v = FxQ32::from_f64(32.0).pow_abs(e15, FxQ32::ZERO).to_f64();
    assert!((v - 2.0).abs() < 1e-6, "{v}");
}
