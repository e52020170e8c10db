//! The paper reproduction through host-sim: published rows that the equations reproduce,
//! what cross-coupling and the laws buy on the helix, and the JSON interface.

use controller_core::gantry::GantryConfig;
use controller_core::params::{LawConfig, PAPER_DSMC, PAPER_LAMBDA, PAPER_PID, PAPER_SMC};
use controller_core::plant::AxisState;
use host_sim::engine::{
    run, DiscreteSpec, MetricSpec, Mode, Numeric, RunResult, RunSpec, VelocitySource,
};
use host_sim::paper::{run_paper, PaperScenario};
use host_sim::scenario::{paper_plants, StepDisturbance, TrajectorySpec};

const HELIX: TrajectorySpec = TrajectorySpec::Helix {
    center: [0.0; 3],
    radius: 1.0,
    omega: 1.0,
    z_rate: 5.0,
};

fn helix(law: LawConfig, lambda: f32, mode: Mode, dist: &[StepDisturbance]) -> RunResult {
    let spec = RunSpec {
        horizon_s: 15.0,
        trajectory: HELIX.build().unwrap(),
        controller: GantryConfig::uniform(law, lambda),
        mode,
        numeric: Numeric::F32,
        metrics: MetricSpec {
            contour_from_s: Some(1.0),
            ..Default::default()
        },
        initial: [AxisState::default(); 3],
    };
    let plants = paper_plants(&controller_core::params::PAPER_PLANT, dist).unwrap();
    run(&spec, &plants).unwrap()
}

const CONTINUOUS: Mode = Mode::Continuous { dt_s: 1e-4 };

#[test]
fn pid_helix_itse_within_8_percent_of_table3() {
    let r = helix(LawConfig::Pid(PAPER_PID), PAPER_LAMBDA, CONTINUOUS, &[]);
    let paper = [0.01551, 0.01749, 3.248];
    for (i, (ours, paper)) in r.itse.iter().zip(paper).enumerate() {
        let rel = (ours - paper).abs() / paper;
        assert!(
            rel < 0.08,
            "axis {i}: ITSE {ours} vs paper {paper} ({:.1} %)",
            rel * 100.0
        );
    }
}

#[test]
fn every_law_tracks_the_helix_and_dsmc_beats_pid() {
    let pid = helix(LawConfig::Pid(PAPER_PID), PAPER_LAMBDA, CONTINUOUS, &[]);
    let smc = helix(LawConfig::Smc(PAPER_SMC), PAPER_LAMBDA, CONTINUOUS, &[]);
    let dsmc = helix(LawConfig::Smc(PAPER_DSMC), PAPER_LAMBDA, CONTINUOUS, &[]);
    // PID's z error grows with the ramp (I = 1 is too slow to catch 5t): bounded, not zero.
    assert!(pid.contour_max < 0.05, "PID contour {}", pid.contour_max);
    // The sliding-mode laws cancel the (exactly known) model: micro-level contouring.
    assert!(smc.contour_max < 1e-5, "SMC contour {}", smc.contour_max);
    assert!(dsmc.contour_max < 1e-5, "DSMC contour {}", dsmc.contour_max);
    for i in 0..3 {
        assert!(
            dsmc.itse[i] < pid.itse[i],
            "axis {i}: DSMC {} vs PID {}",
            dsmc.itse[i],
            pid.itse[i]
        );
    }
    // settled: the whole ITSE is the start-up from rest (y starts 1 away from cos 0)
    assert!(
        dsmc.itse[0] < 1e-6 && dsmc.itse[2] < 1e-5,
        "{:?}",
        dsmc.itse
    );
}

#[test]
fn dsmc_rejects_the_x_load_step_and_cross_coupling_lowers_contour_error() {
    let d = [StepDisturbance {
        axis: 0,
        t_s: 10.0,
        accel: 10.0,
    }];
    let with = helix(LawConfig::Smc(PAPER_DSMC), PAPER_LAMBDA, CONTINUOUS, &d);
    let without = helix(LawConfig::Smc(PAPER_DSMC), 0.0, CONTINUOUS, &d);
    let pid = helix(LawConfig::Pid(PAPER_PID), PAPER_LAMBDA, CONTINUOUS, &d);
    assert!(
        with.contour_max < without.contour_max,
        "{} vs {}",
        with.contour_max,
        without.contour_max
    );
    assert!(with.contour_max < pid.contour_max / 10.0);
    // the integral compensation pulls x back: the x error stays small
    assert!(with.max_abs_error[0] < 0.01, "{}", with.max_abs_error[0]);
}

fn discrete(velocity: VelocitySource) -> Mode {
    Mode::Discrete(DiscreteSpec {
        rate_hz: 10_000.0,
        plant_substeps: 4,
        position_quantum: 1e-4,
        actuator_limit: 500.0,
        velocity,
    })
}

#[test]
fn discrete_dsmc_contours_within_one_count_with_true_velocity() {
    let mut law = PAPER_DSMC;
    law.u_max = 500.0;
    let exact = helix(
        LawConfig::Smc(law),
        PAPER_LAMBDA,
        discrete(VelocitySource::Exact),
        &[],
    );
    assert!(exact.contour_max < 1e-4, "{}", exact.contour_max);
    assert!(exact.peak_u.iter().all(|u| *u <= 500.0));
    // why the firmware needs a velocity estimator: a difference of counts is ~60x worse
    let diff = helix(
        LawConfig::Smc(law),
        PAPER_LAMBDA,
        discrete(VelocitySource::BackwardDifference),
        &[],
    );
    assert!(
        diff.contour_max > 20.0 * exact.contour_max,
        "{} vs {}",
        diff.contour_max,
        exact.contour_max
    );
}

#[test]
fn builtin_scenario_json_has_every_key() {
    let mut sc = PaperScenario::builtin().unwrap();
    // a short horizon keeps the test quick; the keys do not depend on it
    sc.table1.horizon_s = 0.5;
    sc.table1.robustness_window_s = [0.25, 0.5];
    sc.table1.disturbance.t_s = 0.25;
    sc.table3.horizon_s = 0.5;
    sc.table3.contour_from_s = 0.1;
    let rep = run_paper(&sc).unwrap();
    let v = serde_json::to_value(&rep).unwrap();
    for t in ["table1_step", "table1_sine"] {
        for law in ["PID", "SMC", "DSMC"] {
            for k in ["itse", "robustness"] {
                assert!(v[t][law][k].as_f64().unwrap().is_finite(), "{t}.{law}.{k}");
            }
        }
    }
    for law in ["PID", "SMC", "DSMC", "DSMC_no_ccc"] {
        for k in ["x", "y", "z", "contour_max", "contour_rms"] {
            assert!(
                v["table3"][law][k].as_f64().unwrap().is_finite(),
                "table3.{law}.{k}"
            );
            for numeric in ["f32", "fixed"] {
                let x = v["table3_discrete"][numeric][law][k].as_f64().unwrap();
                assert!(x.is_finite(), "table3_discrete.{numeric}.{law}.{k}");
            }
        }
    }
}

#[test]
fn malformed_scenarios_are_rejected_with_a_clear_error() {
    let good = host_sim::paper::DEFAULT_SCENARIO;
    let typo = good.replace("kp = 600.0", "kpp = 600.0");
    let err = toml::from_str::<PaperScenario>(&typo)
        .unwrap_err()
        .to_string();
    assert!(err.contains("kpp"), "{err}");
    let negative = good.replace("kd = 10.0", "kd = -10.0");
    let sc: PaperScenario = toml::from_str(&negative).unwrap();
    let err = run_paper(&sc).unwrap_err();
    assert!(format!("{err:#}").contains("kd"), "{err:#}");
}
