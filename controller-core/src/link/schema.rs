//! The schema hash of a message set: what the handshake compares so that two ends built
//! from different message definitions refuse to talk (see [`super::handshake`]).
//!
//! It hashes both envelopes ([`ToDevice`], [`ToHost`]) with the application's command,
//! telemetry and status types, so it lives above the envelopes; the handshake only
//! carries the number.

use postcard_schema::key::Key;
use postcard_schema::Schema;

use super::envelope::{ToDevice, ToHost};

/// Schema hash of the message set: command type `C`, telemetry sample `T`, status `S`.
///
/// The FNV-1a 64 hash that `postcard-schema` computes over each envelope's schema (field
/// and variant names, order, and types, all the way down), the two combined and folded to
/// 32 bits. A `const fn`: the firmware gets it at compile time.
#[must_use]
pub const fn schema_hash<C: Schema, T: Schema, S: Schema>() -> u32 {
    let down = u64::from_le_bytes(Key::for_path::<ToDevice<C>>("gantry/link/to-device").to_bytes());
    let up = u64::from_le_bytes(Key::for_path::<ToHost<T, S>>("gantry/link/to-host").to_bytes());
    // Rotate one side so that two equal halves do not cancel.
    let h = down ^ up.rotate_left(29);
    (h ^ (h >> 32)) as u32
}
