//! Several powers of one base from a single root.
//!
//! The sliding-mode laws raise the same base to several exponents with one odd
//! denominator: `|e|^(5/9)` and `|e|^(1/3) = |e|^(3/9)` per axis, `|s|^(5/3)` and
//! `|s|^(1/3)`. Computing each with its own fractional power repeats the expensive part (a
//! root) for every exponent; a [`PowerSet`] takes the root once, `r = |x|^(1/D)`, and
//! forms every power as a small integer power of `r`. Exponents that do not fit (a
//! denominator that does not divide the others', or a large numerator) keep the general
//! [`Real::pow_abs`] path, so the result is the same function either way.

use crate::{Exponent, Real};

/// Largest integer power formed by repeated multiplication (beyond it, `pow_abs` is
/// cheaper and more accurate).
const MAX_K: i16 = 15;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Plan {
    /// `r^k` with `r = |x|^(1/D)`.
    Root(u8),
    /// A general `|x|^e`.
    General(Exponent),
}

/// Plan for `|x|^e_i`, `i < N`, all exponents positive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PowerSet<const N: usize> {
    root: Exponent,
    plans: [Plan; N],
    needs_root: bool,
}

impl<const N: usize> PowerSet<N> {
    /// Plan the exponents; any with `num <= 0`, or not expressible as `k/D` with the
    /// largest denominator `D` and `k <= 15`, use the general path.
    pub fn new(exps: [Exponent; N]) -> Self {
        let d = exps.iter().map(|e| e.den).max().unwrap_or(1).max(1);
        let plans = exps.map(|e| {
            // `d / den` when `den` divides `d` (checked: no division panic can reach the
            // control interrupt, which rebuilds laws on a settings change)
            let ratio = (e.den > 0 && d.checked_rem(e.den) == Some(0))
                .then(|| d.checked_div(e.den))
                .flatten();
            let k = ratio
                .filter(|&q| q > 0 && e.num > 0 && e.num <= MAX_K.checked_div(q).unwrap_or(0))
                .and_then(|q| e.num.checked_mul(q));
            match k {
                Some(k) => Plan::Root(k as u8),
                None => Plan::General(e),
            }
        });
        Self {
            root: Exponent { num: 1, den: d },
            needs_root: plans.iter().any(|p| matches!(p, Plan::Root(_))),
            plans,
        }
    }

    /// `[|x|^e_0, …, |x|^e_{N-1}]`.
    #[inline(always)]
    pub fn eval<R: Real>(&self, x: R) -> [R; N] {
        let a = x.abs();
        let r = if self.needs_root {
            a.root_abs(self.root.den)
        } else {
            R::ZERO
        };
        self.plans.map(|p| match p {
            Plan::Root(k) => ipow(r, k),
            Plan::General(e) => a.pow_abs(e, R::ZERO),
        })
    }
}

/// `[r^K0, r^K1]` with `r = |x|^(1/D)`: a two-power plan fixed at compile time, the same
/// operations as [`PowerSet::eval`] for the plan `[Root(K0), Root(K1)]` with root `1/D`
/// (so the results are identical).
#[inline(always)]
pub fn root_powers<R: Real, const D: i16, const K0: u8, const K1: u8>(x: R) -> [R; 2] {
    let r = x.abs().root_abs(D);
    [ipow(r, K0), ipow(r, K1)]
}

/// `r^k`, `1 <= k <= 15`: the laws' small powers unrolled, larger ones by
/// square-and-multiply.
#[inline(always)]
fn ipow<R: Real>(r: R, k: u8) -> R {
    match k {
        1 => return r,
        2 => return r * r,
        3 => return r * r * r,
        5 => {
            let r2 = r * r;
            return r2 * r2 * r;
        }
        _ => {}
    }
    let mut acc = R::ONE;
    let mut base = r;
    let mut k = k;
    while k > 0 {
        if k & 1 == 1 {
            acc = acc * base;
        }
        k >>= 1;
        if k > 0 {
            base = base * base;
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    const fn ex(num: i16, den: i16) -> Exponent {
        Exponent { num, den }
    }

    #[test]
    fn shared_root_matches_separate_powers() {
        let set = PowerSet::new([ex(5, 9), ex(1, 3)]);
        assert_eq!(set.plans, [Plan::Root(5), Plan::Root(3)]);
        let s = PowerSet::new([ex(5, 3), ex(1, 3)]);
        assert_eq!(s.plans, [Plan::Root(5), Plan::Root(1)]);
        for x in [1e-9f64, 1e-4, 0.3, 1.0, 7.5, 1e6] {
            let [a, b] = set.eval(-x);
            assert!((a / libm::pow(x, 5.0 / 9.0) - 1.0).abs() < 1e-12, "{x}");
            assert!((b / libm::cbrt(x) - 1.0).abs() < 1e-12, "{x}");
            let [c, d] = s.eval(x as f32);
            assert!(
                (c as f64 / libm::pow(x, 5.0 / 3.0) - 1.0).abs() < 1e-5,
                "{x}"
            );
            assert!((d as f64 / libm::cbrt(x) - 1.0).abs() < 1e-5, "{x}");
        }
        assert_eq!(set.eval(0.0f32), [0.0, 0.0]);
    }

    #[test]
    fn unfit_exponents_take_the_general_path() {
        let set = PowerSet::new([ex(5, 9), ex(1, 5)]);
        assert_eq!(set.plans[1], Plan::General(ex(1, 5)));
        let big = PowerSet::new([ex(17, 9)]);
        assert_eq!(big.plans[0], Plan::General(ex(17, 9)));
        let [a, b] = set.eval(2.0f64);
        assert!((a - libm::pow(2.0, 5.0 / 9.0)).abs() < 1e-12);
        assert!((b - libm::pow(2.0, 0.2)).abs() < 1e-12);
    }
}
