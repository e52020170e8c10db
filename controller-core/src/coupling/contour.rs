//! 3-D contour error and cross-coupling (paper eqs. 6-15, spec 3.1).
//!
//! With tracking error `E = R1 - P` and local path direction `d`, the contour error is the
//! part of `E` normal to the path, `e = E - d (E·d)/|d|²`, and each axis is driven by the
//! coupled error `C_i = E_i + λ e_i`. The direction is the paper's chord `R1 - R0` or the
//! trajectory's analytic tangent; when the chosen direction is (near) zero the other is
//! tried, and with neither available the contour error is zero: never a division by zero.

use crate::{Real, Vec3};

/// Which local path direction the contour model uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum DirectionSource {
    /// The trajectory's analytic velocity (exact tangent; the default).
    #[default]
    Tangent,
    /// The paper's chord `R1 - R0` between the current and previous reference points.
    Chord,
}

/// Projection of `v` onto the normal plane of `dir`; `None` when `|dir|² <= min_norm_sq`.
pub fn normal_component<R: Real>(v: Vec3<R>, dir: Vec3<R>, min_norm_sq: R) -> Option<Vec3<R>> {
    let n2 = dir.norm_sq();
    if !(n2 > min_norm_sq) {
        return None;
    }
    // (v·d)/|d|² is a bounded ratio for finite v once |d|² is above the threshold; the
    // fallback only matters for fixed point, where the quotient could saturate.
    let k = v.dot(dir).div_or(n2, R::ZERO);
    Some(v - dir * k)
}

/// Contour error vector `e` of tracking error `E`, with fallback direction.
pub fn contour_error<R: Real>(
    tracking: Vec3<R>,
    dir: Vec3<R>,
    fallback_dir: Vec3<R>,
    min_norm_sq: R,
) -> Vec3<R> {
    normal_component(tracking, dir, min_norm_sq)
        .or_else(|| normal_component(tracking, fallback_dir, min_norm_sq))
        .unwrap_or_else(Vec3::zero)
}

/// Coupled errors `C = E + λ e` and their rates `C' = E' + λ e'`, where `e'` is the
/// normal component of `E'` with respect to the same direction (the direction is held
/// constant over the period, consistent with the paper's local linearisation).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Coupled<R> {
    pub tracking: Vec3<R>,
    pub contour: Vec3<R>,
    pub c: Vec3<R>,
    pub c_dot: Vec3<R>,
}

#[inline(always)]
pub fn cross_couple<R: Real>(
    tracking: Vec3<R>,
    tracking_rate: Vec3<R>,
    dir: Vec3<R>,
    fallback_dir: Vec3<R>,
    lambda: R,
    min_norm_sq: R,
) -> Coupled<R> {
    // |d|² once, and one division for both projections (`Real::div2_or`: one reciprocal
    // in floating point; this runs every control period on three axes)
    let mut d = dir;
    let mut n2 = dir.norm_sq();
    if !(n2 > min_norm_sq) {
        d = fallback_dir;
        n2 = fallback_dir.norm_sq();
    }
    if !(n2 > min_norm_sq) {
        return Coupled {
            tracking,
            contour: Vec3::zero(),
            c: tracking,
            c_dot: tracking_rate,
        };
    }
    let (k, k_rate) = R::div2_or(tracking.dot(d), tracking_rate.dot(d), n2, R::ZERO);
    let (contour, contour_rate) = (tracking - d * k, tracking_rate - d * k_rate);
    Coupled {
        tracking,
        contour,
        c: tracking + contour * lambda,
        c_dot: tracking_rate + contour_rate * lambda,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_part_is_orthogonal_and_shorter() {
        let e = Vec3::new(0.3f64, -0.2, 0.5);
        let d = Vec3::new(1.0, 2.0, -0.5);
        let c = contour_error(e, d, Vec3::zero(), 1e-12);
        assert!(c.dot(d).abs() < 1e-12);
        assert!(c.norm() <= e.norm());
    }

    #[test]
    fn zero_directions_give_zero_not_nan() {
        let e = Vec3::new(1.0f32, 2.0, 3.0);
        let c = contour_error(e, Vec3::zero(), Vec3::zero(), 1e-12);
        assert_eq!(c, Vec3::zero());
        // falls back to the tangent
        let c = contour_error(e, Vec3::zero(), Vec3::new(0.0, 0.0, 1.0), 1e-12);
        assert_eq!(c, Vec3::new(1.0, 2.0, 0.0));
    }
}
