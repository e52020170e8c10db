//! Bad options to `gantry-gui` get an error naming the option, before any window or
//! machine starts (exit status 1, or clap's 2), and never hang; a bad program loaded in
//! the window is refused with its file and line, and the session goes on.

use gantry_gui::served::Served;
use gantry_gui::session::{Command, Event, Session};
use host_sim::cli::machine::MachineArgs;
use std::process::Command as Process;
use std::time::{Duration, Instant};

fn gui(args: &[&str]) -> (i32, String) {
    let out = Process::new(env!("CARGO_BIN_EXE_gantry-gui"))
        .args(args)
        // (no display: nothing here may get as far as opening a window)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run gantry-gui");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn bad_options_are_refused_by_name_before_anything_starts() {
    let cases: [(&[&str], &str); 7] = [
        (&[], "which machine?"),
        (
            &["--sim", "--size", "10x10"],
            "--size: 10 px is outside 200-8000",
        ),
        (&["--sim", "--size", "wide"], "--size must be WxH"),
        (
            &["--sim", "--after-s", "1e9"],
            "--after-s must be within 0-86400 s",
        ),
        (
            &["--sim", "--program", "/no/such/file.nc"],
            "--program: no such file",
        ),
        (&["--served", "/tmp/x", "--factory"], "--factory"),
        (&["--sim", "--tab", "3d"], "--tab"),
    ];
    for (args, want) in cases {
        let (code, err) = gui(args);
        assert!(code == 1 || code == 2, "{args:?}: exit {code}, {err}");
        assert!(
            err.contains(want),
            "{args:?}: `{err}` does not say `{want}`"
        );
    }
}

#[test]
fn a_bad_program_is_refused_with_its_line_and_the_session_goes_on() {
    let dir = std::env::temp_dir().join(format!("gantry-gui-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let bad = dir.join("bad.nc");
    std::fs::write(&bad, "G21 G90\nG1 X10 F600\nG81 X1 Y1 Z-1 R1\n").expect("write");
    let sim = MachineArgs {
        sim: true,
        telemetry_hz: 100,
        ..MachineArgs::default()
    };
    let (_served, args) = Served::start(&sim).expect("serve the simulated gantry");
    let s = Session::start(args, || {});
    s.send(Command::Load(bad.clone()));
    s.send(Command::ReadSettings);
    let t0 = Instant::now();
    let (mut refused, mut settings) = (None, false);
    while t0.elapsed() < Duration::from_secs(30) && !(refused.is_some() && settings) {
        while s.tapped.try_recv().is_ok() {}
        match s.events.recv_timeout(Duration::from_millis(50)) {
            Ok(Event::Finished { what, result }) if what.starts_with("load") => {
                refused = Some(result.expect_err("the program is refused"));
            }
            Ok(Event::Program(_)) => panic!("a refused program reached the window"),
            Ok(Event::Settings(all)) => settings = !all.is_empty(),
            Ok(Event::Lost(why)) => panic!("session lost: {why}"),
            _ => {}
        }
    }
    let why = refused.expect("the load finished");
    assert!(why.contains("bad.nc:3"), "{why}");
    assert!(why.contains("G81"), "{why}");
    assert!(settings, "the session took the next command");
}
