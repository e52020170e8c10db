//! Classic fixed-step RK4 over any state that can be scaled and added.
//!
//! Shared by the plant models ([`crate::plant::state::rk4_step`]) and the host simulator's
//! continuous mode, which integrates the laws' internal states together with the plant.

use crate::Real;

/// A state vector of an ODE: `self + d * h`.
pub trait OdeState<R>: Copy {
    fn add_scaled(&self, d: &Self, h: R) -> Self;
}

/// One RK4 step of `x' = f(t, x)` from `t` over `dt`.
pub fn rk4<R: Real, S: OdeState<R>>(x: &S, t: R, dt: R, mut f: impl FnMut(R, &S) -> S) -> S {
    let half = dt * R::from_f64(0.5);
    let k1 = f(t, x);
    let k2 = f(t + half, &x.add_scaled(&k1, half));
    let k3 = f(t + half, &x.add_scaled(&k2, half));
    let k4 = f(t + dt, &x.add_scaled(&k3, dt));
    let sixth = dt * R::from_f64(1.0 / 6.0);
    let third = dt * R::from_f64(1.0 / 3.0);
    x.add_scaled(&k1, sixth)
        .add_scaled(&k2, third)
        .add_scaled(&k3, third)
        .add_scaled(&k4, sixth)
}
