//! Single keys at a terminal: during `gantry run` the operator's `h`, `r` and `a` act at
//! once, without Enter (the terminal's line editing and echo are off while the program
//! runs, and back as they were after it, also when Ctrl-C ends `gantry` at once). Ctrl-C
//! stays a signal ([`super::interrupt`]); the output keeps its line endings.

use std::sync::Mutex;

/// The terminal's settings before single keys, restored when they end.
static SAVED: Mutex<Option<libc::termios>> = Mutex::new(None);

/// Single keys are on while this lives.
pub struct SingleKeys(());

impl SingleKeys {
    /// Line editing and echo off on standard input, when it is a terminal (`None`
    /// otherwise: keys then come a line at a time).
    pub fn start() -> Option<Self> {
        // SAFETY: tcgetattr/tcsetattr on fd 0 with a termios owned here; isatty first
        unsafe {
            if libc::isatty(0) != 1 {
                return None;
            }
            let mut t: libc::termios = std::mem::zeroed();
            if libc::tcgetattr(0, &mut t) != 0 {
                return None;
            }
            let saved = t;
            t.c_lflag &= !(libc::ICANON | libc::ECHO);
            t.c_cc[libc::VMIN] = 1;
            t.c_cc[libc::VTIME] = 0;
            if libc::tcsetattr(0, libc::TCSANOW, &t) != 0 {
                return None;
            }
            if let Ok(mut s) = SAVED.lock() {
                *s = Some(saved);
            }
        }
        Some(Self(()))
    }
}

impl Drop for SingleKeys {
    fn drop(&mut self) {
        restore();
    }
}

/// The terminal as it was before single keys (nothing when they are off).
pub fn restore() {
    let saved = SAVED.lock().ok().and_then(|mut s| s.take());
    if let Some(t) = saved {
        // SAFETY: fd 0's settings as tcgetattr gave them
        unsafe {
            libc::tcsetattr(0, libc::TCSANOW, &t);
        }
    }
}
