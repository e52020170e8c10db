//! Backlash and lead-screw compensation entered over the link (issue 24, item 6): the
//! host sends an axis' table in parts ([`Request::CompBegin`], [`Request::CompPoints`] in
//! order, [`Request::CompCommit`]), each part validated as it comes
//! ([`CompBuilder`], the same checks as a table entered whole), and the machine puts it
//! in use at a period boundary with its outputs off; [`Request::CompRead`] reads a table
//! in use back, a few points at a time. Executed in the control period: a part costs a
//! few hundred cycles, a commit a 2 KiB copy, and no refusal is formatted (the messages
//! are `CompError::message`'s).
//!
//! The tables are kept in RAM (the machine's memory) until the next boot: the host loads
//! them each session (`gantry comp load`), as LinuxCNC reads its `COMP_FILE`s at start;
//! the status says which axes carry one ([`super::messages::Status::comp`]).

use super::messages::{CompChunk, Outcome, Request, COMP_READ_CHUNK};
use crate::axes::Axis;
use crate::motion::compensation::{CompBuilder, CompTables};

/// The transfer under way, if any: the axis and the table entered so far (2 KiB, in the
/// machine's memory; zero bytes are none under way).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompEntry {
    /// Axis index + 1 of the transfer under way (0: none).
    axis: u8,
    builder: CompBuilder,
}

impl Default for CompEntry {
    fn default() -> Self {
        Self::NONE
    }
}

const NO_TRANSFER: &str = "comp: no table transfer under way (send comp begin first)";
const BAD_AXIS: &str = "comp: axis must be 0, 1 or 2";

impl CompEntry {
    /// No transfer under way.
    pub const NONE: Self = Self {
        axis: 0,
        builder: CompBuilder::NONE,
    };

    /// Drop a transfer under way (a new session: a table half entered by another host is
    /// never committed).
    pub fn drop_transfer(&mut self) {
        self.axis = 0;
    }

    /// Execute `r` (a `Comp*` request): `tables` are the machine's in use;
    /// `outputs_on`: the servo drives its outputs (a commit is refused then).
    pub fn execute(&mut self, tables: &mut CompTables, r: &Request, outputs_on: bool) -> Outcome {
        match r {
            Request::CompBegin {
                axis,
                points,
                backlash_mm,
                rate_mm_s,
                accel_mm_s2,
            } => {
                self.axis = 0;
                let Some(a) = Axis::from_index(usize::from(*axis)) else {
                    return Outcome::refused(BAD_AXIS);
                };
                match CompBuilder::begin(
                    usize::from(*points),
                    *backlash_mm,
                    *rate_mm_s,
                    *accel_mm_s2,
                ) {
                    Ok(b) => {
                        self.builder = b;
                        self.axis = a.index() as u8 + 1;
                        Outcome::Done
                    }
                    Err(e) => Outcome::refused(e.message()),
                }
            }
            Request::CompPoints { first, points } => {
                if self.axis == 0 {
                    return Outcome::refused(NO_TRANSFER);
                }
                match self.builder.push(usize::from(*first), points) {
                    Ok(()) => Outcome::Done,
                    Err(e) => Outcome::refused(e.message()),
                }
            }
            Request::CompCommit => {
                let Some(axis) = usize::from(self.axis).checked_sub(1) else {
                    return Outcome::refused(NO_TRANSFER);
                };
                if outputs_on {
                    return Outcome::refused(
                        "comp: the outputs are on; disarm first (a new table moves the reference)",
                    );
                }
                match self.builder.finish() {
                    Ok(t) => {
                        tables.set(axis, t);
                        self.axis = 0;
                        Outcome::Done
                    }
                    Err(e) => Outcome::refused(e.message()),
                }
            }
            Request::CompRead { axis, first } => {
                let Some(a) = Axis::from_index(usize::from(*axis)) else {
                    return Outcome::refused(BAD_AXIS);
                };
                let t = tables.axis(a.index());
                let mut points = heapless::Vec::new();
                let from = usize::from(*first);
                for i in from..from.saturating_add(COMP_READ_CHUNK) {
                    match t.point(i) {
                        Some(p) => {
                            let _ = points.push(p);
                        }
                        None => break,
                    }
                }
                Outcome::Comp(CompChunk {
                    axis: *axis,
                    total: t.len() as u16,
                    first: *first,
                    backlash_mm: t.backlash_mm(),
                    rate_mm_s: t.rate_mm_s(),
                    accel_mm_s2: t.accel_mm_s2(),
                    points,
                })
            }
            _ => Outcome::refused("comp: not a compensation request"),
        }
    }
}
