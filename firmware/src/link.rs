//! The host link task: bytes from the UART's receive queue through the link's device end
//! ([`Endpoint`]: frames, sessions, acks and credit, watchdog) to the machine's queues
//! ([`LinkSide`]), and the replies, acks and telemetry frames back into the UART's
//! transmit queue. It runs every millisecond at a priority below the control interrupt
//! and never touches the machine or the UART itself (see `board::serial`).
//!
//! A settings save is written here, never in the control interrupt: once the machine holds
//! its outputs off, the task's [`SettingsSaver`] writes the flash (the board's sectors with
//! the watchdog stretched; in QEMU, which models no flash controller, a store in RAM). The
//! application (`main.rs`) picks the saver for the build; this module knows neither.
//!
//! The link's clock is the control clock: [`LINK_CLOCK_MS`], the machine time the control
//! interrupt publishes (periods run × period, counted by controller-core's
//! [`controller_core::link::LinkClock`] as the simulated machine counts it), so the
//! watchdog and every timeout count control periods — on the board that is real time, in
//! QEMU it is the emulated machine's time, whatever the emulator's speed.

use core::sync::atomic::{AtomicU32, Ordering};

use controller_core::link::device::DEFAULT_DEVICE_LINK_CONFIG;
use controller_core::machine::{Endpoint, LinkEnds, LinkSide, LinkState};
use controller_core::settings::Settings;
use heapless::spsc::{Consumer, Producer};

/// Machine time, ms, published by the control interrupt after every period.
pub static LINK_CLOCK_MS: AtomicU32 = AtomicU32::new(0);

/// Bytes handed to the endpoint per call.
const CHUNK: usize = 64;

/// Where the link task writes settings saves.
pub trait SettingsSaver {
    /// Write a save or repair that is due on `port` (the machine holds its outputs off);
    /// nothing when none is due.
    fn save_due(&mut self, port: &mut LinkSide<'_, '_>);
}

/// The link task's state; its settings saves go to `S`.
pub struct LinkTask<S> {
    endpoint: Endpoint,
    ends: Option<LinkEnds<'static>>,
    state: LinkState,
    rx: Consumer<'static, u8>,
    tx: Producer<'static, u8>,
    /// Frames dropped whole because the transmit queue had no room for them.
    tx_dropped: u32,
    saver: S,
}

impl<S: SettingsSaver> LinkTask<S> {
    /// The link with the default device configuration (500 ms watchdog), for a machine
    /// that runs `settings` at `rate_hz` (the rate the host is told in the handshake).
    pub fn new(
        ends: LinkEnds<'static>,
        settings: &Settings,
        rate_hz: u32,
        rx: Consumer<'static, u8>,
        tx: Producer<'static, u8>,
        saver: S,
    ) -> Option<Self> {
        let endpoint = Endpoint::new(&DEFAULT_DEVICE_LINK_CONFIG, rate_hz).ok()?;
        Some(Self {
            endpoint,
            ends: Some(ends),
            state: LinkState::new(settings, rate_hz),
            rx,
            tx,
            tx_dropped: 0,
            saver,
        })
    }

    /// One run: what arrived, then the watchdog, replies and telemetry. Returns whether
    /// bytes wait to be sent (the caller pends the UART interrupt).
    pub fn run(&mut self) -> bool {
        let now_ms = LINK_CLOCK_MS.load(Ordering::Acquire);
        let Some(ends) = self.ends.take() else {
            return false;
        };
        let mut port = LinkSide::new(ends, &mut self.state);
        let (tx, dropped) = (&mut self.tx, &mut self.tx_dropped);
        let mut out = |frame: &[u8]| {
            // a frame goes out whole or not at all (the host retransmits)
            if tx.capacity() - tx.len() < frame.len() {
                *dropped = dropped.wrapping_add(1);
                return;
            }
            for &b in frame {
                let _ = tx.enqueue(b);
            }
        };
        let mut buf = [0u8; CHUNK];
        loop {
            let mut n = 0;
            for slot in buf.iter_mut() {
                match self.rx.dequeue() {
                    Some(b) => {
                        *slot = b;
                        n += 1;
                    }
                    None => break,
                }
            }
            if n == 0 {
                break;
            }
            self.endpoint
                .on_bytes(&mut port, buf.get(..n).unwrap_or(&[]), now_ms, &mut out);
        }
        self.endpoint.poll(&mut port, now_ms, &mut out);
        self.saver.save_due(&mut port);
        self.ends = Some(port.into_ends());
        !self.tx.is_empty()
    }

    /// Frames dropped for want of room in the transmit queue, and frames the decoder
    /// dropped (CRC, COBS, length).
    pub fn dropped(&self) -> (u32, u32) {
        (self.tx_dropped, self.endpoint.decode_errors())
    }
}
