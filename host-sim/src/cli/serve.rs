//! `gantry sim serve PTY`: one simulated machine as a long-lived process, behind a
//! pseudo-terminal, as a board sits behind its serial port. Successive `gantry --served
//! PTY …` commands, scripts and the GUI talk to the same machine: its settings, homing,
//! arming and position stay between them (a command ends its session with a goodbye,
//! [`super::client::Client::goodbye`], not with the link watchdog's `LinkLost`), and its
//! settings flash is kept in a file (`--flash`), loaded at power-on as the board loads
//! its store.
//!
//! Time runs by the wall clock times `--speed` (1: real time, so the h/r/a keys of `run`
//! and a person at the keyboard see what a board does); `max` runs as fast as the host
//! can. The machine clock is written to `PTY.clock` (ms, u32 little-endian, as the board
//! twin writes its own), which `gantry --served` counts every link timeout in, so a
//! faster or a starved machine is never "lost".

use super::sim::{SimMachine, SimModels};
use super::Transport;
use anyhow::{bail, Context, Result};
use serialport::{SerialPort, TTYPort};
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Bytes to the host that wait while nobody reads the pty (then the oldest go, as a
/// serial driver's buffer overflows): one second of the link at full rate.
const BACKLOG_MAX_BYTES: usize = 1 << 20;
/// Machine time run between two looks at the pty, ms (a reply's latency at most).
const SLICE_MS: u32 = 1;
/// How far (ms of machine time) the served machine may fall behind the wall clock before
/// it slows down instead of catching up (a starved host: the machine is slow, never lost,
/// as the QEMU rig's is).
const MAX_LAG_MS: u32 = 20;
/// Telemetry decimation until a host subscribes (1 kHz at 10 kHz).
const IDLE_TELEMETRY_PERIODS: u32 = 10;

/// How fast the served machine's time runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Speed {
    /// This many times real time (1: real time).
    Times(f64),
    /// As fast as the host runs it.
    Max,
}

impl std::str::FromStr for Speed {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("max") {
            return Ok(Self::Max);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() && (0.01..=1000.0).contains(&v) => Ok(Self::Times(v)),
            _ => Err(format!(
                "`{s}` is not a speed: a factor of real time within 0.01-1000 (1 = real time), or `max`"
            )),
        }
    }
}

impl std::fmt::Display for Speed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Times(v) if *v == 1.0 => f.write_str("real time"),
            Self::Times(v) => write!(f, "{v} x real time"),
            Self::Max => f.write_str("as fast as it runs"),
        }
    }
}

/// What `gantry sim serve` runs.
#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// Where the pty appears (a symlink to its /dev/pts device).
    pub pty: PathBuf,
    pub speed: Speed,
    /// The settings flash, kept across runs (created on the first save).
    pub flash: Option<PathBuf>,
    pub models: SimModels,
    /// The machine file whose axes it runs (`None`: host-sim/machines/gantry.toml's).
    pub machine: Option<PathBuf>,
    /// Stop after this much machine time, s (`None`: until SIGINT/SIGTERM).
    pub seconds: Option<f64>,
}

/// The flash image kept in `path`: `None` when there is no file yet (an erased store).
fn read_flash(path: &Path) -> Result<Option<Vec<u8>>> {
    match std::fs::read(path) {
        Ok(b) => Ok(Some(b)),
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e).with_context(|| format!("cannot read the flash file {}", path.display())),
    }
}

/// Write `bytes` to `path` whole or not at all (a kill mid-write leaves the old file).
fn write_flash(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes)
        .and_then(|()| std::fs::rename(&tmp, path))
        .with_context(|| format!("cannot write the flash file {}", path.display()))
}

/// The pty's symlink and the clock file, removed when the server ends.
/// `O_NONBLOCK` on the pty master: a write takes what fits and returns.
fn set_nonblocking(port: &TTYPort) -> std::io::Result<()> {
    use std::os::unix::io::AsRawFd;
    let fd = port.as_raw_fd();
    // SAFETY: fcntl on a descriptor this process owns, with integer arguments only.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    if flags < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: as above.
    if unsafe { libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) } < 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

struct Served {
    pty: PathBuf,
    clock_path: PathBuf,
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.pty);
        let _ = std::fs::remove_file(&self.clock_path);
    }
}

/// Serve one simulated machine at `opts.pty` until `stop` is set (or `--seconds` of
/// machine time): the loop runs the machine in slices of [`SLICE_MS`], paced by the wall
/// clock, and moves the link's bytes between it and the pty.
pub fn serve(opts: &ServeOptions, stop: Arc<AtomicBool>) -> Result<()> {
    let image = match &opts.flash {
        Some(p) => read_flash(p)?,
        None => None,
    };
    let (mut sim, outcome) = SimMachine::boot(
        opts.models,
        IDLE_TELEMETRY_PERIODS,
        image.as_deref(),
        opts.machine.as_deref(),
    )
    .with_context(|| match &opts.flash {
        Some(p) => format!("the flash file {}", p.display()),
        None => "the simulated machine".into(),
    })?;
    let mut kept = sim.flash_image().to_vec();
    let (mut master, slave, dev, served, clock) = open_pty(&opts.pty)?;

    eprintln!(
        "gantry: the simulated gantry serves its link at {} ({}), {}; settings flash: {} ({:?}). \
         Talk to it with `gantry --served {} …`; Ctrl-C stops it.",
        opts.pty.display(),
        dev,
        opts.speed,
        opts.flash
            .as_ref()
            .map_or("in memory only".into(), |p| p.display().to_string()),
        outcome,
        opts.pty.display(),
    );

    let rate = u64::from(sim.rate_hz());
    let slice = (sim.rate_hz() * SLICE_MS / 1000).max(1);
    let end_periods = opts.seconds.map(|s| (s * rate as f64) as u64);
    let t0 = Instant::now();
    let mut backlog: VecDeque<u8> = VecDeque::new();
    let mut out = Vec::new();
    let mut inbuf = [0u8; 4096];
    let mut last_ms = 0u32;
    // machine periods given up to starvation (see MAX_LAG_MS)
    let mut slipped = 0u64;
    while !stop.load(Ordering::Relaxed) {
        if end_periods.is_some_and(|e| sim.periods() >= e) {
            break;
        }
        host_to_machine(&mut master, &mut sim, &mut inbuf)?;
        // the machine's time: paced by the wall clock, but never more than MAX_LAG_MS
        // behind it; a serve starved of the CPU (a loaded host) slows the machine down
        // instead of running the lost time in one burst, during which a host starved
        // alongside could not send and the machine's link watchdog would expire
        let due = match opts.speed {
            Speed::Times(f) => {
                let wall = (t0.elapsed().as_secs_f64() * f * rate as f64) as u64;
                let lag_max = u64::from(MAX_LAG_MS) * rate / 1000;
                let behind = wall.saturating_sub(slipped + sim.periods());
                if behind > lag_max {
                    slipped += behind - lag_max;
                }
                wall.saturating_sub(slipped)
            }
            Speed::Max => sim.periods() + u64::from(slice),
        };
        if due > sim.periods() {
            sim.advance(slice.min((due - sim.periods()) as u32));
        } else {
            std::thread::sleep(Duration::from_micros(200));
        }
        // its bytes to the host
        sim.recv(&mut out)?;
        backlog.extend(out.drain(..));
        machine_to_host(&mut master, &mut backlog)?;
        let ms = sim.clock_ms();
        if ms != last_ms {
            clock.write_all_at(&ms.to_le_bytes(), 0)?;
            last_ms = ms;
            // a save or repair the machine wrote: into the file within a millisecond of
            // machine time (a kill loses nothing); looked at once per millisecond, not per
            // turn of this loop
            if let Some(p) = &opts.flash {
                if sim.flash_image() != &kept[..] {
                    kept.copy_from_slice(sim.flash_image());
                    write_flash(p, &kept)?;
                }
            }
        }
    }
    drop(slave);
    drop(served);
    eprintln!(
        "gantry: the simulated gantry stopped after {:.3} s of machine time",
        sim.periods() as f64 / rate as f64
    );
    Ok(())
}

/// The pty at `path` (a link to a fresh pseudo-terminal's device, checked not to replace
/// anything else) and its clock file beside it (`PATH.clock`, the machine's millisecond
/// clock, 0 at the start): the master end (reads and writes that never wait), the slave
/// end (kept open while serving), the device's name, and what removes both links.
fn open_pty(pty: &Path) -> Result<(TTYPort, TTYPort, String, Served, std::fs::File)> {
    if let Some(dir) = pty.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            bail!("{}: no such directory for the pty", dir.display());
        }
    }
    if std::fs::symlink_metadata(pty).is_ok_and(|m| !m.file_type().is_symlink()) {
        bail!(
            "{} exists and is not a pty link: choose another path",
            pty.display()
        );
    }
    let (mut master, slave) = TTYPort::pair().context("cannot open a pseudo-terminal")?;
    let dev = slave
        .name()
        .context("the pseudo-terminal has no device name")?;
    let _ = std::fs::remove_file(pty);
    std::os::unix::fs::symlink(&dev, pty)
        .with_context(|| format!("cannot link {} to {dev}", pty.display()))?;
    let clock_path = PathBuf::from(format!("{}.clock", pty.display()));
    let served = Served {
        pty: pty.to_path_buf(),
        clock_path: clock_path.clone(),
    };
    let clock = std::fs::File::create(&clock_path)
        .with_context(|| format!("cannot write the clock file {}", clock_path.display()))?;
    clock.write_all_at(&0u32.to_le_bytes(), 0)?;
    master
        .set_timeout(Duration::ZERO)
        .context("pseudo-terminal timeout")?;
    // writes that never wait: the timeout only bounds waiting for room, and a write of
    // more than the pty takes then blocks until a reader takes it all; a client that
    // stopped reading (gone, starved, stopped in a debugger) held the machine's loop
    // there, with its clock, its link watchdog and Ctrl-C
    set_nonblocking(&master).context("pseudo-terminal: non-blocking writes")?;
    Ok((master, slave, dev, served, clock))
}

/// The host's bytes waiting at the pty, to the machine.
fn host_to_machine(master: &mut TTYPort, sim: &mut SimMachine, inbuf: &mut [u8]) -> Result<()> {
    loop {
        match master.read(inbuf) {
            Ok(0) => break,
            Ok(n) => sim.send(&inbuf[..n])?,
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => break,
            Err(e) => return Err(e).context("pseudo-terminal read"),
        }
    }
    Ok(())
}

/// The machine's bytes in `backlog` to the pty, as many as it takes now; the backlog
/// kept to its newest [`BACKLOG_MAX_BYTES`] (a client that stopped reading loses the
/// oldest).
fn machine_to_host(master: &mut TTYPort, backlog: &mut VecDeque<u8>) -> Result<()> {
    if backlog.len() > BACKLOG_MAX_BYTES {
        let extra = backlog.len() - BACKLOG_MAX_BYTES;
        backlog.drain(..extra);
    }
    while !backlog.is_empty() {
        let (front, _) = backlog.as_slices();
        match master.write(front) {
            Ok(0) => break,
            Ok(n) => {
                backlog.drain(..n);
            }
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => break,
            Err(e) => return Err(e).context("pseudo-terminal write"),
        }
    }
    Ok(())
}
