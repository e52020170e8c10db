//! The state of a simulated axis, the [`AxisDynamics`] trait every axis model implements,
//! and the fixed-step RK4 integration of a set of axes ([`rk4_step`]), which takes the
//! input as a function of time and state so that a continuous-time controller can be
//! re-evaluated at every RK stage.

use crate::num::ode::{rk4, OdeState};
use crate::Real;

/// Position and velocity of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisState<R> {
    pub pos: R,
    pub vel: R,
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
