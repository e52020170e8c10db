//! Steady-state Kalman filter with a constant-acceleration model driven by the commanded
//! acceleration.
//!
//! State (relative to the last measured count, per-period units): position `p` (counts),
//! velocity `v` (counts/period) and `d`, the acceleration the command does not explain
//! (load, friction, model error; counts/period²). With the commanded acceleration `a`
//! held over the period:
//!
//! ```text
//! p⁺ = p + v + (a + d)/2,   v⁺ = v + a + d,   d⁺ = d + w,   n = p + quantisation
//! ```
//!
//! `w` is white (the discrete Wiener-process-acceleration model), entering the state
//! through `Γ = [1/2, 1, 1]`. The measurement noise is the uniform quantisation of one
//! count (variance 1/12 count²) unless configured otherwise. The Riccati equation is
//! iterated once, at construction, in `f64`; the filter then runs with the constant
//! gains `K = [k_p, k_v, k_d]`, which costs the same per period as the PLL plus one
//! multiply-add. Without the acceleration input this is the classic alpha-beta-gamma
//! filter: three integrators, so even a constant acceleration leaves no steady-state
//! velocity error. With the command as input, known motion causes no lag at all, so the
//! process noise (hence the bandwidth, hence the noise) can be set low.

use super::{
    cubic_is_stable, estimate_of, settle, step_counts, Estimate, EstimatorTiming, Scales,
    MAX_STEP_COUNTS,
};
use crate::config::{positive, ConfigError};
use crate::Real;

/// Kalman tuning, in plant units.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct KalmanConfig {
    /// Standard deviation of the change, per period, of the acceleration the command does
    /// not explain (units/s²). Larger: faster, noisier.
    pub accel_noise_units_s2: f32,
    /// Standard deviation of the position measurement (counts); uniform quantisation of
    /// one count is `1/√12`.
    #[cfg_attr(feature = "serde", serde(default = "quantisation_std"))]
    pub meas_noise_counts: f32,
}

/// Standard deviation of a uniform one-count quantisation error, `1/√12`.
pub const QUANTISATION_STD_COUNTS: f32 = 0.288_675_13;

#[cfg(feature = "serde")]
fn quantisation_std() -> f32 {
    QUANTISATION_STD_COUNTS
}

/// Kalman filter for the paper simulation (10 kHz, 1e-4-unit counts), chosen from the
/// sweep in docs/velocity-estimation.md: σ_w = 0.05 units/s² per period, the value at
/// which DSMC's helix contour error stays below one count while its chattering (z axis)
/// is lowest; the DSMC/SMC results vary little between 0.005 and 0.1.
pub const PAPER_SIM_KALMAN: KalmanConfig = KalmanConfig {
    accel_noise_units_s2: 0.05,
    meas_noise_counts: QUANTISATION_STD_COUNTS,
};

/// Riccati iterations allowed at construction. Convergence is geometric with the slowest
/// closed-loop pole; 10⁶ iterations cover poles up to 1 - 3e-5 to 1e-12, i.e. any
/// bandwidth above ~0.3 rad/s at 10 kHz.
const MAX_RICCATI_ITERATIONS: u32 = 1_000_000;
/// Relative change of the gains below which the Riccati iteration has converged.
const RICCATI_TOLERANCE: f64 = 1e-12;

type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    core::array::from_fn(|i| {
        core::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

fn transpose(a: &M3) -> M3 {
    core::array::from_fn(|i| core::array::from_fn(|j| a[j][i]))
}

/// Steady-state gain of the filter for process-noise variance `q` (counts²/period⁴) and
/// measurement variance `r` (counts²).
fn steady_state_gain(q: f64, r: f64) -> Option<[f64; 3]> {
    const F: M3 = [[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]];
    const G: [f64; 3] = [0.5, 1.0, 1.0];
    let ft = transpose(&F);
    let mut p: M3 = [[0.0; 3]; 3];
    // start from a large diagonal covariance: "nothing known"
    p[0][0] = 1e6;
    p[1][1] = 1e6;
    p[2][2] = 1e6;
    let mut k_prev = [f64::INFINITY; 3];
    for _ in 0..MAX_RICCATI_ITERATIONS {
        let mut pm = mul(&mul(&F, &p), &ft);
        for (row, gi) in pm.iter_mut().zip(G) {
            for (x, gj) in row.iter_mut().zip(G) {
                *x += q * gi * gj;
            }
        }
        let s = pm[0][0] + r;
        if !(s > 0.0) {
            return None;
        }
        let k = [pm[0][0] / s, pm[1][0] / s, pm[2][0] / s];
        // P = (I - K H) P⁻
        p = core::array::from_fn(|i| core::array::from_fn(|j| pm[i][j] - k[i] * pm[0][j]));
        let change = (0..3).fold(0.0f64, |m, i| {
            m.max((k[i] - k_prev[i]).abs() / k[i].abs().max(1e-300))
        });
        if !k.iter().all(|x| x.is_finite()) {
            return None;
        }
        if change < RICCATI_TOLERANCE {
            return Some(k);
        }
        k_prev = k;
    }
    None
}

/// Characteristic polynomial `z³ + a2 z² + a1 z + a0` of `(I - K H) F`.
fn closed_loop_poly(k: [f64; 3]) -> (f64, f64, f64) {
    const F: M3 = [[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]];
    let m: M3 = core::array::from_fn(|i| core::array::from_fn(|j| F[i][j] - k[i] * F[0][j]));
    let tr = m[0][0] + m[1][1] + m[2][2];
    let minors = m[0][0] * m[1][1] - m[0][1] * m[1][0] + m[0][0] * m[2][2] - m[0][2] * m[2][0]
        + m[1][1] * m[2][2]
        - m[1][2] * m[2][1];
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    (-tr, minors, -det)
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kalman<R> {
    scales: Scales<R>,
    k_pos: R,
    k_vel: R,
    k_acc: R,
    /// Last measured wide count: the origin of `rel`.
    last: i64,
    /// Position estimate minus `last` (counts).
    rel: R,
    /// Velocity estimate (counts/period).
    vel: R,
    /// Unexplained acceleration (counts/period²).
    bias: R,
}

impl<R: Real> Kalman<R> {
    /// Build at rest at wide count `count`. The gains come from the Riccati equation;
    /// a configuration for which it does not converge to a stable filter (e.g. noise
    /// levels that are zero or so extreme that `f64` cannot resolve them) is rejected.
    pub fn new(c: &KalmanConfig, t: &EstimatorTiming, count: i64) -> Result<Self, ConfigError> {
        let gains = Self::design(c, t)?;
        let scales = Scales::new(t)?;
        Ok(Self {
            scales,
            k_pos: R::from_f64(gains[0]),
            k_vel: R::from_f64(gains[1]),
            k_acc: R::from_f64(gains[2]),
            last: count,
            rel: R::ZERO,
            vel: R::ZERO,
            bias: R::ZERO,
        })
    }

    /// Steady-state gains `[k_p, k_v, k_d]` per period for a configuration, after
    /// checking that the resulting filter is stable.
    pub fn design(c: &KalmanConfig, t: &EstimatorTiming) -> Result<[f64; 3], ConfigError> {
        let ts = positive(t.period_s, "period_s")? as f64;
        let cs = positive(t.count_size, "count_size")? as f64;
        let sw = positive(c.accel_noise_units_s2, "accel_noise_units_s2")? as f64 * ts * ts / cs;
        let sv = positive(c.meas_noise_counts, "meas_noise_counts")? as f64;
        let k = steady_state_gain(sw * sw, sv * sv).ok_or(ConfigError::Unstable(
            "kalman noise levels (no steady-state gain)",
        ))?;
        let (a2, a1, a0) = closed_loop_poly(k);
        if k.iter().all(|&x| x > 0.0) && cubic_is_stable(a2, a1, a0) {
            Ok(k)
        } else {
            Err(ConfigError::Unstable("kalman gains"))
        }
    }

    /// `accel_cmd`: acceleration commanded over the period that just ended (units/s²).
    pub fn update(&mut self, count: i64, accel_cmd: R) -> Estimate<R> {
        let limit = R::from_f32(MAX_STEP_COUNTS as f32);
        let half = R::from_f32(0.5);
        let acc = accel_cmd.finite_or_zero() * self.scales.accel_in + self.bias;
        let pred = self.rel + self.vel + acc * half - step_counts::<R>(count, self.last);
        let vel_pred = self.vel + acc;
        let innov = -pred;
        self.rel = settle(pred + self.k_pos * innov, limit);
        self.vel = settle(vel_pred + self.k_vel * innov, limit);
        self.bias = settle(self.bias + self.k_acc * innov, limit);
        self.last = count;
        self.estimate()
    }

    pub fn estimate(&self) -> Estimate<R> {
        estimate_of(self.last, self.rel, self.vel, &self.scales)
    }

    /// The unexplained acceleration currently estimated (units/s²).
    pub fn accel_bias(&self) -> R {
        self.bias * self.scales.accel_out
    }

    pub fn reset(&mut self, count: i64) {
        self.last = count;
        self.rel = R::ZERO;
        self.vel = R::ZERO;
        self.bias = R::ZERO;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::PAPER_SIM_TIMING;

    #[test]
    fn gain_is_stable_and_matches_alpha_beta_gamma_relations() {
        let k = Kalman::<f64>::design(&PAPER_SIM_KALMAN, &PAPER_SIM_TIMING).unwrap();
        // Kalata's steady-state relations for this model: k_v² = 2 k_p k_d (to rounding)
        assert!(k[0] > 0.0 && k[0] < 1.0, "{k:?}");
        let rel = (k[1] * k[1] - 2.0 * k[0] * k[2]).abs() / (k[1] * k[1]);
        assert!(rel < 1e-6, "{k:?} {rel}");
    }

    #[test]
    fn rejects_zero_noise() {
        let c = KalmanConfig {
            accel_noise_units_s2: 0.0,
            ..PAPER_SIM_KALMAN
        };
        assert_eq!(
            Kalman::<f32>::new(&c, &PAPER_SIM_TIMING, 0),
            Err(ConfigError::NotPositive("accel_noise_units_s2"))
        );
    }
}
