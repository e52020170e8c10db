//! The device end of the link for a machine: bytes in, bytes out. The firmware's link
//! task and the simulated machine (`gantry --sim`) both drive one: received bytes go to
//! [`Endpoint::on_bytes`], and [`Endpoint::poll`] runs after every batch of control
//! periods (watchdog, credit updates, status replies, telemetry). It reaches the machine
//! only through a [`MachinePort`] (the queues of [`super::port`]). Every reply is a
//! complete frame handed to `out`; nothing but frames goes on the wire.

use super::messages::{Request, Status, Telemetry, SCHEMA_HASH};
use super::port::{Down, MachinePort, Up};
use crate::link::{
    encode, DeviceEvent, DeviceLink, DeviceLinkConfig, Feed, FrameDecoder, LinkConfigError,
    ToDevice, ToHost, MAX_FRAME_LEN,
};

type Up_ = ToHost<Telemetry, Status>;

/// Link state of the device.
pub struct Endpoint {
    link: DeviceLink,
    decoder: FrameDecoder,
}

fn send(frame: &Up_, out: &mut impl FnMut(&[u8])) {
    let mut buf = [0u8; MAX_FRAME_LEN];
    // a frame that does not fit is a bug in the message sizes: dropped, never half-sent
    if let Ok(n) = encode(frame, &mut buf) {
        if let Some(b) = buf.get(..n) {
            out(b);
        }
    }
}

impl Endpoint {
    /// An endpoint with `config` for a machine whose control loop runs at
    /// `control_rate_hz` (the host learns it in the handshake).
    pub fn new(config: &DeviceLinkConfig, control_rate_hz: u32) -> Result<Self, LinkConfigError> {
        Ok(Self {
            link: DeviceLink::new(config, SCHEMA_HASH, control_rate_hz)?,
            decoder: FrameDecoder::new(),
        })
    }

    /// Frames dropped by the decoder so far (CRC, COBS or length errors).
    pub fn decode_errors(&self) -> u32 {
        self.decoder.stats().errors()
    }

    /// Bytes received at `now_ms`: decode every complete frame and act on it.
    pub fn on_bytes(
        &mut self,
        port: &mut impl MachinePort,
        mut bytes: &[u8],
        now_ms: u32,
        out: &mut impl FnMut(&[u8]),
    ) {
        loop {
            match self.decoder.feed::<ToDevice<Request>>(bytes) {
                Feed::NeedMore => return,
                Feed::Frame { result, rest } => {
                    bytes = rest;
                    // corrupt frames are counted by the decoder and dropped: the host
                    // retransmits what was not acknowledged
                    if let Ok(frame) = result {
                        self.on_frame(port, frame, now_ms, out);
                    }
                }
            }
        }
    }

    fn on_frame(
        &mut self,
        port: &mut impl MachinePort,
        frame: ToDevice<Request>,
        now_ms: u32,
        out: &mut impl FnMut(&[u8]),
    ) {
        let step = self.link.on_frame(frame, now_ms, port.free_slots());
        if let Some(r) = step.reply {
            send(&r.into_frame(), out);
        }
        match step.event {
            DeviceEvent::None | DeviceEvent::Mismatch(_) => {}
            DeviceEvent::SessionStarted { .. } => port.down(Down::SessionStarted),
            DeviceEvent::SessionEnded => port.down(Down::SessionEnded),
            DeviceEvent::Command(req) => port.down(Down::Request(req)),
            // answered with the status after the machine acted (next control period)
            DeviceEvent::Realtime { id, req } => port.down(Down::Realtime { id, req }),
            DeviceEvent::StatusOnly { id } => port.down(Down::StatusOnly { id }),
        }
    }

    /// After control periods at `now_ms`: watchdog (expiry stops the machine), credit
    /// updates, and the status replies and telemetry the machine handed up.
    pub fn poll(&mut self, port: &mut impl MachinePort, now_ms: u32, out: &mut impl FnMut(&[u8])) {
        port.poll();
        let p = self.link.poll(now_ms, port.free_slots());
        if p.link_lost {
            port.down(Down::LinkLost);
        }
        if let Some(r) = p.reply {
            send(&r.into_frame(), out);
        }
        while let Some(u) = port.up() {
            match u {
                Up::Status { id, status } => send(&Up_::Status { id, status }, out),
                Up::Telemetry(t) => {
                    if let Some(f) = self.link.telemetry::<Telemetry, Status>(t) {
                        send(&f, out);
                    }
                }
            }
        }
    }
}
