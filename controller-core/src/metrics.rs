//! Performance indices (spec 4): ITSE, IAE, windowed ITSE (the paper's robustness index),
//! contour-error statistics, a chattering measure, and the true distance from a point to
//! an analytic path.
//!
//! Accumulators take samples at a fixed step `dt` (rectangle rule, the sample at `t`
//! weighting the interval `[t, t + dt)`).

use crate::motion::trajectory::Trajectory;
use crate::{Real, Vec3};

/// `∫ t e(t)² dt` restricted to `t_from <= t < t_to`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Itse<R> {
    pub value: R,
    t_from: R,
    t_to: R,
}

impl<R: Real> Itse<R> {
    pub fn new() -> Self {
        Self::window(R::ZERO, R::from_f32(f32::MAX))
    }

    pub fn window(t_from: R, t_to: R) -> Self {
        Self {
            value: R::ZERO,
            t_from,
            t_to,
        }
    }

    pub fn add(&mut self, t: R, e: R, dt: R) {
        if t >= self.t_from && t < self.t_to {
            self.value += t * e * e * dt;
        }
    }
}

impl<R: Real> Default for Itse<R> {
    fn default() -> Self {
        Self::new()
    }
}

/// `∫ |e| dt`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Iae<R> {
    pub value: R,
}

impl<R: Real> Iae<R> {
    pub fn add(&mut self, e: R, dt: R) {
        self.value += e.abs() * dt;
    }
}

/// Max and RMS of a non-negative quantity (contour-error magnitude).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaxRms<R> {
    pub max: R,
    sum_sq: R,
    n: u32,
}

impl<R: Real> MaxRms<R> {
    pub fn add(&mut self, v: R) {
        let a = v.abs();
        self.max = self.max.max_of(a);
        self.sum_sq += a * a;
        self.n = self.n.saturating_add(1);
    }

    pub fn rms(&self) -> R {
        if self.n == 0 {
            R::ZERO
        } else {
            self.sum_sq
                .div_or(R::from_f64(self.n as f64), R::ZERO)
                .sqrt_pos()
        }
    }

    pub fn count(&self) -> u32 {
        self.n
    }
}

/// Chattering: total variation of the control signal, `Σ |u_k - u_{k-1}|`; divide by the
/// duration for a per-second figure.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TotalVariation<R> {
    pub value: R,
    last: Option<R>,
}

impl<R: Real> TotalVariation<R> {
    pub fn add(&mut self, u: R) {
        if let Some(l) = self.last {
            self.value += (u - l).abs();
        }
        self.last = Some(u);
    }
}

/// Distance from `p` to the path `traj` restricted to parameters within `window` of
/// `t_hint`: a coarse scan of `scan` points followed by golden-section refinement. For a
/// path whose nearest point lies within the window (the case for tracking errors much
/// smaller than the path's curvature radius), this is the true contour error.
pub fn distance_to_path<R: Real>(traj: &Trajectory<R>, p: Vec3<R>, t_hint: R, window: R) -> R {
    const SCAN: usize = 64;
    const REFINE: usize = 40;
    let d2 = |t: R| (traj.sample(t).pos - p).norm_sq();
    let lo = t_hint - window;
    let step = (window + window) * R::from_f64(1.0 / SCAN as f64);
    let (mut best_t, mut best) = (t_hint, d2(t_hint));
    for k in 0..=SCAN {
        let t = lo + step * R::from_f64(k as f64);
        let v = d2(t);
        if v < best {
            best = v;
            best_t = t;
        }
    }
    // golden section on [best_t - step, best_t + step]
    let g = R::from_f64(0.618_033_988_749_895);
    let (mut a, mut b) = (best_t - step, best_t + step);
    let mut c = b - (b - a) * g;
    let mut d = a + (b - a) * g;
    let (mut fc, mut fd) = (d2(c), d2(d));
    for _ in 0..REFINE {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - (b - a) * g;
            fc = d2(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + (b - a) * g;
            fd = d2(d);
        }
    }
    best.min_of(fc).min_of(fd).sqrt_pos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn itse_of_constant_error() {
        // ∫_0^2 t * 0.5^2 dt = 0.5
        let mut i = Itse::<f64>::new();
        let dt = 1e-4;
        for k in 0..20_000 {
            i.add(k as f64 * dt, 0.5, dt);
        }
        assert!((i.value - 0.5).abs() < 1e-4);
        let mut w = Itse::<f64>::window(1.0, 2.0);
        for k in 0..30_000 {
            w.add(k as f64 * dt, 0.5, dt);
        }
        // ∫_1^2 t/4 dt = 0.375
        assert!((w.value - 0.375).abs() < 1e-4);
    }

    #[test]
    fn distance_to_helix_is_radial_offset() {
        let h = Trajectory::<f64>::paper_helix();
        // a point 0.01 outside the helix radius at t = 3
        let r = h.sample(3.0).pos;
        let p = Vec3::new(r.x * 1.01, r.y * 1.01, r.z);
        let d = distance_to_path(&h, p, 3.05, 0.5);
        assert!((d - 0.01).abs() < 1e-6, "{d}");
    }

    #[test]
    fn stats() {
        let mut m = MaxRms::<f64>::default();
        m.add(3.0);
        m.add(-4.0);
        assert_eq!(m.max, 4.0);
        assert!((m.rms() - libm::sqrt(12.5)).abs() < 1e-12);
        let mut tv = TotalVariation::<f64>::default();
        for u in [0.0, 1.0, -1.0, -1.0] {
            tv.add(u);
        }
        assert_eq!(tv.value, 3.0);
    }
}
