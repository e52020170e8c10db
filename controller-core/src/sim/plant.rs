//! Axis plant models for simulation (host-sim, and the firmware's QEMU build).
//!
//! [`PaperAxis`] is the normalised ball-screw axis of the reference paper (spec 1.1,
//! paper eq. 5): `θ'' = -a θ' - b θ + k u + d`. It is integrated with classic fixed-step
//! RK4 by [`rk4_step`], which takes the input as a function of time and state so that a
//! continuous-time controller can be re-evaluated at every RK stage.

use crate::num::ode::{rk4, OdeState};
use crate::Real;

/// Position and velocity of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisState<R> {
    pub pos: R,
    pub vel: R,
}

/// `θ'' = -a θ' - b θ + k u + d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperAxis<R> {
    pub a: R,
    pub b: R,
    pub k: R,
}

impl<R: Real> PaperAxis<R> {
    /// The paper's identified axis: a = 10, b = 1, k = 1 (seed 000, section 3).
    pub fn paper() -> Self {
        let p = crate::presets::paper::PAPER_PLANT;
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

/// Any second-order axis model usable by [`rk4_step`].
pub trait AxisDynamics<R> {
    fn accel(&self, s: AxisState<R>, u: R, t: R) -> R;
}

impl<R: Real> OdeState<R> for AxisState<R> {
    fn add_scaled(&self, d: &Self, h: R) -> Self {
        Self {
            pos: self.pos + d.pos * h,
            vel: self.vel + d.vel * h,
        }
    }
}

impl<R: Real, const N: usize> OdeState<R> for [AxisState<R>; N] {
    fn add_scaled(&self, d: &Self, h: R) -> Self {
        let mut o = *self;
        for (x, dx) in o.iter_mut().zip(d) {
            *x = x.add_scaled(dx, h);
        }
        o
    }
}

/// `d/dt` of one axis state under `accel`.
pub fn axis_derivative<R: Real>(s: AxisState<R>, accel: R) -> AxisState<R> {
    AxisState {
        pos: s.vel,
        vel: accel,
    }
}

/// One RK4 step of a set of `N` axes from time `t` over `dt`. `input(t, states)` returns
/// the per-axis input at an RK stage (a zero-order-hold caller returns a constant).
pub fn rk4_step<R: Real, D: AxisDynamics<R>, const N: usize>(
    axes: &[D; N],
    states: &mut [AxisState<R>; N],
    t: R,
    dt: R,
    mut input: impl FnMut(R, &[AxisState<R>; N]) -> [R; N],
) {
    *states = rk4(states, t, dt, |tt, s| {
        let u = input(tt, s);
        let mut d = *s;
        for (((di, si), ui), ax) in d.iter_mut().zip(s).zip(u).zip(axes) {
            *di = axis_derivative(*si, ax.accel(*si, ui, tt));
        }
        d
    });
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

    #[test]
    fn rk4_matches_analytic_step_response() {
        // θ'' = -10θ' - θ + 1 from rest: θ(t) = 1 - (r2 e^{r1 t} - r1 e^{r2 t})/(r2 - r1)
        let ax = DisturbedPaperAxis {
            axis: PaperAxis::<f64>::paper(),
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
