//! What the window knows of the machine, from the session's tapped status and telemetry:
//! the newest status, the newest sample, the last seconds of samples for the live plots,
//! and the executed tool path (the trail) with its contour error. Bounded whatever the
//! program's length: the plots keep [`HISTORY_S`] seconds, the trail halves its density
//! when it reaches [`TRAIL_MAX`] points.

use controller_core::machine::messages::{MachineState, Status, Telemetry};
use host_sim::cli::client::Tapped;
use std::collections::VecDeque;
use std::sync::mpsc::Receiver;

/// Seconds of telemetry the live plots keep.
pub const HISTORY_S: f64 = 10.0;
/// Points the trail keeps at most (then every other one goes).
pub const TRAIL_MAX: usize = 200_000;

/// One point of the executed path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrailPoint {
    pub pos_mm: [f32; 3],
    pub contour_mm: f32,
}

/// The machine as the window sees it.
#[derive(Debug)]
pub struct Live {
    /// The machine's control rate, Hz, as it reported it on connecting (telemetry periods
    /// count it); 0 before a machine is connected.
    pub rate_hz: u32,
    /// Control periods between telemetry samples.
    pub decimation: u32,
    pub status: Option<Status>,
    pub latest: Option<Telemetry>,
    /// The telemetry's signal names, in order.
    pub signals: Vec<String>,
    /// The last [`HISTORY_S`] seconds of samples.
    pub history: VecDeque<Telemetry>,
    /// The path executed in programs since the last [`Live::clear_trail`].
    pub trail: Vec<TrailPoint>,
    /// Keep every `trail_every`-th sample of a run (doubles each time the trail halves).
    trail_every: u32,
    trail_count: u32,
    /// Samples received in all.
    pub samples: u64,
}

impl Default for Live {
    fn default() -> Self {
        Self {
            // (no machine yet: its rate comes with the connection)
            rate_hz: 0,
            decimation: 10,
            status: None,
            latest: None,
            signals: Vec::new(),
            history: VecDeque::new(),
            trail: Vec::new(),
            trail_every: 1,
            trail_count: 0,
            samples: 0,
        }
    }
}

impl Live {
    /// Take everything the session tapped so far; how many items.
    pub fn drain(&mut self, rx: &Receiver<Tapped>) -> usize {
        let mut n = 0;
        while let Ok(t) = rx.try_recv() {
            self.take(t);
            n += 1;
        }
        n
    }

    /// Take one tapped item.
    pub fn take(&mut self, t: Tapped) {
        match t {
            Tapped::Status(s) => self.status = Some(s),
            Tapped::Telemetry(t) => self.sample(t),
        }
    }

    fn sample(&mut self, t: Telemetry) {
        self.samples += 1;
        if matches!(t.state, MachineState::Run { .. }) {
            self.trail_count += 1;
            if self.trail_count >= self.trail_every {
                self.trail_count = 0;
                self.trail.push(TrailPoint {
                    pos_mm: t.pos_mm,
                    contour_mm: t.contour_mm,
                });
                if self.trail.len() >= TRAIL_MAX {
                    let kept: Vec<TrailPoint> = self.trail.iter().step_by(2).copied().collect();
                    self.trail = kept;
                    self.trail_every = self.trail_every.saturating_mul(2);
                }
            }
        }
        let keep = (HISTORY_S * f64::from(self.rate_hz)) as u32;
        while self
            .history
            .front()
            .is_some_and(|f| t.period.wrapping_sub(f.period) > keep)
        {
            self.history.pop_front();
        }
        self.history.push_back(t.clone());
        self.latest = Some(t);
    }

    /// Forget the executed path (a new program).
    pub fn clear_trail(&mut self) {
        self.trail.clear();
        self.trail_every = 1;
        self.trail_count = 0;
    }

    /// Machine time of a sample, s.
    pub fn time_s(&self, t: &Telemetry) -> f64 {
        f64::from(t.period) / f64::from(self.rate_hz.max(1))
    }

    /// The newest position: the newest sample's, else the status'.
    pub fn pos_mm(&self) -> Option<[f32; 3]> {
        self.latest
            .as_ref()
            .map(|t| t.pos_mm)
            .or(self.status.as_ref().map(|s| s.pos_mm))
    }

    /// Index of signal `name` in each sample's signals.
    pub fn signal_index(&self, name: &str) -> Option<usize> {
        self.signals.iter().position(|s| s == name)
    }
}
