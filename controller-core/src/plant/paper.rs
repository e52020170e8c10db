//! The normalised ball-screw axis of the reference paper (spec 1.1, paper eq. 5):
//! `θ'' = -a θ' - b θ + k u + d`, and the same axis with a step disturbance.

use super::params::PlantParams;
use super::state::{AxisDynamics, AxisState};
use crate::Real;

/// `θ'' = -a θ' - b θ + k u + d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperAxis<R> {
    pub a: R,
    pub b: R,
    pub k: R,
}

impl<R: Real> PaperAxis<R> {
    /// The axis of the coefficients `p`; the paper's identified axis is
    /// [`crate::presets::paper::PAPER_PLANT`] (a = 10, b = 1, k = 1, seed 000, section 3).
    pub fn from_params(p: PlantParams) -> Self {
        Self {
            a: R::from_f32(p.a),
            b: R::from_f32(p.b),
            k: R::from_f32(p.k),
        }
    }

    /// Acceleration for input `u` and additive acceleration disturbance `d`.
    pub fn accel(&self, s: AxisState<R>, u: R, d: R) -> R {
        -self.a * s.vel - self.b * s.pos + self.k * u + d
    }
}

/// A [`PaperAxis`] with a step disturbance `d_step` added to θ'' from `t_dist` on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisturbedPaperAxis<R> {
    pub axis: PaperAxis<R>,
    pub d_step: R,
    pub t_dist: R,
}

impl<R: Real> AxisDynamics<R> for DisturbedPaperAxis<R> {
    fn accel(&self, s: AxisState<R>, u: R, t: R) -> R {
        let d = if t >= self.t_dist {
            self.d_step
        } else {
            R::ZERO
        };
        self.axis.accel(s, u, d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::state::rk4_step;
    use crate::presets::paper::PAPER_PLANT;

    #[test]
    fn rk4_matches_analytic_step_response() {
        // θ'' = -10θ' - θ + 1 from rest: θ(t) = 1 - (r2 e^{r1 t} - r1 e^{r2 t})/(r2 - r1)
        let ax = DisturbedPaperAxis {
            axis: PaperAxis::<f64>::from_params(PAPER_PLANT),
            d_step: 0.0,
            t_dist: 1e9,
        };
        let axes = [ax];
        let mut s = [AxisState::default()];
        let dt = 1e-3;
        for i in 0..2000 {
            rk4_step(&axes, &mut s, i as f64 * dt, dt, |_, _| [1.0]);
        }
        let d = libm::sqrt(96.0);
        let (r1, r2) = ((-10.0 + d) / 2.0, (-10.0 - d) / 2.0);
        let t = 2.0;
        let exact = 1.0 - (r2 * libm::exp(r1 * t) - r1 * libm::exp(r2 * t)) / (r2 - r1);
        assert!(
            (s[0].pos - exact).abs() < 1e-10,
            "{} vs {}",
            s[0].pos,
            exact
        );
    }
}
