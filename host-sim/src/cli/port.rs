//! `gantry --port DEV`: a board over its host UART (USART2, PA2/PA3, 921,600 baud 8N1:
//! an ST-Link virtual COM port such as `/dev/ttyACM0`, or any USB-UART adapter). The
//! host's clock is the wall clock.

use super::Transport;
use anyhow::{bail, Context, Result};
use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

/// The firmware's link baud rate (firmware `board::serial::HOST_BAUD`).
pub const BOARD_BAUD: u32 = 921_600;

/// An open serial line to a board.
pub struct BoardPort {
    port: Box<dyn serialport::SerialPort>,
    t0: Instant,
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
        })
    }
}

impl Transport for BoardPort {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        self.port.write_all(bytes).context("serial port write")?;
        Ok(())
    }

    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        let mut chunk = [0u8; 1024];
        loop {
            match self.port.read(&mut chunk) {
                Ok(0) => return Ok(()),
                Ok(n) => buf.extend_from_slice(&chunk[..n]),
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {
                    return Ok(())
                }
                Err(e) => bail!("serial port read: {e}"),
            }
        }
    }

    fn now_ms(&self) -> u32 {
        self.t0.elapsed().as_millis() as u32
    }

    fn wait(&mut self) -> Result<()> {
        std::thread::sleep(Duration::from_millis(1));
        Ok(())
    }
}
