//! Phase-locked-loop (tracking-loop) position/velocity estimator, as in ODrive.
//!
//! Per period, with the state kept relative to the last measured count:
//!
//! ```text
//! predict:  p⁻ = p + v                      (counts; v in counts/period)
//! correct:  ε = n - p⁻,  p = p⁻ + α ε,  v = v + β ε
//! ```
//!
//! This is the discrete form of the continuous loop `p̂' = v̂ + kp ε`, `v̂' = ki ε` with
//! `kp = 2ζω`, `ki = ω²` (ODrive: ζ = 1, `ki = kp²/4`), so `α = kp Ts = 2ζωTs` and
//! `β = ki Ts² = (ωTs)²`. The closed loop has characteristic polynomial
//! `z² - (2 - α - β) z + (1 - α)`; Jury's test gives `0 < α < 2`, `0 < β < 4 - 2α`, which
//! for ζ = 1 means `ωTs < 2√2 - 2 ≈ 0.83`. Configurations outside that are rejected.
//!
//! Trade-off (derived in docs/velocity-estimation.md): two integrators, so a ramp (constant
//! velocity) is tracked with zero steady-state error, but a constant acceleration `A`
//! leaves a velocity lag of about `A·kp/ki = 2ζA/ω`, while white position noise of
//! variance σ² reaches the velocity with variance `σ² 2β²/(α(4 - 2α - β))` per period²
//! (≈ `σ² (ωTs)³/4` for ζ = 1): higher bandwidth, less lag, more noise.

use super::{
    estimate_of, quadratic_is_stable, settle, step_counts, Estimate, EstimatorTiming, Scales,
    MAX_STEP_COUNTS,
};
use crate::config::{positive, ConfigError};
use crate::Real;

/// PLL tuning.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PllConfig {
    /// Loop natural frequency ω (rad/s).
    pub bandwidth_rad_s: f32,
    /// Damping ζ (1 = critically damped, ODrive's choice).
    #[cfg_attr(feature = "serde", serde(default = "one"))]
    pub damping: f32,
}

#[cfg(feature = "serde")]
fn one() -> f32 {
    1.0
}

/// PLL for the paper simulation (10 kHz, 1e-4-unit counts): ω = 500 rad/s, ζ = 1. Chosen
/// from the bandwidth sweep in docs/velocity-estimation.md (100-4000 rad/s): there the lag
/// on the helix's 1 unit/s² (≈ 2/ω = 4e-3 units/s) and the quantisation noise give DSMC
/// its smallest contour error.
pub const PAPER_SIM_PLL: PllConfig = PllConfig {
    bandwidth_rad_s: 500.0,
    damping: 1.0,
};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pll<R> {
    scales: Scales<R>,
    alpha: R,
    beta: R,
    /// Last measured wide count: the origin of `rel`.
    last: i64,
    /// Position estimate minus `last` (counts).
    rel: R,
    /// Velocity estimate (counts/period).
    vel: R,
}

impl<R: Real> Pll<R> {
    /// Build at rest at wide count `count`; unstable gain/period combinations are
    /// rejected with [`ConfigError::Unstable`].
    pub fn new(c: &PllConfig, t: &EstimatorTiming, count: i64) -> Result<Self, ConfigError> {
        let scales = Scales::new(t)?;
        let w = positive(c.bandwidth_rad_s, "bandwidth_rad_s")? as f64;
        let zeta = positive(c.damping, "damping")? as f64;
        let wt = w * positive(t.period_s, "period_s")? as f64;
        let (alpha, beta) = (2.0 * zeta * wt, wt * wt);
        Self::check(alpha, beta)?;
        Ok(Self {
            scales,
            alpha: R::from_f64(alpha),
            beta: R::from_f64(beta),
            last: count,
            rel: R::ZERO,
            vel: R::ZERO,
        })
    }

    /// Jury's test on the closed loop `z² - (2 - α - β) z + (1 - α)`.
    pub fn check(alpha: f64, beta: f64) -> Result<(), ConfigError> {
        if alpha > 0.0 && beta > 0.0 && quadratic_is_stable(-(2.0 - alpha - beta), 1.0 - alpha) {
            Ok(())
        } else {
            Err(ConfigError::Unstable("pll bandwidth_rad_s * period_s"))
        }
    }

    /// The discrete gains (α, β) per period.
    pub fn gains(&self) -> (R, R) {
        (self.alpha, self.beta)
    }

    #[inline(always)]
    pub fn update(&mut self, count: i64) -> Estimate<R> {
        let limit = R::from_f32(MAX_STEP_COUNTS as f32);
        // prediction, re-expressed relative to the new count
        let pred = self.rel + self.vel - step_counts::<R>(count, self.last);
        let innov = -pred;
        self.rel = settle(pred + self.alpha * innov, limit);
        self.vel = settle(self.vel + self.beta * innov, limit);
        self.last = count;
        self.estimate()
    }

    pub fn estimate(&self) -> Estimate<R> {
        estimate_of(self.last, self.rel, self.vel, &self.scales)
    }

    pub fn reset(&mut self, count: i64) {
        self.last = count;
        self.rel = R::ZERO;
        self.vel = R::ZERO;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::PAPER_SIM_TIMING;

    #[test]
    fn gains_follow_bandwidth() {
        let p = Pll::<f64>::new(&PAPER_SIM_PLL, &PAPER_SIM_TIMING, 0).unwrap();
        let (a, b) = p.gains();
        // f32 config: period 1e-4 is stored to ~5e-8 relative
        assert!(
            (a - 0.1).abs() < 1e-8 && (b - 2.5e-3).abs() < 1e-9,
            "{a} {b}"
        );
    }

    #[test]
    fn stability_boundary_for_critical_damping() {
        // ωTs = 0.82 is inside, 0.83 outside (boundary 2√2 - 2 = 0.8284)
        let t = PAPER_SIM_TIMING;
        let ok = PllConfig {
            bandwidth_rad_s: 8200.0,
            damping: 1.0,
        };
        let bad = PllConfig {
            bandwidth_rad_s: 8300.0,
            damping: 1.0,
        };
        assert!(Pll::<f32>::new(&ok, &t, 0).is_ok());
        assert_eq!(
            Pll::<f32>::new(&bad, &t, 0),
            Err(ConfigError::Unstable("pll bandwidth_rad_s * period_s"))
        );
    }
}
