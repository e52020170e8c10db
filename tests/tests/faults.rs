//! The fault matrix (`host-sim faults`): every fault class injected into the simulated
//! physical gantry through the real servo step is detected as its class within its bound
//! and stops the machine within its overrun bound; a reset is refused while an encoder is
//! still stuck. The JSON keeps the issue's shape.

use host_sim::studies::faults::run_matrix;

#[test]
fn every_fault_class_is_detected_within_its_bounds() {
    let m = run_matrix(None).unwrap();
    for c in &m.cases {
        assert!(c.passed, "{}: {}", c.case, c.why);
    }
    assert!(m.passed);
    let by = |name: &str| m.cases.iter().find(|c| c.case == name).unwrap();
    // the issue's explicit bounds
    let stuck = by("encoder_stuck_moving");
    assert!(stuck.detect_periods.unwrap() <= 20 && stuck.overrun_mm < 2.0);
    let holding = by("encoder_stuck_holding");
    assert!(holding.overrun_mm < 2.0);
    assert_eq!(
        by("encoder_jump").detect_periods,
        Some(0),
        "0.5 mm jump: same period"
    );
    assert_eq!(by("encoder_stuck_reset_refused").reset_refused, Some(true));
    // every class the servo knows is exercised except the ones that cannot be injected
    // into a running simulation (configuration, clock, link)
    for k in [
        "estop",
        "limit_max",
        "amplifier_fault",
        "encoder_stuck",
        "encoder_jump",
        "non_finite",
        "following_error",
        "overspeed",
        "deadline_overrun",
    ] {
        assert!(
            m.cases.iter().any(|c| c.detected.as_deref() == Some(k)),
            "{k}"
        );
    }
}

#[test]
fn matrix_json_has_the_issue_keys() {
    let m = run_matrix(None).unwrap();
    let v = serde_json::to_value(&m).unwrap();
    assert_eq!(v["passed"], true);
    for c in v["cases"].as_array().unwrap() {
        for k in [
            "fault",
            "axis",
            "state",
            "detect_periods",
            "overrun_mm",
            "bound_periods",
            "bound_overrun_mm",
            "passed",
        ] {
            assert!(c.get(k).is_some(), "{k}");
        }
    }
}
