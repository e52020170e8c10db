//! A trace of the host's link, for finding timing faults: with `GANTRY_LINK_TRACE=FILE`
//! every frame sent and received, every reading of the machine's clock, one line each,
//! `<wall µs since the first line> <event>`. Off (one check of a static) otherwise.
//!
//! The lines are written by a thread of their own: a write to a file can wait for the
//! disk (hundreds of milliseconds while a build flushes gigabytes), and the link's thread
//! waiting there would itself be the timing fault the trace is looking for. The writer
//! flushes whenever no line is pending, so the file is at most a few milliseconds behind.

use std::io::Write;
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

struct Trace {
    t0: Instant,
    lines: Mutex<Sender<String>>,
}

fn trace() -> Option<&'static Trace> {
    static T: OnceLock<Option<Trace>> = OnceLock::new();
    T.get_or_init(|| {
        let path = std::env::var_os("GANTRY_LINK_TRACE")?;
        let f = std::fs::File::create(path).ok()?;
        let (tx, rx) = channel::<String>();
        std::thread::Builder::new()
            .name("gantry-trace".into())
            .spawn(move || {
                let mut out = std::io::BufWriter::new(f);
                loop {
                    match rx.recv_timeout(Duration::from_millis(5)) {
                        Ok(l) => {
                            let _ = out.write_all(l.as_bytes());
                        }
                        Err(RecvTimeoutError::Timeout) => {
                            let _ = out.flush();
                        }
                        Err(RecvTimeoutError::Disconnected) => break,
                    }
                }
                let _ = out.flush();
            })
            .ok()?;
        Some(Trace {
            t0: Instant::now(),
            lines: Mutex::new(tx),
        })
    })
    .as_ref()
}

/// Whether the trace is on.
pub fn on() -> bool {
    trace().is_some()
}

/// One line of the trace (nothing when it is off).
pub fn line(args: std::fmt::Arguments<'_>) {
    if let Some(t) = trace() {
        let us = t.t0.elapsed().as_micros();
        if let Ok(tx) = t.lines.lock() {
            let _ = tx.send(format!("{us} {args}\n"));
        }
    }
}
