//! Wrapping 16-bit sequence numbers with serial-number arithmetic (RFC 1982).
//!
//! Every channel numbers its frames with a [`Seq`] that wraps from 65535 to 0. Two
//! numbers are compared by their signed distance `a - b` taken modulo 2^16 and read as an
//! `i16`: `a` is "after" `b` when the distance is in 1..=32767. This is correct across the
//! wrap as long as the numbers compared are less than 32768 apart, which the command
//! window (a few frames) and the telemetry gap history guarantee.
//!
//! Why 16 bits: postcard writes integers as varints, so a `u16` costs 1 to 3 bytes on the
//! wire where a `u32` would cost up to 5, and every telemetry frame carries one.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

/// A wrapping frame sequence number.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, Schema)]
pub struct Seq(pub u16);

impl Seq {
    /// The first sequence number of a fresh channel.
    pub const ZERO: Seq = Seq(0);

    /// The number after this one (wraps from 65535 to 0).
    #[must_use]
    pub const fn next(self) -> Seq {
        Seq(self.0.wrapping_add(1))
    }

    /// The number before this one (wraps from 0 to 65535).
    #[must_use]
    pub const fn prev(self) -> Seq {
        Seq(self.0.wrapping_sub(1))
    }

    /// This number advanced by `n` (wrapping).
    #[must_use]
    pub const fn add(self, n: u16) -> Seq {
        Seq(self.0.wrapping_add(n))
    }

    /// Signed serial distance `self - other`, in -32768..=32767. Positive means `self`
    /// comes after `other`.
    #[must_use]
    pub const fn diff(self, other: Seq) -> i16 {
        self.0.wrapping_sub(other.0) as i16
    }

    /// True when `self` comes strictly after `other` in serial order.
    #[must_use]
    pub const fn is_after(self, other: Seq) -> bool {
        self.diff(other) > 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_is_correct_across_the_wrap() {
        assert_eq!(Seq(0).diff(Seq(65535)), 1);
        assert_eq!(Seq(65535).diff(Seq(0)), -1);
        assert_eq!(Seq(5).diff(Seq(65530)), 11);
        assert!(Seq(2).is_after(Seq(65534)));
        assert!(!Seq(65534).is_after(Seq(2)));
        assert_eq!(Seq(65535).next(), Seq(0));
        assert_eq!(Seq(0).prev(), Seq(65535));
        assert_eq!(Seq(65530).add(10), Seq(4));
        // The largest distance still read as "after".
        assert_eq!(Seq(32767).diff(Seq(0)), 32767);
        assert_eq!(Seq(32768).diff(Seq(0)), -32768);
    }
}
