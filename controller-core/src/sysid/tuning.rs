//! From an axis model to the gains of every law: the tuning rules of the seed methods,
//! written once over an [`AxisModel`] (identified, entered by the user, or the preset of
//! a simulated axis) and a [`TuningConfig`] (target bandwidth, torque limit, encoder
//! resolution). The gantry presets ([`crate::presets::gantry`]'s `pid_for`, `dsmc_for`,
//! `dob_smc_for`, `adaptive_for`) take their gains from here. Why each value is what it
//! is (what was tried and measured): docs/identification.md, section 8.
//!
//! All functions are `const` so presets can stay compile-time constants. They do not
//! validate: build laws from a model that passed [`AxisModel::validate`] and a tuning
//! that passed [`TuningConfig::validate`] (the laws' own `new` then checks the gains).

use crate::config::{positive, ConfigError};
use crate::law::adaptive_smc::{AdaptiveSmcConfig, EstimateConfig};
use crate::law::dob_smc::DobSmcConfig;
use crate::law::pid::PidConfig;
use crate::law::smc::{ReachingConfig, SmcConfig, SurfaceConfig};
use crate::plant::AxisModel;
use crate::plant::PlantParams;
use crate::Exponent;

/// What the rules need besides the model.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct TuningConfig {
    /// Closed-loop bandwidth ω of the position loops, rad/s (the gantry: 157, see
    /// [`crate::presets::gantry::LOOP_OMEGA`]).
    pub bandwidth_rad_s: f32,
    /// Peak effort of the axis, mN·m: output limits and integral limits.
    pub torque_max_mnm: f32,
    /// One encoder count, mm: DSMC's singular floor (errors below one count are not
    /// measurable).
    pub count_mm: f32,
}

impl TuningConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        positive(self.bandwidth_rad_s, "bandwidth_rad_s")?;
        positive(self.torque_max_mnm, "torque_max_mnm")?;
        positive(self.count_mm, "count_mm")?;
        Ok(())
    }
}

/// PID from the pole placement `(s + ω)³` on `J s²`: `kp = 3Jω²`, `kd = 3Jω`,
/// `ki = Jω³`; output limited to the peak torque and the integral to what the integral
/// term can use.
pub const fn pid(m: &AxisModel, t: &TuningConfig) -> PidConfig {
    let j = m.inertia;
    let w = t.bandwidth_rad_s;
    let ki = j * w * w * w;
    PidConfig {
        kp: 3.0 * j * w * w,
        ki,
        kd: 3.0 * j * w,
        kv_ff: 0.0,
        ka_ff: 0.0,
        integral_limit: t.torque_max_mnm / ki,
        u_max: t.torque_max_mnm,
    }
}

/// DSMC surface β, mm^(4/9)/s: the terminal term matters below ~0.1 mm.
pub const DSMC_BETA: f32 = 10.0;

/// The paper's DSMC (spec 2.3) rescaled for a physical axis in mm: the equivalent control
/// cancels the known `B/J` (plant a = B/J, b = 0, k = 1/J); friction and load are left to
/// the reaching law and the integral. Surface α = ω (same bandwidth as the PID),
/// β = [`DSMC_BETA`], singular floor one encoder count. Reaching: the paper's
/// k1 = k2 = 20, k3 = 200 (Table 2); larger gains chatter with the velocity observer, so
/// friction and load are rejected by the integral, k4 = ω³ (the PID's `ki/J`).
pub const fn dsmc(m: &AxisModel, t: &TuningConfig) -> SmcConfig {
    let j = m.inertia;
    let w = t.bandwidth_rad_s;
    SmcConfig {
        plant: PlantParams {
            a: m.viscous / j,
            b: 0.0,
            k: 1.0 / j,
        },
        surface: SurfaceConfig::Terminal {
            alpha: w,
            beta: DSMC_BETA,
            p: 9,
            q: 5,
            singular_floor: t.count_mm,
        },
        reaching: ReachingConfig::DoublePower {
            k1: 20.0,
            k2: 20.0,
            k3: 200.0,
            beta2: Exponent { num: 1, den: 3 },
            beta3: Exponent { num: 1, den: 3 },
        },
        k4: w * w * w,
        integral_limit: t.torque_max_mnm / j / (w * w * w),
        u_max: t.torque_max_mnm,
    }
}

/// DOB observer bandwidth ω_o = 2π·40 Hz ≈ 250 rad/s (see [`dob_smc`]).
pub const DOB_OBSERVER_RAD_S: f32 = 250.0;

/// DOB-SMC (spec 2.4): model a = B/J, b = 1/J (nominal = identified values). Surface
/// c = ω. Reaching k = 100 1/s, η = 200 mm/s² with boundary layer φ = 5 mm/s (η/φ = 40
/// 1/s more inside the layer); η covers the observer's residual on a friction reversal.
/// Observer ω_o = [`DOB_OBSERVER_RAD_S`], critically damped (k1 = 2ω_o, k2 = ω_o²),
/// between the loop's 25 Hz and the velocity observer's 100 Hz. `|d̂|` limited to the
/// peak acceleration.
pub const fn dob_smc(m: &AxisModel, t: &TuningConfig) -> DobSmcConfig {
    let j = m.inertia;
    let wo = DOB_OBSERVER_RAD_S;
    DobSmcConfig {
        a: m.viscous / j,
        b: 1.0 / j,
        c: t.bandwidth_rad_s,
        k: 100.0,
        eta: 200.0,
        boundary_layer: 5.0,
        k1: 2.0 * wo,
        k2: wo * wo,
        d_hat_limit: t.torque_max_mnm / j,
        u_max: t.torque_max_mnm,
    }
}

/// Adaptation dead zone δ = 0.05 mm/s: the estimates stop once the remaining torque
/// error is about `δ (k_d + k/Φ)` ≈ 2.7 mN·m on X, below 10 % of each term on the
/// friction scenario; it keeps biased unmodelled torques below that from drifting the
/// estimates (zero-mean velocity noise is averaged by the adaptation integrators).
pub const ADAPTIVE_DEAD_ZONE_MM_S: f32 = 0.05;

/// Per-unit adaptation gain of Ĵ (γ_J = J · g): 6e-4 on the X axis (J = 0.064).
pub const ADAPT_GAIN_J: f32 = 6e-4 / 0.064;
/// Per-unit adaptation gain of B̂: 0.06 on the X axis.
pub const ADAPT_GAIN_B: f32 = 0.06 / 0.064;
/// Per-unit adaptation gain of f̂±: 600 on the X axis.
pub const ADAPT_GAIN_F: f32 = 600.0 / 0.064;

/// Bounds of an adaptive estimate around a known value: `[0.5x, 2x]` (ordered for a
/// negative `x`). The identification's accuracy (inertia 5 %, Coulomb 10 %, viscous 25 %)
/// is well inside, and the projection still stops a drifting estimate at a factor 2.
pub const fn around(x: f32, gamma: f32) -> EstimateConfig {
    let (a, b) = (0.5 * x, 2.0 * x);
    EstimateConfig {
        initial: x,
        min: a.min(b),
        max: a.max(b),
        gamma,
    }
}

/// Adaptive SMC (spec 2.5) whose estimates start at the model's values, bounded by
/// [`around`]. λ = ω; k_d = 2Jω so the s-loop is twice as fast as the surface; k = 10 mN·m
/// covers the unmodelled Stribeck excess (0.3 · 40 mN·m at the lowest speeds on the
/// gantry's X). Switching boundary layer Φ = 0.3 mm/s, adaptation dead zone δ =
/// [`ADAPTIVE_DEAD_ZONE_MM_S`]. Adaptation gains are per unit of the axis' inertia,
/// `γ = J g`, so that every axis converges in the same time on the same motion (the
/// parameter errors decay at a rate ∝ γ φ²/J); each estimate settles within ~2 s on the
/// friction scenario.
///
/// The law's reverse Coulomb estimate must stay `<= 0`: a model whose `f-` came out
/// positive (a constant load larger than the reverse friction, see [`AxisModel`]) starts
/// that estimate at 0; such an axis needs its load compensated outside the law.
pub const fn adaptive_smc(m: &AxisModel, t: &TuningConfig) -> AdaptiveSmcConfig {
    let j = m.inertia;
    let w = t.bandwidth_rad_s;
    let mut neg = around(m.coulomb_neg_mnm, j * ADAPT_GAIN_F);
    neg.max = neg.max.min(0.0);
    neg.min = neg.min.min(0.0);
    neg.initial = neg.initial.min(0.0);
    AdaptiveSmcConfig {
        lambda: w,
        boundary_layer: 0.3,
        dead_zone: ADAPTIVE_DEAD_ZONE_MM_S,
        kd: 2.0 * j * w,
        k: 10.0,
        inertia: around(j, j * ADAPT_GAIN_J),
        viscous: around(m.viscous, j * ADAPT_GAIN_B),
        coulomb_pos: around(m.coulomb_pos_mnm, j * ADAPT_GAIN_F),
        coulomb_neg: neg,
        u_max: t.torque_max_mnm,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::adaptive_smc::AdaptiveSmc;
    use crate::law::dob_smc::DobSmc;
    use crate::law::{Law as AxisLaw, LawConfig};
    use crate::presets::gantry::{COUNT_MM, GANTRY_AXES, GANTRY_Z, LOOP_OMEGA};

    fn tuning(torque_max_mnm: f32) -> TuningConfig {
        TuningConfig {
            bandwidth_rad_s: LOOP_OMEGA,
            torque_max_mnm,
            count_mm: COUNT_MM,
        }
    }

    #[test]
    fn every_law_builds_from_every_preset_model() {
        for axis in &GANTRY_AXES {
            let m = AxisModel::from_physical_with_load(axis);
            let t = tuning(axis.torque_max_mnm);
            assert_eq!(t.validate(), Ok(()));
            assert!(AxisLaw::<f32>::new(&LawConfig::Pid(pid(&m, &t))).is_ok());
            assert!(AxisLaw::<f32>::new(&LawConfig::Smc(dsmc(&m, &t))).is_ok());
            assert!(DobSmc::<f32>::new(&dob_smc(&m, &t)).is_ok());
            let a = AdaptiveSmc::<f32>::new(&adaptive_smc(&m, &t)).unwrap();
            let s = a.initial_state();
            assert_eq!(s.j, m.inertia);
            assert_eq!(s.f_pos, m.coulomb_pos_mnm);
        }
    }

    #[test]
    fn adaptive_bounds_are_half_to_double_and_respect_the_sign_of_f_neg() {
        let m = AxisModel::from_physical(&GANTRY_Z);
        let c = adaptive_smc(&m, &tuning(1000.0));
        assert_eq!((c.inertia.min, c.inertia.max), (0.5 * 0.041, 2.0 * 0.041));
        assert_eq!((c.coulomb_neg.min, c.coulomb_neg.max), (-60.0, -15.0));
        // load 40 > |f-| 30: f- = +10 cannot be represented; starts at 0
        let loaded = AxisModel {
            coulomb_neg_mnm: 10.0,
            ..m
        };
        let c = adaptive_smc(&loaded, &tuning(1000.0));
        assert_eq!(
            (c.coulomb_neg.initial, c.coulomb_neg.min, c.coulomb_neg.max),
            (0.0, 0.0, 0.0)
        );
        assert!(AdaptiveSmc::<f32>::new(&c).is_ok());
    }

    #[test]
    fn tuning_rejects_bad_values() {
        let t = TuningConfig {
            count_mm: 0.0,
            ..tuning(1000.0)
        };
        assert_eq!(t.validate(), Err(ConfigError::NotPositive("count_mm")));
    }
}
