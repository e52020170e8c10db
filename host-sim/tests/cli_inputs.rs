//! Bad input to the `host-sim` command line: every case exits non-zero with an error that
//! names what is wrong and where, writes nothing, and returns promptly (no hang).

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common;
use common::host_sim;

fn scratch(name: &str) -> PathBuf {
    common::scratch("host-sim-cli", name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A valid single-run scenario (the paper machine, 0.2 s) with `extra` appended.
fn scenario(dir: &Path, extra: &str) -> PathBuf {
    let machines = Path::new(env!("CARGO_MANIFEST_DIR")).join("machines/paper_axis.toml");
    let text = format!(
        r#"name = "short"
horizon_s = 0.2
mode = "discrete"
path = {{ helix = {{ radius = 1.0, omega = 1.0, z_rate = 5.0 }} }}
estimator = {{ axes.all = "exact" }}
controller = {{ coupling = "none", laws.all = {{ pid = {{ kp = 600.0, ki = 1.0, kd = 10.0 }} }} }}
[machine]
file = "{}"
{extra}"#,
        machines.display()
    );
    let p = dir.join("s.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `run FILE` with JSON and CSV output into `dir`; asserts a clean failure that
/// mentions every `needles` and wrote nothing.
fn rejected(dir: &Path, file: &Path, needles: &[&str]) {
    let json = dir.join("out.json");
    let out = dir.join("csv");
    let o = host_sim(&[
        "run",
        file.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert!(!o.status.success(), "accepted: {err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
    assert!(!json.exists() && !out.exists(), "wrote output: {err}");
}

#[test]
fn a_valid_scenario_runs_and_writes_its_outputs() {
    let d = scratch("valid");
    let f = scenario(&d, "");
    let json = d.join("o.json");
    let o = host_sim(&[
        "run",
        f.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--out",
        d.join("csv").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v["runs"]["short"]["itse"][0].as_f64().unwrap() > 0.0);
    assert!(d.join("csv/short.csv").exists());
}

#[test]
fn unknown_keys_are_rejected_with_their_path() {
    let d = scratch("unknown");
    let f = scenario(&d, "axes.all.plant.paper.dampening = 3.0\n");
    rejected(&d, &f, &["dampening", "s.toml"]);
    let f = scenario(&d, "[metrics]\ncontour_from = 1.0\n");
    rejected(&d, &f, &["contour_from"]);
}

#[test]
fn bad_numbers_are_rejected_naming_the_parameter() {
    let d = scratch("numbers");
    let f = scenario(&d, "axes.x.plant.paper = { a = nan }\n");
    rejected(&d, &f, &["plant.paper.a"]);
    let f = scenario(&d, "axes.all.encoder.counts_per_mm = -1.0\n");
    rejected(&d, &f, &["counts_per_mm"]);
    let f = scenario(&d, "rate_hz = 1\n");
    rejected(&d, &f, &["rate_hz"]);
    let f = scenario(&d, "plant_substeps = 0\n");
    rejected(&d, &f, &["plant_substeps"]);
}

#[test]
fn runs_over_the_step_cap_are_refused_at_once() {
    let d = scratch("cap");
    let text = std::fs::read_to_string(scenario(&d, "")).unwrap();
    let f = d.join("long.toml");
    std::fs::write(&f, text.replace("horizon_s = 0.2", "horizon_s = 1e6")).unwrap();
    let started = std::time::Instant::now();
    rejected(&d, &f, &["exceed the cap"]);
    assert!(started.elapsed().as_secs() < 30);
}

#[test]
fn names_outside_the_allowed_set_and_big_files_are_refused() {
    let d = scratch("names");
    let text = std::fs::read_to_string(scenario(&d, "")).unwrap();
    let f = d.join("n.toml");
    std::fs::write(
        &f,
        text.replace("name = \"short\"", "name = \"../../etc/x\""),
    )
    .unwrap();
    rejected(&d, &f, &["[A-Za-z0-9_-]"]);
    let big = d.join("big.toml");
    std::fs::write(&big, format!("{text}\n# {}\n", "x".repeat(1 << 20))).unwrap();
    rejected(&d, &big, &["limited to 1048576 bytes"]);
    rejected(&d, &d.join("missing.toml"), &["missing.toml"]);
}

#[test]
fn a_diverging_run_is_an_error_naming_the_figure() {
    let d = scratch("diverge");
    // negative damping and stiffness: the plant blows up to inf within the horizon
    let f = scenario(
        &d,
        "axes.all.plant.paper = { a = -3000.0, b = -1.0e6 }\naxes.all.amplifier.full_scale = 1e30\n",
    );
    rejected(&d, &f, &["not finite"]);
}

#[test]
fn flags_a_subcommand_does_not_take_are_errors() {
    let o = host_sim(&["seeds", "--horizon-s", "3"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--horizon-s"), "{}", stderr(&o));
    let o = host_sim(&["--scenario", "x.toml", "seeds"]);
    assert!(!o.status.success(), "{}", stderr(&o));
}

#[test]
fn unwritable_outputs_are_named() {
    let d = scratch("unwritable");
    let f = scenario(&d, "");
    let blocker = d.join("file");
    std::fs::write(&blocker, "").unwrap();
    let json = blocker.join("x.json");
    let o = host_sim(&[
        "run",
        f.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--no-plots",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains(json.to_str().unwrap()),
        "{}",
        stderr(&o)
    );
}
