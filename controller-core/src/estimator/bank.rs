//! The three axes' estimators as the servo step uses them: wide counts in, [`Measured`]
//! positions and velocities out, and the commanded acceleration fed to the estimators that
//! use one (the Kalman filter).
//!
//! The commanded acceleration ([`AccelInput`]) is either the reference's planned
//! acceleration (no lag on planned motion; available on the board as well) or the axis
//! model times the output *applied* in the previous period (what actually pushes the
//! axis, saturation included).

use super::{Estimate, EstimatorConfig, EstimatorTiming, Scales, VelocityEstimator};
use crate::axes::AXES;
use crate::config::{finite, ConfigError};
use crate::controller::Measured;
use crate::plant::PlantParams;
use crate::{Real, Vec3};

/// Where the estimators' commanded acceleration comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum AccelInput {
    /// None (zero): the Kalman filter relies on its bias state alone.
    #[default]
    None,
    /// The reference acceleration of the current period.
    Reference,
    /// Each axis' model `θ'' = -a θ' - b θ + k u` at the estimate, with the output applied
    /// in the previous period.
    Model(
        #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))] [PlantParams; AXES],
    ),
}

/// Estimator per axis and the commanded-acceleration input.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct EstimatorBankConfig {
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub axes: [EstimatorConfig; AXES],
    #[cfg_attr(feature = "serde", serde(default))]
    pub accel_input: AccelInput,
}

impl EstimatorBankConfig {
    /// The same estimator on every axis, no acceleration input.
    pub const fn uniform(cfg: EstimatorConfig) -> Self {
        Self {
            axes: [cfg; AXES],
            accel_input: AccelInput::None,
        }
    }

    /// True if any axis asks for the simulated true velocity.
    pub fn needs_true_velocity(&self) -> bool {
        self.axes
            .iter()
            .any(|a| matches!(a, EstimatorConfig::Exact))
    }
}

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

#[derive(Clone, Copy, Debug, PartialEq)]
enum Accel<R> {
    None,
    Reference,
    Model([AccelModel<R>; AXES]),
}

/// One estimator per axis plus the output that was applied last period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorBank<R> {
    axes: [VelocityEstimator<R>; AXES],
    exact: [bool; AXES],
    accel: Accel<R>,
    applied_u: Vec3<R>,
    /// Length of one count per axis: positions are `count × length` in `R` (no `f64`,
    /// soft float on the board): the count is exact (one integer conversion within
    /// ±2^24 counts, see [`super::count_to_real`]) and the product rounds once, so the
    /// position is within half an ulp of `R` plus `|count| × length × ε` of the exact
    /// one. In `f32` and within ±2 m of the arm position that is below 0.11 µm, whatever
    /// the run's length (`tests/position_24h.rs` runs 24 h at 10 kHz;
    /// docs/performance.md).
    count_len: [R; AXES],
}

impl<R: Real> EstimatorBank<R> {
    /// Starts at rest at wide counts `counts`; `timing[i]` is axis i's period and count.
    pub fn new(
        cfg: &EstimatorBankConfig,
        timing: &[EstimatorTiming; AXES],
        count_len: [f64; AXES],
        counts: [i64; AXES],
    ) -> Result<Self, ConfigError> {
        let accel = match &cfg.accel_input {
            AccelInput::None => Accel::None,
            AccelInput::Reference => Accel::Reference,
            AccelInput::Model(m) => Accel::Model([
                AccelModel::new(&m[0])?,
                AccelModel::new(&m[1])?,
                AccelModel::new(&m[2])?,
            ]),
        };
        for t in timing {
            Scales::<R>::new(t)?;
        }
        Ok(Self {
            axes: [
                VelocityEstimator::new(&cfg.axes[0], &timing[0], counts[0])?,
                VelocityEstimator::new(&cfg.axes[1], &timing[1], counts[1])?,
                VelocityEstimator::new(&cfg.axes[2], &timing[2], counts[2])?,
            ],
            exact: cfg.axes.map(|a| matches!(a, EstimatorConfig::Exact)),
            accel,
            applied_u: Vec3::zero(),
            count_len: count_len.map(R::from_f64),
        })
    }

    /// Call once per period with this period's wide counts, before the control law.
    /// `reference_acc`: the reference acceleration of this period (used with
    /// [`AccelInput::Reference`]); `true_vel`: the simulated plant's velocity (used by
    /// [`EstimatorConfig::Exact`] axes). Positions are the measured counts (in units),
    /// velocities the estimates.
    pub fn update(
        &mut self,
        counts: [i64; AXES],
        reference_acc: Vec3<R>,
        true_vel: Option<[f64; AXES]>,
    ) -> Measured<R> {
        // written out per axis: each inlines with a constant index
        let x = self.update_axis(0, counts[0], reference_acc, true_vel);
        let y = self.update_axis(1, counts[1], reference_acc, true_vel);
        let z = self.update_axis(2, counts[2], reference_acc, true_vel);
        Measured {
            pos: Vec3::new(x.pos, y.pos, z.pos),
            vel: Vec3::new(x.vel, y.vel, z.vel),
        }
    }

    /// Axis `i` of [`Self::update`]: its measured position and velocity.
    #[inline(always)]
    fn update_axis(
        &mut self,
        i: usize,
        count: i64,
        reference_acc: Vec3<R>,
        true_vel: Option<[f64; AXES]>,
    ) -> Estimate<R> {
        let est = &mut self.axes[i];
        let accel = match &self.accel {
            Accel::None => R::ZERO,
            Accel::Reference => reference_acc[i],
            Accel::Model(md) => md[i].accel(self.applied_u[i], &est.estimate()),
        };
        let e = est.update(count, accel);
        Estimate {
            pos: super::counts_to_position(count, self.count_len[i]),
            vel: match (self.exact[i], true_vel) {
                (true, Some(v)) => R::from_f64(v[i]),
                (true, None) => R::ZERO,
                (false, _) => e.vel,
            },
        }
    }

    /// Call once per period with the (saturated) output actually applied to the axes.
    pub fn applied(&mut self, u: Vec3<R>) {
        self.applied_u = u.map(Real::finite_or_zero);
    }

    /// The full estimates (sub-count positions included) after the last update.
    pub fn estimates(&self) -> [Estimate<R>; AXES] {
        [
            self.axes[0].estimate(),
            self.axes[1].estimate(),
            self.axes[2].estimate(),
        ]
    }

    /// Restart every axis at rest at `counts` and forget the last command.
    pub fn reset(&mut self, counts: [i64; AXES]) {
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
    use crate::presets::paper::PAPER_PLANT;

    #[test]
    fn commanded_acceleration_reaches_the_kalman_filter() {
        // u = 100 on the paper plant from rest: the velocity rises towards 10 units/s
        // (10 counts/period) with a 0.1 s time constant, a fast, lag-dominated motion. The
        // filter told the command follows it far more closely than the
        // same filter left to discover the acceleration through its bias state.
        let cfg = EstimatorBankConfig {
            axes: [EstimatorConfig::Kalman(PAPER_SIM_KALMAN); 3],
            accel_input: AccelInput::Model([PAPER_PLANT; 3]),
        };
        let without_cfg = EstimatorBankConfig {
            accel_input: AccelInput::None,
            ..cfg
        };
        let t = [PAPER_SIM_TIMING; 3];
        let mut with = EstimatorBank::<f64>::new(&cfg, &t, [1e-4; 3], [0; 3]).unwrap();
        let mut without = EstimatorBank::<f64>::new(&without_cfg, &t, [1e-4; 3], [0; 3]).unwrap();
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
            let mw = with.update([n; 3], Vec3::zero(), None);
            let mo = without.update([n; 3], Vec3::zero(), None);
            worst_with = worst_with.max((mw.vel.x - v).abs());
            worst_without = worst_without.max((mo.vel.x - v).abs());
            // positions are the measured counts times the count length
            assert!((mw.pos.x - n as f64 * 1e-4).abs() < 1e-15);
        }
        // measured: 4.8e-3 with the command, 0.33 units/s without (velocity up to 10)
        assert!(worst_with < 0.01, "{worst_with}");
        assert!(
            worst_with < 0.05 * worst_without,
            "{worst_with} {worst_without}"
        );
    }

    #[test]
    fn exact_axes_take_the_true_velocity() {
        let cfg = EstimatorBankConfig::uniform(EstimatorConfig::Exact);
        let mut b =
            EstimatorBank::<f32>::new(&cfg, &[PAPER_SIM_TIMING; 3], [1e-4; 3], [0; 3]).unwrap();
        let m = b.update([3, 4, 5], Vec3::zero(), Some([1.5, -2.0, 0.25]));
        assert_eq!(m.vel, Vec3::new(1.5, -2.0, 0.25));
        assert!(cfg.needs_true_velocity());
    }
}
