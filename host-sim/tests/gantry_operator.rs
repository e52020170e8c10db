//! What an operator reads from `gantry`: the one-screen status with units, the live read-out,
//! refusals that say what is wrong and what to do, the version, the port list and the shell
//! completions (the README's "The gantry CLI").

use std::process::{Command, Output};

const GANTRY: &str = env!("CARGO_BIN_EXE_gantry");

fn gantry(args: &[&str]) -> Output {
    Command::new(GANTRY).args(args).output().unwrap()
}

fn stdout_ok(args: &[&str]) -> String {
    let o = gantry(args);
    assert!(
        o.status.success(),
        "gantry {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn status_is_one_screen_with_units_and_the_next_step() {
    let out = stdout_ok(&["--sim", "status"]);
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines.len() <= 24, "more than a screen:\n{out}");
    let field = |k: &str| {
        lines
            .iter()
            .find(|l| l.starts_with(k))
            .unwrap_or_else(|| panic!("no `{k}` line:\n{out}"))
            .to_string()
    };
    assert!(field("state").contains("Disabled") && field("state").contains("gantry arm"));
    assert!(
        field("position").contains("x     0.000")
            && field("position").ends_with("mm (machine coordinates)")
    );
    assert!(field("velocity").ends_with("mm/s"));
    assert!(field("feed").ends_with("mm/min"));
    assert!(field("homed").contains("none") && field("homed").contains("gantry home"));
    assert_eq!(field("fault"), "fault      none");
    assert!(field("clock").contains("at 10000 Hz"));
    // factory settings: the axes without a model, and a command that identifies one
    let out = stdout_ok(&["--sim", "--factory", "status"]);
    let no_model = out.lines().find(|l| l.starts_with("no model")).unwrap();
    assert!(
        no_model.contains("x y z")
            && no_model.contains("identify --axis x --window-mm 10 --accept"),
        "{no_model}"
    );
}

#[test]
fn watch_prints_a_read_out_per_tick_until_its_time_is_up() {
    let out = stdout_ok(&["--sim", "watch", "--seconds", "0.5", "--hz", "10"]);
    let lines: Vec<&str> = out.lines().collect();
    // 0.0, 0.1, ..., 0.5 s of machine time
    assert!((5..=7).contains(&lines.len()), "{out}");
    for l in &lines {
        assert!(l.starts_with("Disabled"), "{l}");
        assert!(
            l.contains(" mm ") && l.contains("mm/min") && l.contains("fault none"),
            "{l}"
        );
    }
    let e = gantry(&["--sim", "watch", "--hz", "0"]);
    assert!(!e.status.success());
    assert!(String::from_utf8_lossy(&e.stderr).contains("outside [0.5, 50] Hz"));
}

#[test]
fn arm_disarm_and_reset_say_what_is_wrong_instead_of_a_bare_refusal() {
    assert_eq!(
        stdout_ok(&["--sim", "arm"]).trim(),
        "armed: holding position"
    );
    let out = stdout_ok(&["--sim", "reset"]);
    assert!(
        out.starts_with("no fault latched: nothing to reset"),
        "{out}"
    );
    let out = stdout_ok(&["--sim", "disarm"]);
    assert!(out.starts_with("already disarmed"), "{out}");
    // an axis without a model: its name and a command that works
    let o = gantry(&["--sim", "--factory", "arm"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("axis x has no model")
            && e.contains("gantry identify --axis x --window-mm 10 --accept"),
        "{e}"
    );
    let o = gantry(&[
        "--sim",
        "--factory",
        "identify",
        "--axis",
        "x",
        "--window-mm",
        "-3",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("--window-mm must be a positive number of mm") && e.ends_with("got -3\n"),
        "{e}"
    );
}

#[test]
fn version_ports_and_completions_need_no_machine() {
    assert!(stdout_ok(&["--version"]).starts_with("gantry 0."));
    let ports = stdout_ok(&["ports"]);
    assert!(
        ports.contains("gantry --port") || ports.contains("no USB serial port found"),
        "{ports}"
    );
    for shell in ["bash", "zsh", "fish"] {
        let script = stdout_ok(&["completions", shell]);
        assert!(
            script.contains("served") && script.contains("watch"),
            "{shell}"
        );
    }
    let o = gantry(&["--sim", "ports"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("talk to no machine"));
}

#[test]
fn every_argument_of_every_command_has_help() {
    let commands: &[&[&str]] = &[
        &[],
        &["status"],
        &["watch"],
        &["log"],
        &["scope"],
        &["faults"],
        &["jog"],
        &["pendant"],
        &["move"],
        &["run"],
        &["identify"],
        &["ports"],
        &["completions"],
        &["sim", "serve"],
        &["settings", "get"],
        &["settings", "set"],
        &["settings", "export"],
        &["settings", "import"],
    ];
    for cmd in commands {
        let mut args = cmd.to_vec();
        args.push("--help");
        let help = stdout_ok(&args);
        for line in help.lines().map(str::trim_start) {
            if line.starts_with('<') || line.starts_with('-') {
                let text = line.split_once("  ").map_or("", |(_, t)| t.trim());
                assert!(!text.is_empty(), "gantry {cmd:?}: `{line}` has no help");
            }
        }
    }
}
