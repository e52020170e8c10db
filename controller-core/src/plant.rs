//! Axis plant models for simulation (host-sim, and the firmware's QEMU build).
//!
//! [`PaperAxis`] is the normalised ball-screw axis of the reference paper (spec 1.1,
//! paper eq. 5): `θ'' = -a θ' - b θ + k u + d`. It is integrated with classic fixed-step
//! RK4 by [`rk4_step`], which takes the input as a function of time and state so that a
//! continuous-time controller can be re-evaluated at every RK stage.

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
        let p = crate::params::PAPER_PLANT;
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

/// One RK4 step of a set of `N` axes from time `t` over `dt`. `input(t, states)` returns
/// the per-axis input at an RK stage (a zero-order-hold caller returns a constant).
pub fn rk4_step<R: Real, D: AxisDynamics<R>, const N: usize>(
    axes: &[D; N],
    states: &mut [AxisState<R>; N],
    t: R,
    dt: R,
    mut input: impl FnMut(R, &[AxisState<R>; N]) -> [R; N],
) {
    let half = R::from_f32(0.5);
    let sixth = R::from_f64(1.0 / 6.0);
    let two = R::from_f32(2.0);
    let deriv = |s: &[AxisState<R>; N], u: &[R; N], tt: R| -> [AxisState<R>; N] {
        let mut d = [AxisState::default(); N];
        for i in 0..N {
            d[i] = AxisState {
                pos: s[i].vel,
                vel: axes[i].accel(s[i], u[i], tt),
            };
        }
        d
    };
    let offset = |s: &[AxisState<R>; N], k: &[AxisState<R>; N], h: R| -> [AxisState<R>; N] {
        let mut o = *s;
        for i in 0..N {
            o[i].pos += k[i].pos * h;
            o[i].vel += k[i].vel * h;
        }
        o
    };
    let s0 = *states;
    let u1 = input(t, &s0);
    let k1 = deriv(&s0, &u1, t);
    let s2 = offset(&s0, &k1, dt * half);
    let u2 = input(t + dt * half, &s2);
    let k2 = deriv(&s2, &u2, t + dt * half);
    let s3 = offset(&s0, &k2, dt * half);
    let u3 = input(t + dt * half, &s3);
    let k3 = deriv(&s3, &u3, t + dt * half);
    let s4 = offset(&s0, &k3, dt);
    let u4 = input(t + dt, &s4);
    let k4 = deriv(&s4, &u4, t + dt);
    for i in 0..N {
        states[i].pos += (k1[i].pos + two * k2[i].pos + two * k3[i].pos + k4[i].pos) * dt * sixth;
        states[i].vel += (k1[i].vel + two * k2[i].vel + two * k3[i].vel + k4[i].vel) * dt * sixth;
    }
}

/// A [`PaperAxis`] with a step disturbance `d_step` added to θ'' from `t_dist` on.
#[derive(Clone, Copy, Debug)]
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
