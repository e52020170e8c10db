//! The machine's scope: chosen signals recorded at the control rate (or every n-th
//! period) into a fixed buffer, with a pre-trigger window, triggered at once, on a fault,
//! or on a signal crossing a level; then read out over the link in chunks.
//!
//! It runs in the control period after the servo step ([`Scope::record`]: a few loads and
//! stores per channel, no formatting), so what it records is what the period computed.
//! The buffer holds [`SCOPE_VALUES`] values shared by the channels (4 channels × 512
//! samples, or 1 × 2048).

use heapless::Vec;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use crate::motion::planner::PathSample;
use crate::servo::snapshot::Snapshot;

/// Values the scope buffer holds (all channels together): 8 KiB of RAM.
pub const SCOPE_VALUES: usize = 2048;
/// Channels at most.
pub const SCOPE_CHANNELS: usize = 4;
/// Values per read-out chunk (one status frame carries one chunk).
pub const SCOPE_CHUNK: usize = 16;

/// A signal of the control period, as the scope records it (mm, mm/s, effort units).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum Signal {
    /// Measured position of axis 0/1/2, mm.
    Pos(u8),
    /// Reference position, mm.
    Ref(u8),
    /// Estimated velocity, mm/s.
    Vel(u8),
    /// Tracking error (reference - measured), mm.
    Tracking(u8),
    /// Applied (saturated) effort; 0 with the outputs off.
    Effort(u8),
    /// Sliding variable (0 for PID axes).
    Sliding(u8),
    /// The planner's reference velocity, mm/s.
    RefVel(u8),
    /// Norm of the contour-error estimate, mm.
    Contour,
    /// The planner's feed ratio (actual / programmed feed).
    FeedRatio,
}

/// A per-axis signal's constructor.
type AxisSignal = fn(u8) -> Signal;

/// Names of the per-axis signals, as `gantry scope --signals` spells them (`pos.x`).
const AXIS_SIGNALS: [(&str, AxisSignal); 7] = [
    ("pos", Signal::Pos),
    ("ref", Signal::Ref),
    ("vel", Signal::Vel),
    ("tracking", Signal::Tracking),
    ("effort", Signal::Effort),
    ("sliding", Signal::Sliding),
    ("ref_vel", Signal::RefVel),
];
const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

impl Signal {
    /// The signal named `name` (`pos.x`, `tracking.z`, `contour`, `feed_ratio`, …).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "contour" => return Some(Self::Contour),
            "feed_ratio" => return Some(Self::FeedRatio),
            _ => {}
        }
        let (kind, axis) = name.split_once('.')?;
        let a = AXIS_NAMES.iter().position(|n| *n == axis)? as u8;
        AXIS_SIGNALS
            .iter()
            .find(|(k, _)| *k == kind)
            .map(|(_, make)| make(a))
    }

    /// Every name [`Self::from_name`] takes.
    pub fn names() -> impl Iterator<Item = (&'static str, Option<&'static str>)> {
        AXIS_SIGNALS
            .iter()
            .flat_map(|(k, _)| AXIS_NAMES.iter().map(move |a| (*k, Some(*a))))
            .chain([("contour", None), ("feed_ratio", None)])
    }

    /// The signal's value in this period (0 for an axis that does not exist).
    pub fn value(self, s: &Snapshot, p: &PathSample) -> f32 {
        let at = |v: &[f32; 3], a: u8| v.get(usize::from(a)).copied().unwrap_or(0.0);
        match self {
            Self::Pos(a) => at(&s.pos, a),
            Self::Ref(a) => at(&s.reference, a),
            Self::Vel(a) => at(&s.vel, a),
            Self::Tracking(a) => at(&s.tracking, a),
            Self::Effort(a) => at(&s.effort, a),
            Self::Sliding(a) => at(&s.s, a),
            Self::RefVel(a) => at(&p.vel_mm_s.to_array(), a),
            Self::Contour => s.contour_norm(),
            Self::FeedRatio => p.feed_ratio,
        }
    }
}

/// What starts the part of the record after the pre-trigger window.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum Trigger {
    /// At once (the pre-trigger window is filled first).
    Now,
    /// A fault is latched (the period it is latched in).
    Fault,
    /// `signal` goes from below `level` to at or above it.
    Rising { signal: Signal, level: f32 },
    /// `signal` goes from above `level` to at or below it.
    Falling { signal: Signal, level: f32 },
}

/// A capture to arm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct ScopeConfig {
    pub channels: Vec<Signal, SCOPE_CHANNELS>,
    /// Samples per channel (channels × samples ≤ [`SCOPE_VALUES`]).
    pub samples: u16,
    /// One sample every this many control periods (≥ 1).
    pub every_periods: u16,
    /// Samples before the trigger (< `samples`); a trigger counts only once this many
    /// are recorded.
    pub pre_trigger: u16,
    pub trigger: Trigger,
}

impl ScopeConfig {
    /// Why the machine cannot arm this capture (no formatting: a fixed text).
    pub fn check(&self) -> Result<(), &'static str> {
        let ch = self.channels.len();
        if ch == 0 {
            return Err("scope: at least one signal");
        }
        if self.samples == 0 || usize::from(self.samples) * ch > SCOPE_VALUES {
            return Err("scope: samples x signals must be within 1-2048");
        }
        if self.every_periods == 0 {
            return Err("scope: every_periods must be >= 1");
        }
        if self.pre_trigger >= self.samples {
            return Err("scope: pre-trigger samples must be fewer than samples");
        }
        if let Trigger::Rising { level, .. } | Trigger::Falling { level, .. } = self.trigger {
            if !level.is_finite() {
                return Err("scope: trigger level must be finite");
            }
        }
        Ok(())
    }
}

/// Where a capture is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum ScopeState {
    /// Nothing armed.
    Off,
    /// Filling the pre-trigger window, or waiting for the trigger.
    Waiting,
    /// Triggered, recording the rest.
    Triggered,
    /// Complete: ready to read.
    Done,
}

/// One read-out chunk: `values` from value `offset` of the record (sample-major: all
/// channels of the oldest sample first).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct ScopeChunk {
    pub offset: u16,
    /// Values in the whole record (samples × channels).
    pub total: u16,
    /// Sample index of the trigger within the record.
    pub trigger_at: u16,
    /// Control periods between samples.
    pub every_periods: u16,
    pub values: Vec<f32, SCOPE_CHUNK>,
}

/// The scope's state and buffer.
pub struct Scope {
    cfg: Option<ScopeConfig>,
    state: ScopeState,
    buf: [f32; SCOPE_VALUES],
    /// Samples written so far (the ring's write position is `written % samples`).
    written: u32,
    /// Samples still to record after the trigger.
    remaining: u32,
    /// `written` when triggered.
    trigger_written: u32,
    since: u16,
    last: Option<f32>,
    fault_before: bool,
}

impl Default for Scope {
    fn default() -> Self {
        Self::new()
    }
}

impl Scope {
    pub const fn new() -> Self {
        Self {
            cfg: None,
            state: ScopeState::Off,
            buf: [0.0; SCOPE_VALUES],
            written: 0,
            remaining: 0,
            trigger_written: 0,
            since: 0,
            last: None,
            fault_before: false,
        }
    }

    /// Makes this scope [`Scope::new`] in place, field by field (no image of its 8 KiB
    /// buffer is copied from flash or through the stack): the firmware keeps the scope in
    /// a zero-filled static and calls this at boot.
    pub fn blank(&mut self) {
        self.cfg = None;
        self.state = ScopeState::Off;
        self.buf.fill(0.0);
        self.written = 0;
        self.remaining = 0;
        self.trigger_written = 0;
        self.since = 0;
        self.last = None;
        self.fault_before = false;
    }

    pub fn state(&self) -> ScopeState {
        self.state
    }

    /// Drop any capture.
    pub fn disarm(&mut self) {
        self.cfg = None;
        self.state = ScopeState::Off;
    }

    /// Arm a capture (a running one is dropped).
    pub fn arm(&mut self, cfg: ScopeConfig) -> Result<(), &'static str> {
        cfg.check()?;
        self.cfg = Some(cfg);
        self.state = ScopeState::Waiting;
        self.written = 0;
        self.remaining = 0;
        self.trigger_written = 0;
        // the first period records
        self.since = u16::MAX;
        self.last = None;
        self.fault_before = true;
        Ok(())
    }

    /// This period's signals, when a capture is running (see the module docs).
    pub fn record(&mut self, s: &Snapshot, p: &PathSample) {
        let Some(cfg) = &self.cfg else { return };
        if matches!(self.state, ScopeState::Off | ScopeState::Done) {
            return;
        }
        let fault = s.fault.is_some();
        // (a fault already latched when the capture was armed does not trigger it)
        let fault_edge = fault && !self.fault_before;
        self.fault_before = fault;
        self.since = self.since.saturating_add(1);
        if self.since < cfg.every_periods && !fault_edge {
            return;
        }
        self.since = 0;
        let samples = u32::from(cfg.samples);
        let ch = cfg.channels.len();
        let slot = (self.written % samples.max(1)) as usize * ch;
        for (i, sig) in cfg.channels.iter().enumerate() {
            if let Some(v) = self.buf.get_mut(slot + i) {
                *v = sig.value(s, p);
            }
        }
        self.written = self.written.saturating_add(1);
        match self.state {
            ScopeState::Waiting => {
                // (a level is watched at the sample rate: one value per recorded sample)
                let (edge, watched) = match cfg.trigger {
                    Trigger::Now => (true, None),
                    Trigger::Fault => (fault_edge, None),
                    Trigger::Rising { signal, level } => {
                        let v = signal.value(s, p);
                        (self.last.is_some_and(|l| l < level && v >= level), Some(v))
                    }
                    Trigger::Falling { signal, level } => {
                        let v = signal.value(s, p);
                        (self.last.is_some_and(|l| l > level && v <= level), Some(v))
                    }
                };
                self.last = watched;
                if edge && self.written > u32::from(cfg.pre_trigger) {
                    self.trigger_written = self.written - 1;
                    self.remaining = samples - u32::from(cfg.pre_trigger) - 1;
                    self.state = if self.remaining == 0 {
                        ScopeState::Done
                    } else {
                        ScopeState::Triggered
                    };
                }
            }
            ScopeState::Triggered => {
                self.remaining = self.remaining.saturating_sub(1);
                if self.remaining == 0 {
                    self.state = ScopeState::Done;
                }
            }
            ScopeState::Off | ScopeState::Done => {}
        }
    }

    /// Values from `offset` of a complete record (oldest sample first).
    pub fn read(&self, offset: u16) -> Result<ScopeChunk, &'static str> {
        let Some(cfg) = &self.cfg else {
            return Err("scope: nothing captured (arm it first)");
        };
        if self.state != ScopeState::Done {
            return Err("scope: the capture is not complete yet");
        }
        let ch = cfg.channels.len().max(1);
        let samples = u32::from(cfg.samples).max(1);
        let total = samples as usize * ch;
        // the oldest sample of the ring
        let start = self.written.saturating_sub(samples) % samples;
        let mut values = Vec::new();
        let first = usize::from(offset);
        for i in first..total.min(first + SCOPE_CHUNK) {
            let sample = (start + (i / ch) as u32) % samples;
            let v = self
                .buf
                .get(sample as usize * ch + i % ch)
                .copied()
                .unwrap_or(0.0);
            let _ = values.push(v);
        }
        let trigger_at = self
            .trigger_written
            .saturating_sub(self.written.saturating_sub(samples));
        Ok(ScopeChunk {
            offset,
            total: total as u16,
            trigger_at: trigger_at as u16,
            every_periods: cfg.every_periods,
            values,
        })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::servo::faults::{Fault, FaultKind, FaultRecord};

    /// Every field of `a` equals `b`'s (the scope has no `PartialEq`: its buffer is
    /// compared bit for bit).
    fn same(a: &Scope, b: &Scope) -> bool {
        a.cfg.is_none() == b.cfg.is_none()
            && a.state == b.state
            && a.buf
                .iter()
                .zip(&b.buf)
                .all(|(x, y)| x.to_bits() == y.to_bits())
            && (a.written, a.remaining, a.trigger_written, a.since)
                == (b.written, b.remaining, b.trigger_written, b.since)
            && a.last.map(f32::to_bits) == b.last.map(f32::to_bits)
            && a.fault_before == b.fault_before
    }

    /// `blank` leaves exactly `Scope::new()` after a capture moved every field away
    /// from it (the firmware's zero-filled static is blanked at boot the same way).
    #[test]
    fn blank_in_place_equals_new() {
        let mut s = Scope::new();
        s.arm(cfg(&[Signal::Pos(0)], 8, 1, 0, Trigger::Now))
            .unwrap();
        let p = PathSample::default();
        for k in 0..20 {
            s.record(&snap(k as f32 + 1.0), &p);
        }
        assert!(!same(&s, &Scope::new()));
        s.blank();
        assert!(same(&s, &Scope::new()));
    }

    fn snap(x: f32) -> Snapshot {
        let mut s = Snapshot::boot();
        s.pos = [x, 2.0 * x, -x];
        s.tracking = [0.5 * x, 0.0, 0.0];
        s
    }

    fn cfg(
        channels: &[Signal],
        samples: u16,
        every: u16,
        pre: u16,
        trigger: Trigger,
    ) -> ScopeConfig {
        ScopeConfig {
            channels: Vec::from_slice(channels).unwrap(),
            samples,
            every_periods: every,
            pre_trigger: pre,
            trigger,
        }
    }

    /// The whole record, chunk by chunk.
    fn read_all(sc: &Scope) -> (std::vec::Vec<f32>, u16) {
        let mut out = std::vec::Vec::new();
        loop {
            let c = sc.read(out.len() as u16).unwrap();
            assert!(!c.values.is_empty());
            out.extend_from_slice(&c.values);
            if out.len() >= usize::from(c.total) {
                return (out, c.trigger_at);
            }
        }
    }

    #[test]
    fn a_capture_triggered_now_records_consecutive_periods_of_every_channel() {
        let mut sc = Scope::new();
        let p = PathSample::default();
        sc.arm(cfg(
            &[Signal::Pos(0), Signal::Pos(1)],
            10,
            1,
            0,
            Trigger::Now,
        ))
        .unwrap();
        for k in 0..9 {
            sc.record(&snap(k as f32), &p);
            assert_eq!(sc.state(), ScopeState::Triggered, "{k}");
        }
        assert!(sc.read(0).is_err());
        sc.record(&snap(9.0), &p);
        assert_eq!(sc.state(), ScopeState::Done);
        let (v, at) = read_all(&sc);
        let want: std::vec::Vec<f32> = (0..10).flat_map(|k| [k as f32, 2.0 * k as f32]).collect();
        assert_eq!(v, want);
        assert_eq!(at, 0);
        // later periods change nothing
        sc.record(&snap(100.0), &p);
        assert_eq!(read_all(&sc).0, want);
    }

    /// `cfg` armed and fed the ramp x = 0, 1, 2, … until complete: the record.
    fn ramp(cfg: ScopeConfig) -> (std::vec::Vec<f32>, u16) {
        let mut sc = Scope::new();
        sc.arm(cfg).unwrap();
        let mut k = 0;
        while sc.state() != ScopeState::Done {
            sc.record(&snap(k as f32), &PathSample::default());
            k += 1;
            assert!(k < 1000);
        }
        read_all(&sc)
    }

    #[test]
    fn a_rising_edge_keeps_the_pre_trigger_window() {
        let trigger = Trigger::Rising {
            signal: Signal::Tracking(0),
            level: 25.0,
        };
        // tracking = x / 2 crosses 25 at x = 50: samples 45..=64, the trigger 5th
        let (v, at) = ramp(cfg(&[Signal::Pos(0)], 20, 1, 5, trigger));
        assert_eq!(v, (45..65).map(|x| x as f32).collect::<std::vec::Vec<_>>());
        assert_eq!(at, 5);
        assert_eq!(v[usize::from(at)], 50.0);
    }

    #[test]
    fn a_falling_edge_with_decimation() {
        let trigger = Trigger::Falling {
            signal: Signal::Pos(2),
            level: -30.0,
        };
        // every 3rd period: 0, 3, 6, …; -x <= -30 first at x = 30
        let (v, at) = ramp(cfg(&[Signal::Pos(0)], 8, 3, 2, trigger));
        assert_eq!(v, [24.0, 27.0, 30.0, 33.0, 36.0, 39.0, 42.0, 45.0]);
        assert_eq!(at, 2);
    }

    #[test]
    fn a_fault_triggers_in_its_period_but_not_one_latched_before() {
        let p = PathSample::default();
        let fault = FaultRecord {
            fault: Fault {
                kind: FaultKind::EStop,
                axis: None,
            },
            period: 0,
            value: 0.0,
        };
        let mut sc = Scope::new();
        sc.arm(cfg(&[Signal::Pos(0)], 4, 10, 1, Trigger::Fault))
            .unwrap();
        let mut s = snap(0.0);
        s.fault = Some(fault);
        for _ in 0..100 {
            sc.record(&s, &p);
        }
        assert_eq!(sc.state(), ScopeState::Waiting);
        // cleared, then a new fault between two decimated samples: recorded at once
        let mut k = 0.0;
        for _ in 0..25 {
            sc.record(&snap(k), &p);
            k += 1.0;
        }
        let mut s = snap(1000.0);
        s.fault = Some(fault);
        sc.record(&s, &p);
        assert_eq!(sc.state(), ScopeState::Triggered);
        for _ in 0..30 {
            sc.record(&s, &p);
        }
        let (v, at) = read_all(&sc);
        assert_eq!(at, 1);
        assert_eq!(v[1], 1000.0);
        assert_eq!(v[0], 20.0);
    }

    #[test]
    fn bad_captures_are_refused_and_arm_nothing() {
        let mut sc = Scope::new();
        let s = Signal::Pos(0);
        for (c, why) in [
            (cfg(&[], 10, 1, 0, Trigger::Now), "at least one"),
            (cfg(&[s, s, s], 683, 1, 0, Trigger::Now), "2048"),
            (cfg(&[s], 0, 1, 0, Trigger::Now), "2048"),
            (cfg(&[s], 10, 0, 0, Trigger::Now), "every_periods"),
            (cfg(&[s], 10, 1, 10, Trigger::Now), "pre-trigger"),
            (
                cfg(
                    &[s],
                    10,
                    1,
                    0,
                    Trigger::Rising {
                        signal: s,
                        level: f32::NAN,
                    },
                ),
                "finite",
            ),
        ] {
            assert!(sc.arm(c).unwrap_err().contains(why));
            assert_eq!(sc.state(), ScopeState::Off);
        }
        assert!(sc.arm(cfg(&[s, s, s, s], 512, 1, 0, Trigger::Now)).is_ok());
    }

    #[test]
    fn signal_names_round_trip() {
        let mut n = 0;
        for (kind, axis) in Signal::names() {
            let name = match axis {
                Some(a) => std::format!("{kind}.{a}"),
                None => kind.into(),
            };
            assert!(Signal::from_name(&name).is_some(), "{name}");
            n += 1;
        }
        assert_eq!(n, 23);
        assert_eq!(Signal::from_name("tracking.z"), Some(Signal::Tracking(2)));
        assert_eq!(Signal::from_name("pos.w"), None);
        assert_eq!(Signal::from_name("speed.x"), None);
    }
}
