//! A trace of the host's link, for finding timing faults: with `GANTRY_LINK_TRACE=FILE`
//! every frame sent and received, every reading of the machine's clock, one line each,
//! `<wall µs since the first line> <event>`. Off (one check of a static) otherwise.

use std::io::Write;
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

struct Trace {
    t0: Instant,
    out: Mutex<std::io::BufWriter<std::fs::File>>,
}

fn trace() -> Option<&'static Trace> {
    static T: OnceLock<Option<Trace>> = OnceLock::new();
    T.get_or_init(|| {
        let path = std::env::var_os("GANTRY_LINK_TRACE")?;
        let f = std::fs::File::create(path).ok()?;
        Some(Trace {
            t0: Instant::now(),
            out: Mutex::new(std::io::BufWriter::new(f)),
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
        if let Ok(mut o) = t.out.lock() {
            let _ = writeln!(o, "{us} {args}");
            let _ = o.flush();
        }
    }
}
