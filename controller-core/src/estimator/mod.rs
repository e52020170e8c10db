//! Axis velocity (and sub-count position) from quantised encoder counts (spec 6).
//!
//! The board measures only whole encoder counts once per control period; every law needs
//! the axis velocity. The naive backward difference `(n[k] - n[k-1]) / Ts` resolves one
//! count per period (1 unit/s for the paper simulation's 1e-4 units at 10 kHz; 6.25 mm/s
//! for the 0.625 µm axis), which turns the sliding variables into quantisation noise. This
//! module offers, selectable per axis by [`EstimatorConfig`]:
//!
//! - [`BackwardDifference`]: the naive baseline, kept for comparison;
//! - [`Pll`]: the ODrive-style tracking loop (an alpha-beta observer) with gains from one
//!   bandwidth parameter and a discrete stability check;
//! - [`Kalman`]: a steady-state Kalman filter on position, velocity and an unknown
//!   acceleration bias, driven by the *commanded* acceleration, so that known motion
//!   causes no lag and the bandwidth can be set low, for noise only.
//!
//! All estimators take wide counts (`i64`, see [`WideCounter`] for undoing the hardware
//! counter wrap) and keep their state *relative to the last measured count*, in counts and
//! counts per period. The numbers the filters work with are therefore a few counts at most,
//! whatever the absolute position: no precision is lost in `f32` or fixed point after long
//! travel, and no count is ever lost. Conversion to plant units happens only at the
//! output, through the [`EstimatorTiming`] scales.

mod bank;
mod kalman;
mod pll;
mod wide;

pub use bank::{AccelInput, AccelModel, EstimatorBank, EstimatorBankConfig};
pub use kalman::{Kalman, KalmanConfig, PAPER_SIM_KALMAN};
pub use pll::{Pll, PllConfig, PAPER_SIM_PLL};
pub use wide::{CounterWidth, WideCounter};

use crate::config::{positive, ConfigError};
use crate::Real;

/// Sample period and encoder resolution, shared by all estimators of a machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorTiming {
    /// Control period (s).
    pub period_s: f32,
    /// Length of one encoder count in plant units (1e-4 for the paper simulation,
    /// 0.625e-3 mm for the physical axis).
    pub count_size: f32,
}

/// The reference paper simulation: 10 kHz control, position quantised to 1e-4 units.
pub const PAPER_SIM_TIMING: EstimatorTiming = EstimatorTiming {
    period_s: 1e-4,
    count_size: 1e-4,
};

/// Which estimator an axis uses.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum EstimatorConfig {
    /// The plant's true velocity. Only a simulated machine can provide it (the reference
    /// case of the estimator studies); a servo on hardware rejects it.
    Exact,
    BackwardDifference,
    Pll(PllConfig),
    Kalman(KalmanConfig),
}

impl EstimatorConfig {
    /// Short snake_case name used in reports (`exact`, `backward_difference`, `pll`,
    /// `kalman`).
    pub const fn name(&self) -> &'static str {
        match self {
            Self::Exact => "exact",
            Self::BackwardDifference => "backward_difference",
            Self::Pll(_) => "pll",
            Self::Kalman(_) => "kalman",
        }
    }
}

/// One estimate, in plant units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate<R> {
    /// Position (units), sub-count resolution for the observers.
    pub pos: R,
    /// Velocity (units/s).
    pub vel: R,
}

/// Unit conversions, precomputed once from [`EstimatorTiming`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Scales<R> {
    /// units per count
    pub(crate) pos: R,
    /// (units/s) per (count/period)
    pub(crate) vel: R,
    /// (counts/period²) per (units/s²)
    pub(crate) accel_in: R,
    /// (units/s²) per (counts/period²)
    pub(crate) accel_out: R,
}

impl<R: Real> Scales<R> {
    pub(crate) fn new(t: &EstimatorTiming) -> Result<Self, ConfigError> {
        let ts = positive(t.period_s, "period_s")? as f64;
        let c = positive(t.count_size, "count_size")? as f64;
        Ok(Self {
            pos: R::from_f64(c),
            vel: R::from_f64(c / ts),
            accel_in: R::from_f64(ts * ts / c),
            accel_out: R::from_f64(c / (ts * ts)),
        })
    }
}

/// Count increments beyond this per period are physically impossible (2^20 counts of
/// 0.625 µm per 100 µs is 6.5 km/s); clamping keeps a corrupted reading from producing a
/// value the number type cannot hold.
const MAX_STEP_COUNTS: i64 = 1 << 20;

/// `n - last` as a Real, clamped to [`MAX_STEP_COUNTS`]. Converted through `i32`/`f32`
/// (exact below 2^24): the Cortex-M4 does that in hardware, while `i64`/`f64`
/// conversions are software routines costing hundreds of cycles.
#[inline(always)]
pub(crate) fn step_counts<R: Real>(n: i64, last: i64) -> R {
    // in range (the common case): one 64-bit subtraction and one unsigned comparison;
    // otherwise the clamp of the exact difference, whose sign is that of `n - last`
    let (d, overflow) = n.overflowing_sub(last);
    let c = if !overflow && (d.wrapping_add(MAX_STEP_COUNTS) as u64) <= (2 * MAX_STEP_COUNTS) as u64
    {
        d as i32
    } else {
        step_counts_clamped(n, last)
    };
    R::from_f32(c as f32)
}

/// [`step_counts`] beyond ±[`MAX_STEP_COUNTS`] (a corrupted reading).
#[cold]
#[inline(never)]
fn step_counts_clamped(n: i64, last: i64) -> i32 {
    if n > last {
        MAX_STEP_COUNTS as i32
    } else {
        -MAX_STEP_COUNTS as i32
    }
}

/// A wide count as a Real: exact in every `Real` while `|n| <= 2^24` (10 m of 0.625 µm
/// counts), which is one hardware `i32 -> f32` conversion; beyond, two (upper and lower
/// 16 bits, each exact; the sum rounds once, so the result is `n` correctly rounded to
/// `R`, while `|n| < 2^47`).
#[inline(always)]
pub(crate) fn count_to_real<R: Real>(n: i64) -> R {
    const EXACT: i64 = 1 << 24;
    if (n.wrapping_add(EXACT) as u64) <= (2 * EXACT) as u64 {
        return R::from_f32(n as i32 as f32);
    }
    let hi = (n >> 16).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
    let lo = (n & 0xFFFF) as i32;
    R::from_f32(hi as f32) * R::from_f32(65_536.0) + R::from_f32(lo as f32)
}

/// The position of wide count `n` with counts of length `len`: the servo step's (and the
/// estimator bank's) one formula, in `R` without `f64`.
pub fn counts_to_position<R: Real>(n: i64, len: R) -> R {
    count_to_real::<R>(n) * len
}

/// `(count + frac) * units_per_count`.
pub(crate) fn to_units<R: Real>(count: i64, frac: R, s: &Scales<R>) -> R {
    (count_to_real::<R>(count) + frac) * s.pos
}

/// An observer state after its correction: NaN never survives a period, and the state
/// stays within `±limit` counts (per period) of the last count.
#[inline(always)]
pub(crate) fn settle<R: Real>(x: R, limit: R) -> R {
    x.clamp_finite(limit)
}

/// Position and velocity in units from an observer's state relative to the last count.
pub(crate) fn estimate_of<R: Real>(last: i64, rel: R, vel_counts: R, s: &Scales<R>) -> Estimate<R> {
    Estimate {
        pos: to_units(last, rel, s),
        vel: vel_counts * s.vel,
    }
}

/// Naive backward difference: one count per period of velocity resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BackwardDifference<R> {
    scales: Scales<R>,
    last: i64,
    vel_cpp: R,
}

impl<R: Real> BackwardDifference<R> {
    pub fn new(t: &EstimatorTiming, count: i64) -> Result<Self, ConfigError> {
        Ok(Self {
            scales: Scales::new(t)?,
            last: count,
            vel_cpp: R::ZERO,
        })
    }

    pub fn update(&mut self, count: i64) -> Estimate<R> {
        self.vel_cpp = step_counts(count, self.last);
        self.last = count;
        self.estimate()
    }

    pub fn estimate(&self) -> Estimate<R> {
        Estimate {
            pos: to_units(self.last, R::ZERO, &self.scales),
            vel: self.vel_cpp * self.scales.vel,
        }
    }

    pub fn reset(&mut self, count: i64) {
        self.last = count;
        self.vel_cpp = R::ZERO;
    }
}

/// One axis's estimator, selected by configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VelocityEstimator<R> {
    BackwardDifference(BackwardDifference<R>),
    Pll(Pll<R>),
    Kalman(Kalman<R>),
}

impl<R: Real> VelocityEstimator<R> {
    /// Build the configured estimator, at rest at wide count `count`. A rejected
    /// configuration returns the reason and builds nothing.
    pub fn new(
        cfg: &EstimatorConfig,
        t: &EstimatorTiming,
        count: i64,
    ) -> Result<Self, ConfigError> {
        Ok(match cfg {
            // the true velocity is supplied by the bank; the difference keeps the counts
            EstimatorConfig::Exact | EstimatorConfig::BackwardDifference => {
                Self::BackwardDifference(BackwardDifference::new(t, count)?)
            }
            EstimatorConfig::Pll(c) => Self::Pll(Pll::new(c, t, count)?),
            EstimatorConfig::Kalman(c) => Self::Kalman(Kalman::new(c, t, count)?),
        })
    }

    /// Feed the wide count measured this period and the acceleration commanded over the
    /// period that just ended (units/s²; only the Kalman filter uses it, pass zero when it
    /// is unknown). Returns the estimate at the sample instant.
    #[inline(always)]
    pub fn update(&mut self, count: i64, accel_cmd: R) -> Estimate<R> {
        match self {
            Self::BackwardDifference(e) => e.update(count),
            Self::Pll(e) => e.update(count),
            Self::Kalman(e) => e.update(count, accel_cmd),
        }
    }

    /// The latest estimate.
    pub fn estimate(&self) -> Estimate<R> {
        match self {
            Self::BackwardDifference(e) => e.estimate(),
            Self::Pll(e) => e.estimate(),
            Self::Kalman(e) => e.estimate(),
        }
    }

    /// Restart at rest at `count` (e.g. after homing or a fault).
    pub fn reset(&mut self, count: i64) {
        match self {
            Self::BackwardDifference(e) => e.reset(count),
            Self::Pll(e) => e.reset(count),
            Self::Kalman(e) => e.reset(count),
        }
    }
}

/// Schur stability of `z² + a1 z + a0` (Jury): both roots strictly inside the unit circle.
pub(crate) fn quadratic_is_stable(a1: f64, a0: f64) -> bool {
    a0.abs() < 1.0 && 1.0 + a1 + a0 > 0.0 && 1.0 - a1 + a0 > 0.0
}

/// Schur stability of `z³ + a2 z² + a1 z + a0` (Jury).
pub(crate) fn cubic_is_stable(a2: f64, a1: f64, a0: f64) -> bool {
    let p1 = 1.0 + a2 + a1 + a0;
    let pm1 = -1.0 + a2 - a1 + a0;
    p1 > 0.0 && pm1 < 0.0 && a0.abs() < 1.0 && (a0 * a0 - 1.0).abs() > (a0 * a2 - a1).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jury_tests_match_known_polynomials() {
        // (z - 0.5)²
        assert!(quadratic_is_stable(-1.0, 0.25));
        // (z - 1.1)(z - 0.5)
        assert!(!quadratic_is_stable(-1.6, 0.55));
        // (z + 0.9)(z - 0.9): stable; (z + 1.0)(z - 0.5): marginal, rejected
        assert!(quadratic_is_stable(0.0, -0.81));
        assert!(!quadratic_is_stable(0.5, -0.5));
        // (z - 0.5)³ = z³ - 1.5 z² + 0.75 z - 0.125
        assert!(cubic_is_stable(-1.5, 0.75, -0.125));
        // (z - 0.5)²(z + 1.2)
        assert!(!cubic_is_stable(0.2, -0.95, 0.3));
    }

    #[test]
    fn backward_difference_resolution_is_one_count_per_period() {
        let mut b = BackwardDifference::<f64>::new(&PAPER_SIM_TIMING, 0).unwrap();
        let e = b.update(1);
        assert!((e.vel - 1.0).abs() < 1e-12, "{}", e.vel); // 1e-4 units / 1e-4 s
        assert!((e.pos - 1e-4).abs() < 1e-11); // f32 config: 1e-4 is not exact
    }

    #[test]
    fn rejects_bad_timing() {
        let t = EstimatorTiming {
            period_s: 0.0,
            count_size: 1e-4,
        };
        assert_eq!(
            VelocityEstimator::<f32>::new(&EstimatorConfig::BackwardDifference, &t, 0),
            Err(ConfigError::NotPositive("period_s"))
        );
    }

    /// The count conversions as they were written before their fast paths.
    fn step_counts_general(n: i64, last: i64) -> f32 {
        let d = n
            .saturating_sub(last)
            .clamp(-MAX_STEP_COUNTS, MAX_STEP_COUNTS);
        d as i32 as f32
    }

    fn count_to_real_general<R: Real>(n: i64) -> R {
        let hi = (n >> 16).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        let lo = (n & 0xFFFF) as i32;
        R::from_f32(hi as f32) * R::from_f32(65_536.0) + R::from_f32(lo as f32)
    }

    proptest::proptest! {
        #[test]
        fn count_fast_paths_equal_the_general_formulas(
            n in proptest::num::i64::ANY, d in -(1i64 << 21)..(1i64 << 21), small in -(1i64 << 25)..(1i64 << 25),
        ) {
            // every kind of pair: extremes (overflowing differences), near and far
            for (a, b) in [(n, n.wrapping_sub(d)), (n, 0), (n, -n), (n, i64::MAX), (small, d)] {
                proptest::prop_assert_eq!(step_counts::<f32>(a, b), step_counts_general(a, b));
            }
            for x in [n, small, d, n >> 20] {
                proptest::prop_assert_eq!(count_to_real::<f32>(x), count_to_real_general::<f32>(x));
                proptest::prop_assert_eq!(count_to_real::<f64>(x), count_to_real_general::<f64>(x));
            }
        }
    }

    #[test]
    fn count_conversions_at_their_edges() {
        for n in [
            0,
            1,
            -1,
            (1 << 24) - 1,
            1 << 24,
            (1 << 24) + 1,
            -(1 << 24),
            -(1 << 24) - 1,
        ] {
            assert_eq!(
                count_to_real::<f32>(n),
                count_to_real_general::<f32>(n),
                "{n}"
            );
            assert_eq!(count_to_real::<f64>(n), n as f64, "{n}");
        }
        let max = MAX_STEP_COUNTS;
        for (a, b) in [
            (max, 0),
            (max + 1, 0),
            (-max, 0),
            (-max - 1, 0),
            (i64::MIN, i64::MAX),
        ] {
            assert_eq!(
                step_counts::<f32>(a, b),
                step_counts_general(a, b),
                "{a} {b}"
            );
        }
        assert_eq!(step_counts::<f32>(i64::MIN, i64::MAX), -(max as f32));
    }
}
