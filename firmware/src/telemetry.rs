//! What the telemetry task gets from the control interrupt besides the core's
//! [`Snapshot`](controller_core::servo::snapshot::Snapshot): the interrupt's own timing.
//!
//! The interrupt only adds numbers here; the low-priority logger divides and formats.

use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::ServoState;

/// What the control interrupt publishes for the lower-priority tasks: its timing and
/// state every period, the whole snapshot when the telemetry task asks for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Telemetry {
    /// The servo step's snapshot of the period in which `snapshot_wanted` was last seen
    /// set (and of a QEMU run's last period).
    pub snapshot: Snapshot,
    /// Set by the telemetry task; the control interrupt copies its snapshot at its next
    /// period and clears it.
    pub snapshot_wanted: bool,
    /// The servo state of the last period (the arm button's commands depend on it).
    pub state: ServoState,
    /// The interrupt's timing so far.
    pub timing: IsrTiming,
}

impl Telemetry {
    /// Before the first control period.
    pub const fn boot() -> Self {
        Self {
            snapshot: Snapshot::boot(),
            snapshot_wanted: false,
            state: Snapshot::boot().state,
            timing: IsrTiming::new(),
        }
    }
}

/// Execution time and deadline overruns of the control interrupt.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct IsrTiming {
    /// Periods measured.
    pub periods: u32,
    /// Periods whose next timer update had already happened when the interrupt finished.
    pub overruns: u32,
    /// Cycles (board: DWT) or instructions (QEMU, see `board/cycles.rs`) of the last
    /// measured interrupt body.
    pub last: u32,
    /// Smallest and largest `last` seen (`min` is `u32::MAX` before the first period).
    pub min: u32,
    pub max: u32,
    /// Sum of every `last`, for the mean.
    pub sum: u64,
}

impl IsrTiming {
    /// Nothing measured yet.
    pub const fn new() -> Self {
        Self {
            periods: 0,
            overruns: 0,
            last: 0,
            min: u32::MAX,
            max: 0,
            sum: 0,
        }
    }

    /// One period took `cycles`; `overran`: its next period had already started.
    pub fn record(&mut self, cycles: u32, overran: bool) {
        self.periods = self.periods.saturating_add(1);
        self.last = cycles;
        self.min = self.min.min(cycles);
        self.max = self.max.max(cycles);
        self.sum = self.sum.saturating_add(u64::from(cycles));
        if overran {
            self.overruns = self.overruns.saturating_add(1);
        }
    }

    /// Mean over the measured periods (0 before the first).
    pub fn mean(&self) -> u32 {
        match self.periods {
            0 => 0,
            n => (self.sum / u64::from(n)) as u32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_min_mean_max_and_overruns() {
        let mut t = IsrTiming::new();
        assert_eq!(t.mean(), 0);
        t.record(100, false);
        t.record(300, true);
        t.record(200, false);
        assert_eq!((t.min, t.max, t.last, t.mean()), (100, 300, 200, 200));
        assert_eq!((t.periods, t.overruns), (3, 1));
    }
}
