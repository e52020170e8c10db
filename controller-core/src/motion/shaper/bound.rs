//! The contour deviation the shaper adds, bounded by the reference's acceleration.
//!
//! Every axis `i` of the shaped reference is a weighted sum of the reference's samples,
//! `yᵢ(t) = Σₖ wₖ rᵢ(t − τₖ)`, with weights `wₖ ≥ 0` summing to 1 and centred on the
//! common delay `D` (`Σₖ wₖ τₖ = D`: the taps sit on whole periods, and their amplitudes
//! are tilted so that each axis' centroid is on `D` exactly, module docs "Whole
//! periods"). Taylor's theorem about
//! `t − D` with the integral remainder gives
//!
//! ```text
//! yᵢ(t) − rᵢ(t − D) = Σₖ wₖ [rᵢ(t − τₖ) − rᵢ(t − D)]
//!                   = −rᵢ'(t − D) Σₖ wₖ (τₖ − D)  +  Σₖ wₖ ∫ (remainder, |·| ≤ ½ |rᵢ''| (τₖ − D)²)
//! ```
//!
//! The first sum is zero (common centroid), so `|yᵢ(t) − rᵢ(t − D)| ≤ ½ aᵢ Mᵢ` with
//! `Mᵢ = Σₖ wₖ (τₖ − D)²` the axis' second moment and `aᵢ` a bound on `|rᵢ''|` over the
//! window. Over the axes, the shaped point lies within `½ √(Σᵢ (aᵢ Mᵢ)²)` of the path
//! point `r(t − D)`, so within that distance of the path: the delay only moves the point
//! along the path. With one bound `a` on every axis' acceleration (or on the norm of the
//! acceleration vector, which bounds each component) this is `½ a √(Σᵢ Mᵢ²)`.
//!
//! The bound is tight on a circle (a constant centripetal acceleration over the whole
//! window): the shaped circle has the radius `ρ |H(ω)|`, `H` the shaper's response, and
//! `1 − |H| = ½ ω² M + O(ω⁴)`, so it moves inward by `½ a M`; the bound is `√2` times
//! that when X and Y carry the same shaper (and Z none). At a corner blend the
//! acceleration lasts for a fraction of the window and the deviation is smaller.
//!
//! How it is counted inside the path tolerance `ε`: the planner blends corners within
//! `ε − B` (B this bound at the planner's acceleration limits,
//! [`DeviationBound::blend_tolerance_mm`]), so the shaped reference stays within `ε` of the
//! programmed path; or the acceleration is limited so that `B` fits a share of `ε`
//! ([`DeviationBound::acc_for_deviation_mm_s2`]). On this gantry (Y's 35 Hz mode, ZV,
//! M = 5.06e-5 s² on whole periods) at the planner's 2000 mm/s² B = 0.051 mm, five times its 0.01 mm
//! tolerance: Klipper's "smoothing", the price of the shaper, is the reason its
//! calibration recommends a maximum acceleration per shaper.

use crate::axes::AXES;

/// The shaper's contour deviation bound: the second moment `Mᵢ` of every axis' taps about
/// the common delay (s²; 0 for an axis delayed without shaping).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviationBound {
    pub second_moment_s2: [f32; AXES],
}

impl DeviationBound {
    /// `½ √(Σᵢ (aᵢ Mᵢ)²)` (mm) for per-axis acceleration bounds `aᵢ` (mm/s², the planner's
    /// per-axis limits); infinite or NaN bounds give an infinite deviation.
    pub fn deviation_bound_axes_mm(&self, acc_max_mm_s2: [f32; AXES]) -> f32 {
        let mut s = 0.0f32;
        for (m, a) in self.second_moment_s2.iter().zip(acc_max_mm_s2) {
            if *m > 0.0 {
                if !(a.abs() < f32::INFINITY) {
                    return f32::INFINITY;
                }
                let d = a * m;
                s += d * d;
            }
        }
        0.5 * libm::sqrtf(s)
    }

    /// `½ a √(Σᵢ Mᵢ²)` (mm): one bound `a` (mm/s²) on every axis' acceleration, or on the
    /// norm of the acceleration.
    pub fn deviation_bound_mm(&self, acc_max_mm_s2: f32) -> f32 {
        self.deviation_bound_axes_mm([acc_max_mm_s2; AXES])
    }

    /// The largest acceleration bound (same on every axis, mm/s²) whose deviation bound is
    /// at most `deviation_mm`: `2 d / √(Σ Mᵢ²)`; infinite without shaping, 0 for a
    /// deviation ≤ 0.
    pub fn acc_for_deviation_mm_s2(&self, deviation_mm: f32) -> f32 {
        let unit = self.deviation_bound_mm(1.0);
        if !(deviation_mm > 0.0) {
            0.0
        } else if unit > 0.0 {
            deviation_mm / unit
        } else {
            f32::INFINITY
        }
    }

    /// What remains of the path tolerance `path_tolerance_mm` for the planner's blends
    /// once the shaper's deviation at the per-axis acceleration limits is counted:
    /// `ε − B`, or `None` when the shaper alone uses all of it.
    pub fn blend_tolerance_mm(
        &self,
        path_tolerance_mm: f32,
        acc_max_mm_s2: [f32; AXES],
    ) -> Option<f32> {
        let rest = path_tolerance_mm - self.deviation_bound_axes_mm(acc_max_mm_s2);
        (rest > 0.0).then_some(rest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bound_is_half_a_times_the_moment_norm() {
        let b = DeviationBound {
            second_moment_s2: [3.0e-5, 4.0e-5, 0.0],
        };
        // ½ · 1000 · √(3² + 4²)e-5 = 0.025 mm
        assert!((b.deviation_bound_mm(1000.0) - 0.025).abs() < 1e-7);
        assert!((b.deviation_bound_axes_mm([1000.0, 0.0, 5.0]) - 0.015).abs() < 1e-7);
        assert!((b.acc_for_deviation_mm_s2(0.025) - 1000.0).abs() < 1e-2);
        assert_eq!(b.blend_tolerance_mm(0.02, [1000.0; 3]), None);
        let rest = b.blend_tolerance_mm(0.03, [1000.0; 3]).unwrap();
        assert!((rest - 0.005).abs() < 1e-7, "{rest}");
        assert_eq!(b.deviation_bound_mm(f32::INFINITY), f32::INFINITY);
        // an unshaped axis does not care about its acceleration
        assert!((b.deviation_bound_axes_mm([1000.0, 0.0, f32::INFINITY]) - 0.015).abs() < 1e-7);
        let none = DeviationBound::default();
        assert_eq!(none.deviation_bound_mm(1e6), 0.0);
        assert_eq!(none.acc_for_deviation_mm_s2(0.01), f32::INFINITY);
    }
}
