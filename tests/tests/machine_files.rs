//! The machine files host-sim reads (`host-sim/machines/*.toml`) describe exactly the
//! machines the core's presets name (the firmware builds its board default from the
//! presets): a change to one without the other fails here.

use controller_core::presets::gantry::{
    GANTRY_AMPLIFIERS, GANTRY_AXES, GANTRY_BRAKES, GANTRY_ENCODERS, GANTRY_SAFETY,
    GANTRY_Z_BRAKE_HOLDING_MNM,
};
use controller_core::presets::paper::PAPER_PLANT;
use controller_core::sim::world::PlantConfig;
use gantry_tests::resolve_text;

fn machine(file: &str) -> gantry_scenario::Resolved {
    resolve_text(&format!(
        r#"
name = "machine_check"
horizon_s = 0.01
path = {{ step = {{ target = [0.0, 0.0, 0.0] }} }}
estimator = {{ axes.all = {{ pll = {{ bandwidth_rad_s = 1000.0 }} }} }}
controller = {{ coupling = "none", laws.all = {{ pid = {{ kp = 1.0, ki = 0.0, kd = 0.0 }} }} }}
machine = {{ file = "../machines/{file}" }}
"#
    ))
}

#[test]
fn gantry_machine_file_equals_the_core_presets() {
    let r = machine("gantry.toml");
    let s = &r.run.servo;
    assert_eq!(s.rate_hz, 10_000);
    assert_eq!(s.encoders, GANTRY_ENCODERS);
    assert_eq!(s.amplifiers, GANTRY_AMPLIFIERS);
    assert_eq!(s.safety.axes, GANTRY_SAFETY);
    assert_eq!(s.brakes, GANTRY_BRAKES);
    for (i, p) in r.run.world.plants.iter().enumerate() {
        assert_eq!(*p, PlantConfig::Physical(GANTRY_AXES[i]), "axis {i}");
    }
    let holding = r.run.world.brakes.map(|b| b.holding_mnm);
    assert_eq!(holding, [0.0, 0.0, GANTRY_Z_BRAKE_HOLDING_MNM]);
    for (w, s) in r.run.world.brakes.iter().zip(&s.brakes) {
        assert_eq!((w.engage_s, w.release_s), (s.engage_s, s.release_s));
    }
}

#[test]
fn the_flexible_gantry_is_the_gantry_with_frames() {
    let rigid = machine("gantry.toml");
    let flexible = machine("gantry_flexible.toml");
    // everything but the frames is gantry.toml's
    let mut unframed = flexible.run;
    for p in &mut unframed.world.plants {
        let PlantConfig::Physical(a) = p else {
            panic!("physical plant expected")
        };
        assert!(a.frame.is_some());
        a.frame = None;
    }
    assert_eq!(unframed, rigid.run);
    // the modes the file's header states: Y 35 Hz, Z 55 Hz, X 90 Hz; backlash 20 µm on X
    // and Y; ±15 µm of periodic lead error on X and Y
    let frames = flexible.run.world.plants.map(|p| match p {
        PlantConfig::Physical(a) => a.frame.unwrap(),
        PlantConfig::Paper(_) => unreachable!(),
    });
    assert_eq!(frames.map(|f| f.mode_hz), [90.0, 35.0, 55.0]);
    assert_eq!(frames.map(|f| f.backlash_mm), [0.02, 0.02, 0.0]);
    assert_eq!(frames.map(|f| f.pitch_error.periodic_um), [15.0, 15.0, 5.0]);
}

#[test]
fn paper_machine_file_is_the_papers_axis() {
    let r = machine("paper_axis.toml");
    for p in r.run.world.plants {
        let PlantConfig::Paper(p) = p else {
            panic!("paper plant expected")
        };
        assert_eq!(
            (p.a, p.b, p.k),
            (PAPER_PLANT.a, PAPER_PLANT.b, PAPER_PLANT.k)
        );
        assert_eq!(p.disturbance_accel, 0.0);
    }
}

// ---- machine files checked as the settings are ----

use gantry_scenario::file::{load, load_str_with, DirIncludes};
use gantry_scenario::Resolved;
use std::path::{Path, PathBuf};

fn host_sim() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim")
}

/// The error of the gantry machine file with `field = value` replaced in it (its first
/// occurrence: the X axis), through a scenario that includes it as `gcode.toml` does.
fn refusal(field: &str, old: &str, new: &str) -> String {
    let text = std::fs::read_to_string(host_sim().join("machines/gantry.toml")).unwrap();
    let from = format!("{field} = {old}");
    assert!(text.contains(&from), "{from} not in gantry.toml");
    let bad = text.replacen(&from, &format!("{field} = {new}"), 1);
    let dir = std::env::temp_dir().join(format!("machine_check_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join(format!("bad_{}.toml", field));
    std::fs::write(&file, bad).unwrap();
    let scenario = format!(
        r#"
name = "machine_check"
horizon_s = 0.01
path = {{ step = {{ target = [0.0, 0.0, 0.0] }} }}
estimator = {{ axes.all = {{ pll = {{ bandwidth_rad_s = 1000.0 }} }} }}
controller = {{ coupling = "none", laws.all = {{ tuned = "dsmc" }} }}
machine = {{ file = "{}" }}
"#,
        file.display()
    );
    let f = load_str_with("check.toml", &scenario, &DirIncludes(dir.clone()), "").unwrap();
    let e = Resolved::new(&f.file, &f.runs[0]).expect_err("a bad machine must be refused");
    let _ = std::fs::remove_file(&file);
    let text = e.to_string();
    // the error names the scenario, the machine file and the field
    assert!(
        text.starts_with("check.toml: run `machine_check`: machine file "),
        "{text}"
    );
    assert!(text.contains(&file.display().to_string()), "{text}");
    text
}

#[test]
fn the_audits_four_machine_values_are_refused_with_the_field_and_the_range() {
    // following error below its at-rest value: the settings' cross-field rule
    let e = refusal("ferror_mm", "1.0", "0.05");
    assert!(e.contains("`machine.axes.x`"), "{e}");
    assert!(e.contains("safety.ferror_mm (>= min_ferror_mm)"), "{e}");
    // overspeed effectively off: the setting's range
    let e = refusal("vel_max_mm_s", "250.0", "1e30");
    assert!(
        e.contains("`machine.axes.x.safety.vel_max_mm_s` = 1000000000000000000000000000000 is outside the allowed range [0.1, 10000] mm/s (the range of the setting axis.x.vel_max_mm_s)"),
        "{e}"
    );
    // the plant: physical ranges
    let e = refusal("inertia", "0.064", "1e-30");
    assert!(
        e.contains("`machine.axes.x.plant.physical.inertia` = 0.000000000000000000000000000001")
            && e.contains("outside its physical range [0.0001, 100] mN·m/(mm/s²)"),
        "{e}"
    );
    let e = refusal("resolution_bits", "12", "1");
    assert!(
        e.contains("`machine.axes.x.amplifier.resolution_bits` = 1 is outside its physical range [8, 24] bits"),
        "{e}"
    );
}

#[test]
fn nan_infinite_and_negative_machine_values_are_refused_with_the_field() {
    for (field, old, new, path) in [
        (
            "min_ferror_mm",
            "0.1",
            "nan",
            "machine.axes.x.safety.min_ferror_mm` = NaN",
        ),
        (
            "vel_max_mm_s",
            "250.0",
            "inf",
            "machine.axes.x.safety.vel_max_mm_s` = inf",
        ),
        (
            "counts_per_mm",
            "1600.0",
            "-1600.0",
            "machine.axes.x.encoder.counts_per_mm` = -1600",
        ),
        (
            "full_scale",
            "1000.0",
            "-1000.0",
            "machine.axes.x.amplifier.full_scale` = -1000",
        ),
        (
            "stop_decel_mm_s2",
            "2000.0",
            "0.0",
            "machine.axes.x.safety.stop_decel_mm_s2` = 0",
        ),
        (
            "inertia",
            "0.064",
            "inf",
            "machine.axes.x.plant.physical.inertia` = inf",
        ),
        (
            "viscous",
            "0.25",
            "-0.25",
            "machine.axes.x.plant.physical.viscous` = -0.25",
        ),
        (
            "torque_max_mnm",
            "1000.0",
            "nan",
            "machine.axes.x.plant.physical.torque_max_mnm` = NaN",
        ),
        ("rate_hz", "10000", "10", "machine.rate_hz` = 10"),
        // the Z brake (the only one): its timings are settings, its torque physical
        (
            "engage_s",
            "0.03",
            "nan",
            "machine.axes.z.brake.engage_s` = NaN",
        ),
        (
            "release_s",
            "0.07",
            "-0.07",
            "machine.axes.z.brake.release_s` = -0.07",
        ),
        (
            "engage_s",
            "0.03",
            "1.5",
            "machine.axes.z.brake.engage_s` = 1.5",
        ),
        (
            "holding_mnm",
            "320.0",
            "-320.0",
            "machine.axes.z.brake.holding_mnm` = -320",
        ),
        (
            "holding_mnm",
            "320.0",
            "nan",
            "machine.axes.z.brake.holding_mnm` = NaN",
        ),
    ] {
        let e = refusal(field, old, new);
        assert!(e.contains(path), "{field} = {new}: {e}");
        assert!(e.contains("range ["), "{field} = {new}: no range in {e}");
    }
}

/// Every scenario file under `dir`, recursively.
fn scenario_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            scenario_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "toml") {
            out.push(p);
        }
    }
}

#[test]
fn every_shipped_scenario_and_machine_file_loads_and_resolves() {
    let mut files = Vec::new();
    scenario_files(&host_sim().join("scenarios"), &mut files);
    assert!(files.len() >= 19, "{} scenario files", files.len());
    let mut runs = 0;
    for f in &files {
        let loaded = load(f).unwrap_or_else(|e| panic!("{e}"));
        for r in &loaded.runs {
            Resolved::new(&loaded.file, r).unwrap_or_else(|e| panic!("{e}"));
            runs += 1;
        }
    }
    assert!(runs >= files.len());
    // and each machine file through the minimal scenario above
    for m in std::fs::read_dir(host_sim().join("machines")).unwrap() {
        let name = m.unwrap().file_name().to_string_lossy().into_owned();
        machine(&name);
    }
}

#[test]
fn a_present_brake_without_holding_torque_is_refused_by_name() {
    let e = refusal("holding_mnm", "320.0", "0.0");
    assert!(
        e.contains(
            "`machine.axes.z.brake.holding_mnm` = 0 must be positive when `brake.present = true`"
        ),
        "{e}"
    );
}

#[test]
fn a_bad_feedforward_is_refused_naming_the_axis_and_the_key() {
    let e = refusal(
        "resolution_bits",
        "12 }",
        "12 }\nfeedforward = { coulomb_pos_mnm = 40.0, coulomb_neg_mnm = 5.0 }",
    );
    assert!(
        e.contains("machine.axes.x.") && e.contains("feedforward.coulomb_neg_mnm"),
        "{e}"
    );
}
