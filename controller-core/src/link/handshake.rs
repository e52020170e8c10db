//! Handshake: protocol version, schema hash and session.
//!
//! The host opens a session by sending [`Hello`] (role host, a session id it chose); the
//! device answers with its own [`Hello`] (role device, the same session id) whatever the
//! outcome, so both sides see both versions. When the protocol version or the schema hash
//! differ, both sides report [`ProtocolMismatch`] naming ours and theirs, and the device
//! refuses commands until a matching handshake.
//!
//! The device's answer also carries its control rate: the host counts telemetry
//! decimations, capture lengths and timeouts in control periods, and learns their length
//! here rather than assuming it.
//!
//! The schema hash covers both envelopes with the application's message types (field
//! names, variant names and order, field types; see [`super::schema::schema_hash`]), so a
//! host and a firmware built from different message definitions cannot talk past each
//! other, as ODrive's interface CRC guarantees.
//!
//! The session id makes a stale or duplicated Hello harmless: the device restarts its
//! command numbering only for a Hello with a session id other than the current one.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::PROTOCOL_VERSION;

/// Which end of the link sent a [`Hello`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum Role {
    /// The PC (CLI, GUI).
    Host,
    /// The controller board.
    Device,
}

/// Handshake message, the same in both directions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub struct Hello {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u16,
    /// [`super::schema::schema_hash`] of the sender's message set.
    pub schema_hash: u32,
    /// Who sent it (a device that receives its own role is talking to an echo).
    pub role: Role,
    /// Session id chosen by the host, echoed by the device.
    pub session: u16,
    /// The sender's control rate, Hz: the device's control interrupt (what its telemetry
    /// decimation, periods and period-counted timeouts are counted in); 0 from a host,
    /// which runs no control loop.
    pub control_rate_hz: u32,
}

/// Protocol version and schema hash: what must match for two ends to talk.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub struct Version {
    /// Protocol (transport) version.
    pub protocol_version: u16,
    /// Hash of the message schema.
    pub schema_hash: u32,
}

impl Version {
    /// This build's protocol version with the given schema hash.
    #[must_use]
    pub const fn current(schema_hash: u32) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            schema_hash,
        }
    }

    /// The version a [`Hello`] announces.
    #[must_use]
    pub const fn of(hello: &Hello) -> Self {
        Self {
            protocol_version: hello.protocol_version,
            schema_hash: hello.schema_hash,
        }
    }

    /// A [`Hello`] announcing this version, from an end whose control loop runs at
    /// `control_rate_hz` (0 for a host).
    #[must_use]
    pub const fn hello(self, role: Role, session: u16, control_rate_hz: u32) -> Hello {
        Hello {
            protocol_version: self.protocol_version,
            schema_hash: self.schema_hash,
            role,
            session,
            control_rate_hz,
        }
    }
}

/// The two ends were built from different protocol versions or message schemas.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProtocolMismatch {
    /// This end.
    pub ours: Version,
    /// The other end.
    pub theirs: Version,
}

impl core::fmt::Display for ProtocolMismatch {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "link protocol mismatch: ours is protocol {} schema {:#010x}, theirs is protocol {} \
             schema {:#010x}; build the host tool and the firmware from the same version",
            self.ours.protocol_version,
            self.ours.schema_hash,
            self.theirs.protocol_version,
            self.theirs.schema_hash
        )
    }
}

/// Compare the other end's [`Hello`] with our version.
///
/// # Errors
/// [`ProtocolMismatch`] when the protocol version or the schema hash differ.
pub const fn check(ours: Version, theirs: &Hello) -> Result<(), ProtocolMismatch> {
    let theirs = Version::of(theirs);
    if ours.protocol_version == theirs.protocol_version && ours.schema_hash == theirs.schema_hash {
        Ok(())
    } else {
        Err(ProtocolMismatch { ours, theirs })
    }
}
