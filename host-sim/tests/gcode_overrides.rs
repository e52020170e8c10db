//! `cargo sim gcode FILE --set KEY=VALUE`: overrides checked like `gantry settings set`
//! (key, type, range, whole tree), refused when the run would not use them, and taken by
//! the planner of the run.

use std::path::PathBuf;
use std::process::Command;

use controller_core::settings::FACTORY;
use host_sim::bench_programs::{rest_to_rest, Direction};
use host_sim::gcode::runner::run_with_settings;
use host_sim::overrides::{gcode_run_settings, used_by_gcode_run};

/// The default machine's control rate (10 kHz).
const RATE_HZ: u32 = 10_000;

fn set(assignments: &[&str]) -> anyhow::Result<controller_core::settings::Settings> {
    let a: Vec<String> = assignments.iter().map(|s| s.to_string()).collect();
    gcode_run_settings(&FACTORY, &a, RATE_HZ)
}

fn err(assignments: &[&str]) -> String {
    format!("{:#}", set(assignments).unwrap_err())
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("host-sim-set-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn overrides_are_set_by_dotted_key() {
    let s = set(&[
        "planner.servo_reserve=0",
        "axis.z.planner.vel_max_mm_s = 100",
    ])
    .unwrap();
    assert_eq!(s.planner.servo_reserve, 0.0);
    assert_eq!(s.axis[2].planner.vel_max_mm_s, 100.0);
    // the rest stays factory
    assert_eq!(s.planner.tolerance_mm, FACTORY.planner.tolerance_mm);
    assert_eq!(s.axis[0], FACTORY.axis[0]);
    // a later assignment of the same key wins
    let s = set(&["planner.tolerance_mm=0.02", "planner.tolerance_mm=0.05"]).unwrap();
    assert_eq!(s.planner.tolerance_mm, 0.05);
    assert_eq!(set(&[]).unwrap(), FACTORY);
}

#[test]
fn a_bad_override_is_an_error_naming_it() {
    let e = err(&["planner.nonsense=1"]);
    assert!(
        e.contains("planner.nonsense") && e.contains("unknown key"),
        "{e}"
    );
    let e = err(&["planner.servo_reserve=2"]);
    assert!(
        e.contains("planner.servo_reserve=2") && e.contains("outside the allowed range"),
        "{e}"
    );
    let e = err(&["planner.servo_reserve=lots"]);
    assert!(
        e.contains("planner.servo_reserve") && e.contains("expected"),
        "{e}"
    );
    for bad in ["planner.servo_reserve", "=1", "planner.servo_reserve="] {
        let e = err(&[bad]);
        assert!(e.contains("expected KEY=VALUE"), "{bad}: {e}");
    }
    // a valid key the run would ignore (its servo is the scenario's)
    let e = err(&["axis.x.following_error_mm=0.8"]);
    assert!(
        e.contains("axis.x.following_error_mm") && e.contains("not used"),
        "{e}"
    );
    // the first bad one stops it, whatever follows
    let e = err(&["planner.servo_reserve=0", "planner.nonsense=1"]);
    assert!(e.contains("planner.nonsense"), "{e}");
}

#[test]
fn the_run_uses_the_planner_keys_work_offsets_and_tools() {
    for k in [
        "planner.servo_reserve",
        "planner.tolerance_mm",
        "axis.y.planner.jerk_max_mm_s3",
        "work.g54.x_mm",
        "tool.1.length_mm",
        "axis.y.feedforward.coulomb_pos_mnm",
        "axis.z.filter.stage3.kind",
    ] {
        assert!(used_by_gcode_run(k), "{k}");
    }
    for k in [
        "axis.x.following_error_mm",
        "coupling.lambda",
        "jog.timeout_s",
    ] {
        assert!(!used_by_gcode_run(k), "{k}");
    }
}

#[test]
fn the_planner_of_the_run_takes_the_overrides() {
    let dir = scratch("run");
    let file = dir.join("r2r_x_10.nc");
    std::fs::write(&file, rest_to_rest(10.0, Direction::X)).unwrap();
    let factory = run_with_settings(&file, None, &FACTORY, false).unwrap();
    let full = set(&["planner.servo_reserve=0", "planner.tolerance_mm=0.02"]).unwrap();
    let r = run_with_settings(&file, None, &full, false).unwrap();
    assert!(factory.completed() && r.completed());
    // (the G61 line's own tolerance is 0; the default is the override)
    assert_eq!(r.tolerance_default_mm, 0.02);
    assert_eq!(r.tolerance_mm, 0.0);
    // the full jerk (reserve 0 instead of 0.75) makes the short line faster
    assert!(
        r.duration_s < 0.9 * factory.duration_s,
        "{} vs {}",
        r.duration_s,
        factory.duration_s
    );
    // a work offset moves the program: 10 mm more along X than the travel allows
    let shifted = set(&["work.g54.x_mm=145"]).unwrap();
    let r = run_with_settings(&file, None, &shifted, false).unwrap();
    assert_eq!(r.status, "rejected", "{:?}", r.error);
}

#[test]
fn the_cli_refuses_a_bad_override_before_anything_runs() {
    let dir = scratch("cli");
    let file = dir.join("r2r_x_1.nc");
    std::fs::write(&file, rest_to_rest(1.0, Direction::X)).unwrap();
    let json = dir.join("out.json");
    // `host-sim gcode FILE --no-plots --json JSON --set S …`
    let gcode = |sets: &[&str]| {
        let mut args = vec![
            "gcode",
            file.to_str().unwrap(),
            "--no-plots",
            "--json",
            json.to_str().unwrap(),
        ];
        for s in sets {
            args.extend(["--set", s]);
        }
        Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .output()
            .unwrap()
    };
    let o = gcode(&["planner.servo_reserve=0", "planner.servo_reserve=1.5"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("planner.servo_reserve=1.5"), "{stderr}");
    assert!(!json.exists(), "a JSON was written");
    let o = gcode(&["planner.servo_reserve=0"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("settings overrides: planner.servo_reserve=0"),
        "{stdout}"
    );
    assert!(json.exists());
}

#[test]
fn the_servo_of_the_run_takes_the_feedforward_and_filter_keys() {
    use controller_core::filter::FilterConfig;
    let s = set(&[
        "axis.y.filter.stage1.kind=notch",
        "axis.y.filter.stage1.freq_hz=35",
        "axis.x.feedforward.lag_s=4e-5",
    ])
    .unwrap();
    let (run, _) = host_sim::sim_gantry::machine_and_planner_with(None, &s).unwrap();
    assert_eq!(
        run.servo.filters[1].stages(),
        [FilterConfig::Notch {
            freq_hz: 35.0,
            width_hz: 20.0,
            depth_db: 20.0
        }]
    );
    assert!(run.servo.filters[0].stages().is_empty());
    assert_eq!(run.servo.feedforward[0].lag_s, 4e-5);

    // the Coulomb pre-compensation entered by keys takes DSMC's quadrant glitches out of a
    // circle (R 10 mm at 1200 mm/min): the contour's rms halves
    let dir = scratch("ff");
    let file = dir.join("circle.nc");
    std::fs::write(
        &file,
        "G21 G90 G17\nG0 X10 Y0\nG2 X10 Y0 I-10 J0 F1200\nM2\n",
    )
    .unwrap();
    let ff = set(&[
        "axis.x.feedforward.coulomb_pos_mnm=40",
        "axis.x.feedforward.coulomb_neg_mnm=-32",
        "axis.x.feedforward.stiction_ratio=1.3",
        "axis.y.feedforward.coulomb_pos_mnm=60",
        "axis.y.feedforward.coulomb_neg_mnm=-50",
        "axis.y.feedforward.stiction_ratio=1.3",
    ])
    .unwrap();
    let without = run_with_settings(&file, None, &FACTORY, false).unwrap();
    let with = run_with_settings(&file, None, &ff, false).unwrap();
    assert!(without.completed() && with.completed());
    assert!(
        with.contour_rms_mm < 0.6 * without.contour_rms_mm,
        "{} vs {} mm",
        with.contour_rms_mm,
        without.contour_rms_mm
    );
}
