//! Host link protocol: the transport shared by the firmware (USART2 at 921,600 baud) and
//! the host tools. `no_std`, no allocation, no clocks inside: every call that depends on
//! time takes the caller's monotonic millisecond counter (`u32`, wrapping; a device
//! counts it from its control periods with [`LinkClock`]).
//!
//! Layers, bottom up (full description in `docs/link-protocol.md`):
//! - [`frame`]: `COBS(postcard(envelope) ++ CRC-32) ++ 0x00`; streaming [`FrameDecoder`]
//!   with a fixed buffer, counted errors and resync at the next delimiter.
//! - [`envelope`]: [`ToDevice`] / [`ToHost`], one enum per direction, naming the channel
//!   and its sequence numbers; generic over the application's command, telemetry and
//!   status types.
//! - [`handshake`]: [`Hello`] with protocol version, schema hash, session id and the
//!   device's control rate; [`ProtocolMismatch`] on both sides when they differ.
//! - [`schema`]: [`schema_hash`], the hash of both envelopes with the application's types.
//! - Channels: [`command`] (reliable, windowed, credit flow control), [`telemetry`]
//!   (unreliable, gaps counted), [`realtime`] (hold/resume/stop/status, outside the
//!   queue), [`watchdog`] (heartbeat, expiry → controlled stop + `LinkLost`).
//! - Ends: [`DeviceLink`] (firmware link task) and [`HostLink`] (host tool) tie the
//!   channels together; each is driven by "frame received" and "poll" calls.
//! - [`clock`]: [`LinkClock`], the device's link time in ms counted from control periods.
//! - [`kernels`]: fixed-input decode/encode functions for instruction counting.
//!
//! The application's message types must implement `serde::Serialize`,
//! `serde::de::DeserializeOwned` and `postcard_schema::Schema` (derive all three); the
//! schema hash in the handshake is computed from them by [`schema_hash`].

pub mod clock;
pub mod command;
pub mod device;
pub mod envelope;
pub mod frame;
pub mod handshake;
pub mod host;
pub mod kernels;
pub mod realtime;
pub mod schema;
pub mod seq;
pub mod telemetry;
pub mod watchdog;

pub use clock::LinkClock;
pub use command::{Ack, CommandConfig, CommandReceiver, CommandSender, Receipt};
pub use device::{
    DeviceEvent, DeviceLink, DeviceLinkConfig, DevicePoll, DeviceSession, DeviceStep, Reply,
};
pub use envelope::{RealtimeRequest, Refusal, RefusedFrame, ToDevice, ToHost};
pub use frame::{
    encode, DecodeStats, EncodeError, Feed, FrameDecoder, FrameError, MAX_FRAME_LEN,
    MAX_PAYLOAD_LEN,
};
pub use handshake::{Hello, ProtocolMismatch, Role, Version};
pub use host::{HostEvent, HostLink, HostLinkConfig, HostState, LinkError};
pub use schema::schema_hash;
pub use seq::Seq;
pub use telemetry::{Arrival, TelemetryReceiver, TelemetrySender};
pub use watchdog::{Watchdog, WatchdogConfig};

/// Transport protocol version, sent in the handshake. Bump it whenever the framing, the
/// envelopes or the channel rules change (the schema hash alone catches type changes, not
/// rule changes). 3: the handshake's [`Hello`] carries the device's control rate.
pub const PROTOCOL_VERSION: u16 = 3;

/// A link setting out of its valid range; names the field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkConfigError {
    /// The named setting is outside its documented range.
    OutOfRange(&'static str),
}

impl core::fmt::Display for LinkConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::OutOfRange(name) => write!(f, "link config: {name} out of range"),
        }
    }
}

#[cfg(test)]
mod tests;
