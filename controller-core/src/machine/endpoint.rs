//! The device end of the link for a [`Machine`]: bytes in, bytes out. The firmware's link
//! task and the simulated machine (`gantry --sim`) both drive one: received bytes go to
//! [`Endpoint::on_bytes`], and [`Endpoint::poll`] runs after every batch of control
//! periods (watchdog, credit updates, telemetry). Every reply is a complete frame handed
//! to `out`; nothing but frames goes on the wire.

use super::messages::{Request, Status, Telemetry, SCHEMA_HASH};
use super::Machine;
use crate::link::{
    encode, DeviceEvent, DeviceLink, DeviceLinkConfig, Feed, FrameDecoder, LinkConfigError,
    ToDevice, ToHost, MAX_FRAME_LEN,
};

type Up = ToHost<Telemetry, Status>;

/// Link state of the device.
pub struct Endpoint {
    link: DeviceLink,
    decoder: FrameDecoder,
    /// One telemetry frame every this many periods (0: none).
    decimation: u32,
    last_telemetry_period: u32,
}

fn send(frame: &Up, out: &mut impl FnMut(&[u8])) {
    let mut buf = [0u8; MAX_FRAME_LEN];
    // a frame that does not fit is a bug in the message sizes: dropped, never half-sent
    if let Ok(n) = encode(frame, &mut buf) {
        if let Some(b) = buf.get(..n) {
            out(b);
        }
    }
}

impl Endpoint {
    /// An endpoint with `config`; telemetry every `decimation` control periods (0: off).
    pub fn new(config: &DeviceLinkConfig, decimation: u32) -> Result<Self, LinkConfigError> {
        Ok(Self {
            link: DeviceLink::new(config, SCHEMA_HASH)?,
            decoder: FrameDecoder::new(),
            decimation,
            last_telemetry_period: 0,
        })
    }

    /// Bytes received at `now_ms`: decode every complete frame and act on it.
    pub fn on_bytes(
        &mut self,
        machine: &mut Machine,
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
                        self.on_frame(machine, frame, now_ms, out);
                    }
                }
            }
        }
    }

    fn on_frame(
        &mut self,
        machine: &mut Machine,
        frame: ToDevice<Request>,
        now_ms: u32,
        out: &mut impl FnMut(&[u8]),
    ) {
        let step = self.link.on_frame(frame, now_ms, machine.free_slots());
        if let Some(r) = step.reply {
            send(&r.into_frame(), out);
        }
        match step.event {
            DeviceEvent::None | DeviceEvent::Mismatch(_) => {}
            DeviceEvent::SessionStarted { .. } => machine.session_started(),
            DeviceEvent::Command(req) => machine.submit(req),
            DeviceEvent::Realtime { id, req } => {
                machine.realtime(req);
                send(
                    &ToHost::Status {
                        id,
                        status: machine.status(),
                    },
                    out,
                );
            }
            DeviceEvent::StatusOnly { id } => send(
                &ToHost::Status {
                    id,
                    status: machine.status(),
                },
                out,
            ),
        }
    }

    /// After control periods at `now_ms`: watchdog (expiry stops the machine), credit
    /// updates, and a telemetry frame when one is due.
    pub fn poll(&mut self, machine: &mut Machine, now_ms: u32, out: &mut impl FnMut(&[u8])) {
        let p = self.link.poll(now_ms, machine.free_slots());
        if p.link_lost {
            machine.link_lost();
        }
        if let Some(r) = p.reply {
            send(&r.into_frame(), out);
        }
        if self.decimation > 0 {
            let t = machine.telemetry();
            if t.period.wrapping_sub(self.last_telemetry_period) >= self.decimation {
                self.last_telemetry_period = t.period;
                if let Some(f) = self.link.telemetry::<Telemetry, Status>(t) {
                    send(&f, out);
                }
            }
        }
    }
}
