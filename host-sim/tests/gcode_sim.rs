//! `host-sim gcode` end to end on the shipped programs: the planner and the servo step on
//! the simulated gantry, measured against the programmed path.

use controller_core::motion::planner::Blend;
use host_sim::gcode::parse_str;
use host_sim::studies::gcode::{run, segments, GcodeReport};
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

#[test]
fn path_control_reaches_the_planner_as_linuxcnc_defines_it() {
    let p = parse_str(
        "p.nc",
        "G61\nG1 X10 F600\nG61.1\nX20\nG64 P0.05 Q0.1\nX30\nG64\nX40\n",
    )
    .unwrap();
    let blends: Vec<Blend> = segments(&p).iter().map(|s| s.blend).collect();
    // G61: tolerance 0 (corners stop, smooth junctions pass); G61.1: a stop after every
    // move; G64 P: the planner blends within P (Q is the path compressor's)
    assert_eq!(
        blends,
        [
            Blend::Tolerance(0.0),
            Blend::ExactStop,
            Blend::Tolerance(0.05),
            Blend::Default
        ]
    );
}

#[test]
fn exact_path_passes_collinear_junctions_and_exact_stop_stops_at_each() {
    let dir = std::env::temp_dir().join(format!("gcode_sim_paths_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run_mode = |mode: &str| {
        // three collinear 10 mm moves, then a corner
        let text = format!("G21 G90 {mode}\nG1 X10 F1200\nX20\nX30\nY10\nM2\n");
        let file = dir.join(format!("{}.nc", mode.replace('.', "_")));
        std::fs::write(&file, text).unwrap();
        run(&file, None, false).unwrap()
    };
    let path = run_mode("G61");
    let stop = run_mode("G61.1");
    std::fs::remove_dir_all(&dir).ok();
    for r in [&path, &stop] {
        assert_eq!(r.status, "completed");
        // both reach every programmed point: no corner is cut
        assert!(
            r.corner_deviation_max_mm < 1e-4,
            "{}",
            r.corner_deviation_max_mm
        );
        within_limits(r);
    }
    // G61.1 comes to rest at X10 and X20 too: two more stops and starts than G61
    assert!(
        stop.duration_s > path.duration_s + 0.1,
        "G61.1 {} s, G61 {} s",
        stop.duration_s,
        path.duration_s
    );
    assert!(path.feed_ratio_mean > stop.feed_ratio_mean);
}
