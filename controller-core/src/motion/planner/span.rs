//! Spans: the commanded path cut into polynomial pieces that the executor evaluates in a
//! few dozen instructions, and the speed/acceleration/jerk limits of each span.
//!
//! A span is a degree-7 polynomial per axis in `u = σ_local / len ∈ [0, 1]`, fitted by
//! Hermite interpolation to the exact commanded curve (programmed piece + blend
//! corrections): position and the first three σ-derivatives match at both ends, so
//! consecutive spans join with continuous position, tangent, curvature and curvature
//! rate. Straight spans and line–line blends are polynomials of degree ≤ 3, so the fit is
//! exact; spans on arcs are checked against the exact curve and halved until the error is
//! below [`FIT_TOL_MM`].
//!
//! **Limits.** From Bernstein-coefficient bounds of the fitted polynomial's derivatives
//! (`P1_i ≥ max|dp_i/dσ|`, `P2_i ≥ max|d²p_i/dσ²|`, `P3_i ≥ max|d³p_i/dσ³|` over the span;
//! the convex-hull property makes them rigorous) each span gets a path speed cap V, a
//! path acceleration limit A and a path jerk limit J such that, for any motion with
//! `0 ≤ σ̇ ≤ V`, `|σ̈| ≤ A`, `|σ⃛| ≤ J` on the span, every axis stays within its limits:
//!
//! ```text
//! v_i = p_i' σ̇                          ≤ P1 V                     ≤ vmax_i
//! a_i = p_i'' σ̇² + p_i' σ̈               ≤ P2 V² + P1 A             ≤ amax_i
//! j_i = p_i''' σ̇³ + 3 p_i'' σ̇ σ̈ + p_i' σ⃛ ≤ P3 V³ + 3 P2 V A + P1 J ≤ jmax_i
//! ```
//!
//! V is the largest speed that still leaves the floor `acc_floor`/`jerk_floor` (the
//! configured tangential share of the weakest axis, over the largest tangent component)
//! to A and J, capped at twice the programmed feed (the override's maximum) so that slow
//! spans give the rest to A. A then takes everything V leaves, and J what V and A leave
//! (at least the floor). On a straight span P2 = P3 = 0 and A and J are the full axis
//! limits projected on the direction (`min_i amax_i / |u_i|`: a 45° line in XY gets √2
//! times an axis' limits). The limits hold for the polynomial that is actually executed,
//! whatever the fit error.

use super::blend::Jet;
use super::config::ValidPlannerConfig;
use super::fmath::{self, F32Ext};
use super::geometry::V3;

/// Largest deviation of a fitted span from the exact commanded curve (mm); taken from the
/// blend tolerance budget. 20 nm is a thirtieth of one encoder count (0.625 µm).
pub const FIT_TOL_MM: f32 = 2.0e-5;

/// The executor may cross at most this many spans per period: span speeds are capped at
/// `SPANS_PER_PERIOD · len / period`, which bounds the executor's advance loop.
pub const SPANS_PER_PERIOD: usize = 2;

/// One polynomial piece of the commanded path, as the executor samples it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Sequence number (increasing along the path).
    pub seq: u32,
    /// Path generation: incremented by every abort, so that the executor drops spans of a
    /// cleared program.
    pub path_gen: u16,
    /// Program run (set by every restart): with the planner in a task of its own, the
    /// executor drops spans of an earlier run still in the channel (see
    /// [`super::split`]). Fills what was padding: no larger span.
    pub run: u16,
    /// Tag of the programmed segment this span lies on.
    pub tag: u32,
    /// Length in σ (mm of programmed path).
    pub len_mm: f32,
    /// `1 / len_mm` (0 for a zero-length span).
    pub inv_len: f32,
    /// `1 / programmed feed` (s/mm; 0 for rapids and dwells), for the feed ratio.
    pub inv_feed: f32,
    /// `coef[axis][k]`: position = Σ `coef[axis][k]` u^k (mm), `coef[axis][0]` absolute.
    pub coef: [[f32; 8]; 3],
}

/// Position, first and second σ-derivative of a span at local σ.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpanPoint {
    pub pos: V3,
    pub d1: V3,
    pub d2: V3,
}

impl Span {
    /// Evaluates position and derivatives at `sigma_mm` (local, 0..len): Horner for the
    /// polynomial and its first two derivatives together, 3 FMAs per coefficient and axis.
    #[inline]
    pub fn eval(&self, sigma_mm: f32) -> SpanPoint {
        let u = sigma_mm * self.inv_len;
        // (p'' = 2 p2 / len², the factor once for the three axes)
        let d2_scale = 2.0 * self.inv_len * self.inv_len;
        let mut out = SpanPoint::default();
        for (i, c) in self.coef.iter().enumerate() {
            // Horner for p, p' and p'' at once; the first two steps written out (p'' and
            // p' start at zero, so they are exact copies there: same result, 5 fewer
            // operations per axis in the control interrupt)
            let mut p1 = c[7];
            let mut p0 = c[7] * u + c[6];
            let mut p2 = p1;
            p1 = p1 * u + p0;
            p0 = p0 * u + c[5];
            for k in (0..5).rev() {
                p2 = p2 * u + p1;
                p1 = p1 * u + p0;
                p0 = p0 * u + c[k];
            }
            out.pos[i] = p0;
            out.d1[i] = p1 * self.inv_len;
            out.d2[i] = p2 * d2_scale;
        }
        out
    }
}

/// Inverse of the end-condition matrix of the septic Hermite fit (rows give c4..c7 from
/// the residuals of value, first, second and third u-derivative at u = 1).
const HERMITE_INV: [[f32; 4]; 4] = [
    [35.0, -15.0, 2.5, -1.0 / 6.0],
    [-84.0, 39.0, -7.0, 0.5],
    [70.0, -34.0, 6.5, -0.5],
    [-20.0, 10.0, -2.0, 1.0 / 6.0],
];

/// Septic Hermite fit over a span of length `h`: `j0.p` is zero (the span start is the
/// origin of the offsets), `j1.p` the offset of the end; `origin` is the absolute start.
pub(crate) fn fit(j0: &Jet, j1: &Jet, h: f32, origin: V3) -> [[f32; 8]; 3] {
    let (h2, h3) = (h * h, h * h * h);
    let mut coef = [[0.0f32; 8]; 3];
    for i in 0..3 {
        let c1 = h * j0.d1[i];
        let c2 = 0.5 * h2 * j0.d2[i];
        let c3 = h3 * j0.d3[i] * (1.0 / 6.0);
        let r = [
            j1.p[i] - j0.p[i] - (c1 + c2 + c3),
            h * j1.d1[i] - (c1 + 2.0 * c2 + 3.0 * c3),
            h2 * j1.d2[i] - (2.0 * c2 + 6.0 * c3),
            h3 * j1.d3[i] - 6.0 * c3,
        ];
        let c = &mut coef[i];
        c[0] = origin[i] + j0.p[i];
        c[1] = c1;
        c[2] = c2;
        c[3] = c3;
        for (k, row) in HERMITE_INV.iter().enumerate() {
            c[4 + k] = row[0] * r[0] + row[1] * r[1] + row[2] * r[2] + row[3] * r[3];
        }
    }
    coef
}

/// Offset (position minus start) of a fitted span at `u`, without the absolute term.
pub(crate) fn offset_at(coef: &[[f32; 8]; 3], u: f32) -> V3 {
    let mut out = [0.0; 3];
    for (i, c) in coef.iter().enumerate() {
        let mut p = c[7];
        for k in (1..7).rev() {
            p = p * u + c[k];
        }
        out[i] = p * u;
    }
    V3::from_array(out)
}

/// Bernstein conversion of degree `n` (`D = n + 1` coefficients): row `i` holds
/// `C(i,j)/C(n,j)` for `j ≤ i`, so that `b_i = Σ_j row_i[j] m_j`.
const fn bernstein_matrix<const D: usize>() -> [[f32; D]; D] {
    let n = D - 1;
    let mut out = [[0.0f32; D]; D];
    let mut i = 0;
    while i < D {
        let mut j = 0;
        let mut cij = 1.0f32; // C(i, j)
        let mut cnj = 1.0f32; // C(n, j)
        while j <= i {
            out[i][j] = cij / cnj;
            cij = cij * (i - j) as f32 / (j + 1) as f32;
            cnj = cnj * (n - j) as f32 / (j + 1) as f32;
            j += 1;
        }
        i += 1;
    }
    out
}

const BERN6: [[f32; 7]; 7] = bernstein_matrix::<7>();
const BERN5: [[f32; 6]; 6] = bernstein_matrix::<6>();
const BERN4: [[f32; 5]; 5] = bernstein_matrix::<5>();

/// `max |b_i|` of the Bernstein coefficients of the polynomial with monomial coefficients
/// `m` (degree `D − 1`) under the conversion `bm`: an upper bound of its magnitude on
/// [0, 1].
#[inline(always)]
fn bernstein_bound<const D: usize>(m: &[f32; D], bm: &[[f32; D]; D]) -> f32 {
    let mut best = 0.0f32;
    for (i, row) in bm.iter().enumerate() {
        let mut b = 0.0f32;
        for j in 0..=i {
            b += row[j] * m[j];
        }
        // Plain select (no NaN handling: a non-finite coefficient makes the caller's
        // bounds infinite, see `derivative_bounds`).
        let b = b.abs();
        best = if b > best { b } else { best };
    }
    best
}

/// Bounds of |first|, |second|, |third| σ-derivative per axis over a span.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct DerivBounds {
    pub p1: V3,
    pub p2: V3,
    pub p3: V3,
}

pub(crate) fn derivative_bounds(coef: &[[f32; 8]; 3], h: f32) -> DerivBounds {
    let mut b = DerivBounds::default();
    if !(h > 0.0) {
        return b;
    }
    let inv = 1.0 / h;
    for (i, c) in coef.iter().enumerate() {
        if c[1..].iter().all(|&x| x == 0.0) {
            // The axis does not move on this span (a plane move, a line along an axis).
            continue;
        }
        let mut m1 = [0.0f32; 7];
        for j in 0..7 {
            m1[j] = (j + 1) as f32 * c[j + 1];
        }
        let mut m2 = [0.0f32; 6];
        for j in 0..6 {
            m2[j] = ((j + 2) * (j + 1)) as f32 * c[j + 2];
        }
        let mut m3 = [0.0f32; 5];
        for j in 0..5 {
            m3[j] = ((j + 3) * (j + 2) * (j + 1)) as f32 * c[j + 3];
        }
        b.p1[i] = bernstein_bound(&m1, &BERN6) * inv;
        b.p2[i] = bernstein_bound(&m2, &BERN5) * inv * inv;
        b.p3[i] = bernstein_bound(&m3, &BERN4) * inv * inv * inv;
        if !c.iter().all(|x| x.is_finite()) {
            // Cannot happen for validated geometry; an unusable span gets no speed.
            b.p1[i] = f32::INFINITY;
            b.p2[i] = f32::INFINITY;
            b.p3[i] = f32::INFINITY;
        }
    }
    b
}

/// Path-level limits of one span.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct PathLimits {
    /// Speed cap from the geometry and the axis limits (mm/s of σ).
    pub vel: f32,
    /// Path acceleration limit (mm/s²).
    pub acc: f32,
    /// Path jerk limit (mm/s³).
    pub jerk: f32,
}

/// Positive root of `a V³ + b V = c` (a, b ≥ 0, c > 0), rounded down: Newton from an upper
/// bound converges from above on this convex increasing function.
fn cubic_root_down(a: f32, b: f32, c: f32) -> f32 {
    let mut v = f32::INFINITY;
    if a > 0.0 {
        v = v.mn(fmath::cbrt(c / a));
    }
    if b > 0.0 {
        v = v.mn(c / b);
    }
    if !v.is_finite() {
        return v;
    }
    for _ in 0..12 {
        let f = a * v * v * v + b * v - c;
        let df = 3.0 * a * v * v + b;
        if !(df > 0.0) || !(f > 0.0) {
            break;
        }
        let step = f / df;
        v -= step;
        if step <= 1.0e-6 * v {
            // Quadratic convergence: the next step would be below f32 resolution.
            break;
        }
    }
    let mut v = v * (1.0 - 1.0e-5);
    // Newton from above stays above the root; the factor puts it just below (a few
    // tenths of a percent more at most, bounded).
    for _ in 0..8 {
        if !(a * v * v * v + b * v > c) {
            return v.mx(0.0);
        }
        v *= 0.999;
    }
    // Never reached in practice; a root of each half is a safe lower bound.
    let mut safe = f32::INFINITY;
    if a > 0.0 {
        safe = safe.mn(fmath::cbrt(0.5 * c / a));
    }
    if b > 0.0 {
        safe = safe.mn(0.5 * c / b);
    }
    safe.mn(v).mx(0.0)
}

/// Limits of a span of length `h` with derivative bounds `b`; `v_design` is the highest
/// speed the span will be asked for (programmed feed × largest override, +∞ for rapids).
///
/// Every span keeps at least the floor `acc_floor`/`jerk_floor` for the path acceleration
/// and jerk (the look-ahead brakes with these where spans differ, and its horizon is the
/// stopping distance at the floor). V is the largest speed that still leaves the floor,
/// capped at `v_design` so that slow spans give the rest to A and J instead.
pub(crate) fn path_limits(
    b: &DerivBounds,
    h: f32,
    v_design: f32,
    s: &ValidPlannerConfig,
) -> PathLimits {
    let (a_req, j_req) = (s.acc_floor, s.jerk_floor);
    let mut vel = if h > 0.0 {
        SPANS_PER_PERIOD as f32 * h / s.period_s
    } else {
        0.0
    };
    vel = vel.mn(v_design.mx(0.0));
    for i in 0..3 {
        if b.p1[i] > 0.0 {
            vel = vel.mn(s.vel_max[i] / b.p1[i]);
        }
        if b.p2[i] > 0.0 {
            let room = (s.acc_max[i] - b.p1[i] * a_req).mx(0.0);
            vel = vel.mn(fmath::sqrt(room / b.p2[i]));
        }
        if b.p3[i] > 0.0 || b.p2[i] > 0.0 {
            let room = (s.jerk_max[i] - b.p1[i] * j_req).mx(0.0);
            vel = vel.mn(cubic_root_down(b.p3[i], 3.0 * b.p2[i] * a_req, room));
        }
    }
    let vel = vel.mx(0.0);
    let mut acc = f32::INFINITY;
    for i in 0..3 {
        if b.p1[i] > 0.0 {
            acc = acc.mn((s.acc_max[i] - b.p2[i] * vel * vel) / b.p1[i]);
        }
        let coupling = 3.0 * b.p2[i] * vel;
        if coupling > 0.0 {
            let room = s.jerk_max[i] - b.p3[i] * vel * vel * vel - b.p1[i] * j_req;
            acc = acc.mn(room / coupling);
        }
    }
    if !acc.is_finite() {
        acc = s.acc_max[0].mx(s.acc_max[1]).mx(s.acc_max[2]);
    }
    let acc = acc.mx(a_req);
    // The jerk takes what V and A leave: j_i = p_i''' σ̇³ + 3 p_i'' σ̇ σ̈ + p_i' σ⃛ ≤ jmax_i at
    // σ̇ ≤ V, |σ̈| ≤ A. On a straight span that is the axis limit projected on the direction
    // (jmax_i / |u_i|); V and A above leave at least the floor on every span, so the
    // look-ahead may brake with the floor anywhere. The look-ahead takes the lowest jerk
    // of the spans a profile crosses (see `lookahead`).
    // The servo's reserve: at most `1 − servo_reserve` of the projected axis jerk.
    let mut jerk = f32::INFINITY;
    for i in 0..3 {
        if b.p1[i] > 0.0 {
            let room = s.jerk_max[i] - b.p3[i] * vel * vel * vel - 3.0 * b.p2[i] * vel * acc;
            jerk = jerk
                .mn(room / b.p1[i])
                .mn(s.path_jerk_share * s.jerk_max[i] / b.p1[i]);
        }
    }
    if !jerk.is_finite() {
        jerk = s.jerk_max[0].mx(s.jerk_max[1]).mx(s.jerk_max[2]);
    }
    PathLimits {
        vel,
        acc,
        jerk: jerk.mx(j_req),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bernstein_bound_is_an_upper_bound_and_tight_for_monotone() {
        // p(u) = 1 - 4u + 4u² (min 0 at 1/2, 1 at the ends).
        let m = [1.0, -4.0, 4.0];
        let b = bernstein_bound(&m, &bernstein_matrix::<3>());
        assert!((1.0..=1.0 + 1e-6).contains(&b), "{b}");
        // Constant polynomial.
        assert!((bernstein_bound(&[2.5], &bernstein_matrix::<1>()) - 2.5).abs() < 1e-7);
    }

    #[test]
    fn hermite_fit_reproduces_a_cubic_exactly() {
        // x(σ) = σ + 0.1 σ² - 0.02 σ³ over h = 2.
        let h = 2.0f32;
        let f = |s: f32| V3::new(s + 0.1 * s * s - 0.02 * s * s * s, 0.0, 0.0);
        let df = |s: f32| V3::new(1.0 + 0.2 * s - 0.06 * s * s, 0.0, 0.0);
        let d2f = |s: f32| V3::new(0.2 - 0.12 * s, 0.0, 0.0);
        let j0 = Jet {
            p: V3::new(0.0, 0.0, 0.0),
            d1: df(0.0),
            d2: d2f(0.0),
            d3: V3::new(-0.12, 0.0, 0.0),
        };
        let j1 = Jet {
            p: f(h),
            d1: df(h),
            d2: d2f(h),
            d3: V3::new(-0.12, 0.0, 0.0),
        };
        let c = fit(&j0, &j1, h, V3::new(5.0, 0.0, 0.0));
        for (k, ck) in c[0].iter().enumerate().skip(4) {
            assert!(ck.abs() < 1e-5, "c{k} = {ck}");
        }
        for k in 0..=10 {
            let u = k as f32 / 10.0;
            let o = offset_at(&c, u);
            assert!((o[0] - f(u * h)[0]).abs() < 1e-6);
        }
    }

    #[test]
    fn straight_span_gets_the_projected_axis_limits() {
        let mut c = super::super::config::GANTRY_PLANNER;
        c.servo_reserve = 0.0;
        let s = ValidPlannerConfig::new(&c).unwrap();
        let u = [0.6f32, 0.8, 0.0];
        let b = DerivBounds {
            p1: V3::new(0.6, 0.8, 0.0),
            ..DerivBounds::default()
        };
        let l = path_limits(&b, 10.0, f32::INFINITY, &s);
        assert!((l.vel - 250.0 / 0.8).abs() < 1e-2, "{l:?}");
        assert!((l.acc - 2000.0 / 0.8).abs() < 1e-2);
        // the jerk projected too (no fixed fraction on a straight span)
        assert!((l.jerk - 1.0e5 / 0.8).abs() < 1.0, "{l:?}");
        let _ = u;
    }
}
