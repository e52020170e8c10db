//! Bad input to the `gantry` command line that used to hang or be accepted silently: a
//! named pipe or a device as a program or settings file, non-finite or out-of-range
//! times, speeds and coordinates. Each is refused promptly with an error naming it, and
//! nothing runs.

use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// Runs `gantry ARGS`, killed after 20 s (a hang fails the test instead of the suite).
fn gantry(args: &[&str]) -> (Output, Duration) {
    let t0 = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("gantry runs");
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if t0.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    (child.wait_with_output().unwrap(), t0.elapsed())
}

fn refused(args: &[&str], needles: &[&str]) {
    let (o, took) = gantry(args);
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        took < Duration::from_secs(15),
        "{args:?} took {took:?}: {text}"
    );
    assert!(!o.status.success(), "{args:?} accepted: {text}");
    for n in needles {
        assert!(text.contains(n), "{args:?}: no `{n}` in: {text}");
    }
}

#[test]
fn pipes_and_devices_are_refused_before_they_are_opened() {
    let dir = std::env::temp_dir().join(format!("gantry-inputs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("program.nc");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if made.map(|s| s.success()).unwrap_or(false) {
        let f = fifo.to_str().unwrap();
        refused(&["--sim", "run", f], &["not a regular file"]);
        refused(&["--sim", "settings", "import", f], &["not a regular file"]);
    }
    refused(
        &["--sim", "settings", "import", "/dev/zero"],
        &["/dev/zero", "not a regular file"],
    );
    refused(&["--sim", "run", "/dev/zero"], &["not a regular file"]);
    refused(
        &["--sim", "comp", "load", "y", "/dev/zero"],
        &["/dev/zero", "not a regular file"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn non_finite_and_out_of_range_numbers_are_refused() {
    let prog = concat!(env!("CARGO_MANIFEST_DIR"), "/programs/square.nc");
    refused(&["--sim", "jog", "x", "nan"], &["VEL_MM_S", "not finite"]);
    refused(
        &["--sim", "jog", "x", "fast"],
        &["VEL_MM_S", "not a number"],
    );
    refused(&["--sim", "jog", "x", "inf"], &["VEL_MM_S", "not finite"]);
    refused(
        &["--sim", "jog", "x", "10", "--seconds", "inf"],
        &["--seconds", "not finite"],
    );
    refused(
        &["--sim", "jog", "x", "10", "--seconds", "0"],
        &["--seconds", "outside"],
    );
    refused(
        &["--sim", "run", prog, "--hold-at-s", "nan"],
        &["--hold-at-s", "not finite"],
    );
    refused(
        &["--sim", "run", prog, "--hold-for-s", "inf"],
        &["--hold-for-s", "not finite"],
    );
    refused(&["--sim", "move", "1", "2", "nan"], &["Z_MM", "not finite"]);
    refused(
        &["--sim", "log", "out.csv", "--seconds", "1e9"],
        &["--seconds", "outside"],
    );
    refused(
        &["--sim", "scope", "out.csv", "--timeout-s=-1"],
        &["--timeout-s", "outside"],
    );
    // compensation: the flags are checked before anything is sent
    let comp = std::env::temp_dir().join(format!("gantry-inputs-comp-{}.txt", std::process::id()));
    std::fs::write(&comp, "-100 -100.01 -99.99\n100 100.01 99.99\n").unwrap();
    let c = comp.to_str().unwrap();
    refused(
        &["--sim", "comp", "load", "y", c, "--backlash-mm", "nan"],
        &["--backlash-mm", "not finite"],
    );
    refused(
        &["--sim", "comp", "load", "y", c, "--backlash-mm", "3"],
        &["--backlash-mm", "backlash must be in 0..=1 mm"],
    );
    refused(
        &["--sim", "comp", "load", "y", c, "--rate-mm-s", "0"],
        &["--rate-mm-s", "finite positive"],
    );
    refused(
        &["--sim", "comp", "load", "y", c, "--file-type", "2"],
        &["COMP_FILE_TYPE must be 0"],
    );
    refused(
        &["--sim", "comp", "load", "w", c],
        &["axis must be x, y or z"],
    );
    let _ = std::fs::remove_file(&comp);
    // the frequency response: the axis and the window are checked before anything moves
    refused(&["--sim", "freqresp", "w"], &["axis must be x, y or z"]);
    refused(
        &["--sim", "freqresp", "y", "--window-mm", "nan"],
        &["--window-mm", "positive number"],
    );
    // a simulated machine's file: named when it cannot be read; only with --sim
    refused(
        &["--sim", "--machine", "/nonexistent/flexible.toml", "status"],
        &["/nonexistent/flexible.toml"],
    );
    refused(
        &["--port", "/dev/null", "--machine", "m.toml", "status"],
        &["--machine", "--sim"],
    );
    // --elf belongs to --qemu
    refused(&["--sim", "--elf", "x.elf", "status"], &["--elf", "--qemu"]);
    refused(
        &["--port", "/dev/null", "--factory", "status"],
        &["--factory", "--sim"],
    );
}

/// A reader that goes away (`gantry settings list | head -1`) ends gantry with the shell's
/// broken-pipe status and no panic message.
#[test]
fn a_closed_stdout_ends_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(["--sim", "settings", "list"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("gantry runs");
    // The read end closes at once, long before the simulated machine is up and the
    // first line is printed.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(141), "{err}");
}
