//! The QEMU scenario: the paper's helix on the simulated gantry, and its pass bounds.
//!
//! The same scenario is `firmware/qemu/helix-scenario.toml` for host-sim. Paper (seed 000)
//! section 4.2 as host-sim's `paper.toml` states it: three identical
//! axes `θ'' = -10θ' - θ + u` from rest at the origin, reference helix
//! `x = sin t, y = cos t, z = 5t`, DSMC (Table 2 gains) on every axis with cross-coupling
//! λ = 0.01 and |u| <= 500, +10 added to θ'' of X from 10 s. Discretised the way the machine runs it
//! (controller-core's `PAPER_SIM_TIMING`): 10 kHz control with zero-order hold, positions
//! quantised to whole counts of 1e-4 units, velocities from controller-core's PLL
//! estimator (`PAPER_SIM_PLL`). Figures are taken on the true plant state with host-sim's
//! definitions: ITSE and max |error| per axis over the whole run, contour error as the true
//! distance to the helix sampled every 1 ms from 1 s on.

use controller_core::estimator::{EstimatorConfig, PAPER_SIM_PLL, PAPER_SIM_TIMING};
use controller_core::gantry::GantryConfig;
use controller_core::params::{LawConfig, SmcConfig, PAPER_DSMC, PAPER_LAMBDA};
use controller_core::plant::{AxisState, DisturbedPaperAxis, PaperAxis};
use controller_core::trajectory::Trajectory;

use crate::control::{LoopConfig, PathPlan};
use crate::sim::{SimConfig, TruthSpec};
use crate::telemetry::Figures;
use crate::AXES;

/// Simulated duration, seconds.
pub const HORIZON_S: f32 = 15.0;
/// Control periods in the run.
pub const PERIODS: u32 = 150_000;
/// Step load disturbance on X (added to θ''), and when it starts.
pub const DISTURBANCE_X: f64 = 10.0;
pub const DISTURBANCE_T_S: f64 = 10.0;
/// Actuator saturation |u| <= 500 (the DSMC laws' `u_max`).
pub const EFFORT_LIMIT: f32 = 500.0;
/// Contour error statistics exclude the start-up transient (y starts 1 unit off).
pub const CONTOUR_FROM_S: f64 = 1.0;
/// Following-error trip level: the helix starts at y = 1 with the plant at rest at the
/// origin, so the initial tracking error is 1 unit.
pub const FOLLOWING_ERROR_LIMIT: [f32; AXES] = [2.0; AXES];

/// The control-loop side of the scenario.
pub fn loop_config() -> LoopConfig {
    LoopConfig {
        gantry: GantryConfig::uniform(
            LawConfig::Smc(SmcConfig {
                u_max: EFFORT_LIMIT,
                ..PAPER_DSMC
            }),
            PAPER_LAMBDA,
        ),
        estimator: [EstimatorConfig::Pll(PAPER_SIM_PLL); AXES],
        accel_model: [None; AXES],
        timing: PAPER_SIM_TIMING,
        path: PathPlan::Absolute(Trajectory::paper_helix()),
        following_error_limit: FOLLOWING_ERROR_LIMIT,
        horizon_s: Some(HORIZON_S),
        path_duration_s: HORIZON_S,
    }
}

/// The plant side of the scenario.
pub fn sim_config() -> SimConfig {
    let axis = |d_step: f64| DisturbedPaperAxis {
        axis: PaperAxis::paper(),
        d_step,
        t_dist: DISTURBANCE_T_S,
    };
    SimConfig {
        axes: [axis(DISTURBANCE_X), axis(0.0), axis(0.0)],
        initial: [AxisState::default(); AXES],
        length_per_count: PAPER_SIM_TIMING.count_size as f64,
        period_s: PAPER_SIM_TIMING.period_s as f64,
        plant_substeps: 1,
        truth: TruthSpec {
            reference: Trajectory::paper_helix(),
            contour_from_s: CONTOUR_FROM_S,
            contour_every_periods: 10,
            contour_window_s: 0.5,
        },
        record_periods: PERIODS,
    }
}

/// Upper bounds the QEMU run must meet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub itse: [f32; AXES],
    pub tracking_max: [f32; AXES],
    pub contour_max: f32,
    pub contour_rms: f32,
    /// The run must have accumulated exactly this many periods.
    pub samples: u32,
}

/// Pass bounds. See [`BOUNDS_SOURCE`].
pub const BOUNDS: Bounds = Bounds {
    itse: [1.0, 1.0, 1.0],
    tracking_max: [2.0, 2.0, 2.0],
    contour_max: 2.0,
    contour_rms: 1.0,
    samples: PERIODS,
};

/// Where [`BOUNDS`] come from.
pub const BOUNDS_SOURCE: &str = "placeholder";

/// Which figures failed their bound (all false = pass).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Verdict {
    pub itse: [bool; AXES],
    pub tracking_max: [bool; AXES],
    pub contour_max: bool,
    pub contour_rms: bool,
    pub samples: bool,
    pub not_finite: bool,
}

impl Verdict {
    /// Compares the figures with the bounds. NaN figures fail.
    pub fn check(f: &Figures, b: &Bounds) -> Self {
        let over = |v: f32, bound: f32| !(v <= bound);
        let mut v = Self {
            contour_max: over(f.contour_max, b.contour_max),
            contour_rms: over(f.contour_rms, b.contour_rms),
            samples: f.samples != b.samples,
            ..Self::default()
        };
        let mut finite = f.contour_max.is_finite() && f.contour_rms.is_finite();
        for i in 0..AXES {
            v.itse[i] = over(f.itse[i], b.itse[i]);
            v.tracking_max[i] = over(f.tracking_max[i], b.tracking_max[i]);
            finite &= f.itse[i].is_finite() && f.tracking_max[i].is_finite();
        }
        v.not_finite = !finite;
        v
    }

    /// True if every figure is within its bound.
    pub fn passed(&self) -> bool {
        *self == Self::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::ControlLoop;
    use crate::io::{GantryIo, SafetyInputSource};
    use crate::safety::SafetyInputs;
    use crate::sim::SimGantry;

    /// Input pins of a healthy machine (what QEMU's unmodelled GPIO reads as: all low).
    struct Healthy;
    impl SafetyInputSource for Healthy {
        fn read_safety_inputs(&mut self) -> SafetyInputs {
            SafetyInputs::default()
        }
    }

    /// The host-side run of exactly the code the QEMU build runs in its interrupt:
    /// (controller's own figures, true-state figures).
    pub(crate) fn run_scenario() -> (Figures, Figures) {
        let mut sim = SimGantry::new(sim_config(), Healthy);
        let mut lp = ControlLoop::new(loop_config(), [0; AXES]).unwrap();
        loop {
            let snap = *lp.step(&mut sim);
            sim.period_end();
            if snap.finished {
                return (snap.figures, sim.truth_figures());
            }
            assert!(snap.period <= PERIODS + 1, "scenario did not finish");
        }
    }

    #[test]
    fn host_run_of_the_qemu_scenario_is_within_bounds() {
        let (controller, truth) = run_scenario();
        std::println!("controller: {controller:#?}\ntruth: {truth:#?}");
        let v = Verdict::check(&truth, &BOUNDS);
        assert!(v.passed(), "{v:?}");
    }
}
