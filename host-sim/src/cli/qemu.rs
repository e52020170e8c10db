//! `gantry --qemu`: the real firmware ELF (its QEMU build) booted on QEMU's netduinoplus2
//! in the link rig (`firmware/src/qemu/link.rs`: the machine's supervisor, planner
//! and servo step against the simulated gantry), its USART2 on a local TCP socket. The
//! bytes are the firmware's own: its UART interrupt, link task and queues, its control
//! interrupt.
//!
//! The simulated machine's operator panel is its USART1 (QEMU models no GPIO to press an
//! e-stop with), on a second local TCP socket: [`QemuMachine::press_estop`] sends the
//! panel's bytes (`firmware/src/panel.rs`) and waits for the rig's acknowledgement, which
//! names the control period the press takes effect in. QEMU listens on it without
//! waiting for a client (`wait=off`), so the boot never depends on it; the host connects
//! right after the link.
//!
//! # The clock: the machine's, not the wall's
//!
//! QEMU runs with `-icount shift=0,sleep=off` (1 ns of emulated time per instruction,
//! idle time skipped) and the firmware's link clock is the machine's control clock, so
//! the device's timeouts count control periods however fast or slow the host emulates.
//! The host's timeouts here count the same clock: [`Transport::now_ms`] is the machine's
//! link clock (`firmware::panel::CLOCK_QUERY`: the host asks on the panel line, one
//! question at a time, and the control interrupt answers with the link clock in ms).
//! While QEMU is starved of CPU or stopped, neither end's clock moves, so neither end's
//! watchdog, retransmission limit or reply timeout runs out: a slow emulator is never a
//! lost link. The host's reading lags the machine by one round trip on the panel line
//! (a control period of emulated time and the socket's latency).
//!
//! A machine whose clock stops for good (QEMU stopped or hung, the firmware's control
//! interrupt dead) would then never time out, so the wall clock stays as a backstop:
//! when the machine's clock has not advanced for [`MACHINE_CLOCK_STALL_LIMIT`] of wall
//! time, every [`Transport::wait`] fails and names it. A QEMU that exits or closes the
//! socket is reported at once. `--port` stays on the wall clock (a board runs in real
//! time). The firmware's own log (defmt over semihosting, raw) goes to a file next to
//! the ELF.

use super::Transport;
use anyhow::{anyhow, bail, Context, Result};
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Where `cargo fw-qemu-build` (the firmware's QEMU build) puts the ELF, relative to the
/// workspace root.
pub const DEFAULT_ELF: &str = "target/qemu/thumbv7em-none-eabihf/release/firmware";

/// QEMU's side of both serial sockets without Nagle's algorithm. QEMU writes what the
/// firmware sends one byte at a time (a data register write each), and its sockets keep
/// Nagle's algorithm unless told: the first byte of a reply went out, the rest waited
/// for the host's acknowledgement of it, which Linux delays by 40 ms (its minimum
/// delayed ACK) unless the host happens to send first. Every status reply and every
/// answer to the clock question took 44 ms of wall time (median and p99 47 ms over a
/// scenario: `GANTRY_LINK_TRACE`), while the machine ran on, so the host read a clock
/// 40 ms of wall time stale and acted that much late on every exchange. The host's own
/// sockets set `TCP_NODELAY` too.
const QEMU_NODELAY: &str = "nodelay=on";

/// Longest wait for QEMU to open its socket.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(20);

/// The operator panel's bytes (the firmware's `firmware::panel::ESTOP_PRESS`,
/// `ESTOP_RELEASE` and `CLOCK_QUERY`, firmware/src/panel.rs).
const PANEL_ESTOP_PRESS: u8 = b'E';
const PANEL_ESTOP_RELEASE: u8 = b'e';
const PANEL_CLOCK_QUERY: u8 = b'T';
/// Bytes of the rig's acknowledgement or clock answer (`firmware::panel::ACK_LEN`).
const PANEL_ACK_LEN: usize = 5;
/// Longest wait for the rig's acknowledgement of a panel byte (wall time; the rig reads
/// the panel every control period, a fraction of a millisecond of wall time in QEMU).
const PANEL_ACK_TIMEOUT: Duration = Duration::from_secs(10);

/// Wall time the machine's clock may stand still before the host gives the machine up
/// (the backstop of the machine-clock timeouts, see the module doc): 20 times the link
/// watchdog's 500 ms (controller-core `DEFAULT_WATCHDOG_CONFIG`), so that an emulator
/// starved of CPU for seconds on a loaded host is waited for, while a stopped or hung one
/// is still reported within seconds. The control interrupt advances the clock every
/// period while QEMU runs at all, so only a stopped machine stands still this long.
pub const MACHINE_CLOCK_STALL_LIMIT: Duration = Duration::from_secs(10);

/// How often the clock question is asked again while the firmware boots (wall time): its
/// USART1 takes bytes only once the rig has enabled it, a few milliseconds of wall time
/// after the link connects.
const FIRST_CLOCK_REASK: Duration = Duration::from_millis(20);
/// How long a failed socket waits for QEMU's process to be seen exited before the
/// socket's own error is reported (the kernel closes the socket as the process dies).
const EXIT_REAP_WAIT: Duration = Duration::from_millis(200);

/// The machine's link clock as the host last read it on the panel line.
struct MachineClock {
    /// The newest answer, ms of the machine's link clock.
    ms: u32,
    /// The question out (wall time sent), if any: one at a time, so that the panel line
    /// carries at most one answer per question and never piles up.
    asked_at: Option<Instant>,
    /// Wall time the clock was last seen advancing (the connection, at first).
    advanced_at: Instant,
}

/// The firmware in QEMU, connected.
pub struct QemuMachine {
    child: Child,
    stream: TcpStream,
    /// The operator panel (USART1): e-stop presses and the machine's clock.
    panel: TcpStream,
    /// Panel bytes received and not yet parsed into a whole answer.
    panel_rx: Vec<u8>,
    /// E-stop acknowledgements received and not yet taken (byte, period).
    panel_acks: VecDeque<(u8, u32)>,
    clock: MachineClock,
    log: PathBuf,
}

impl QemuMachine {
    /// Boot `elf` in the link rig and connect to its USART2.
    ///
    /// A start that fails before the firmware has answered (QEMU could not listen on the
    /// ports picked for it, because another process took one in the window between, or a
    /// first connection failed) is tried once more on fresh ports; the error names both
    /// attempts when the second fails too.
    pub fn boot(elf: &Path) -> Result<Self> {
        if !elf.is_file() {
            bail!(
                "{}: no firmware ELF; build its QEMU version first: cargo fw-qemu-build",
                elf.display()
            );
        }
        match Self::boot_once(elf) {
            Ok(m) => Ok(m),
            Err(first) => Self::boot_once(elf)
                .map_err(|second| anyhow!("{second:#} (and before, on other ports: {first:#})")),
        }
    }

    fn boot_once(elf: &Path) -> Result<Self> {
        // free ports (QEMU listens on them; another process may take one in the window between:
        // `boot` then tries again)
        let (port, panel_port) = free_ports()?;
        let log = elf.with_extension("link.defmt");
        let out = std::fs::File::create(&log)
            .with_context(|| format!("cannot write {}", log.display()))?;
        let child = Command::new("qemu-system-arm")
            .args([
                "-machine",
                "netduinoplus2",
                "-nographic",
                "-monitor",
                "none",
            ])
            // USART1 = the operator panel (QEMU does not wait for it), USART2 = the host
            // link (QEMU starts the machine once the host is connected); both without
            // Nagle's algorithm (see [`QEMU_NODELAY`])
            .arg("-serial")
            .arg(format!(
                "tcp:127.0.0.1:{panel_port},server=on,wait=off,{QEMU_NODELAY}"
            ))
            .arg("-serial")
            .arg(format!(
                "tcp:127.0.0.1:{port},server=on,wait=on,{QEMU_NODELAY}"
            ))
            .args([
                "-semihosting-config",
                "enable=on,target=native,arg=firmware,arg=link",
                "-icount",
                "shift=0,sleep=off",
                "-kernel",
            ])
            .arg(elf)
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                anyhow!("cannot start qemu-system-arm ({e}): apt-get install qemu-system-arm")
            })?;
        // (QEMU needs a moment to listen: `connect` retries; it opens the panel's socket
        // before the link's, so the panel connects at once once the link has)
        let stream = connect(port, CONNECT_TIMEOUT).map_err(|e| anyhow!("QEMU: {e}"));
        let panel = stream.and_then(|s| {
            connect(panel_port, CONNECT_TIMEOUT)
                .map(|p| (s, p))
                .map_err(|e| anyhow!("QEMU's operator panel: {e}"))
        });
        let (stream, panel) = match panel {
            Ok(sp) => sp,
            Err(e) => {
                // (no QEMU left behind, waiting for a client)
                let mut child = child;
                let _ = child.kill();
                let _ = child.wait();
                return Err(e);
            }
        };
        let mut m = Self {
            child,
            stream,
            panel,
            panel_rx: Vec::new(),
            panel_acks: VecDeque::new(),
            clock: MachineClock {
                ms: 0,
                asked_at: None,
                advanced_at: Instant::now(),
            },
            log,
        };
        m.stream.set_nodelay(true)?;
        m.stream.set_nonblocking(true)?;
        m.panel.set_nodelay(true)?;
        m.panel.set_nonblocking(true)?;
        m.alive()?;
        m.first_clock_reading()?;
        Ok(m)
    }

    /// The operating system's id of the QEMU process (tests stop and continue it).
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The machine's link clock, ms, as last read (what [`Transport::now_ms`] returns).
    pub fn machine_ms(&self) -> u32 {
        self.clock.ms
    }

    /// Wait for the first answer to a clock question: the machine runs and its firmware
    /// knows the question (an ELF from before it never answers).
    /// Until the firmware has set USART1 up, QEMU drops what arrives on it: the question
    /// is asked again every [`FIRST_CLOCK_REASK`] until the first answer (extra answers
    /// are harmless: each carries the clock).
    fn first_clock_reading(&mut self) -> Result<()> {
        let t0 = Instant::now();
        self.tick_clock()?;
        loop {
            std::thread::sleep(Duration::from_millis(1));
            self.panel_read()?;
            match self.clock.asked_at {
                None => return Ok(()),
                Some(t) if t.elapsed() > FIRST_CLOCK_REASK => {
                    self.panel_send(PANEL_CLOCK_QUERY)?;
                    self.clock.asked_at = Some(Instant::now());
                }
                Some(_) => {}
            }
            self.alive()?;
            if t0.elapsed() > CONNECT_TIMEOUT {
                bail!(
                    "the firmware in QEMU does not answer the clock question on its operator \
                     panel within {CONNECT_TIMEOUT:?}: rebuild it (cargo fw-qemu-build)"
                );
            }
        }
    }

    /// Send one panel byte (the socket does not block: a full send buffer is waited out,
    /// within [`PANEL_ACK_TIMEOUT`]).
    fn panel_send(&mut self, byte: u8) -> Result<()> {
        let t0 = Instant::now();
        loop {
            match self.panel.write(&[byte]) {
                Ok(1) => return Ok(()),
                Ok(_) => bail!("QEMU closed the operator panel's serial line"),
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    if t0.elapsed() > PANEL_ACK_TIMEOUT {
                        bail!("QEMU's operator panel takes no byte within {PANEL_ACK_TIMEOUT:?}");
                    }
                    std::thread::sleep(Duration::from_micros(200));
                }
                Err(e) => return Err(self.line_failed("QEMU's operator panel line", e)),
            }
        }
    }

    /// Read what the panel sent: clock answers update the clock, e-stop acknowledgements
    /// are queued for [`QemuMachine::press_estop`].
    fn panel_read(&mut self) -> Result<()> {
        let mut chunk = [0u8; 256];
        loop {
            match self.panel.read(&mut chunk) {
                Ok(0) => bail!("QEMU closed the operator panel's serial line"),
                Ok(n) => self.panel_rx.extend_from_slice(&chunk[..n]),
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) => return Err(self.line_failed("QEMU's operator panel line", e)),
            }
        }
        let whole = self.panel_rx.len() / PANEL_ACK_LEN * PANEL_ACK_LEN;
        let answers: Vec<u8> = self.panel_rx.drain(..whole).collect();
        for a in answers.chunks_exact(PANEL_ACK_LEN) {
            let value = u32::from_le_bytes([a[1], a[2], a[3], a[4]]);
            match a[0] {
                PANEL_CLOCK_QUERY => {
                    super::trace::line(format_args!(
                        "clock {value} (asked {} us ago)",
                        self.clock.asked_at.map_or(0, |t| t.elapsed().as_micros())
                    ));
                    if value != self.clock.ms {
                        self.clock.advanced_at = Instant::now();
                    }
                    self.clock.ms = value;
                    self.clock.asked_at = None;
                }
                PANEL_ESTOP_PRESS | PANEL_ESTOP_RELEASE => self.panel_acks.push_back((a[0], value)),
                _ => {
                    bail!("the operator panel sent {a:?}: neither an acknowledgement nor the clock")
                }
            }
        }
        Ok(())
    }

    /// Take the clock's answer if it came, ask again if none is out, and apply the
    /// wall-clock backstop ([`MACHINE_CLOCK_STALL_LIMIT`]).
    fn tick_clock(&mut self) -> Result<()> {
        self.panel_read()?;
        if self.clock.asked_at.is_none() {
            self.panel_send(PANEL_CLOCK_QUERY)?;
            self.clock.asked_at = Some(Instant::now());
        }
        let still = self.clock.advanced_at.elapsed();
        if still > MACHINE_CLOCK_STALL_LIMIT {
            bail!(
                "the link to the firmware in QEMU is lost: the machine's clock stood at {} ms \
                 for {:.1} s of wall time (limit {:?}): QEMU or its firmware stopped",
                self.clock.ms,
                still.as_secs_f64(),
                MACHINE_CLOCK_STALL_LIMIT
            );
        }
        Ok(())
    }

    /// Press (`true`) or release the simulated machine's e-stop on its operator panel
    /// (USART1); returns once the rig has acknowledged it, with the control period whose
    /// servo step reads the new state first (the period of the link's status and
    /// telemetry).
    pub fn press_estop(&mut self, pressed: bool) -> Result<u32> {
        let byte = if pressed {
            PANEL_ESTOP_PRESS
        } else {
            PANEL_ESTOP_RELEASE
        };
        self.panel_send(byte)?;
        // the acknowledgement: the byte, then the period (u32, little-endian), among the
        // clock's answers
        let t0 = Instant::now();
        loop {
            self.tick_clock()?;
            if let Some((b, period)) = self.panel_acks.pop_front() {
                if b == byte {
                    return Ok(period);
                }
                bail!(
                    "the operator panel acknowledged `{}` to `{}`",
                    char::from(b),
                    char::from(byte)
                );
            }
            self.alive()?;
            if t0.elapsed() > PANEL_ACK_TIMEOUT {
                bail!(
                    "the firmware did not take the operator panel's `{}` within {:?}",
                    char::from(byte),
                    PANEL_ACK_TIMEOUT
                );
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }

    /// The firmware's raw defmt log (decode with `defmt-print -e ELF < LOG`).
    pub fn log(&self) -> &Path {
        &self.log
    }

    /// Stop the connection without stopping QEMU (the link goes silent: the device's
    /// watchdog must notice), then connect again.
    pub fn reconnect_after(&mut self, silence: Duration) -> Result<()> {
        let port = self.stream.peer_addr()?.port();
        let _ = self.stream.shutdown(std::net::Shutdown::Both);
        std::thread::sleep(silence);
        self.stream = connect(port, CONNECT_TIMEOUT)?;
        self.stream.set_nodelay(true)?;
        self.stream.set_nonblocking(true)?;
        Ok(())
    }

    /// The error for a failed read or write on one of QEMU's sockets. A QEMU that dies with
    /// bytes unread in its socket resets the connection instead of closing it: the
    /// error names QEMU's exit when it has exited (waiting a moment for the process to be
    /// reaped: the socket closes as it dies), the socket's error otherwise.
    fn line_failed(&mut self, line: &str, e: std::io::Error) -> anyhow::Error {
        let t0 = Instant::now();
        while t0.elapsed() < EXIT_REAP_WAIT {
            if let Err(exited) = self.alive() {
                return exited;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        anyhow!("{line} failed: {e}")
    }

    fn alive(&mut self) -> Result<()> {
        if let Some(status) = self.child.try_wait()? {
            let mut err = String::new();
            if let Some(e) = self.child.stderr.as_mut() {
                let _ = e.read_to_string(&mut err);
            }
            bail!("QEMU exited ({status}): {}", err.trim());
        }
        Ok(())
    }
}

/// Two distinct free local TCP ports (both held until both are known, so that the system
/// cannot hand out the same one twice).
fn free_ports() -> Result<(u16, u16)> {
    let bind =
        || TcpListener::bind("127.0.0.1:0").context("no local TCP port for QEMU's serial lines");
    let (a, b) = (bind()?, bind()?);
    Ok((a.local_addr()?.port(), b.local_addr()?.port()))
}

fn connect(port: u16, timeout: Duration) -> Result<TcpStream> {
    let t0 = Instant::now();
    loop {
        match TcpStream::connect(("127.0.0.1", port)) {
            // (a connection to a local port nobody listens on yet can pick that very port
            // as its own and connect to itself: QEMU could then never listen on it)
            Ok(s) if !is_self_connected(&s) => return Ok(s),
            Ok(_) if t0.elapsed() > timeout => {
                bail!("no connection to 127.0.0.1:{port} within {timeout:?}: only to itself")
            }
            Err(e) if t0.elapsed() > timeout => {
                bail!("no connection to 127.0.0.1:{port} within {timeout:?}: {e}")
            }
            _ => std::thread::sleep(Duration::from_millis(20)),
        }
    }
}

/// Whether `s` is connected to itself (TCP simultaneous open on a local port).
fn is_self_connected(s: &TcpStream) -> bool {
    matches!((s.local_addr(), s.peer_addr()), (Ok(l), Ok(p)) if l == p)
}

impl Drop for QemuMachine {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Transport for QemuMachine {
    fn send(&mut self, mut bytes: &[u8]) -> Result<()> {
        while !bytes.is_empty() {
            match self.stream.write(bytes) {
                Ok(0) => bail!("QEMU closed the serial line"),
                Ok(n) => bytes = &bytes[n..],
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_micros(200))
                }
                Err(e) => return Err(self.line_failed("the serial line to QEMU", e)),
            }
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        let mut chunk = [0u8; 4096];
        loop {
            match self.stream.read(&mut chunk) {
                Ok(0) => bail!("QEMU closed the serial line"),
                Ok(n) => buf.extend_from_slice(&chunk[..n]),
                Err(e) if e.kind() == ErrorKind::WouldBlock => return Ok(()),
                Err(e) => return Err(self.line_failed("the serial line to QEMU", e)),
            }
        }
    }

    /// The machine's link clock (module doc): stands still while QEMU does.
    fn now_ms(&self) -> u32 {
        self.clock.ms
    }

    /// A millisecond of wall time, the machine's clock read before and after (so that
    /// each call sees it advance by what the machine ran meanwhile); fails when QEMU has
    /// exited or the clock stood still for [`MACHINE_CLOCK_STALL_LIMIT`].
    /// Its clock runs on while the host computes.
    fn clock_runs_alone(&self) -> bool {
        true
    }

    fn wait(&mut self) -> Result<()> {
        self.tick_clock()?;
        std::thread::sleep(Duration::from_millis(1));
        self.alive()?;
        self.tick_clock()
    }
}
