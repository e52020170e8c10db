//! Fast fractional powers `|x|^(num/den)` for the exponents of the paper's laws, and the
//! `f32` sine/cosine the trajectory generator needs (libm's evaluates in soft `f64`).
//!
//! Every exponent the laws use has denominator 1, 3 or 9 (1/3, 5/3, 5/9, -4/9), so a
//! power is an integer power of a cube root (den 3) or of a cube root of a cube root
//! (den 9). A generic `powf` (log + exp, with argument reduction) costs hundreds of cycles
//! on a Cortex-M4F; the cube roots here cost a few dozen instructions and no division.
//!
//! Both the `f32` and the fixed-point paths compute the *inverse* root `y = x^(-1/3)`
//! with a division-free iteration and derive `x^(1/3) = x y²` from it; negative exponents
//! then need no division either. For den 9, `f32` computes `x^(-1/9)` directly with the
//! same kind of iteration (one root instead of two); fixed point takes the cube root of
//! a cube root (`x^(-1/9) = cbrt(x^(-1/3))`).
//!
//! Iteration: with `r = 1 - x y^p`, `y ← y (1 - r)^(-1/p)` truncated after a few terms of
//! its series. Seeds: the `f32` path uses the exponent-bit trick (max relative seed error
//! 3.4 % for p = 3, 3.0 % for p = 9, so `|r|` up to 0.105 and 0.27), the fixed-point path
//! a 28-entry table over the normalised mantissa (2.6 %).
//!
//! Error budget of the `f32` roots: the laws form powers `r^k` (k <= 5) of a
//! shared root, and a power term must stay within 1e-5 relative, so that a term as large as
//! the amplifier's full scale errs by less than 1/24 of its 12-bit command quantum
//! (2.4e-4 of full scale); that allows 2e-6 per root. Within it, the iteration is as short
//! as the instruction count allows:
//! - p = 3: one step of fifth order (`1 + r/3 + 2r²/9 + 14r³/81 + 35r⁴/243 + 91r⁵/729`,
//!   truncation `≈ 0.11 r⁶ ≤ 1.5e-7`) instead of two of third order: 4 instructions less
//!   per root, the result within [`CBRT_F32_MAX_REL_ERR`] (6e-7, from 4e-7; perfect
//!   cubes are no longer exact: `cbrt(8) = 2 - 1 ulp`).
//! - p = 9: two third-order steps (`1 + r/9 + 5r²/81`, truncation `≈ 0.043 r³`). From the
//!   3 % seed one step would need seven terms to stay within the budget (`r` is 9 times
//!   the seed error): as many instructions as the two steps, whose loaded constants it
//!   multiplies, so the two steps stay.
//! - fixed point: two third-order steps in Q30 reach the format's precision.
//!
//! Maximum relative errors (tested in this module and in `tests/tests/fixed_powers.rs`):
//! - [`inv_cbrt_f32`], [`cbrt_f32`]: [`CBRT_F32_MAX_REL_ERR`] (5 ulp; the exhaustive
//!   worst over one period of the seed, [1, 8), is 2.4e-7 and 5.6e-7).
//! - [`inv_root9_f32`]: [`CBRT_F32_MAX_REL_ERR`] as well (exhaustive worst 1.2e-7).
//! - [`pow_abs_f32`] for den 3 and 9: about `|num|` times the root's error plus one
//!   rounding per multiply; bounded by [`POW_F32_MAX_REL_ERR`] for |num| <= 5. The
//!   exhaustive worst over one period of both seeds, [1, 512) (every `f32` there; the
//!   error pattern repeats with the exponent), is 6.45e-6 for 5/9 at x = 22.47246 (the
//!   ninth root `x y⁸` carries 8 times the error of `y`, the fifth power 5 times that),
//!   5.2e-6 for 4/9, 2.8e-6 for 5/3, below 1.4e-6 for the others: within the 1e-5 budget.
//! - [`cbrt_norm`], the fixed-point core: [`CBRT_NORM_MAX_REL_ERR`] (about 2^-27:
//!   a few LSB of the Q30 result); the fixed types round the result to their resolution.

use crate::Exponent;

/// Maximum relative error of [`cbrt_f32`], [`inv_cbrt_f32`] and [`inv_root9_f32`] over
/// all positive finite `f32` (the module's error budget).
pub const CBRT_F32_MAX_REL_ERR: f32 = 6.0e-7;

/// Maximum relative error of [`pow_abs_f32`] for `den ∈ {1, 3, 9}`, `|num| <= 5`
/// (exhaustive worst 6.45e-6, module docs).
pub const POW_F32_MAX_REL_ERR: f32 = 7.0e-6;

/// Maximum relative error of [`cbrt_norm`] and [`inv_cbrt_norm`].
pub const CBRT_NORM_MAX_REL_ERR: f64 = 1.0e-8;

/// Magic constant of the inverse-cube-root bit trick: `bits(y0) = M - bits(x)/3`. Chosen
/// by a sweep minimising the seed's maximum relative error over [1, 8) (3.4 %).
const INV_CBRT_MAGIC: u32 = 0x54a2_32a0;

/// `x^(-1/3)` for `x > 0` finite; other inputs: `0 → +inf`-free large value is the
/// caller's job (see [`pow_abs_f32`], which floors the base first).
#[inline]
pub fn inv_cbrt_f32(x: f32) -> f32 {
    if x < f32::MIN_POSITIVE {
        // Subnormals break the bit trick: scale by 2^24 (whose cube root is 2^8).
        return inv_cbrt_normal_f32(x * 16_777_216.0) * 256.0;
    }
    inv_cbrt_normal_f32(x)
}

/// [`inv_cbrt_f32`] for a normal, finite, positive `x` (the caller has checked): the
/// bit-trick seed and one fifth-order step (module docs: error budget).
#[inline(always)]
fn inv_cbrt_normal_f32(x: f32) -> f32 {
    let y = f32::from_bits(INV_CBRT_MAGIC.wrapping_sub(x.to_bits() / 3));
    let r = 1.0 - x * (y * y * y);
    y + y
        * (r * (1.0 / 3.0
            + r * (2.0 / 9.0 + r * (14.0 / 81.0 + r * (35.0 / 243.0 + r * (91.0 / 729.0))))))
}

/// Real cube root, odd in `x` (`cbrt(-8) = -2`), exact at 0, NaN/inf pass through.
#[inline]
pub fn cbrt_f32(x: f32) -> f32 {
    let a = if x < 0.0 { -x } else { x };
    if a == 0.0 || !(a <= f32::MAX) {
        return x;
    }
    // Very large `a`: a * y² is fine (y ~ a^(-1/3)), no overflow anywhere.
    let y = inv_cbrt_f32(a);
    let c = a * y * y;
    if x < 0.0 {
        -c
    } else {
        c
    }
}

/// `b^n` (n >= 0): the small powers the laws use are unrolled, larger ones loop.
#[inline(always)]
fn ipow_f32(b: f32, n: u32) -> f32 {
    match n {
        0 => 1.0,
        1 => b,
        2 => b * b,
        3 => b * b * b,
        4 => {
            let b2 = b * b;
            b2 * b2
        }
        5 => {
            let b2 = b * b;
            b2 * b2 * b
        }
        _ => {
            let (mut acc, mut b, mut n) = (1.0f32, b, n);
            while n > 0 {
                if n & 1 == 1 {
                    acc *= b;
                }
                b *= b;
                n >>= 1;
            }
            acc
        }
    }
}

/// Largest `|x|` for which [`sin_cos_f32`] uses its own reduction (`n · PIO2_1` is then
/// exact); beyond it, and for NaN/inf, it defers to `libm::sincosf`.
const SIN_COS_FAST_MAX: f32 = 65_536.0;

/// `π/2` in three parts (Cephes): `PIO2_1` has 8 significant bits so `n · PIO2_1` is exact.
const PIO2_1: f32 = 1.570_312_5;
const PIO2_2: f32 = 4.837_513e-4;
const PIO2_3: f32 = 7.549_79e-8;

/// Maximum absolute error of [`sin_cos_f32`] for `|x| <= 100` (tested; grows with `|x|`
/// by the reduction's `|n| · 2^-47` and the input's own ulp).
pub const SIN_COS_F32_MAX_ABS_ERR: f32 = 3.0e-7;

/// `(sin x, cos x)` in `f32` arithmetic only. `libm::sincosf` evaluates in `f64`, which is
/// soft-float on the Cortex-M4F (about 2,700 instructions per call there); this costs
/// about 40. Cody-Waite reduction to `[-π/4, π/4]` and the Cephes minimax polynomials.
#[inline]
pub fn sin_cos_f32(x: f32) -> (f32, f32) {
    if !(x.abs() <= SIN_COS_FAST_MAX) {
        return libm::sincosf(x);
    }
    // round(x · 2/π) by the 1.5 · 2^23 trick (|x · 2/π| < 2^22 here)
    const SHIFTER: f32 = 12_582_912.0;
    let n = (x * core::f32::consts::FRAC_2_PI + SHIFTER) - SHIFTER;
    let r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3;
    let z = r * r;
    let s = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * r + r;
    let c = ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
    match (n as i32) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Magic constant of the inverse-ninth-root bit trick: `bits(y0) = M - bits(x)/9`
/// (max relative seed error 3.0 %, same sweep as [`INV_CBRT_MAGIC`]).
const INV_ROOT9_MAGIC: u32 = 0x4687_6c98;

/// `x^(-1/9)` for `x > 0` finite: bit-trick seed and two third-order steps of
/// `y ← y (1 + r/9 + 5r²/81)`, `r = 1 - x y⁹` (one root instead of two cube roots).
#[inline]
pub fn inv_root9_f32(x: f32) -> f32 {
    if x < f32::MIN_POSITIVE {
        // Subnormals: scale by 2^63, whose ninth root is 2^7.
        return inv_root9_normal_f32(x * 9.223_372e18) * 128.0;
    }
    inv_root9_normal_f32(x)
}

/// [`inv_root9_f32`] for a normal, finite, positive `x` (the caller has checked).
#[inline(always)]
fn inv_root9_normal_f32(x: f32) -> f32 {
    let mut y = f32::from_bits(INV_ROOT9_MAGIC.wrapping_sub(x.to_bits() / 9));
    for _ in 0..2 {
        let y2 = y * y;
        let y4 = y2 * y2;
        let r = 1.0 - x * (y4 * y4 * y);
        y += y * (r * (1.0 / 9.0 + r * (5.0 / 81.0)));
    }
    y
}

/// `x^(1/3)` and `x^(1/9)` from their inverse roots, `x` normal, finite, positive.
#[inline(always)]
fn root_normal_f32(a: f32, den: i16) -> Option<f32> {
    match den {
        3 => {
            let y = inv_cbrt_normal_f32(a);
            Some(a * y * y)
        }
        9 => {
            let y = inv_root9_normal_f32(a);
            let y2 = y * y;
            let y4 = y2 * y2;
            Some(a * (y4 * y4))
        }
        _ => None,
    }
}

/// Bits of `f32::MIN_POSITIVE` (the smallest normal) and of `+inf`.
const MIN_NORMAL_BITS: u32 = 0x0080_0000;
const INF_BITS: u32 = 0x7f80_0000;

/// `|x|^(1/den)`, the shared root of the sliding-mode powers: cube and ninth roots by
/// their bit-trick seeds and Newton-type steps directly (no exponent dispatch), any other
/// denominator through [`pow_abs_f32`]. Same accuracy as [`pow_abs_f32`]. Always inlined:
/// the laws call it with a constant `den` (the dispatch then folds away); a normal, finite
/// `x` (the control period's case) is recognised by one unsigned comparison of its bits,
/// everything else (0, subnormals, inf, NaN) takes `root_abs_rare_f32`.
#[inline(always)]
pub fn root_abs_f32(x: f32, den: i16) -> f32 {
    let a = x.abs();
    if a.to_bits().wrapping_sub(MIN_NORMAL_BITS) < INF_BITS - MIN_NORMAL_BITS {
        if let Some(r) = root_normal_f32(a, den) {
            return r;
        }
    }
    root_abs_rare_f32(a, den)
}

/// [`root_abs_f32`] of `a >= 0` (or NaN) for zero, subnormal, infinite and NaN `a`, and
/// for denominators other than 3 and 9.
#[cold]
#[inline(never)]
fn root_abs_rare_f32(a: f32, den: i16) -> f32 {
    if a == 0.0 || !(a <= f32::MAX) {
        return pow_abs_f32(a, Exponent { num: 1, den }, 0.0);
    }
    match den {
        3 => {
            let y = inv_cbrt_f32(a);
            a * y * y
        }
        9 => {
            let y = inv_root9_f32(a);
            let y2 = y * y;
            let y4 = y2 * y2;
            a * (y4 * y4)
        }
        _ => pow_abs_f32(a, Exponent { num: 1, den }, 0.0),
    }
}

/// `|x|^e` with the [`crate::Real::pow_abs`] contract: for `e < 0` the base is floored at
/// `floor`; `0^e = 0` for `e > 0`, `x^0 = 1`; a non-finite result becomes `f32::MAX`.
/// Denominators 1, 3 and 9 take the fast path, any other falls back to `libm::powf`.
#[inline]
pub fn pow_abs_f32(x: f32, e: Exponent, floor: f32) -> f32 {
    let mut base = if x < 0.0 { -x } else { x };
    if e.num < 0 {
        if !(base >= floor) {
            base = floor;
        }
        if base == 0.0 {
            return f32::MAX; // floor 0 (no floor): 0^(negative) is unbounded
        }
    } else if e.num == 0 {
        return 1.0;
    } else if base == 0.0 {
        return 0.0;
    }
    let n = e.num.unsigned_abs() as u32;
    let r = if !(base <= f32::MAX) {
        // inf or NaN: the reference handles the special cases
        libm::powf(base, e.as_f32())
    } else {
        match e.den {
            1 if e.num > 0 => ipow_f32(base, n),
            1 => 1.0 / ipow_f32(base, n),
            3 => {
                let y = inv_cbrt_f32(base);
                // x^(1/3) = x y², x^(-1/3) = y
                ipow_f32(if e.num > 0 { base * y * y } else { y }, n)
            }
            9 => {
                let y = inv_root9_f32(base);
                // x^(1/9) = x y⁸, x^(-1/9) = y
                let root = if e.num > 0 {
                    let y2 = y * y;
                    let y4 = y2 * y2;
                    base * (y4 * y4)
                } else {
                    y
                };
                ipow_f32(root, n)
            }
            _ => libm::powf(base, e.as_f32()),
        }
    };
    if r.is_finite() {
        r
    } else {
        f32::MAX
    }
}

/// `|x|^e` through libm's generic `pow` with the [`crate::Real::pow_abs`] contract (base
/// floored for `e < 0`, `0^e = 0` for `e > 0`, non-finite results saturate to `MAX`).
macro_rules! libm_pow_abs {
    ($(#[$doc:meta])* $vis:vis $name:ident, $t:ty, $pow:path, $as:ident) => {
        $(#[$doc])*
        #[inline]
        $vis fn $name(x: $t, e: Exponent, floor: $t) -> $t {
            let mut base = if x < 0.0 { -x } else { x };
            if e.num < 0 {
                if !(base >= floor) {
                    base = floor;
                }
            } else if e.num == 0 {
                return 1.0;
            } else if base == 0.0 {
                return 0.0;
            }
            let r = $pow(base, e.$as());
            if r.is_finite() {
                r
            } else {
                <$t>::MAX
            }
        }
    };
}

libm_pow_abs!(
    /// The libm reference of [`pow_abs_f32`] (same contract), kept for comparison and for
    /// the `dsmc3_f32_libm` cost measurement.
    pub pow_abs_f32_libm, f32, libm::powf, as_f32
);

libm_pow_abs!(
    /// `f64` keeps the generic libm `pow`: it is the host's reference precision.
    pub(crate) pow_abs_f64, f64, libm::pow, as_f64
);

// ---------------------------------------------------------------------------------------
// Integer core for the fixed-point types.
// ---------------------------------------------------------------------------------------

/// Seeds of `f^(-1/3)` in Q30 for `f ∈ [i/32, (i+1)/32)`, i = 4..31 (geometric mean of the
/// interval's end values; max relative seed error 2.6 % at i = 4).
const INV_CBRT_SEED_Q30: [u32; 32] = [
    0x4000_0000,
    0x4000_0000,
    0x4000_0000,
    0x4000_0000,
    0x7b53_b8c2,
    0x7344_ad0a,
    0x6cfb_6979,
    0x67e1_4804,
    0x639e_6858,
    0x5ffb_60c7,
    0x5cd3_2d0e,
    0x5a0b_f267,
    0x5792_faa7,
    0x555a_54ea,
    0x5357_5d18,
    0x5181_c8ec,
    0x4fd3_05b2,
    0x4e45_c8bf,
    0x4cd5_c0dc,
    0x4b7f_5da4,
    0x4a3f_a5ec,
    0x4914_18b8,
    0x47fa_95aa,
    0x46f1_4ae0,
    0x45f6_a6db,
    0x4509_4d63,
    0x4428_0eae,
    0x4351_e048,
    0x4285_d74e,
    0x41c3_23c0,
    0x4109_0ca2,
    0x4056_ecc6,
];

/// `a * b >> s` for u32 operands (one UMULL).
#[inline(always)]
fn mulu(a: u32, b: u32, s: u32) -> u32 {
    ((a as u64 * b as u64) >> s) as u32
}

/// `a * b >> s` for i32 operands (one SMULL); the caller guarantees the result fits.
#[inline(always)]
fn smul(a: i32, b: i32, s: u32) -> i32 {
    ((a as i64 * b as i64) >> s) as i32
}

/// One third-order step for Q32 `f` and Q30 `y`. Returns the new `y` (Q30).
#[inline(always)]
fn inv_cbrt_step_q(f: u32, y: u32) -> u32 {
    // t = f y³ in Q30; every partial product stays below 2^32 because f < 1, y <= 2.
    let t = mulu(mulu(mulu(f, y, 32), y, 30), y, 30);
    let r = (1i32 << 30).wrapping_sub(t as i32); // Q30, |r| < 0.06 after the seed
    let r2 = smul(r, r, 30);
    // c = r/3 + 2r²/9 in Q30 (1/3 = 0x5555_5555 / 2^32, 2/9 = 0x38E3_8E39 / 2^32); |c| is
    // below 2^27, so every product here is one 32 x 32 -> 64 SMULL
    let c = smul(r, 0x5555_5555, 32) + smul(r2, 0x38E3_8E39, 32);
    // y c: y (<= 2^31) halved to fit an i32, the lost bit only touches the small correction
    y.wrapping_add(smul((y >> 1) as i32, c, 29) as u32)
}

/// `f^(-1/3)` in Q30 for `f` in Q32 with `f ∈ [2^29, 2^32)` (i.e. [1/8, 1)); result in
/// (1, 2]. Inputs below 2^29 are treated as 2^29.
#[inline]
pub fn inv_cbrt_norm(f: u32) -> u32 {
    let f = if f < (1 << 29) { 1 << 29 } else { f };
    let idx = (f >> 27) as usize & 31;
    let y0 = match INV_CBRT_SEED_Q30.get(idx) {
        Some(v) => *v,
        None => 1 << 30,
    };
    inv_cbrt_step_q(f, inv_cbrt_step_q(f, y0))
}

/// `f^(1/3)` in Q30 for `f` in Q32, `f ∈ [2^29, 2^32)`; result in [1/2, 1).
#[inline]
pub fn cbrt_norm(f: u32) -> u32 {
    let y = inv_cbrt_norm(f);
    mulu(mulu(f, y, 32), y, 30)
}

/// Split a non-zero magnitude `m` (value `m · 2^-frac`) into `f · 2^(3k)` with `f` in Q32
/// in [1/8, 1): returns `(f, k)`.
#[inline(always)]
fn normalise3(m: u64, frac: u32) -> (u32, i32) {
    let bits = 64 - m.leading_zeros() as i32; // m ∈ [2^(bits-1), 2^bits)
                                              // Choose e ∈ {bits, bits+1, bits+2} with e - frac ≡ 0 (mod 3); then m / 2^e ∈ [1/8, 1).
    let rem = (bits - frac as i32).rem_euclid(3);
    let e = bits + if rem == 0 { 0 } else { 3 - rem };
    let sh = 32 - e; // f = m · 2^(32 - e)
    let f = if sh >= 0 {
        (m << sh) as u32
    } else {
        (m >> (-sh)) as u32
    };
    (f, (e - frac as i32) / 3)
}

/// `v · 2^sh` for a signed shift, rounding to nearest on right shifts and saturating at
/// `u64::MAX >> 1` so the caller's conversion to a signed raw value cannot wrap.
#[inline(always)]
fn shift_sat(v: u64, sh: i32) -> u64 {
    const MAX: u64 = u64::MAX >> 1;
    if sh >= 0 {
        if sh >= 63 || v > (MAX >> sh) {
            MAX
        } else {
            v << sh
        }
    } else if sh <= -63 {
        0
    } else {
        (v >> (-sh - 1)).div_ceil(2)
    }
}

/// Cube root of a fixed-point magnitude: `m` is the raw value of `x = m · 2^-frac`;
/// returns the raw value (same format) of `x^(1/3)`, truncated.
#[inline]
pub fn cbrt_raw(m: u64, frac: u32) -> u64 {
    if m == 0 {
        return 0;
    }
    let (f, k) = normalise3(m, frac);
    // x^(1/3) = cbrt(f) 2^k, cbrt(f) in Q30 → raw = c · 2^(k + frac - 30)
    shift_sat(cbrt_norm(f) as u64, k + frac as i32 - 30)
}

/// Inverse cube root of a non-zero fixed-point magnitude (raw in, raw out, same
/// format); saturates at the largest raw magnitude; `m == 0` gives that maximum.
#[inline]
pub fn inv_cbrt_raw(m: u64, frac: u32) -> u64 {
    if m == 0 {
        return u64::MAX >> 1;
    }
    let (f, k) = normalise3(m, frac);
    // x^(-1/3) = f^(-1/3) 2^-k, y in Q30 → raw = y · 2^(frac - 30 - k)
    shift_sat(inv_cbrt_norm(f) as u64, frac as i32 - 30 - k)
}

/// `1/f` in Q30 for `f` in Q32 with `f ∈ [2^31, 2^32)` ([1/2, 1)); result in (1, 2].
/// Linear seed `48/17 - 32/17 f` (max error 1/17) and three Newton steps.
#[inline]
pub fn recip_norm(f: u32) -> u32 {
    let f = if f < (1 << 31) { 1 << 31 } else { f };
    // 48/17 in Q30 = 0xB4B4_B4B4 (> 2^31: keep in u64), 32/17 in Q30 = 0x7878_7878
    let mut y = (0xB4B4_B4B4u64 - ((f as u64 * 0x7878_7878) >> 32)) as u32;
    for _ in 0..3 {
        // y ← y (2 - f y); e = 1 - f y in Q30 (small, signed)
        let fy = mulu(f, y, 32);
        let e = (1i32 << 30).wrapping_sub(fy as i32);
        y = y.wrapping_add(smul((y >> 1) as i32, e, 29) as u32);
    }
    y
}

/// `a / b` for fixed-point magnitudes of the same format (`frac` fractional bits): the
/// raw result `a · 2^frac / b`, saturating; `None` when `b == 0` or the quotient does
/// not fit. Relative error below 2^-28 (reciprocal of the normalised divisor).
#[inline]
pub fn div_raw(a: u64, b: u64, frac: u32) -> Option<u64> {
    div_by_raw(a, &RawDivisor::new(b)?, frac)
}

/// A non-zero fixed-point magnitude prepared as a divisor: its normalised reciprocal, so
/// several quotients by it ([`div_by_raw`]) cost one reciprocal. `div_by_raw(a, &d)` is
/// exactly `div_raw(a, b)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawDivisor {
    /// `1/g` in Q30 for the divisor's top 32 bits `g` in Q32 ∈ [1/2, 1).
    y: u64,
    /// The divisor's bit length: `b = g · 2^(bb - 32)`.
    bb: i32,
}

impl RawDivisor {
    /// `None` for `b == 0`.
    #[inline]
    pub fn new(b: u64) -> Option<Self> {
        if b == 0 {
            return None;
        }
        // b = g · 2^(bb - 32) with g in Q32 ∈ [1/2, 1) (g's raw value is b's top 32 bits)
        let bb = 64 - b.leading_zeros() as i32;
        let g = if bb >= 32 {
            (b >> (bb - 32)) as u32
        } else {
            (b << (32 - bb)) as u32
        };
        Some(Self {
            y: recip_norm(g) as u64,
            bb,
        })
    }
}

/// [`div_raw`] by a prepared divisor.
#[inline]
pub fn div_by_raw(a: u64, d: &RawDivisor, frac: u32) -> Option<u64> {
    if a == 0 {
        return Some(0);
    }
    let (y, bb) = (d.y, d.bb);
    // a / b = a · y · 2^-30 · 2^(32 - bb); raw quotient = that · 2^frac.
    // Normalise a to its top 32 bits to keep the product in u64.
    let ab = 64 - a.leading_zeros() as i32;
    let (a_top, a_sh) = if ab > 32 {
        (a >> (ab - 32), ab - 32)
    } else {
        (a, 0)
    };
    let p = a_top * y; // < 2^63
                       // 1/b = (y / 2^30) 2^-bb, so the raw quotient is a_top y 2^(a_sh + frac - 30 - bb).
    let sh = a_sh + frac as i32 - 30 - bb;
    let q = shift_sat(p, sh);
    if q == u64::MAX >> 1 {
        None
    } else {
        Some(q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        ((a - b) / b).abs()
    }

    #[test]
    fn f32_cbrt_error_bound_over_all_binades() {
        let mut worst = 0.0f64;
        // 2^-140 .. 2^120 (subnormals included), dense within each binade
        let mut x = 1.0e-42f32;
        while x < 1.0e36 {
            let c = cbrt_f32(x) as f64;
            let y = inv_cbrt_f32(x) as f64;
            let y9 = inv_root9_f32(x) as f64;
            let t = (x as f64).cbrt();
            worst = worst
                .max(rel(c, t))
                .max(rel(y, 1.0 / t))
                .max(rel(y9, (x as f64).powf(-1.0 / 9.0)));
            assert_eq!(cbrt_f32(-x), -cbrt_f32(x));
            x *= 1.000_731;
        }
        assert!(worst <= CBRT_F32_MAX_REL_ERR as f64, "worst {worst:e}");
        assert!(
            worst > 1e-8,
            "the bound must be tight enough to mean something"
        );
        assert_eq!(cbrt_f32(0.0), 0.0);
        assert!((cbrt_f32(-27.0) + 3.0).abs() <= 3.0 * CBRT_F32_MAX_REL_ERR);
        assert!(cbrt_f32(f32::NAN).is_nan());
    }

    #[test]
    fn f32_pow_abs_error_bound_for_paper_exponents() {
        let exps = [(1, 3), (5, 3), (5, 9), (-4, 9), (2, 1), (-1, 3), (4, 9)];
        let mut worst = 0.0f64;
        let mut x = 1.0e-6f32;
        while x < 1.0e4 {
            for (n, d) in exps {
                let e = Exponent { num: n, den: d };
                let v = pow_abs_f32(x, e, 0.0) as f64;
                let t = (x as f64).powf(n as f64 / d as f64);
                worst = worst.max(rel(v, t));
            }
            x *= 1.003;
        }
        // the exhaustive worst points of 5/9 and 5/3 (module docs), scaled by powers of
        // the seeds' period 2^9, where the error pattern repeats
        for x0 in [22.47246f32, 183.38795] {
            for k in -4..=4 {
                let x = x0 * libm::exp2f(9.0 * k as f32);
                for (n, d) in exps {
                    let e = Exponent { num: n, den: d };
                    let v = pow_abs_f32(x, e, 0.0) as f64;
                    let t = (x as f64).powf(n as f64 / d as f64);
                    worst = worst.max(rel(v, t));
                }
            }
        }
        assert!(worst <= POW_F32_MAX_REL_ERR as f64, "worst {worst:e}");
        assert!(
            worst > 6.0e-6,
            "the worst point must be in the sweep: {worst:e}"
        );
    }

    #[test]
    fn f32_sin_cos_error_bound() {
        let mut worst = 0.0f64;
        for k in -100_000..=100_000 {
            let x = k as f32 * 1.0e-3;
            let (s, c) = sin_cos_f32(x);
            let xd = x as f64;
            worst = worst
                .max((s as f64 - xd.sin()).abs())
                .max((c as f64 - xd.cos()).abs());
        }
        assert!(worst <= SIN_COS_F32_MAX_ABS_ERR as f64, "worst {worst:e}");
        assert!(worst > 1e-9);
        // beyond the fast range: libm
        assert_eq!(sin_cos_f32(1.0e6), libm::sincosf(1.0e6));
        assert!(sin_cos_f32(f32::NAN).0.is_nan());
    }

    #[test]
    fn f32_pow_abs_contract() {
        let m49 = Exponent { num: -4, den: 9 };
        assert_eq!(pow_abs_f32(0.0, m49, 1e-4), pow_abs_f32(1e-4, m49, 1e-4));
        assert_eq!(pow_abs_f32(0.0, Exponent { num: 5, den: 9 }, 0.0), 0.0);
        assert_eq!(pow_abs_f32(-3.0, Exponent { num: 0, den: 1 }, 0.0), 1.0);
        assert_eq!(
            pow_abs_f32(1e30, Exponent { num: 5, den: 1 }, 0.0),
            f32::MAX
        );
        // fallback path (den 5) agrees with libm exactly
        let e15 = Exponent { num: 1, den: 5 };
        assert_eq!(pow_abs_f32(7.0, e15, 0.0), libm::powf(7.0, 0.2));
        // odd root of a negative base, within the root's bound (a perfect cube is not
        // exact after the one fifth-order step: 2 - 1 ulp)
        let c = pow_abs_f32(-8.0, Exponent { num: 1, den: 3 }, 0.0);
        assert!((c - 2.0).abs() <= 2.0 * CBRT_F32_MAX_REL_ERR, "{c}");
    }

    #[test]
    fn normalised_integer_roots() {
        let mut worst = 0.0f64;
        let mut f = 1u32 << 29;
        while f < u32::MAX - 4096 {
            let x = f as f64 / 4_294_967_296.0;
            let c = cbrt_norm(f) as f64 / (1u64 << 30) as f64;
            let y = inv_cbrt_norm(f) as f64 / (1u64 << 30) as f64;
            worst = worst.max(rel(c, x.cbrt())).max(rel(y, 1.0 / x.cbrt()));
            f += 4093;
        }
        assert!(worst <= CBRT_NORM_MAX_REL_ERR, "worst {worst:e}");
        let mut worst_r = 0.0f64;
        let mut f = 1u32 << 31;
        while f < u32::MAX - 4096 {
            let x = f as f64 / 4_294_967_296.0;
            let y = recip_norm(f) as f64 / (1u64 << 30) as f64;
            worst_r = worst_r.max(rel(y, 1.0 / x));
            f += 4093;
        }
        assert!(worst_r < 4e-9, "recip worst {worst_r:e}");
    }

    #[test]
    fn raw_roots_and_division_in_q16_and_q32() {
        for frac in [16u32, 32] {
            let one = 1u64 << frac;
            assert_eq!(cbrt_raw(0, frac), 0);
            // 8 → 2, 1/8 → 1/2 exactly representable
            // within one LSB or the core's relative error, whichever is larger
            let tol = |v: u64| (v as f64 * CBRT_NORM_MAX_REL_ERR).max(1.0) as u64;
            let c8 = cbrt_raw(8 * one, frac);
            assert!(c8.abs_diff(2 * one) <= tol(2 * one), "frac {frac}: {c8}");
            let i8 = inv_cbrt_raw(8 * one, frac);
            assert!(i8.abs_diff(one / 2) <= tol(one / 2));
            let c = cbrt_raw(one / 8, frac);
            assert!(c.abs_diff(one / 2) <= tol(one / 2));
            // 1 LSB: cube root of 2^-frac
            let lsb = cbrt_raw(1, frac) as f64;
            assert!((lsb - (1.0 / one as f64).cbrt() * one as f64).abs() <= 1.0);
            let q = div_raw(3 * one, 4 * one, frac).unwrap();
            assert!(q.abs_diff(3 * one / 4) <= 1);
            assert_eq!(div_raw(one, 0, frac), None);
            assert_eq!(div_raw(u64::MAX >> 2, 1, frac), None);
        }
    }
}
