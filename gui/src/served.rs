//! `gantry gui --sim`: the simulated gantry served in real time by this process (the
//! machine of `gantry sim serve`, on a thread), so the window sees it move at the speed
//! a board would and can be talked to by other `gantry --served PTY` commands meanwhile.
//! An in-process `--sim` session would run the machine only while the session waits,
//! as fast as the host computes.

use anyhow::{bail, Result};
use host_sim::cli::machine::MachineArgs;
use host_sim::cli::serve::{serve, ServeOptions, Speed};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A machine served by this process; stopped (its pty removed) when dropped.
pub struct Served {
    pub pty: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<Result<()>>>,
}

impl Served {
    /// Serve the simulated machine `args` describes (`--sim`, `--factory`) at a pty in
    /// the temporary directory; the machine options to talk to it.
    pub fn start(args: &MachineArgs) -> Result<(Self, MachineArgs)> {
        // (a counter: tests serve several machines from one process)
        static SERVED: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = SERVED.fetch_add(1, Ordering::Relaxed);
        let pty = std::env::temp_dir().join(format!("gantry-gui-{}-{n}", std::process::id()));
        let opts = ServeOptions {
            pty: pty.clone(),
            speed: Speed::Times(1.0),
            flash: None,
            models: args.models(),
            machine: args.machine.clone(),
            seconds: None,
        };
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::Builder::new()
            .name("gantry-served".into())
            .spawn(move || serve(&opts, s))?;
        let clock = PathBuf::from(format!("{}.clock", pty.display()));
        let t0 = Instant::now();
        while !clock.exists() {
            if thread.is_finished() {
                return match thread.join() {
                    Ok(Err(e)) => Err(e),
                    _ => bail!("the simulated machine stopped at start"),
                };
            }
            if t0.elapsed() > Duration::from_secs(10) {
                bail!("the simulated machine did not start within 10 s");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let served = MachineArgs {
            served: Some(pty.display().to_string()),
            telemetry_hz: args.telemetry_hz,
            ..MachineArgs::default()
        };
        Ok((
            Self {
                pty,
                stop,
                thread: Some(thread),
            },
            served,
        ))
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
