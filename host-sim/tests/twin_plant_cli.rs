//! `twin-plant`, the board twin's plant, on bad input: a bad flag or rate is exit 2 with a
//! message naming it; a request it does not know ends it with exit 2, naming the byte; a
//! step it is given is answered with one record (host_sim::twin_plant has the protocol).

use std::io::Write;
use std::process::{Command, Stdio};

use host_sim::twin_plant::STEP_ANSWER_BYTES;

fn plant(args: &[&str], stdin: &[u8]) -> (i32, Vec<u8>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_twin-plant"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // (a plant that refused its flags has exited: the write may find the pipe closed)
    let _ = child.stdin.take().unwrap().write_all(stdin);
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        out.stdout,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_bad_rate_or_flag_is_exit_2_naming_it() {
    for (args, names) in [
        (&["--rate-hz", "fast"][..], "--rate-hz fast"),
        (&["--rate-hz", "10"][..], "--rate-hz 10"),
        (&["--rate-hz", "99999"][..], "--rate-hz 99999"),
        (&["--speed", "2"][..], "usage"),
    ] {
        let (code, out, err) = plant(args, b"");
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?}");
        assert!(err.contains(names), "{args:?}: {err}");
    }
}

#[test]
fn a_step_is_answered_and_an_unknown_request_ends_the_plant_naming_it() {
    let mut req = vec![b'S', 0, 0];
    req.extend_from_slice(&[0u8; 24]);
    req.push(b'?');
    let (code, out, err) = plant(&["--rate-hz", "10000"], &req);
    assert_eq!(out.len(), STEP_ANSWER_BYTES, "{err}");
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("0x3f"), "{err}");
}

#[test]
fn the_end_of_its_input_ends_it_cleanly() {
    let (code, out, err) = plant(&[], b"");
    assert_eq!(code, 0, "{err}");
    assert!(out.is_empty());
}
