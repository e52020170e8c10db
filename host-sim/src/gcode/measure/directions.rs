//! Per-axis limits seen along a path direction.
//!
//! * [`projected`]: a motion along the unit direction `t` at path rate `x` has axis rates
//!   `x·t_i`, so per-axis limits `lim_i` allow `x ≤ min_i lim_i/|t_i|` (exact for the
//!   velocity on any path, and for acceleration and jerk along a straight line).
//! * [`support`]: the largest component along `t` of a vector in the box `|a_i| ≤ lim_i`,
//!   `Σ lim_i·|t_i|`: on a curve the tangential acceleration is `a·t`, which the centripetal
//!   part can push beyond the projected limit but never beyond this.
//!
//! Both also as maxima over the directions a path takes between two tangents (a blended
//! corner: the great circle from one to the other) and along a helix.

use controller_core::num::vec3::Vec3;

/// Axis rates along `t` allow a path rate of at most this (∞ for a zero vector).
pub fn projected(lim: [f64; 3], t: [f64; 3]) -> f64 {
    (0..3)
        .filter(|&i| t[i] != 0.0)
        .map(|i| lim[i] / t[i].abs())
        .fold(f64::INFINITY, f64::min)
}

/// `Σ lim_i·|t_i|`: the largest `a·t` over the box `|a_i| ≤ lim_i`.
pub fn support(lim: [f64; 3], t: [f64; 3]) -> f64 {
    (0..3).map(|i| lim[i] * t[i].abs()).sum()
}

/// The largest [`projected`] limit along the great circle of directions from `a` to `b`
/// (unit vectors; for a reversal, any half circle: the bound over all directions).
///
/// Along `t(φ) = cos φ·a + sin φ·w` (`w` ⟂ `a` in the plane of both), the projected limit is
/// `1 / max_i |t_i(φ)|/lim_i`; its maximum is where that envelope is least: at an end, where
/// one component vanishes, or where two of them cross. All those candidates are evaluated.
pub fn max_projected_between(lim: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let (va, vb) = (Vec3::from_array(a), Vec3::from_array(b));
    let c = va.dot(vb).clamp(-1.0, 1.0);
    let ang = c.acos();
    let w0 = vb - va.scale(c);
    if !(w0.norm() > 1e-12) {
        return if c > 0.0 {
            projected(lim, a)
        } else {
            lim.iter().map(|x| x * x).sum::<f64>().sqrt()
        };
    }
    let w = w0.unit_or_zero();
    let at = |phi: f64| {
        let (s, co) = phi.sin_cos();
        projected(
            lim,
            [
                co * a[0] + s * w[0],
                co * a[1] + s * w[1],
                co * a[2] + s * w[2],
            ],
        )
    };
    let mut best = at(0.0).max(at(ang));
    let mut candidate = |phi: f64| {
        // every solution φ + jπ in [0, ang]
        let pi = std::f64::consts::PI;
        let mut x = phi.rem_euclid(pi);
        while x <= ang {
            best = best.max(at(x));
            x += pi;
        }
    };
    for i in 0..3 {
        // component i vanishes: cos φ·a_i + sin φ·w_i = 0
        candidate((-a[i]).atan2(w[i]));
        for j in (i + 1)..3 {
            // |t_i|/lim_i = ±|t_j|/lim_j: (a_i/l_i ∓ a_j/l_j) cos φ + (w_i/l_i ∓ w_j/l_j) sin φ = 0
            for sign in [1.0, -1.0] {
                let p = a[i] / lim[i] - sign * a[j] / lim[j];
                let q = w[i] / lim[i] - sign * w[j] / lim[j];
                candidate((-p).atan2(q));
            }
        }
    }
    best
}

/// An upper bound of [`support`] along the great circle from `a` to `b` (unit vectors):
/// the support is a norm, so at `t = (sin((1−λ)θ)·a + sin(λθ)·b)/sin θ` it is at most
/// `max(S(a), S(b))·(sin((1−λ)θ) + sin(λθ))/sin θ ≤ max(S(a), S(b))/cos(θ/2)`; and never
/// more than the box's largest, `√Σ lim_i²`.
pub fn max_support_between(lim: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let all = lim.iter().map(|x| x * x).sum::<f64>().sqrt();
    let half = 0.5
        * Vec3::from_array(a)
            .dot(Vec3::from_array(b))
            .clamp(-1.0, 1.0)
            .acos();
    let ends = support(lim, a).max(support(lim, b));
    if half.cos() > 0.0 {
        (ends / half.cos()).min(all)
    } else {
        all
    }
}

/// Largest value over `[a, b]` of `g(α) = min(l1/|cos α|, l2/|sin α|)` (the projected limit
/// of an in-plane direction at angle α): `g` is unimodal between multiples of π/2, peaking
/// where both are equal (|tan α| = l2/l1), so the maximum is at an end or at such a peak.
pub fn max_planar_projected(l1: f64, l2: f64, a: f64, b: f64) -> f64 {
    let g = |x: f64| projected([l1, l2, 0.0], [x.cos(), x.sin(), 0.0]);
    max_at_ends_and_peaks(g, l1, l2, a, b)
}

/// Largest value of `g` over `[a, b]` for a `g` that, between multiples of π/2, peaks only
/// where |tan α| = l2/l1: the larger of the ends and of every such peak inside.
fn max_at_ends_and_peaks(g: impl Fn(f64) -> f64, l1: f64, l2: f64, a: f64, b: f64) -> f64 {
    let mut best = g(a).max(g(b));
    let peak = l2.atan2(l1);
    for base in [peak, -peak] {
        let pi = std::f64::consts::PI;
        let mut x = a + (base - a).rem_euclid(pi);
        while x <= b {
            best = best.max(g(x));
            x += pi;
        }
    }
    best
}

/// Largest value over `[a, b]` of `l1·|cos α| + l2·|sin α|` (the support along an
/// in-plane direction at angle α): concave between multiples of π/2, peaking at
/// |tan α| = l2/l1.
pub fn max_planar_support(l1: f64, l2: f64, a: f64, b: f64) -> f64 {
    let g = |x: f64| l1 * x.cos().abs() + l2 * x.sin().abs();
    max_at_ends_and_peaks(g, l1, l2, a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIM: [f64; 3] = [250.0, 200.0, 100.0];

    fn unit(a: [f64; 3]) -> [f64; 3] {
        Vec3::from_array(a).unit_or_zero().to_array()
    }

    fn dense_max(f: impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
        (0..=200_000)
            .map(|k| f(a + (b - a) * k as f64 / 200_000.0))
            .fold(0.0, f64::max)
    }

    #[test]
    fn projected_and_support_along_axes_and_diagonals() {
        assert_eq!(projected(LIM, [1.0, 0.0, 0.0]), 250.0);
        let d = 0.5f64.sqrt();
        assert!((projected([250.0; 3], [d, d, 0.0]) - 250.0 * 2f64.sqrt()).abs() < 1e-9);
        assert!((support([250.0; 3], [d, d, 0.0]) - 250.0 * 2f64.sqrt()).abs() < 1e-9);
        assert_eq!(support(LIM, [0.0, 0.0, -1.0]), 100.0);
    }

    #[test]
    fn maxima_between_directions_match_dense_sampling() {
        let cases = [
            ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            ([1.0, 0.0, 0.0], unit([0.3, 0.4, -0.8])),
            (unit([0.2, -1.0, 0.1]), unit([-0.5, 0.1, 0.9])),
            ([0.0, 0.0, 1.0], unit([1.0, 1.0, 0.0])),
        ];
        for (a, b) in cases {
            let (va, vb) = (Vec3::from_array(a), Vec3::from_array(b));
            let c = va.dot(vb).clamp(-1.0, 1.0);
            let ang = c.acos();
            let w = (vb - va.scale(c)).unit_or_zero();
            let t = |phi: f64| {
                let (s, co) = phi.sin_cos();
                [
                    co * a[0] + s * w[0],
                    co * a[1] + s * w[1],
                    co * a[2] + s * w[2],
                ]
            };
            let want = dense_max(|phi| projected(LIM, t(phi)), 0.0, ang);
            let got = max_projected_between(LIM, a, b);
            assert!(
                got >= want - 1e-9 && got <= want * (1.0 + 1e-4),
                "{got} {want}"
            );
            let want = dense_max(|phi| support(LIM, t(phi)), 0.0, ang);
            assert!(max_support_between(LIM, a, b) >= want - 1e-9);
        }
    }

    #[test]
    fn planar_maxima_match_dense_sampling() {
        for (a, b) in [(0.1, 0.5), (-2.0, 3.0), (0.0, 12.0), (1.0, 1.2)] {
            let want = dense_max(
                |x| projected([250.0, 200.0, 0.0], [x.cos(), x.sin(), 0.0]),
                a,
                b,
            );
            let got = max_planar_projected(250.0, 200.0, a, b);
            assert!(
                got >= want - 1e-9 && got <= want * (1.0 + 1e-4),
                "{got} {want}"
            );
            let want = dense_max(|x| 250.0 * x.cos().abs() + 200.0 * x.sin().abs(), a, b);
            let got = max_planar_support(250.0, 200.0, a, b);
            assert!(
                got >= want - 1e-9 && got <= want * (1.0 + 1e-4),
                "{got} {want}"
            );
        }
    }
}
