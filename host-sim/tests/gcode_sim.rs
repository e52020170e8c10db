//! `host-sim gcode` end to end on the shipped programs: the planner and the servo step on
//! the simulated gantry, measured against the programmed path.

use host_sim::studies::gcode::{run, GcodeReport};
use std::path::{Path, PathBuf};

fn program(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("programs")
        .join(name)
}

fn within_limits(r: &GcodeReport) {
    for i in 0..3 {
        // the executor's samples may exceed a limit by float rounding only
        assert!(
            r.max_vel_mm_s[i] <= r.limits.vel[i] * 1.001,
            "{}: v{i}",
            r.program
        );
        assert!(
            r.max_acc_mm_s2[i] <= r.limits.acc[i] * 1.001,
            "{}: a{i}",
            r.program
        );
        assert!(
            r.max_jerk_mm_s3[i] <= r.limits.jerk[i] * 1.001,
            "{}: j{i}",
            r.program
        );
    }
}

#[test]
fn square_stops_exactly_at_its_corners_and_the_tool_stays_on_the_path() {
    let r = run(&program("square.nc"), None, false).unwrap();
    assert_eq!(r.status, "completed");
    assert_eq!(r.segments, 9);
    // G61: the planned path passes through every corner
    assert!(
        r.corner_deviation_max_mm < 1e-4,
        "{}",
        r.corner_deviation_max_mm
    );
    // DSMC with contour coupling on the gantry: within 20 µm everywhere, 3 µm RMS
    assert!(r.contour_max_mm < 0.02, "{}", r.contour_max_mm);
    assert!(r.contour_rms_mm < 0.003, "{}", r.contour_rms_mm);
    assert!(r.feed_ratio_mean > 0.9, "{}", r.feed_ratio_mean);
    within_limits(&r);
}

#[test]
fn arcs_stay_within_the_path_tolerance() {
    let r = run(&program("arcs.nc"), None, false).unwrap();
    assert_eq!(r.status, "completed");
    assert!(
        r.corner_deviation_max_mm <= r.tolerance_mm + 1e-4,
        "{} > {}",
        r.corner_deviation_max_mm,
        r.tolerance_mm
    );
    assert!(r.contour_max_mm < 0.03, "{}", r.contour_max_mm);
    within_limits(&r);
}

#[test]
fn rejected_programs_run_nothing_and_name_the_line() {
    let dir = std::env::temp_dir().join(format!("gcode_sim_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("cycle.nc");
    std::fs::write(&bad, "G21 G90\nG1 X10 F600\nG81 X1 Y1 Z-1 R1\n").unwrap();
    let r = run(&bad, None, false).unwrap();
    assert_eq!(r.status, "rejected");
    let e = r.error.unwrap();
    assert_eq!(e.line, Some(3));
    assert!(e.message.ends_with("is not supported"), "{}", e.message);
    assert_eq!(r.duration_s, 0.0);

    let far = dir.join("far.nc");
    std::fs::write(&far, "G21 G90\nG1 X10 F600\nG1 Z-60\n").unwrap();
    let r = run(&far, None, false).unwrap();
    assert_eq!(r.status, "rejected");
    let e = r.error.unwrap();
    assert_eq!(e.line, Some(3));
    assert!(
        e.message.contains("Z would leave the travel"),
        "{}",
        e.message
    );
    std::fs::remove_dir_all(&dir).ok();
}
