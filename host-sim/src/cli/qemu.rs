//! `gantry --qemu`: the real firmware ELF (its QEMU build) booted on QEMU's netduinoplus2
//! in the link rig (`firmware/src/qemu/link_rig.rs`: the machine's supervisor, planner
//! and servo step against the simulated gantry), its USART2 on a local TCP socket. The
//! bytes are the firmware's own: its UART interrupt, link task and queues, its control
//! interrupt.
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

/// The firmware in QEMU, connected.
pub struct QemuMachine {
    child: Child,
    stream: TcpStream,
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
        // a free port (QEMU listens on it; the tiny window between is harmless locally)
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .context("no local TCP port for QEMU's serial line")?
            .port();
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
            // USART1 unused, USART2 = the host link
            .args(["-serial", "null", "-serial"])
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
        let mut m = Self {
            child,
            // (QEMU needs a moment to listen: `connect` retries)
            stream: connect(port, CONNECT_TIMEOUT).map_err(|e| anyhow!("QEMU: {e}"))?,
            t0: Instant::now(),
            log,
        };
        m.stream.set_nodelay(true)?;
        m.stream.set_nonblocking(true)?;
        m.alive()?;
        Ok(m)
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
