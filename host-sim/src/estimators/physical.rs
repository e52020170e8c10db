//! Issue 6's comparison on the physical 3-axis gantry (`host-sim estimators`, JSON key
//! `"physical"`): the seed methods' helix (`host-sim/scenarios/seeds_helix.toml`: radius
//! 20 mm at 50 mm/s rising 10 mm/s, 150 mN·m load step on X at 1.5 s, 3 s, starting on
//! the moving reference) on [`controller_core::physical_plant`] axes with friction,
//! driven through the seeds' amplifier model (peak torque, 12-bit PWM), 0.625 µm counts,
//! 10 kHz, controller in f32. PID, DSMC and DOB-SMC with the seeds' per-axis presets
//! (`controller_core::seed_params`, no cross-coupling), once per velocity source.
//!
//! The Kalman filter is told each axis' *commanded* acceleration through its physical
//! model `J x'' + B x' = u` (`a = B/J`, `b = 0`, `k = 1/J`, [`axis_model`]) fed with the
//! applied torque; Coulomb friction, gravity and the load step are left to its bias state.

use super::{Comparison, Estimating, Figures};
use crate::engine::{discrete_loop, Mode, RunResult, VelocitySource};
use crate::seeds::{builtin_file, setup};
use anyhow::{anyhow, Result};
use controller_core::estimator::{
    EstimatorConfig, EstimatorTiming, Estimators3, KalmanConfig, PllConfig, PAPER_SIM_KALMAN,
};
use controller_core::params::PlantParams;
use controller_core::physical_plant::PhysicalAxisConfig;
use controller_core::seed_gantry::SeedController;
use controller_core::seed_params::{SeedMethod, GANTRY_AXES};
use controller_core::Vec3;

/// The seeds scenario file whose helix is run.
pub const SCENARIO_FILE: &str = "seeds_helix.toml";
/// The scenario's name in [`SCENARIO_FILE`].
pub const SCENARIO_NAME: &str = "helix";

/// PLL on the physical axis: 1000 rad/s, critically damped. Of the sweep 628 / 1000 /
/// 2000 / 4000 rad/s on this helix (docs/velocity-estimation.md) it gave the lowest DSMC
/// contour max with chattering within 1.5x that with the exact velocity; 2000 rad/s (the
/// seeds scenarios' value) triples the chattering for 12 % less DOB-SMC contour error
/// (without the load step), 628 rad/s (the board's) raises DOB-SMC's by 25 % over 1000.
pub const PHYSICAL_PLL: PllConfig = PllConfig {
    bandwidth_rad_s: 1000.0,
    damping: 1.0,
};

/// Kalman filter on the physical axis (mm): σ of the unexplained acceleration's change per
/// period. The unexplained part here is mostly Coulomb friction (a 1100 mm/s² jump at a
/// reversal on X), yet the contour error hardly depends on σ: of 30 / 100 / 300 / 1000 /
/// 3000 / 10000 mm/s² (docs/velocity-estimation.md) DSMC's contour max stays within
/// 28.1..28.4 µm while the chattering grows ~σ^0.5, so the smallest, 30 mm/s², is taken
/// (DOB-SMC's contour max is 8 % above its exact-velocity value there, 0.5 % at 1000,
/// without the load step; 7 % with it).
/// Measurement noise: uniform quantisation of one count.
pub const PHYSICAL_KALMAN: KalmanConfig = KalmanConfig {
    accel_noise_units_s2: 30.0,
    ..PAPER_SIM_KALMAN
};

/// The laws compared on the physical axes (the seeds' presets, uncoupled).
pub const PHYSICAL_LAWS: [SeedMethod; 3] = [SeedMethod::Pid, SeedMethod::Dsmc, SeedMethod::DobSmc];

/// One velocity source on the physical axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhysicalSource {
    /// The plant's true velocity (the reference case).
    Exact,
    /// `(q[k] - q[k-1]) / Ts` of the counts: 6.25 mm/s per count.
    BackwardDifference,
    Pll(PllConfig),
    /// Driven by each axis' [`axis_model`] and the applied torque.
    Kalman(KalmanConfig),
}

impl PhysicalSource {
    pub fn name(&self) -> &'static str {
        match self {
            Self::Exact => "exact",
            Self::BackwardDifference => "backward_difference",
            Self::Pll(_) => "pll",
            Self::Kalman(_) => "kalman",
        }
    }
}

/// The sources compared by default, with [`PHYSICAL_PLL`] and [`PHYSICAL_KALMAN`].
pub fn default_physical_sources() -> Vec<PhysicalSource> {
    vec![
        PhysicalSource::Exact,
        PhysicalSource::BackwardDifference,
        PhysicalSource::Pll(PHYSICAL_PLL),
        PhysicalSource::Kalman(PHYSICAL_KALMAN),
    ]
}

/// JSON key of a law: `pid`, `dsmc`, `dob_smc`.
pub fn law_key(m: SeedMethod) -> String {
    m.name().to_lowercase().replace('-', "_")
}

/// The commanded-acceleration model of a physical axis, `x'' = u/J - (B/J) x'`.
pub fn axis_model(axis: &PhysicalAxisConfig) -> PlantParams {
    PlantParams {
        a: axis.viscous / axis.inertia,
        b: 0.0,
        k: 1.0 / axis.inertia,
    }
}

/// Run one law with one source; `horizon_s`: `None` = the scenario's 3 s.
pub fn run_physical(
    method: SeedMethod,
    source: &PhysicalSource,
    horizon_s: Option<f64>,
) -> Result<RunResult> {
    let file = builtin_file(SCENARIO_FILE)?;
    let sc = file
        .scenario
        .iter()
        .find(|s| s.name == SCENARIO_NAME)
        .ok_or_else(|| anyhow!("{SCENARIO_FILE} has no scenario {SCENARIO_NAME}"))?;
    let mut s = setup(&file, sc)?;
    if let Some(h) = horizon_s {
        s.spec.horizon_s = h;
    }
    // estimating sources overwrite the velocity in [`Estimating`]
    s.disc.velocity = match source {
        PhysicalSource::BackwardDifference => VelocitySource::BackwardDifference,
        _ => VelocitySource::Exact,
    };
    s.spec.mode = Mode::Discrete(s.disc);
    let mut ctl = SeedController::<f32>::new(&method.controller(false))
        .map_err(|e| anyhow!("invalid {} configuration: {e}", method.name()))?;
    let traj = s.spec.trajectory.cast();
    let (cfg, models) = match *source {
        PhysicalSource::Exact | PhysicalSource::BackwardDifference => {
            return discrete_loop(&s.spec, &s.disc, &s.plants, &traj, &mut ctl);
        }
        PhysicalSource::Pll(c) => (EstimatorConfig::Pll(c), [None; 3]),
        PhysicalSource::Kalman(c) => (
            EstimatorConfig::Kalman(c),
            GANTRY_AXES.map(|a| Some(axis_model(&a))),
        ),
    };
    let quantum = s.disc.position_quantum;
    let timing = EstimatorTiming {
        period_s: (1.0 / s.disc.rate_hz) as f32,
        count_size: quantum as f32,
    };
    let n0 = s.spec.initial.map(|st| (st.pos / quantum).round() as i64);
    let estimators = Estimators3::new(&[cfg; 3], &models, &timing, n0)
        .map_err(|e| anyhow!("invalid estimator configuration: {e}"))?;
    let mut est = Estimating {
        inner: ctl,
        estimators,
        quantum,
        u_limit: Vec3::new(
            GANTRY_AXES[0].torque_max_mnm,
            GANTRY_AXES[1].torque_max_mnm,
            GANTRY_AXES[2].torque_max_mnm,
        ),
    };
    discrete_loop(&s.spec, &s.disc, &s.plants, &traj, &mut est)
}

/// `laws` x `sources` on the physical helix, on two threads.
pub fn compare_physical(
    laws: &[SeedMethod],
    sources: &[PhysicalSource],
    horizon_s: Option<f64>,
) -> Result<Comparison> {
    let jobs: Vec<(SeedMethod, PhysicalSource)> = laws
        .iter()
        .flat_map(|&l| sources.iter().map(move |&s| (l, s)))
        .collect();
    super::compare_parallel(&jobs, |(law, src)| {
        let r = run_physical(*law, src, horizon_s)?;
        Ok((law_key(*law), src.name().to_string(), Figures::from(&r)))
    })
}

/// A terminal table of the physical comparison (lengths mm, torques mN·m).
pub fn physical_table(c: &Comparison, sources: &[PhysicalSource]) -> String {
    let names: Vec<&str> = sources.iter().map(|s| s.name()).collect();
    super::table_named(c, &names)
}
