//! The envelope: what every frame carries, one enum per direction.
//!
//! A frame's payload is exactly one envelope, postcard-encoded. The envelope names the
//! channel and carries its sequence information; the application messages (commands,
//! telemetry samples, status replies) are type parameters, defined by the supervisor's
//! message set. Two enums instead of one make a frame in the wrong direction a parse error
//! rather than a runtime case.
//!
//! | direction | variant | channel |
//! |---|---|---|
//! | host → device | [`ToDevice::Hello`] / device → host [`ToHost::Hello`] | handshake |
//! | host → device | [`ToDevice::Heartbeat`] | watchdog feed on an idle link (answered by an ack) |
//! | host → device | [`ToDevice::Goodbye`] | the session ends cleanly (watchdog off, no `LinkLost`) |
//! | host → device | [`ToDevice::Command`] | reliable, windowed, credit flow control |
//! | device → host | [`ToHost::Ack`] | cumulative ack + free queue slots (credits) |
//! | device → host | [`ToHost::Nak`] | ack + "this frame came out of order": go back now |
//! | device → host | [`ToHost::Refused`] | command / request refused (no session, mismatch) |
//! | host → device | [`ToDevice::Realtime`] | hold / resume / stop / status, skips the queue |
//! | device → host | [`ToHost::Status`] | reply to a real-time request (acks it) |
//! | device → host | [`ToHost::Telemetry`] | unreliable, numbered, gaps counted |
//!
//! Variant order is part of the wire format (postcard writes the variant index): append
//! new variants at the end and bump [`super::PROTOCOL_VERSION`]; the schema hash changes
//! on its own.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::handshake::Hello;
use super::seq::Seq;

/// Real-time requests: executed on arrival, never queued behind commands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Schema)]
pub enum RealtimeRequest {
    /// Feed hold: decelerate along the path and wait.
    Hold,
    /// Resume after a hold.
    Resume,
    /// Controlled stop: decelerate, flush the command queue, disable motion.
    Stop,
    /// Only report the status.
    Status,
}

/// What a [`ToHost::Refused`] refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum RefusedFrame {
    /// The command with this sequence number.
    Command(Seq),
    /// The real-time request with this id.
    Realtime(Seq),
}

/// Why the device refused a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum Refusal {
    /// No handshake yet, or the session ended (watchdog expired, device restarted): the
    /// host must handshake again.
    NoSession,
    /// The last handshake found a protocol or schema mismatch.
    ProtocolMismatch,
}

/// Frames from the host to the device. `C` is the command message type.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum ToDevice<C> {
    /// Handshake request (role [`super::Role::Host`]).
    Hello(Hello),
    /// Keeps the device watchdog fed on an idle link; the device answers with an ack.
    Heartbeat,
    /// Reliable command number `seq`.
    Command {
        /// Sequence number on the command channel.
        seq: Seq,
        /// The command.
        cmd: C,
    },
    /// Real-time request number `id` (own numbering, see [`super::realtime`]).
    Realtime {
        /// Request id, echoed in the status reply.
        id: Seq,
        /// The request.
        req: RealtimeRequest,
    },
    /// The host ends its session cleanly (a `gantry` command that finished, a GUI that
    /// closes): the device's watchdog is disarmed without a `LinkLost` fault, and what the
    /// host started that needs it (a streaming program, a jog) comes to a controlled stop;
    /// the machine otherwise stays as it is (armed and holding, homed, its settings), as
    /// a board stays between two sessions. Not answered.
    Goodbye,
}

/// Frames from the device to the host. `T` is the telemetry sample type, `S` the status.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum ToHost<T, S> {
    /// Handshake reply (role [`super::Role::Device`]), sent whatever the outcome.
    Hello(Hello),
    /// Cumulative ack: every command up to and including `seq` was accepted; the command
    /// queue has `credits` free slots after it.
    Ack {
        /// Last command accepted in order.
        seq: Seq,
        /// Free command queue slots: the host may have this many commands in flight.
        credits: u16,
    },
    /// Negative ack: command `got` arrived out of order and was dropped; the fields
    /// `seq` and `credits` are as in [`ToHost::Ack`]. The host sends again from `seq + 1`.
    Nak {
        /// Last command accepted in order.
        seq: Seq,
        /// Free command queue slots.
        credits: u16,
        /// The out-of-order command that was dropped.
        got: Seq,
    },
    /// A command or request was not executed.
    Refused {
        /// Which frame.
        what: RefusedFrame,
        /// Why.
        reason: Refusal,
    },
    /// Telemetry frame number `seq` (never retransmitted).
    Telemetry {
        /// Telemetry sequence number; gaps are lost frames.
        seq: Seq,
        /// The sample.
        sample: T,
    },
    /// Reply to real-time request `id` (also the request's ack).
    Status {
        /// The request id answered.
        id: Seq,
        /// The device status.
        status: S,
    },
}

impl<C> ToDevice<C> {
    /// The same frame with the command borrowed: it encodes to identical bytes, so a
    /// sender can keep its commands and encode references to them.
    pub fn as_ref(&self) -> ToDevice<&C> {
        match self {
            Self::Hello(h) => ToDevice::Hello(*h),
            Self::Heartbeat => ToDevice::Heartbeat,
            Self::Command { seq, cmd } => ToDevice::Command { seq: *seq, cmd },
            Self::Realtime { id, req } => ToDevice::Realtime { id: *id, req: *req },
            Self::Goodbye => ToDevice::Goodbye,
        }
    }
}
