//! The encoder index check: counts lost or gained (a glitch) between two passes of the
//! encoder's index pulse are corrected at the next pass, or faulted when they are more than
//! glitches explain.
//!
//! An incremental encoder's index pulse comes once per revolution at the same place on
//! its disk, so the counter captured at it (`ServoIo::read_index`) is the same modulo the
//! counts per revolution (`EncoderConfig::index_period_counts`) at every pass — unless
//! counts were lost or gained in between. The first capture after boot (or after homing
//! re-based the counts) is the reference; one is kept per direction of travel, because a
//! real index pulse is one count wide and its capture edge lies a count apart depending
//! on the side the axis comes from. At each later capture the phase error `e` (the
//! capture less the reference, wrapped to ±half a revolution) is
//!
//! - within the encoders' edge noise (`SafetyConfig::encoder_noise_counts`, each capture
//!   may be half of it off): nothing to do;
//! - up to `SafetyConfig::index_max_correction_counts`: corrected, the count moves by
//!   `-e` (the axis' position jumps back to the truth, by `e` counts) and the correction is
//!   reported ([`IndexCheck::corrected_counts`], the snapshot);
//! - beyond it: `FaultKind::EncoderIndex` (a slipping coupling, a damaged disk, a wrong
//!   `index_period_counts`), an immediate stop.
//!
//! A glitch the jump check sees as it happens (larger than its threshold) faults there; a
//! smaller one that noise or slow motion could explain is what this check exists for
//! (docs/safety.md, "Glitches and the index pulse").

use crate::axes::AXES;
use crate::config::ConfigError;

/// Largest `index_max_correction_counts`: a correction of more than this many counts at
/// one index pass is never a glitch.
pub const MAX_INDEX_CORRECTION_COUNTS: u32 = 1024;

/// How far apart the captures of the two directions of travel may lie, counts: the index
/// pulse is one count wide, and the counter captures at its rising edge, which the axis
/// meets a count later from one side than from the other.
pub const INDEX_EDGE_COUNTS: i64 = 1;

/// One axis' reference phases and what was corrected.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct AxisIndex {
    /// Counts per index pulse (0: the check is off on this axis).
    period: i64,
    /// The first capture moving up and moving down, in the current count frame.
    reference: [Option<i64>; 2],
    /// The last direction the count moved was down (the reference index: 0 up, 1 down;
    /// a `bool`, so that indexing by it needs no bounds check in the control interrupt).
    down: bool,
    /// Sum of the corrections applied, counts (what the glitches lost or gained).
    corrected: i32,
}

/// What an index capture means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IndexVerdict {
    /// Within the noise, the first capture of a direction, or no check.
    Agrees,
    /// Move the count by this many counts (the count becomes `count - shift`).
    Correct(i64),
    /// Off by this many counts, more than a glitch explains.
    Fault(i64),
}

/// The index check of every axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexCheck {
    axes: [AxisIndex; AXES],
    /// Phase errors up to this are edge noise, counts.
    noise_counts: i64,
    /// Phase errors up to this are corrected, counts.
    max_correction: i64,
}

impl IndexCheck {
    /// `period_counts` per axis (0: no index), the edge noise the encoders show (counts
    /// peak to peak, validated by the monitor) and the largest correction.
    pub fn new(
        period_counts: [u32; AXES],
        noise_counts: f32,
        max_correction_counts: u32,
    ) -> Result<Self, ConfigError> {
        if max_correction_counts > MAX_INDEX_CORRECTION_COUNTS {
            return Err(ConfigError::OutOfRange(
                "safety.index_max_correction_counts (0 to 1024)",
            ));
        }
        let noise = if noise_counts.is_finite() {
            // two captures, each up to half the noise off: at most the noise apart
            libm::ceilf(noise_counts.clamp(0.0, 1.0e6)) as i64
        } else {
            return Err(ConfigError::NotFinite("safety.encoder_noise_counts"));
        };
        let mut axes = [AxisIndex::default(); AXES];
        for (a, p) in axes.iter_mut().zip(period_counts) {
            let p = i64::from(p);
            // a revolution must span more than the window of errors the check acts on
            if p != 0 && p <= 2 * (i64::from(max_correction_counts) + noise) {
                return Err(ConfigError::OutOfRange(
                    "encoder.index_period_counts (0, or more than twice index_max_correction_counts plus the noise)",
                ));
            }
            a.period = p;
        }
        Ok(Self {
            axes,
            noise_counts: noise,
            max_correction: i64::from(max_correction_counts),
        })
    }

    /// Whether any axis has an index to check.
    pub fn any(&self) -> bool {
        self.axes.iter().any(|a| a.period > 0)
    }

    /// Note the direction of this period's count step (a capture belongs to the side the
    /// axis last moved from).
    pub fn moved(&mut self, steps: &[i32; AXES]) {
        for (a, &s) in self.axes.iter_mut().zip(steps) {
            if s != 0 {
                a.down = s < 0;
            }
        }
    }

    /// A capture at machine count `captured` on `axis`: what to do about it. A correction
    /// is counted as applied (the caller re-bases the count by it).
    pub fn capture(&mut self, axis: usize, captured: i64) -> IndexVerdict {
        let Some(a) = self.axes.get_mut(axis) else {
            return IndexVerdict::Agrees;
        };
        if a.period <= 0 {
            return IndexVerdict::Agrees;
        }
        let (dir, other) = (usize::from(a.down), usize::from(!a.down));
        let (r, tolerance) = match (a.reference[dir], a.reference[other]) {
            (Some(r), _) => (r, self.noise_counts),
            // the first pass this way: measured against the other way's reference, which
            // its edge may lie a count from (a glitch since must not become the reference)
            (None, Some(r)) => (r, self.noise_counts + INDEX_EDGE_COUNTS),
            (None, None) => {
                a.reference[dir] = Some(captured);
                return IndexVerdict::Agrees;
            }
        };
        // wrapped to (-period/2, period/2]
        let p = a.period;
        let mut e = captured.wrapping_sub(r).rem_euclid(p);
        if e > p / 2 {
            e -= p;
        }
        if e.abs() <= tolerance {
            if a.reference[dir].is_none() {
                a.reference[dir] = Some(captured);
            }
            IndexVerdict::Agrees
        } else if e.abs() <= self.max_correction {
            // |e| <= 1024: exact in i32
            a.corrected = a.corrected.saturating_add(e as i32);
            IndexVerdict::Correct(e)
        } else {
            IndexVerdict::Fault(e)
        }
    }

    /// The count frame of `axis` moved (the count became `count - shift`: homing): the
    /// references move with it.
    pub fn rebased(&mut self, axis: usize, shift: i64) {
        if let Some(a) = self.axes.get_mut(axis) {
            for r in a.reference.iter_mut().flatten() {
                *r = r.saturating_sub(shift);
            }
        }
    }

    /// Drop `axis`' references (its counts were found off by more than a correction: the
    /// next passes learn new ones).
    pub fn forget(&mut self, axis: usize) {
        if let Some(a) = self.axes.get_mut(axis) {
            a.reference = [None; 2];
        }
    }

    /// Take over `old`'s references and corrections where an axis' index period is
    /// unchanged (a reconfiguration that keeps the count frame).
    pub fn carry_over(&mut self, old: &IndexCheck) {
        for (a, o) in self.axes.iter_mut().zip(&old.axes) {
            if a.period == o.period {
                a.reference = o.reference;
                a.down = o.down;
                a.corrected = o.corrected;
            }
        }
    }

    /// Counts corrected so far per axis (the sum of the corrections: the glitches' net).
    pub fn corrected_counts(&self) -> [i32; AXES] {
        [0, 1, 2].map(|i| self.axes[i].corrected)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check() -> IndexCheck {
        IndexCheck::new([8000, 8000, 0], 2.0, 16).unwrap()
    }

    #[test]
    fn a_lost_count_burst_is_corrected_at_the_next_pass_and_noise_is_not() {
        let mut c = check();
        c.moved(&[1, 1, 1]);
        assert_eq!(c.capture(0, 8000), IndexVerdict::Agrees); // the reference
        assert_eq!(c.capture(0, 16_002), IndexVerdict::Agrees); // noise
        assert_eq!(c.capture(0, 23_998), IndexVerdict::Agrees);
        // 3 counts gained: the count is 3 ahead of where the index puts it
        assert_eq!(c.capture(0, 32_003), IndexVerdict::Correct(3));
        // moving down, a new reference one count off (the other edge), then 5 lost
        c.moved(&[-1, 0, 0]);
        assert_eq!(c.capture(0, 24_001), IndexVerdict::Agrees);
        assert_eq!(c.capture(0, 15_996), IndexVerdict::Correct(-5));
        assert_eq!(c.corrected_counts(), [-2, 0, 0]);
        // beyond 16 counts: more than a glitch
        assert_eq!(c.capture(0, 8001 + 17), IndexVerdict::Fault(17));
        // the wrap: 7990 is 11 counts below the reference 8001 (mod 8000)
        assert_eq!(c.capture(0, 7990), IndexVerdict::Correct(-11));
        // no index on Z
        assert_eq!(c.capture(2, 123), IndexVerdict::Agrees);
        assert_eq!(c.capture(2, 999), IndexVerdict::Agrees);
    }

    #[test]
    fn homing_moves_the_references_with_the_counts() {
        let mut c = check();
        c.moved(&[1, 0, 0]);
        assert_eq!(c.capture(0, 8000), IndexVerdict::Agrees);
        c.rebased(0, 100_000); // the count became count - 100000
        assert_eq!(c.capture(0, 16_000 - 100_000), IndexVerdict::Agrees);
        assert_eq!(c.capture(0, 24_004 - 100_000), IndexVerdict::Correct(4));
    }

    #[test]
    fn a_revolution_shorter_than_the_correction_window_is_refused() {
        assert!(IndexCheck::new([36, 0, 0], 2.0, 16).is_err());
        assert!(IndexCheck::new([37, 0, 0], 2.0, 16).is_ok());
        assert!(IndexCheck::new([8000, 0, 0], 2.0, 1025).is_err());
        assert!(IndexCheck::new([8000, 0, 0], f32::NAN, 16).is_err());
    }
}
