//! The paper reproduction through host-sim: published rows that the equations reproduce,
//! what cross-coupling and the laws buy on the helix, and the JSON interface.

use gantry_tests::run_builtin;
use host_sim::builtin;
use host_sim::studies::paper::run_paper;

fn paper(run: &str) -> host_sim::engine::RunResult {
    run_builtin("paper.toml", run, "")
}

#[test]
fn pid_helix_itse_within_8_percent_of_table3() {
    let r = paper("table3_PID");
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
    let pid = paper("table3_PID");
    let smc = paper("table3_SMC");
    let dsmc = paper("table3_DSMC");
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
    let with = paper("table3_disturbed_DSMC");
    let without = paper("table3_disturbed_DSMC_no_ccc");
    let pid = paper("table3_disturbed_PID");
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

#[test]
fn discrete_dsmc_contours_within_one_count_with_true_velocity() {
    // the firmware's arrangement: 10 kHz, 1e-4 counts, |u| <= 500, law limited to 500 too
    let limit = "controller.laws.all.smc.u_max = 500.0\n";
    let exact = run_builtin("paper.toml", "table3_discrete_f32_DSMC", limit);
    assert!(exact.contour_max < 1e-4, "{}", exact.contour_max);
    assert!(exact.peak_u.iter().all(|u| *u <= 500.0));
    // why the firmware needs a velocity estimator: a difference of counts is ~60x worse
    let diff = run_builtin(
        "paper.toml",
        "table3_discrete_f32_DSMC",
        &format!("{limit}estimator.axes.all = \"backward_difference\"\n"),
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
    // a short horizon keeps the test quick; the keys do not depend on it
    let f = builtin::load_with("paper.toml", "horizon_s = 0.5\n").unwrap();
    let (_, rep) = run_paper(&f).unwrap();
    let v = serde_json::to_value(&rep).unwrap();
    for t in ["table1_step", "table1_sine"] {
        for law in ["PID", "SMC", "DSMC"] {
            for k in ["itse", "robustness", "tv_u_per_s"] {
                assert!(v[t][law][k].as_f64().unwrap().is_finite(), "{t}.{law}.{k}");
            }
        }
    }
    for law in ["PID", "SMC", "DSMC", "DSMC_no_ccc"] {
        for k in ["x", "y", "z", "contour_max", "contour_rms"] {
            for t in ["table3", "table3_disturbed"] {
                assert!(v[t][law][k].as_f64().unwrap().is_finite(), "{t}.{law}.{k}");
            }
            for numeric in ["f32", "fixed"] {
                let x = v["table3_discrete"][numeric][law][k].as_f64().unwrap();
                assert!(x.is_finite(), "table3_discrete.{numeric}.{law}.{k}");
            }
        }
    }
}

#[test]
fn malformed_scenarios_are_rejected_with_a_clear_error() {
    let (_, good) = builtin::FILES
        .iter()
        .find(|(n, _)| *n == "paper.toml")
        .unwrap();
    let includes = gantry_scenario::file::EmbeddedIncludes(builtin::FILES);
    let typo = good.replacen("kp = 600.0", "kpp = 600.0", 1);
    let err = gantry_scenario::load_str("paper.toml", &typo, &includes)
        .unwrap_err()
        .to_string();
    assert!(err.contains("kpp") && err.contains("paper.toml"), "{err}");
    let negative = good.replace("kd = 10.0", "kd = -10.0");
    let f = gantry_scenario::load_str("paper.toml", &negative, &includes).unwrap();
    let err = run_paper(&f).unwrap_err();
    assert!(format!("{err:#}").contains("kd"), "{err:#}");
}
