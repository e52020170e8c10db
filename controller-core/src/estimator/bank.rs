//! The three axes' estimators as the control interrupt uses them: wide counts in,
//! [`Measured`] (positions and velocities for the laws) out, and the saturated output fed
//! back so the Kalman filter knows the commanded acceleration.

use super::{Estimate, EstimatorConfig, EstimatorTiming, Scales, VelocityEstimator};
use crate::gantry::Measured;
use crate::params::{finite, ConfigError, PlantParams};
use crate::{Real, Vec3};

/// The acceleration a command produces according to the axis model
/// `θ'' = -a θ' - b θ + k u` (spec 1.1; for the physical axis `J x'' + B x' = u`:
/// `a = B/J`, `b = 0`, `k = 1/J`, friction being left to the Kalman filter's bias state).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelModel<R> {
    a: R,
    b: R,
    k: R,
}

impl<R: Real> AccelModel<R> {
    pub fn new(p: &PlantParams) -> Result<Self, ConfigError> {
        Ok(Self {
            a: R::from_f32(finite(p.a, "accel_model.a")?),
            b: R::from_f32(finite(p.b, "accel_model.b")?),
            k: R::from_f32(finite(p.k, "accel_model.k")?),
        })
    }

    /// `k u - a v - b q` at the estimated state.
    pub fn accel(&self, u: R, at: &Estimate<R>) -> R {
        (self.k * u - self.a * at.vel - self.b * at.pos).finite_or_zero()
    }
}

/// One estimator per axis plus the command that was applied last period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimators3<R> {
    axes: [VelocityEstimator<R>; 3],
    models: [Option<AccelModel<R>>; 3],
    applied_u: Vec3<R>,
    scales: Scales<R>,
}

impl<R: Real> Estimators3<R> {
    /// `models[i]`: the axis model for the commanded acceleration (`None`: no input, the
    /// Kalman filter then relies on its bias state alone). Starts at rest at `counts`.
    pub fn new(
        cfg: &[EstimatorConfig; 3],
        models: &[Option<PlantParams>; 3],
        timing: &EstimatorTiming,
        counts: [i64; 3],
    ) -> Result<Self, ConfigError> {
        let model = |m: &Option<PlantParams>| m.as_ref().map(AccelModel::new).transpose();
        Ok(Self {
            axes: [
                VelocityEstimator::new(&cfg[0], timing, counts[0])?,
                VelocityEstimator::new(&cfg[1], timing, counts[1])?,
                VelocityEstimator::new(&cfg[2], timing, counts[2])?,
            ],
            models: [model(&models[0])?, model(&models[1])?, model(&models[2])?],
            applied_u: Vec3::zero(),
            scales: Scales::new(timing)?,
        })
    }

    /// Call once per period with this period's wide counts, before the control law.
    /// Positions are the measured counts (in units), velocities the estimates.
    pub fn update(&mut self, counts: [i64; 3]) -> Measured<R> {
        let mut m = Measured::default();
        for (i, ((est, model), &n)) in self
            .axes
            .iter_mut()
            .zip(&self.models)
            .zip(&counts)
            .enumerate()
        {
            let accel = match model {
                Some(md) => md.accel(self.applied_u[i], &est.estimate()),
                None => R::ZERO,
            };
            let e = est.update(n, accel);
            m.pos[i] = super::to_units(n, R::ZERO, &self.scales);
            m.vel[i] = e.vel;
        }
        m
    }

    /// Call once per period with the (saturated) output actually applied to the axes.
    pub fn applied(&mut self, u: Vec3<R>) {
        self.applied_u = u.map(Real::finite_or_zero);
    }

    /// The full estimates (sub-count positions included) after the last update.
    pub fn estimates(&self) -> [Estimate<R>; 3] {
        [
            self.axes[0].estimate(),
            self.axes[1].estimate(),
            self.axes[2].estimate(),
        ]
    }

    /// Restart every axis at rest at `counts` and forget the last command.
    pub fn reset(&mut self, counts: [i64; 3]) {
        for (e, &n) in self.axes.iter_mut().zip(&counts) {
            e.reset(n);
        }
        self.applied_u = Vec3::zero();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::{PAPER_SIM_KALMAN, PAPER_SIM_TIMING};
    use crate::params::PAPER_PLANT;

    #[test]
    fn commanded_acceleration_reaches_the_kalman_filter() {
        // u = 100 on the paper plant from rest: the velocity rises towards 10 units/s
        // (10 counts/period) with a 0.1 s time constant, a fast, lag-dominated motion. The
        // filter told the command follows it far more closely than the
        // same filter left to discover the acceleration through its bias state.
        let cfg = [EstimatorConfig::Kalman(PAPER_SIM_KALMAN); 3];
        let mut with =
            Estimators3::<f64>::new(&cfg, &[Some(PAPER_PLANT); 3], &PAPER_SIM_TIMING, [0; 3])
                .unwrap();
        let mut without =
            Estimators3::<f64>::new(&cfg, &[None; 3], &PAPER_SIM_TIMING, [0; 3]).unwrap();
        // exact motion under u = 100 with θ'' = -10θ' - θ + 100, Euler at 1 µs
        let (mut q, mut v) = (0.0f64, 0.0f64);
        let (mut worst_with, mut worst_without) = (0.0f64, 0.0f64);
        for _ in 0..1000 {
            for _ in 0..100 {
                let a = -10.0 * v - q + 100.0;
                q += v * 1e-6;
                v += a * 1e-6;
            }
            let n = (q / 1e-4).round() as i64;
            with.applied(Vec3::splat(100.0));
            without.applied(Vec3::splat(100.0));
            let mw = with.update([n; 3]);
            let mo = without.update([n; 3]);
            worst_with = worst_with.max((mw.vel.x - v).abs());
            worst_without = worst_without.max((mo.vel.x - v).abs());
            // positions are the measured counts times the (f32) count size, exactly
            assert_eq!(mw.pos.x, n as f64 * f64::from(1e-4f32));
        }
        // measured: 4.8e-3 with the command, 0.33 units/s without (velocity up to 10)
        assert!(worst_with < 0.01, "{worst_with}");
        assert!(
            worst_with < 0.05 * worst_without,
            "{worst_with} {worst_without}"
        );
    }
}
