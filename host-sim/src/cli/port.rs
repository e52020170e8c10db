//! `gantry --port DEV`: a board over its host UART (USART2, PA2/PA3, 921,600 baud 8N1:
//! an ST-Link virtual COM port such as `/dev/ttyACM0`, or any USB-UART adapter). The
//! host's clock is the wall clock.
//!
//! `gantry --twin PTY`: the board twin (`firmware/twin/run --serve PTY`, the release ELF
//! on the emulated STM32F407) over the same serial path; the host's clock is the twin's
//! machine clock, which it writes to `PTY.clock` (milliseconds, u32 little-endian), so
//! every link timeout counts machine time however slowly the twin runs.

use super::Transport;
use anyhow::{bail, Context, Result};
use std::cell::Cell;
use std::io::{ErrorKind, Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The firmware's link baud rate (firmware `board::serial::HOST_BAUD`).
pub const BOARD_BAUD: u32 = 921_600;

/// Wall time the twin's clock may stand still before the session ends (the twin runs at
/// about 0.1 x real time: a millisecond of machine time takes about 10 ms).
pub const TWIN_CLOCK_STALL_LIMIT: Duration = Duration::from_secs(10);

/// The machine clock of the board twin, read from the file it writes.
struct TwinClock {
    path: PathBuf,
    last_ms: Cell<u32>,
    last_change: Cell<Instant>,
}

impl TwinClock {
    fn read(&self) -> Option<u32> {
        let b = std::fs::read(&self.path).ok()?;
        let ms = u32::from_le_bytes(b.get(..4)?.try_into().ok()?);
        if ms != self.last_ms.get() {
            self.last_ms.set(ms);
            self.last_change.set(Instant::now());
        }
        Some(ms)
    }
}

/// An open serial line to a board (or to the board twin).
pub struct BoardPort {
    port: Box<dyn serialport::SerialPort>,
    t0: Instant,
    twin: Option<TwinClock>,
}

impl BoardPort {
    /// Open `dev` at the link's baud rate, 8N1, no flow control.
    pub fn open(dev: &str) -> Result<Self> {
        let port = serialport::new(dev, BOARD_BAUD)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(1))
            .open()
            .with_context(|| format!("cannot open the serial port {dev}"))?;
        Ok(Self {
            port,
            t0: Instant::now(),
            twin: None,
        })
    }

    /// The board twin serving its USART2 at `pty`, with its machine clock at `pty.clock`.
    pub fn open_twin(pty: &str) -> Result<Self> {
        let mut p = Self::open(pty)?;
        let clock = TwinClock {
            path: PathBuf::from(format!("{pty}.clock")),
            last_ms: Cell::new(0),
            last_change: Cell::new(Instant::now()),
        };
        if clock.read().is_none() {
            bail!(
                "{}: no machine clock (is `firmware/twin/run --serve {pty}` running?)",
                clock.path.display()
            );
        }
        p.twin = Some(clock);
        Ok(p)
    }
}

impl Transport for BoardPort {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        self.port.write_all(bytes).context("serial port write")?;
        Ok(())
    }

    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        let mut chunk = [0u8; 4096];
        loop {
            match self.port.read(&mut chunk) {
                Ok(0) => return Ok(()),
                // what was buffered, not all that keeps coming: a machine that streams
                // faster than this host reads (a served machine at `--speed` 10 and
                // 1 kHz telemetry) would keep this loop reading while the link's clock
                // runs past its watchdog
                Ok(n) if n < chunk.len() => {
                    buf.extend_from_slice(&chunk[..n]);
                    return Ok(());
                }
                Ok(n) => buf.extend_from_slice(&chunk[..n]),
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {
                    return Ok(())
                }
                Err(e) => bail!("serial port read: {e}"),
            }
        }
    }

    fn now_ms(&self) -> u32 {
        match &self.twin {
            Some(c) => c.read().unwrap_or_else(|| c.last_ms.get()),
            None => self.t0.elapsed().as_millis() as u32,
        }
    }

    /// Its clock runs on while the host computes.
    fn clock_runs_alone(&self) -> bool {
        true
    }

    fn wait(&mut self) -> Result<()> {
        std::thread::sleep(Duration::from_millis(1));
        if let Some(c) = &self.twin {
            c.read();
            if c.last_change.get().elapsed() > TWIN_CLOCK_STALL_LIMIT {
                bail!(
                    "the board twin's clock ({}) stood still for {} s: the twin is gone",
                    c.path.display(),
                    TWIN_CLOCK_STALL_LIMIT.as_secs()
                );
            }
        }
        Ok(())
    }
}

/// ST-Microelectronics' USB vendor id: an ST-Link's virtual COM port (Nucleo and
/// Discovery boards, the STM32F407's usual link).
const ST_VID: u16 = 0x0483;

/// `gantry ports`: this computer's serial ports, the likely boards first, one per line
/// with what the system says about them, and the command that talks to the first.
pub fn ports_text() -> Result<String> {
    let mut ports = serialport::available_ports().context("cannot list the serial ports")?;
    let rank = |p: &serialport::SerialPortInfo| match &p.port_type {
        serialport::SerialPortType::UsbPort(u) if u.vid == ST_VID => 0,
        serialport::SerialPortType::UsbPort(_) => 1,
        _ => 2,
    };
    ports.sort_by_key(|p| (rank(p), p.port_name.clone()));
    let mut out = String::new();
    for p in &ports {
        let what = match &p.port_type {
            serialport::SerialPortType::UsbPort(u) => format!(
                "USB {:04x}:{:04x} {}{}{}",
                u.vid,
                u.pid,
                u.manufacturer.as_deref().unwrap_or(""),
                u.product
                    .as_deref()
                    .map_or(String::new(), |s| format!(" {s}")),
                if u.vid == ST_VID {
                    "  (an ST-Link: likely the board)"
                } else {
                    ""
                }
            ),
            serialport::SerialPortType::PciPort => "PCI".into(),
            serialport::SerialPortType::BluetoothPort => "Bluetooth".into(),
            serialport::SerialPortType::Unknown => "unknown".into(),
        };
        out.push_str(&format!("{:<24} {what}\n", p.port_name));
    }
    match ports.first() {
        Some(p) if rank(p) < 2 => out.push_str(&format!(
            "talk to the board: gantry --port {} status\n",
            p.port_name
        )),
        _ => out.push_str(
            "no USB serial port found: is the board's USB cable in (an ST-Link shows up as /dev/ttyACM0)? \
             Without a board: `gantry sim serve /tmp/gantry` and `gantry --served /tmp/gantry status`\n",
        ),
    }
    Ok(out)
}
