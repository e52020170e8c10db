//! What the command-line tests of `host-sim` share: running the binary, and a scratch
//! directory of their own.

use std::path::PathBuf;
use std::process::{Command, Output};

/// `host-sim ARGS`, run to its end.
pub fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("host-sim runs")
}

/// An empty directory for this test process, `prefix` and `name` in its name.
pub fn scratch(prefix: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
