//! A machine that stays: `gantry sim serve PTY` runs one simulated machine behind a
//! pseudo-terminal, and successive `gantry --served PTY` commands find it as the last one
//! left it (settings, arming, no `LinkLost` after a command's goodbye); a saved setting
//! survives a restart through the `--flash` file; bad input is refused by name. And the
//! goodbye itself, in-process: a jog the host leaves comes to a controlled stop without a
//! fault.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use controller_core::machine::messages::{MachineState, Request};
use host_sim::cli::client::{expect_done, Client};
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self, Transport};

const GANTRY: &str = env!("CARGO_BIN_EXE_gantry");

/// A temporary directory of this test, removed at the end.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let d = std::env::temp_dir().join(format!("gantry-serve-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Self(d)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A served machine, stopped (SIGTERM, as Ctrl-C) when dropped.
struct Server(Child);

impl Server {
    fn start(pty: &Path, flash: &Path) -> Self {
        let child = Command::new(GANTRY)
            .args(["sim", "serve"])
            .arg(pty)
            .arg("--flash")
            .arg(flash)
            // real time, as served by default: a faster machine shortens the link
            // watchdog's 500 ms in wall time, which a loaded CI host's process start-up
            // can exceed between a handshake and the next frame
            .args(["--speed", "1"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let clock = PathBuf::from(format!("{}.clock", pty.display()));
        let t0 = Instant::now();
        while !clock.exists() {
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "the server never came up"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Self(child)
    }

    /// SIGTERM, then its stderr (it must exit by itself, cleaning up).
    fn stop(mut self) -> String {
        let pid = self.0.id().to_string();
        Command::new("kill").args(["-TERM", &pid]).status().unwrap();
        let t0 = Instant::now();
        loop {
            if let Some(status) = self.0.try_wait().unwrap() {
                assert!(status.success(), "the server exited with {status}");
                break;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "the server did not stop"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let mut err = String::new();
        use std::io::Read;
        self.0
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        err
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn gantry(pty: &Path, args: &[&str]) -> Output {
    Command::new(GANTRY)
        .arg("--served")
        .arg(pty)
        .args(args)
        .output()
        .unwrap()
}

fn ok(pty: &Path, args: &[&str]) -> String {
    let o = gantry(pty, args);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "gantry {args:?}: {}{}",
        out,
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

fn status(pty: &Path) -> serde_json::Value {
    serde_json::from_str(&ok(pty, &["status", "--json"])).unwrap()
}

#[test]
fn a_served_machine_keeps_its_settings_and_arming_between_commands_and_its_flash_across_restarts() {
    let dir = TempDir::new("keeps");
    let pty = dir.0.join("tty");
    let flash = dir.0.join("gantry.flash");
    let server = Server::start(&pty, &flash);

    ok(
        &pty,
        &["settings", "set", "axis.x.following_error_mm", "0.8"],
    );
    assert_eq!(
        ok(&pty, &["settings", "get", "axis.x.following_error_mm"]).trim(),
        "0.8"
    );
    // armed by one command, still armed (and without a `LinkLost`) for the next, well
    // past the link watchdog's 500 ms of machine time
    ok(&pty, &["arm"]);
    std::thread::sleep(Duration::from_millis(1200)); // past the 500 ms watchdog
    let s = status(&pty);
    assert_eq!(s["state"], "Idle", "{s}");
    assert!(s["first_fault"].is_null(), "{s}");
    assert_eq!(s["fault_bits"]["system"], 0, "{s}");
    // a save needs the outputs off
    ok(&pty, &["disarm"]);
    ok(&pty, &["settings", "save"]);
    assert_eq!(std::fs::metadata(&flash).unwrap().len(), 8192);
    let log = server.stop();
    assert!(log.contains("stopped after"), "{log}");
    assert!(!pty.exists(), "the pty link is left behind");
    assert!(!PathBuf::from(format!("{}.clock", pty.display())).exists());

    // power on again from the same flash: the saved value runs
    let server = Server::start(&pty, &flash);
    assert_eq!(
        ok(&pty, &["settings", "get", "axis.x.following_error_mm"]).trim(),
        "0.8"
    );
    let s = status(&pty);
    assert_eq!(s["state"], "Disabled", "{s}");
    assert!(s["first_fault"].is_null(), "{s}");
    let log = server.stop();
    assert!(log.contains("(Stored)"), "{log}");
}

#[test]
fn bad_serve_input_is_refused_by_name_and_nothing_is_served() {
    let dir = TempDir::new("bad");
    let run = |args: &[&str]| {
        let o = Command::new(GANTRY).args(args).output().unwrap();
        assert!(!o.status.success(), "{args:?} succeeded");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = run(&["sim", "serve", "/nonexistent-gantry-dir/tty"]);
    assert!(
        e.contains("/nonexistent-gantry-dir: no such directory"),
        "{e}"
    );
    let pty = dir.0.join("tty");
    let p = pty.to_str().unwrap();
    for bad in ["0", "-3", "fast", "NaN"] {
        let e = run(&["sim", "serve", p, "--speed", bad]);
        assert!(e.contains("is not a speed"), "{bad}: {e}");
    }
    // a flash file that is not a store image
    let flash = dir.0.join("short.flash");
    std::fs::write(&flash, [0u8; 100]).unwrap();
    let e = run(&["sim", "serve", p, "--flash", flash.to_str().unwrap()]);
    assert!(e.contains("short.flash") && e.contains("100 bytes"), "{e}");
    assert!(!pty.exists());
    // a regular file where the pty would go is not replaced
    std::fs::write(&pty, "keep me").unwrap();
    let e = run(&["sim", "serve", p]);
    assert!(e.contains("is not a pty link"), "{e}");
    assert_eq!(std::fs::read_to_string(&pty).unwrap(), "keep me");
    // nobody serving there
    let e = run(&["--served", dir.0.join("none").to_str().unwrap(), "status"]);
    assert!(e.contains("cannot open the serial port"), "{e}");
    // serve with a machine option, and no machine at all
    let e = run(&["--sim", "sim", "serve", p]);
    assert!(e.contains("runs a machine of its own"), "{e}");
    let e = run(&["status"]);
    assert!(e.contains("which machine?"), "{e}");
}

#[test]
fn a_jog_the_host_leaves_with_a_goodbye_stops_without_a_fault_and_the_machine_stays_armed() {
    let mut c =
        Client::connect_session(SimMachine::new(SimModels::Designed, 10).unwrap(), 3).unwrap();
    cli::ready(&mut c, true).unwrap();
    expect_done(
        "jog",
        c.exec(Request::Jog {
            axis: 0,
            vel_mm_s: 20.0,
        })
        .unwrap(),
    )
    .unwrap();
    c.sleep_ms(100).unwrap();
    assert_eq!(c.status().unwrap().state, MachineState::Jog);
    c.goodbye().unwrap();
    let mut m = c.into_transport();
    // two seconds with nobody on the link: four times the watchdog's timeout
    for _ in 0..2000 {
        m.wait().unwrap();
    }
    let mut c = Client::connect_session(m, 4).unwrap();
    let s = c.status().unwrap();
    assert_eq!(s.state, MachineState::Idle, "{s:?}");
    assert_eq!(s.first_fault, None, "{s:?}");
    assert_eq!(s.homed, 0b111);
    // at rest (the jog was 20 mm/s): the estimate's noise while holding
    assert!(s.vel_mm_s[0].abs() < 1.0, "{s:?}");
}

#[test]
fn a_compensation_table_loaded_on_a_served_machine_reads_back_as_sent_and_is_refused_while_armed() {
    let dir = TempDir::new("comp");
    let pty = dir.0.join("tty");
    let flash = dir.0.join("gantry.flash");
    let server = Server::start(&pty, &flash);
    // a LinuxCNC type-0 file: the positions measured at the tool
    let file = dir.0.join("comp_y.txt");
    std::fs::write(
        &file,
        "# nominal forward-actual reverse-actual\n-150 -150.012 -149.992\n0 0.004 0.021\n150 150.010 150.030\n",
    )
    .unwrap();
    let f = file.to_str().unwrap();
    let out = ok(&pty, &["comp", "load", "y", f, "--backlash-mm", "0.02"]);
    assert!(out.contains("3 points"), "{out}");
    assert_eq!(status(&pty)["comp"], 0b010);
    // read back: the trims are nominal − actual, the backlash as given
    let shown: serde_json::Value =
        serde_json::from_str(&ok(&pty, &["comp", "show", "y", "--json"])).unwrap();
    assert_eq!(shown["backlash_mm"], 0.02, "{shown}");
    assert_eq!(
        shown["points"],
        serde_json::json!([
            [-150.0, 0.012, -0.008],
            [0.0, -0.004, -0.021],
            [150.0, -0.01, -0.03]
        ]),
        "{shown}"
    );
    // the text form is a type-1 file that loads back to the same table
    let text = ok(&pty, &["comp", "show", "y"]);
    let again = dir.0.join("again.txt");
    std::fs::write(&again, text.lines().skip(1).collect::<Vec<_>>().join("\n")).unwrap();
    let load_again = [
        "comp",
        "load",
        "y",
        again.to_str().unwrap(),
        "--file-type",
        "1",
    ];
    ok(
        &pty,
        &[&load_again[..], &["--backlash-mm", "0.02"]].concat(),
    );
    assert_eq!(ok(&pty, &["comp", "show", "y"]), text);
    // a bad file is refused by FILE:LINE and changes nothing
    std::fs::write(&file, "0 0 0\n-1 0 0\n").unwrap();
    let o = gantry(&pty, &["comp", "load", "y", f]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("comp_y.txt:2"), "{err}");
    assert_eq!(ok(&pty, &["comp", "show", "y"]), text);
    // armed: refused, nothing changes; disarmed: cleared
    ok(&pty, &["arm"]);
    let o = gantry(&pty, &["comp", "clear", "y"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("outputs are on"),
        "{err}"
    );
    assert_eq!(status(&pty)["comp"], 0b010);
    ok(&pty, &["disarm"]);
    ok(&pty, &["comp", "clear", "y"]);
    assert_eq!(status(&pty)["comp"], 0);
    // a table beside the feed-forward's friction deflection: loaded, with a warning that
    // the reversal is compensated twice
    ok(
        &pty,
        &[
            "settings",
            "set",
            "axis.y.feedforward.deflection_pos_mm",
            "0.02",
        ],
    );
    let o = gantry(&pty, &load_again);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("compensated twice"),
        "{err}"
    );
    assert_eq!(status(&pty)["comp"], 0b010);
    server.stop();
}
