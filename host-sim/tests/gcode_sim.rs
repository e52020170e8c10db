//! `host-sim gcode` end to end on the shipped programs: the planner and the servo step on
//! the simulated gantry, measured against the programmed path.

use controller_core::motion::planner::Blend;
use host_sim::gcode::measure::tolerance::TOLERANCE_SLACK_MM;
use host_sim::gcode::parse_str;
use host_sim::gcode::program::segments;
use host_sim::gcode::report::GcodeReport;
use host_sim::gcode::runner::run;
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
    // G61 throughout: the program's tolerance is 0, and it holds
    assert_eq!(r.tolerances_mm, vec![0.0]);
    assert_eq!(r.tolerance_mm, 0.0);
    assert_eq!(r.tolerance_default_mm, 0.01);
    assert_eq!(r.tolerance_violations, 0);
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
    let blends: Vec<Blend> = segments(&p, 0.01).0.iter().map(|s| s.seg.blend).collect();
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

/// Runs `text` as a program file of its own.
fn run_text(name: &str, text: &str) -> GcodeReport {
    let dir = std::env::temp_dir().join(format!("gcode_sim_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join(format!("{name}.nc"));
    std::fs::write(&file, text).unwrap();
    let r = run(&file, None, false).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(r.status, "completed", "{name}: {:?}", r.error);
    r
}

#[test]
fn a_steep_helix_within_its_tolerance_reads_no_violation() {
    // 0.86 mm radius, 85 mm of lead: the nearest point of a point beside the path is far
    // from its planar angle (the old per-angle distance read 0.037 mm here)
    let r = run_text(
        "steep",
        "G21 G90 G64 P0.01\nG0 X0.86 Y0 Z42\nG1 Z41 F600\nG3 X0.86 Y0 Z-43 I-0.86 J0 F1200\nG1 X0 Y0 Z-44\nM30\n",
    );
    assert_eq!(
        r.tolerance_violations, 0,
        "lines {:?}, by {} mm",
        r.tolerance_violation_lines, r.tolerance_violation_max_mm
    );
    assert!(
        r.corner_deviation_max_mm <= 0.01 + TOLERANCE_SLACK_MM,
        "{}",
        r.corner_deviation_max_mm
    );
    assert!(r.contour_max_mm < 0.02, "{}", r.contour_max_mm);
    assert!(
        r.time_bound_s <= r.duration_s,
        "{} > {}",
        r.time_bound_s,
        r.duration_s
    );
}

#[test]
fn g64_p005_and_g61_parts_each_keep_their_own_tolerance() {
    let r = run_text(
        "mixed",
        "G21 G90 G61\nG0 X-40 Y-40 Z2\nG1 Z-1 F600\nG1 X40 F3000\nG1 Y40\nG64 P0.05\nG1 X-40\n\
         G1 Y-20\nG2 X-20 Y0 I20 J0\nG1 X20 Y10\nG61\nG1 X30 Y-30\nG1 X-40 Y-40\nG0 Z2\nM30\n",
    );
    assert_eq!(r.tolerances_mm, vec![0.0, 0.05]);
    assert_eq!(r.tolerance_mm, 0.0);
    assert_eq!(
        r.tolerance_violations, 0,
        "lines {:?}, by {} mm",
        r.tolerance_violation_lines, r.tolerance_violation_max_mm
    );
    // the P0.05 corners use their tolerance, not the default's 0.01
    assert!(
        r.corner_deviation_max_mm > 0.02 && r.corner_deviation_max_mm <= 0.05 + TOLERANCE_SLACK_MM,
        "{}",
        r.corner_deviation_max_mm
    );
    assert!(
        r.time_bound_s <= r.duration_s,
        "{} > {}",
        r.time_bound_s,
        r.duration_s
    );
}

#[test]
fn the_feed_ratio_of_a_feed_far_above_the_axes_is_near_1_on_a_long_line() {
    // F600000 = 10 m/s, 40 times what X allows (the programmed feed would give 0.02)
    let r = run_text(
        "fast",
        "G21 G90 G61\nG0 X-140 Y0 Z0\nG1 X140 F600000\nM30\n",
    );
    assert!(
        r.feed_ratio_mean > 0.8 && r.feed_ratio_mean < 1.001,
        "{}",
        r.feed_ratio_mean
    );
    // cruising at the axis' 250 mm/s reads 1
    let top = r.trace.feed_ratio.iter().copied().fold(0.0, f64::max);
    assert!((top - 1.0).abs() < 0.002, "{top}");
    within_limits(&r);
}

#[test]
fn no_run_beats_its_time_bound() {
    for name in ["square.nc", "arcs.nc", "helix.nc", "dense_contour.nc"] {
        let r = run(&program(name), None, false).unwrap();
        assert_eq!(r.status, "completed");
        assert_eq!(
            r.tolerance_violations, 0,
            "{name}: lines {:?}, by {} mm",
            r.tolerance_violation_lines, r.tolerance_violation_max_mm
        );
        assert!(
            r.time_bound_s > 0.0 && r.time_bound_s <= r.duration_s,
            "{name}: bound {} s, run {} s",
            r.time_bound_s,
            r.duration_s
        );
        // the planner is within a factor of 2 of any planner on these
        assert!(
            r.time_ratio_to_bound < 2.0,
            "{name}: {}",
            r.time_ratio_to_bound
        );
    }
    // a circle of 10,000 chords of radius 25.4 mm: a planner could cruise near
    // √(2000·25.4) = 225 mm/s; this one takes 14.5 times the bound (the 4-decimal
    // rounding turns each 0.016 mm chord by up to 9 mrad: docs/planner.md §3)
    let mut text = String::from("G21 G90 G61\nG0 X25.4 Y0\nG64\nF30000\n");
    for k in 1..=10_000 {
        let a = std::f64::consts::TAU * k as f64 / 10_000.0;
        text += &format!("G1 X{:.4} Y{:.4}\n", 25.4 * a.cos(), 25.4 * a.sin());
    }
    let r = run_text("circle", &text);
    assert!(
        r.time_bound_s > 0.9 && r.time_bound_s <= r.duration_s,
        "{} vs {}",
        r.time_bound_s,
        r.duration_s
    );
}
