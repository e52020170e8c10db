//! A recording of everything that enters the machine behind the link, period by period,
//! and a digest of what it did: the QEMU link rig records them (firmware
//! `qemu::link`), host-sim replays the records into the same machine and world and
//! compares the digests bit for bit (host-sim `studies::machine_replay`).
//!
//! What enters the machine ([`Machine::linked_period`]) in a period, all recorded:
//!
//! - the link's events it takes ([`Down`], and a [`Down::Apply`]'s settings tree), as
//!   [`Machine::linked_period_seen`] shows them;
//! - the operator panel's e-stop, set in the world before the period
//!   ([`Record::Estop`]);
//! - the planning half's runs since the last period ([`Record::Plan`], only when it is
//!   not exactly one run: the firmware spawns it once after every period; a period that
//!   found it still running — preempted, so partly run — cannot be replayed and says so).
//!
//! Nothing else reaches it: the link's clock and the link side's state (credit, settings
//! agent, saves) act only through the events; replies and telemetry go up and come back
//! to the machine only as events.
//!
//! The digest ([`Digest`]): per period a 64-bit FNV-1a over the bit patterns of the
//! servo's snapshot after the period (period counter, state, fault, inputs, positions,
//! velocities, references, errors, efforts, wide counts, outputs, brakes), chained over
//! the periods; per period also a 16-bit fold of its own hash ([`Digest::fold`]), so a
//! difference is named to the period.
//!
//! [`Machine::linked_period`]: super::Machine::linked_period
//! [`Machine::linked_period_seen`]: super::Machine::linked_period_seen

use serde::{Deserialize, Serialize};

use super::port::Down;
use super::Seen;
use crate::servo::snapshot::Snapshot;
use crate::settings::Settings;

/// One input of a period, as recorded ([`RecordRef`] is the same, by reference).
#[derive(Clone, Debug, PartialEq, Deserialize)]
// (a settings tree is one record of a whole session: not worth a box on the host)
#[allow(clippy::large_enum_variant)]
pub enum Record {
    /// An event the machine took from the link.
    Down(Down),
    /// The tree of the [`Down::Apply`] before it.
    Settings(Settings),
    /// The operator panel set the world's e-stop input (pressed or released) before the
    /// period.
    Estop(bool),
    /// The planning half ran `runs` times since the last period (recorded when not
    /// once); `busy`: it was still running (preempted by the period).
    Plan { runs: u32, busy: bool },
}

/// [`Record`] for serialising without a copy (the same encoding: serde writes a
/// reference as its value; `tests::refs_encode_as_records`).
#[derive(Clone, Copy, Debug, Serialize)]
pub enum RecordRef<'a> {
    Down(&'a Down),
    Settings(&'a Settings),
    Estop(bool),
    Plan { runs: u32, busy: bool },
}

impl<'a> From<Seen<'a>> for RecordRef<'a> {
    fn from(s: Seen<'a>) -> Self {
        match s {
            Seen::Down(d) => Self::Down(d),
            Seen::Settings(s) => Self::Settings(s),
        }
    }
}

/// Periods per block of per-period digests (one log line of the QEMU link rig).
pub const BLOCK_PERIODS: usize = 100;

/// A period's records, postcard-encoded one after the other in a buffer of `N` bytes.
pub struct Recorder<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// A record did not fit: the recording is incomplete.
    overflowed: bool,
}

impl<const N: usize> Default for Recorder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Recorder<N> {
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            overflowed: false,
        }
    }

    /// Append `r` (or note that it did not fit).
    pub fn note(&mut self, r: RecordRef<'_>) {
        match postcard::to_slice(&r, &mut self.buf[self.len..]) {
            Ok(used) => self.len += used.len(),
            Err(_) => self.overflowed = true,
        }
    }

    /// The records so far, and whether one was lost; then empty.
    pub fn take(&mut self) -> (&[u8], bool) {
        let (len, lost) = (self.len, self.overflowed);
        self.len = 0;
        self.overflowed = false;
        (&self.buf[..len], lost)
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0 && !self.overflowed
    }
}

/// The records of one period, decoded in order.
pub fn records(mut bytes: &[u8]) -> impl Iterator<Item = Result<Record, postcard::Error>> + '_ {
    core::iter::from_fn(move || {
        if bytes.is_empty() {
            return None;
        }
        match postcard::take_from_bytes::<Record>(bytes) {
            Ok((r, rest)) => {
                bytes = rest;
                Some(Ok(r))
            }
            Err(e) => {
                bytes = &[];
                Some(Err(e))
            }
        }
    })
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a over bit patterns.
struct Fnv(u64);

impl Fnv {
    #[inline]
    fn word(&mut self, w: u32) {
        for b in w.to_le_bytes() {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(FNV_PRIME);
        }
    }
    fn f32s(&mut self, v: &[f32]) {
        for x in v {
            self.word(x.to_bits());
        }
    }
}

/// The running digest of a machine's periods (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Digest(pub u64);

impl Default for Digest {
    fn default() -> Self {
        Self::new()
    }
}

impl Digest {
    pub const fn new() -> Self {
        Self(FNV_OFFSET)
    }

    /// The 64-bit hash of one snapshot's bit patterns.
    pub fn of(s: &Snapshot) -> u64 {
        let mut h = Fnv(FNV_OFFSET);
        h.word(s.period);
        h.word(s.motion_t_s.to_bits());
        h.word(s.state as u32);
        match s.fault {
            Some(f) => {
                h.word(1 + f.fault.kind as u32);
                h.word(f.fault.axis.map_or(9, |a| a as u32));
                h.word(f.period);
                h.word(f.value.to_bits());
            }
            None => h.word(0),
        }
        h.word(s.fault_bits.0);
        for b in s.fault_bits.1 {
            h.word(b);
        }
        let i = &s.inputs;
        let mut bits = u32::from(i.estop) | u32::from(i.overrun) << 1;
        for a in 0..i.limits.len() {
            bits |= u32::from(i.limits[a][0]) << (2 + 4 * a);
            bits |= u32::from(i.limits[a][1]) << (3 + 4 * a);
            bits |= u32::from(i.amp_fault[a]) << (4 + 4 * a);
            bits |= u32::from(s.brakes_released[a]) << (5 + 4 * a);
        }
        h.word(bits);
        h.word(
            u32::from(s.homed) | u32::from(s.model_missing) << 8 | u32::from(s.outputs_on) << 16,
        );
        h.word(s.progress.to_bits());
        h.f32s(&s.pos);
        h.f32s(&s.vel);
        h.f32s(&s.reference);
        h.f32s(&s.tracking);
        h.f32s(&s.contour);
        h.f32s(&s.s);
        h.f32s(&s.effort);
        for c in s.counts {
            h.word(c as u32);
            h.word((c >> 32) as u32);
        }
        for c in s.index_corrected_counts {
            h.word(c as u32);
        }
        h.0
    }

    /// Fold the snapshot after a period into the running digest; the period's own 16-bit
    /// tag.
    pub fn fold(&mut self, s: &Snapshot) -> u16 {
        let h = Self::of(s);
        self.0 = (self.0 ^ h).wrapping_mul(FNV_PRIME);
        (h ^ h >> 16 ^ h >> 32 ^ h >> 48) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::{RealtimeRequest, Seq};
    use crate::machine::messages::Request;
    use crate::motion::planner::Segment;
    use crate::settings::FACTORY;

    #[test]
    fn refs_encode_as_records() {
        let seg = Down::Request(Request::Segment(Segment::line([1.0, 2.0, 3.0], 60.0, 7)));
        let rt = Down::Realtime {
            id: Seq(3),
            req: RealtimeRequest::Hold,
        };
        let mut rec = Recorder::<2048>::new();
        rec.note(RecordRef::Plan {
            runs: 0,
            busy: false,
        });
        rec.note(RecordRef::Down(&seg));
        rec.note(RecordRef::Down(&Down::Apply { class: None }));
        rec.note(RecordRef::Settings(&FACTORY));
        rec.note(RecordRef::Estop(true));
        rec.note(RecordRef::Down(&rt));
        let (bytes, lost) = rec.take();
        assert!(!lost);
        let got: heapless::Vec<Record, 8> = records(bytes).map(Result::unwrap).collect();
        assert_eq!(
            got[..],
            [
                Record::Plan {
                    runs: 0,
                    busy: false
                },
                Record::Down(seg),
                Record::Down(Down::Apply { class: None }),
                Record::Settings(FACTORY),
                Record::Estop(true),
                Record::Down(rt),
            ]
        );
        assert!(rec.is_empty());
    }

    #[test]
    fn a_record_that_does_not_fit_is_reported() {
        let mut rec = Recorder::<64>::new();
        rec.note(RecordRef::Settings(&FACTORY));
        assert!(rec.take().1);
    }

    #[test]
    fn one_bit_changes_the_digest() {
        let s = Snapshot::boot();
        let mut t = s;
        t.pos[1] = f32::from_bits(t.pos[1].to_bits() ^ 1);
        assert_ne!(Digest::of(&s), Digest::of(&t));
        let (mut a, mut b) = (Digest::new(), Digest::new());
        assert_ne!(a.fold(&s), b.fold(&t));
        assert_ne!(a, b);
    }
}
