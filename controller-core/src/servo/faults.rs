//! Fault codes, their stop categories, and the latched fault record.
//!
//! Every fault the servo step detects has a kind ([`FaultKind`]), an axis where one
//! applies, the control period it was detected in, and a stop category:
//!
//! | category | kinds | what happens |
//! | --- | --- | --- |
//! | immediate | e-stop, hard limit, amplifier fault, encoder stuck / jump / runaway / index, non-finite controller state, invalid configuration, clock fault, corrupt settings store (at boot, outputs already off) | every output off in the period of detection |
//! | controlled | following error, overspeed, deadline overrun, link lost, soft limit, homing failed | the reference decelerates to rest along its direction at the axes' stop deceleration, the controller keeps tracking it, then every output goes off |
//!
//! A controlled stop is used only where the position is still trustworthy (the encoders
//! are healthy); anything that makes the measurement or the controller suspect stops at
//! once. Faults latch ([`FaultLog`]): per axis and for the system, the first fault with its
//! period, and a short history.

use crate::axes::{Axis, AXES};

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum FaultKind {
    /// The emergency-stop input is active (pressed or wire broken).
    EStop = 0,
    /// A limit switch at the low end of the axis is active.
    LimitMin = 1,
    /// A limit switch at the high end of the axis is active.
    LimitMax = 2,
    /// The axis' amplifier reports a fault.
    AmplifierFault = 3,
    /// The encoder stopped counting while the axis had to move.
    EncoderStuck = 4,
    /// The count changed by more than the axis can physically move in one period.
    EncoderJump = 5,
    /// The measured velocity grows against the effort pushing the axis (reversed
    /// encoder or motor wiring).
    EncoderRunaway = 6,
    /// A law's output or state is not finite, or has saturated the number type.
    NonFinite = 7,
    /// |reference - measured| beyond the speed-scaled limit.
    FollowingError = 8,
    /// The axis moves faster than its configured maximum allows.
    Overspeed = 9,
    /// The control interrupt missed its deadline too often within the window.
    DeadlineOverrun = 10,
    /// The host link's heartbeat watchdog expired.
    LinkLost = 11,
    /// The configuration was rejected at boot: the outputs never get enabled.
    ConfigInvalid = 12,
    /// The board's crystal failed (at start-up or later, by the clock security system)
    /// and the controller runs on its internal oscillator: its timing is not trustworthy.
    ClockFault = 13,
    /// A reference left the axis' travel (the planner or a jog failed to keep it in).
    SoftLimit = 14,
    /// Homing did not find (or could not leave) the home switch or the index.
    HomingFailed = 15,
    /// The settings store was unreadable at boot: factory defaults are in use.
    SettingsCorrupt = 16,
    /// The count at an index pulse is further from the index's place than glitches
    /// explain (`safety.index_max_correction_counts`): counts lost or gained in bulk (a
    /// slipping coupling, a damaged disk, a wrong `index_period_counts`).
    EncoderIndex = 17,
    /// The board's peripheral configuration read back after init differs from its
    /// register table (firmware/twin/expect.toml: a pin's function, a timer's mode, a
    /// priority): the outputs never get enabled on such a board (cleared only by a reboot).
    BoardConfig = 18,
}

/// How the machine stops on a fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopCategory {
    /// Every output off in the period of detection.
    Immediate,
    /// Decelerate along the path at the configured limit, then outputs off.
    Controlled,
}

impl FaultKind {
    /// Every kind, in code order.
    pub const ALL: [FaultKind; 19] = [
        Self::EStop,
        Self::LimitMin,
        Self::LimitMax,
        Self::AmplifierFault,
        Self::EncoderStuck,
        Self::EncoderJump,
        Self::EncoderRunaway,
        Self::NonFinite,
        Self::FollowingError,
        Self::Overspeed,
        Self::DeadlineOverrun,
        Self::LinkLost,
        Self::ConfigInvalid,
        Self::ClockFault,
        Self::SoftLimit,
        Self::HomingFailed,
        Self::SettingsCorrupt,
        Self::EncoderIndex,
        Self::BoardConfig,
    ];

    pub const fn stop(self) -> StopCategory {
        match self {
            Self::FollowingError
            | Self::Overspeed
            | Self::DeadlineOverrun
            | Self::LinkLost
            | Self::SoftLimit
            | Self::HomingFailed => StopCategory::Controlled,
            _ => StopCategory::Immediate,
        }
    }

    /// A fault of the position measurement: the axis' encoder must prove healthy before
    /// the fault can be reset.
    pub const fn is_encoder(self) -> bool {
        matches!(
            self,
            Self::EncoderStuck | Self::EncoderJump | Self::EncoderRunaway | Self::EncoderIndex
        )
    }

    /// snake_case name (reports, JSON, the link).
    pub const fn name(self) -> &'static str {
        match self {
            Self::EStop => "estop",
            Self::LimitMin => "limit_min",
            Self::LimitMax => "limit_max",
            Self::AmplifierFault => "amplifier_fault",
            Self::EncoderStuck => "encoder_stuck",
            Self::EncoderJump => "encoder_jump",
            Self::EncoderRunaway => "encoder_runaway",
            Self::NonFinite => "non_finite",
            Self::FollowingError => "following_error",
            Self::Overspeed => "overspeed",
            Self::DeadlineOverrun => "deadline_overrun",
            Self::LinkLost => "link_lost",
            Self::ConfigInvalid => "config_invalid",
            Self::ClockFault => "clock_fault",
            Self::SoftLimit => "soft_limit",
            Self::HomingFailed => "homing_failed",
            Self::SettingsCorrupt => "settings_corrupt",
            Self::EncoderIndex => "encoder_index",
            Self::BoardConfig => "board_config",
        }
    }

    const fn bit(self) -> u32 {
        1 << (self as u8)
    }
}

/// A fault, on an axis where one applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fault {
    pub kind: FaultKind,
    pub axis: Option<Axis>,
}

impl Fault {
    pub const fn system(kind: FaultKind) -> Self {
        Self { kind, axis: None }
    }

    pub const fn on(kind: FaultKind, axis: Axis) -> Self {
        Self {
            kind,
            axis: Some(axis),
        }
    }
}

/// A detected fault: when, and the value that tripped it (error in mm, speed in mm/s,
/// count step, overruns; 0 where none applies).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultRecord {
    pub fault: Fault,
    /// Control period of detection (the snapshot's period counter).
    pub period: u32,
    pub value: f32,
}

/// Faults kept in the history.
pub const FAULT_HISTORY: usize = 8;

/// Latched faults: bit sets per axis and for the system (bit = [`FaultKind`] code), the
/// first fault since the last reset, and the last [`FAULT_HISTORY`] faults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultLog {
    first: Option<FaultRecord>,
    system: u32,
    axes: [u32; AXES],
    history: [Option<FaultRecord>; FAULT_HISTORY],
    next: usize,
}

impl Default for FaultLog {
    fn default() -> Self {
        Self::new()
    }
}

impl FaultLog {
    pub const fn new() -> Self {
        Self {
            first: None,
            system: 0,
            axes: [0; AXES],
            history: [None; FAULT_HISTORY],
            next: 0,
        }
    }

    /// Record a fault (the first one since the last reset stays the root cause).
    pub fn record(&mut self, r: FaultRecord) {
        let bit = r.fault.kind.bit();
        if self.latched_bits(r.fault.axis) & bit != 0 {
            // already latched: a repeat, not news
            return;
        }
        match r.fault.axis {
            Some(a) => self.axes[a.index()] |= bit,
            None => self.system |= bit,
        }
        if self.first.is_none() {
            self.first = Some(r);
        }
        if let Some(slot) = self.history.get_mut(self.next) {
            *slot = Some(r);
        }
        self.next = (self.next + 1) % FAULT_HISTORY;
    }

    fn latched_bits(&self, axis: Option<Axis>) -> u32 {
        match axis {
            Some(a) => self.axes[a.index()],
            None => self.system,
        }
    }

    /// Whether `kind` is latched (on `axis`, or for the system).
    pub fn is_latched(&self, kind: FaultKind, axis: Option<Axis>) -> bool {
        self.latched_bits(axis) & kind.bit() != 0
    }

    /// Any fault latched.
    pub fn any(&self) -> bool {
        self.system != 0 || self.axes.iter().any(|&a| a != 0)
    }

    /// The first fault since the last reset.
    pub fn first(&self) -> Option<FaultRecord> {
        self.first
    }

    /// Latched kinds as bit sets: (system, per axis).
    pub fn bits(&self) -> (u32, [u32; AXES]) {
        (self.system, self.axes)
    }

    /// Every latched fault.
    pub fn latched(&self) -> impl Iterator<Item = Fault> + '_ {
        let sys = FaultKind::ALL
            .into_iter()
            .filter(|k| self.system & k.bit() != 0)
            .map(Fault::system);
        let axes = Axis::ALL.into_iter().flat_map(move |a| {
            FaultKind::ALL
                .into_iter()
                .filter(move |k| self.axes[a.index()] & k.bit() != 0)
                .map(move |k| Fault::on(k, a))
        });
        sys.chain(axes)
    }

    /// The history, oldest first.
    pub fn history(&self) -> impl Iterator<Item = FaultRecord> + '_ {
        (0..FAULT_HISTORY).filter_map(move |i| self.history[(self.next + i) % FAULT_HISTORY])
    }

    /// Clear the latched faults (the history stays).
    pub fn clear(&mut self) {
        self.first = None;
        self.system = 0;
        self.axes = [0; AXES];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(kind: FaultKind, axis: Option<Axis>, period: u32) -> FaultRecord {
        FaultRecord {
            fault: Fault { kind, axis },
            period,
            value: 0.0,
        }
    }

    #[test]
    fn first_fault_stays_and_history_wraps() {
        let mut log = FaultLog::new();
        log.record(rec(FaultKind::EncoderStuck, Some(Axis::X), 10));
        log.record(rec(FaultKind::FollowingError, Some(Axis::Y), 11));
        log.record(rec(FaultKind::EncoderStuck, Some(Axis::X), 12)); // repeat
        assert_eq!(log.first().unwrap().period, 10);
        assert!(log.is_latched(FaultKind::FollowingError, Some(Axis::Y)));
        assert!(!log.is_latched(FaultKind::FollowingError, Some(Axis::X)));
        assert_eq!(log.history().count(), 2);
        log.clear();
        for p in 0..20u32 {
            let axis = Axis::from_index((p / 13) as usize);
            log.record(rec(FaultKind::ALL[(p % 13) as usize], axis, 100 + p));
        }
        assert_eq!(log.history().count(), FAULT_HISTORY);
        // oldest first: the last FAULT_HISTORY records, in order
        let mut last = 0;
        for r in log.history() {
            assert!(r.period > last);
            last = r.period;
        }
        assert_eq!(last, 119);
        log.clear();
        assert!(!log.any() && log.first().is_none());
        assert_eq!(log.history().count(), FAULT_HISTORY);
    }

    #[test]
    fn stop_categories() {
        use StopCategory::*;
        assert_eq!(FaultKind::EStop.stop(), Immediate);
        assert_eq!(FaultKind::EncoderStuck.stop(), Immediate);
        assert_eq!(FaultKind::FollowingError.stop(), Controlled);
        assert_eq!(FaultKind::DeadlineOverrun.stop(), Controlled);
        assert!(FaultKind::EncoderJump.is_encoder() && !FaultKind::EStop.is_encoder());
    }
}
