//! The frequency response a machine measures for its host (issue 24, items 2 and 8 on a
//! board): [`Request::MeasureResponse`] starts the servo's stepped sine
//! (`servo::Command::MeasureResponse`), which keeps only its latest point; the record
//! takes each point as the control period sees it, in the order measured, and
//! [`Request::ResponseRead`] reads them back a few at a time once the measurement has
//! ended. The host sorts them and finds the modes (`sysid::frequency::find_modes`, the
//! same code `cargo sim freqresp` runs). 1.5 KiB in the machine's memory; zero bytes are
//! an empty record.

use super::messages::{
    Outcome, Request, ResponseChunk, ResponsePointMsg, ResponseState, RESPONSE_READ_CHUNK,
};
use crate::servo::identify::ResponseOutcome;
use crate::sysid::frequency::{ResponsePoint, MAX_POINTS};
use crate::sysid::IdentifyStatus;

/// The points of the last measurement, in the order measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResponseRecord {
    points: [ResponsePointMsg; MAX_POINTS],
    len: u8,
    /// The servo's index of the last point taken, plus one (0: none yet).
    seen: u8,
    /// The servo's identification run the points are from (`Servo::identify_runs`).
    run: u8,
}

impl Default for ResponseRecord {
    fn default() -> Self {
        Self::EMPTY
    }
}

const NOT_MEASURED: &str = "freqresp: no frequency response measured since the last identification";
const RUNNING: &str = "freqresp: the measurement is still running";
const PAST_END: &str = "freqresp: first point past the measured ones";

impl ResponseRecord {
    /// No points.
    pub const EMPTY: Self = Self {
        points: [ResponsePointMsg {
            freq_hz: 0.0,
            re: 0.0,
            im: 0.0,
        }; MAX_POINTS],
        len: 0,
        seen: 0,
        run: 0,
    };

    /// The servo's latest point (`Servo::response_point`) of its identification run
    /// `run` (`Servo::identify_runs`), taken once; the first point of a new run drops the
    /// last run's points (a refused measurement starts no run: they stay readable).
    pub fn collect(&mut self, run: u8, latest: Option<(u8, ResponsePoint)>) {
        let Some((n, p)) = latest else {
            return;
        };
        if run != self.run {
            self.run = run;
            self.len = 0;
            self.seen = 0;
        }
        let tag = n.saturating_add(1);
        if tag == self.seen {
            return;
        }
        self.seen = tag;
        if let Some(slot) = self.points.get_mut(usize::from(self.len)) {
            *slot = ResponsePointMsg {
                freq_hz: p.freq_hz,
                re: p.re,
                im: p.im,
            };
            self.len = self.len.saturating_add(1);
        }
    }

    /// The points taken so far.
    pub fn points(&self) -> &[ResponsePointMsg] {
        self.points.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// [`Request::ResponseRead`]: the points from `first` on, once the measurement
    /// `outcome` (`Servo::response_outcome`) has ended; `running`: the servo still
    /// identifies.
    pub fn read(&self, r: &Request, outcome: Option<ResponseOutcome>, running: bool) -> Outcome {
        let Request::ResponseRead { first } = r else {
            return Outcome::None;
        };
        if running {
            return Outcome::refused(RUNNING);
        }
        let Some(o) = outcome else {
            return Outcome::refused(NOT_MEASURED);
        };
        let first = usize::from(*first);
        let all = self.points();
        if first > all.len() {
            return Outcome::refused(PAST_END);
        }
        let mut points = heapless::Vec::new();
        for p in all.iter().skip(first).take(RESPONSE_READ_CHUNK) {
            let _ = points.push(*p);
        }
        Outcome::Response(ResponseChunk {
            axis: o.axis.index() as u8,
            state: if o.status == IdentifyStatus::Done {
                ResponseState::Done
            } else {
                ResponseState::Aborted
            },
            total: self.len,
            first: first as u8,
            points,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axes::Axis;

    fn point(f: f32) -> ResponsePoint {
        ResponsePoint {
            freq_hz: f,
            re: -f,
            im: 0.5 * f,
        }
    }

    fn done() -> Option<ResponseOutcome> {
        Some(ResponseOutcome {
            axis: Axis::Y,
            status: IdentifyStatus::Done,
            points: 9,
        })
    }

    /// Each point is taken once however many periods the servo reports it, in the order
    /// measured, and read back in chunks with the axis and the count.
    #[test]
    fn points_are_taken_once_and_read_in_chunks() {
        let mut r = ResponseRecord::EMPTY;
        for n in 0..9u8 {
            for _ in 0..3 {
                r.collect(1, Some((n, point(300.0 - 10.0 * f32::from(n)))));
            }
            r.collect(1, None);
        }
        assert_eq!(r.points().len(), 9);
        let read = |first| r.read(&Request::ResponseRead { first }, done(), false);
        let Outcome::Response(c) = read(6) else {
            panic!("a chunk: {:?}", read(6));
        };
        assert_eq!(
            (c.axis, c.state, c.total, c.first),
            (1, ResponseState::Done, 9, 6)
        );
        let f: heapless::Vec<f32, RESPONSE_READ_CHUNK> =
            c.points.iter().map(|p| p.freq_hz).collect();
        assert_eq!(f.as_slice(), [240.0, 230.0, 220.0]);
        assert_eq!(c.points[0].im, 120.0);
        let Outcome::Response(c) = read(0) else {
            panic!("a chunk");
        };
        assert_eq!(c.points.len(), RESPONSE_READ_CHUNK);
        let Outcome::Response(c) = read(9) else {
            panic!("an empty chunk at the end");
        };
        assert!(c.points.is_empty());
        assert_eq!(read(10), Outcome::refused(PAST_END));
    }

    /// Nothing is read while the measurement runs or when none was made; a new
    /// measurement drops the last one's points.
    #[test]
    fn refusals_and_restart() {
        let mut r = ResponseRecord::EMPTY;
        r.collect(1, Some((0, point(100.0))));
        r.collect(1, Some((1, point(90.0))));
        let q = Request::ResponseRead { first: 0 };
        assert_eq!(r.read(&q, done(), true), Outcome::refused(RUNNING));
        assert_eq!(r.read(&q, None, false), Outcome::refused(NOT_MEASURED));
        // a later run (a model identification sends no point) keeps them until its
        // first point
        r.collect(2, None);
        assert_eq!(r.points().len(), 2);
        // the servo's index restarts at 0 with the new run: the old points go
        r.collect(3, Some((0, point(300.0))));
        assert_eq!(r.points().len(), 1);
        assert_eq!(r.points()[0].freq_hz, 300.0);
        let aborted = Some(ResponseOutcome {
            axis: Axis::X,
            status: IdentifyStatus::Aborted(crate::sysid::AbortReason::LeftWindow),
            points: 1,
        });
        let Outcome::Response(c) = r.read(&q, aborted, false) else {
            panic!("a chunk");
        };
        assert_eq!((c.axis, c.state, c.total), (0, ResponseState::Aborted, 1));
    }
}
