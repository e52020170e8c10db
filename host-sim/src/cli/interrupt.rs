//! Ctrl-C in the `gantry` commands: the first one asks for a controlled stop (a running
//! program, a jog, homing, an identification stop on the path, the session ends with a
//! goodbye and the command says where the machine stopped); a second one ends the process
//! at once (the machine's link watchdog then stops it).

use anyhow::{Context, Result};
use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Take Ctrl-C (and SIGTERM) from here on.
pub fn install() -> Result<()> {
    ctrlc::set_handler(|| {
        if REQUESTED.swap(true, Ordering::SeqCst) {
            // the second one: leave now (130: killed by SIGINT, as a shell reports it),
            // the terminal as it was
            super::keys::restore();
            std::process::exit(130);
        }
    })
    .context("cannot handle Ctrl-C")
}

/// Ctrl-C was pressed.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

/// Ask for the controlled stop Ctrl-C asks for (a GUI's stop button): the command running
/// on the session stops the machine on its path as for Ctrl-C.
pub fn request() {
    REQUESTED.store(true, Ordering::SeqCst);
}

/// The stop was handled: the next command runs as usual.
pub fn clear() {
    REQUESTED.store(false, Ordering::SeqCst);
}
