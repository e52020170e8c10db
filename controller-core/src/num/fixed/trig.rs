//! Fixed-point `sin`/`cos` for the trajectory generator, integer arithmetic only.
//!
//! The angle is reduced to `r ∈ [-π/4, π/4]` with a quadrant index `n = round(x / (π/2))`
//! using a two-part `π/2` (64 + 32 bits, Cody-Waite style), so the reduction error is
//! below 2^-33 rad for every angle a Q32.32 value can hold. `sin r` and `cos r` are their
//! Taylor polynomials to degree 11 and 10 in Q31 (truncation below 2^-31 at `|r| = π/4`).
//! Maximum absolute error of the Q31 results: 4 · 2^-31 (tested in `tests/tests/fixed_*`);
//! the fixed types then truncate to their own resolution.

/// `2/π` in Q61.
const TWO_OVER_PI_Q61: i64 = 0x145F_306D_C9C8_82A5;
/// `π/2 · 2^64 = PIO2_HI · 2^32 + PIO2_LO`.
const PIO2_HI: i64 = 0x1_921F_B544;
const PIO2_LO: i64 = 0x42D1_8469;

/// Taylor coefficients in Q31: sin r = r (1 + z (S1 + z (S2 + ...))), z = r².
const SIN_Q31: [i64; 5] = [-357_913_941, 17_895_697, -426_088, 5_918, -54];
/// cos r = 1 + z (C1 + z (C2 + ...)).
const COS_Q31: [i64; 5] = [-1_073_741_824, 89_478_485, -2_982_616, 53_261, -592];

#[inline(always)]
fn mul31(a: i64, b: i64) -> i64 {
    (a * b) >> 31
}

#[inline(always)]
fn horner(z: i64, c: &[i64; 5]) -> i64 {
    let mut acc = c[4];
    acc = c[3] + mul31(z, acc);
    acc = c[2] + mul31(z, acc);
    acc = c[1] + mul31(z, acc);
    c[0] + mul31(z, acc)
}

/// Convert a Q31 value (|v| <= 2^31) to `frac` fractional bits (truncating).
#[inline(always)]
pub fn q31_to(v: i64, frac: u32) -> i64 {
    if frac >= 31 {
        v << (frac - 31).min(32)
    } else {
        v >> (31 - frac)
    }
}

/// `(sin x, cos x)` in Q31 for `x` given as a raw fixed-point value with `frac <= 32`
/// fractional bits.
pub fn sin_cos_q31(x: i64, frac: u32) -> (i64, i64) {
    let sh = 32u32.saturating_sub(frac);
    // Q32 angle; the caller's formats keep |x| · 2^sh below 2^63 (Q16.16: 2^47).
    let xq = x.checked_shl(sh).unwrap_or(0);
    let n = ((xq as i128 * TWO_OVER_PI_Q61 as i128 + (1i128 << 92)) >> 93) as i64;
    // r = x - n π/2. The true r is below π/4 in magnitude, so wrapping (modular) i64
    // arithmetic gives it exactly even when n · PIO2_HI alone would overflow.
    let r = xq
        .wrapping_sub(n.wrapping_mul(PIO2_HI))
        .wrapping_sub(n.wrapping_mul(PIO2_LO) >> 32);
    let r31 = r >> 1;
    let z = mul31(r31, r31);
    let s = r31 + mul31(r31, mul31(z, horner(z, &SIN_Q31)));
    let c = (1i64 << 31) + mul31(z, horner(z, &COS_Q31));
    match n & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_f64_within_four_q31_lsb() {
        let lsb = 1.0 / 2_147_483_648.0;
        let mut worst = 0.0f64;
        for k in -20_000i64..20_000 {
            let x = k as f64 * 0.01234;
            let raw = (x * 4_294_967_296.0) as i64;
            let xr = raw as f64 / 4_294_967_296.0;
            let (s, c) = sin_cos_q31(raw, 32);
            worst = worst
                .max((s as f64 * lsb - xr.sin()).abs())
                .max((c as f64 * lsb - xr.cos()).abs());
        }
        assert!(worst <= 4.0 * lsb, "worst {worst:e}");
        // Q16.16 input path and the largest Q32.32 angle
        let (s, c) = sin_cos_q31(3 << 16, 16);
        assert!((s as f64 * lsb - 3f64.sin()).abs() < 4.0 * lsb);
        assert!((c as f64 * lsb - 3f64.cos()).abs() < 4.0 * lsb);
        let big = i64::MAX;
        let (s, c) = sin_cos_q31(big, 32);
        let xb = big as f64 / 4_294_967_296.0;
        assert!((s as f64 * lsb - xb.sin()).abs() < 1e-6);
        assert!((c as f64 * lsb - xb.cos()).abs() < 1e-6);
    }
}
