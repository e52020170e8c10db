//! `gantry --qemu`: the real firmware ELF (its QEMU build) booted on QEMU's netduinoplus2
//! in the link rig (`firmware/src/qemu/link_rig.rs`: the machine's supervisor, planner
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
//! QEMU runs with `-icount shift=0,sleep=off` (1 ns of emulated time per instruction,
//! idle time skipped) and the firmware's link clock is the machine's control clock, so
//! the device's timeouts count control periods however fast the host emulates; the
//! host's clock here is the wall clock. The firmware's own log (defmt over semihosting,
//! raw) goes to a file next to the ELF.

use super::Transport;
use anyhow::{anyhow, bail, Context, Result};
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Where `cargo fw-qemu-build` (the firmware's QEMU build) puts the ELF, relative to the
/// workspace root.
pub const DEFAULT_ELF: &str = "target/qemu/thumbv7em-none-eabihf/release/firmware";

/// Longest wait for QEMU to open its socket.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(20);

/// The operator panel's bytes (the firmware's `firmware::panel::ESTOP_PRESS` and
/// `ESTOP_RELEASE`, firmware/src/panel.rs).
const PANEL_ESTOP_PRESS: u8 = b'E';
const PANEL_ESTOP_RELEASE: u8 = b'e';
/// Bytes of the rig's acknowledgement (`firmware::panel::ACK_LEN`).
const PANEL_ACK_LEN: usize = 5;
/// Longest wait for the rig's acknowledgement of a panel byte (wall time; the rig reads
/// the panel every control period, a fraction of a millisecond of wall time in QEMU).
const PANEL_ACK_TIMEOUT: Duration = Duration::from_secs(10);

/// The firmware in QEMU, connected.
pub struct QemuMachine {
    child: Child,
    stream: TcpStream,
    /// The operator panel (USART1).
    panel: TcpStream,
    t0: Instant,
    log: PathBuf,
}

impl QemuMachine {
    /// Boot `elf` in the link rig and connect to its USART2.
    pub fn boot(elf: &Path) -> Result<Self> {
        if !elf.is_file() {
            bail!(
                "{}: no firmware ELF; build its QEMU version first: cargo fw-qemu-build",
                elf.display()
            );
        }
        // free ports (QEMU listens on them; the tiny window between is harmless locally)
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
            // link (QEMU starts the machine once the host is connected)
            .arg("-serial")
            .arg(format!("tcp:127.0.0.1:{panel_port},server=on,wait=off"))
            .arg("-serial")
            .arg(format!("tcp:127.0.0.1:{port},server=on,wait=on"))
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
            t0: Instant::now(),
            log,
        };
        m.stream.set_nodelay(true)?;
        m.stream.set_nonblocking(true)?;
        m.panel.set_nodelay(true)?;
        // (blocking reads with a short timeout: `press_estop` waits for the acknowledgement)
        m.panel.set_read_timeout(Some(Duration::from_millis(100)))?;
        m.alive()?;
        Ok(m)
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
        self.panel
            .write_all(&[byte])
            .context("QEMU's operator panel line")?;
        // the acknowledgement: the byte, then the period (u32, little-endian); one byte
        // is sent at a time, so nothing else is on the line
        let t0 = Instant::now();
        let mut ack = [0u8; PANEL_ACK_LEN];
        let mut got = 0;
        loop {
            match self.panel.read(&mut ack[got..]) {
                Ok(0) => bail!("QEMU closed the operator panel's serial line"),
                Ok(n) => {
                    got += n;
                    if got == PANEL_ACK_LEN {
                        if ack[0] != byte {
                            bail!(
                                "the operator panel answered {ack:?} to `{}`",
                                char::from(byte)
                            );
                        }
                        return Ok(u32::from_le_bytes([ack[1], ack[2], ack[3], ack[4]]));
                    }
                }
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                Err(e) => return Err(e.into()),
            }
            self.alive()?;
            if t0.elapsed() > PANEL_ACK_TIMEOUT {
                bail!(
                    "the firmware did not take the operator panel's `{}` within {:?}",
                    char::from(byte),
                    PANEL_ACK_TIMEOUT
                );
            }
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
            Ok(s) => return Ok(s),
            Err(e) if t0.elapsed() > timeout => {
                bail!("no connection to 127.0.0.1:{port} within {timeout:?}: {e}")
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
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
                Err(e) => return Err(e.into()),
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
                Err(e) => return Err(e.into()),
            }
        }
    }

    fn now_ms(&self) -> u32 {
        self.t0.elapsed().as_millis() as u32
    }

    fn wait(&mut self) -> Result<()> {
        std::thread::sleep(Duration::from_millis(1));
        self.alive()
    }
}
