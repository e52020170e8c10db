//! Holding brakes: one spring-applied, power-released brake per axis (a vertical axis
//! falls when its amplifier goes off; the brake is what keeps it up).
//!
//! The brake grips when its coil is de-energised (fail-safe: a cut wire, a reset chip, a
//! lost supply all grip), and opens when energised. Neither happens at once: the spring
//! needs [`BrakeConfig::engage_s`] to grip after the coil is switched off, the magnet
//! [`BrakeConfig::release_s`] to lift the armature after it is switched on (catalogue
//! values of small servo-motor brakes: 20-40 ms to engage, 50-100 ms to release; the
//! defaults take the slow end of engaging's range and the middle of releasing's).
//!
//! The servo step ([`super::Servo::period`]) decides every period which brake may be
//! released ([`Brakes::update`], which keeps the axes it drove the period before, and
//! each axis' [`BrakeState::update`]) and writes that command out
//! ([`super::io::ServoIo::write_brakes`]):
//!
//! - a brake is released only while the servo drives its axis and has held it for a
//!   period already (the amplifier holds before the brake lets go); at boot, in
//!   `Disabled` and `Fault` it grips;
//! - motion waits for the brakes: the first period a motion may use is the one in which
//!   every driven axis' brake has been released for `release_s` ([`BrakeState::open`]);
//!   until then the servo holds the reference where it is;
//! - a controlled stop ends with the brakes gripping at rest: they are engaged when the
//!   stop's reference comes to rest (or, for a category-1 e-stop, `engage_s` before its
//!   deadline at the latest), and the outputs stay on, holding, until the axes have
//!   settled and the brakes have been engaged for `engage_s` ([`BrakeState::gripping`]);
//! - an immediate stop engages the brakes in the period the outputs go off (nothing
//!   better exists: the axis coasts for `engage_s` before the brake grips).
//!
//! An axis without a brake (`present = false`) is "open" and "gripping" at once, so it
//! never delays anything.

use crate::axes::AXES;
use crate::config::ConfigError;

/// Time a brake needs to grip after its coil is de-energised, s: 30 ms (the slow end of
/// the 20-40 ms that small servo-motor brakes list).
pub const DEFAULT_ENGAGE_S: f32 = 0.030;
/// Time a brake needs to open after its coil is energised, s: 70 ms (small servo-motor
/// brakes list 50-100 ms).
pub const DEFAULT_RELEASE_S: f32 = 0.070;
/// Longest engage or release time accepted, s: a brake slower than a second is a fault
/// (or a unit slip: milliseconds written as seconds).
pub const MAX_BRAKE_TIME_S: f32 = 1.0;

/// One axis' holding brake.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
pub struct BrakeConfig {
    /// The axis has a brake (and its output is wired).
    pub present: bool,
    /// Time the brake needs to grip after its coil is de-energised, s (0..=1).
    pub engage_s: f32,
    /// Time the brake needs to open after its coil is energised, s (0..=1).
    pub release_s: f32,
}

impl BrakeConfig {
    /// No brake (the default: configurations written before brakes existed keep working).
    pub const NONE: Self = Self {
        present: false,
        engage_s: DEFAULT_ENGAGE_S,
        release_s: DEFAULT_RELEASE_S,
    };

    /// A brake with the default timings.
    pub const FITTED: Self = Self {
        present: true,
        ..Self::NONE
    };

    /// Both times finite and within `0..=1` s; the error names the axis' field.
    pub fn validate(&self, axis: usize) -> Result<(), ConfigError> {
        const ENGAGE: [&str; AXES] = [
            "brakes.x.engage_s (finite, 0..=1 s)",
            "brakes.y.engage_s (finite, 0..=1 s)",
            "brakes.z.engage_s (finite, 0..=1 s)",
        ];
        const RELEASE: [&str; AXES] = [
            "brakes.x.release_s (finite, 0..=1 s)",
            "brakes.y.release_s (finite, 0..=1 s)",
            "brakes.z.release_s (finite, 0..=1 s)",
        ];
        let ok = |t: f32| (0.0..=MAX_BRAKE_TIME_S).contains(&t);
        let i = axis.min(AXES - 1);
        if !ok(self.engage_s) {
            return Err(ConfigError::OutOfRange(ENGAGE[i]));
        }
        if !ok(self.release_s) {
            return Err(ConfigError::OutOfRange(RELEASE[i]));
        }
        Ok(())
    }
}

impl Default for BrakeConfig {
    fn default() -> Self {
        Self::NONE
    }
}

/// Every axis' brake validated (the error names the first bad field).
pub fn validate_all(brakes: &[BrakeConfig; AXES]) -> Result<(), ConfigError> {
    brakes
        .iter()
        .enumerate()
        .try_for_each(|(i, b)| b.validate(i))
}

/// Every axis' brake as the servo drives it, and the axes it drove in the previous period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Brakes {
    pub axes: [BrakeState; AXES],
    /// Axes the servo drove in the previous period (bit i = axis i): a brake is released
    /// only once its axis' amplifier has held it for a period.
    prev_driven: u8,
}

impl Brakes {
    /// Every axis' brake engaged (the boot state), with the timings of `cfg` in periods
    /// of `period_s`.
    pub fn new(cfg: &[BrakeConfig; AXES], period_s: f64) -> Self {
        Self {
            axes: cfg.map(|b| BrakeState::new(&b, period_s)),
            prev_driven: 0,
        }
    }

    /// Every brake of the axes in `mask` is open in the coming period (or absent).
    #[inline]
    pub fn open(&self, mask: u8) -> bool {
        (0..AXES).all(|i| mask & (1 << i) == 0 || self.axes[i].open())
    }

    /// Every brake grips in the coming period (or is absent).
    #[inline]
    pub fn gripping(&self) -> bool {
        self.axes.iter().all(BrakeState::gripping)
    }

    /// Per axis: the brake is commanded released (coil energised), as written last period.
    #[inline]
    pub fn released(&self) -> [bool; AXES] {
        self.axes.map(|b| b.released())
    }

    /// The period's commands: released only on an axis in `driven` now and in the
    /// previous period, and none while `braking` (a stop that ends with them engaging).
    #[inline]
    pub fn update(&mut self, driven: u8, braking: bool) {
        for (i, b) in self.axes.iter_mut().enumerate() {
            let bit = 1 << i;
            b.update(!braking && driven & self.prev_driven & bit != 0);
        }
        self.prev_driven = driven;
    }

    /// Longest engage time of the brakes fitted, periods (0 without any).
    pub fn engage_periods(&self) -> u32 {
        self.axes
            .iter()
            .map(BrakeState::engage_periods)
            .max()
            .unwrap_or(0)
    }
}

/// One axis' brake as the servo drives it: the command and how long it has stood.
///
/// The command is updated once per period, at its end ([`Self::update`]), and acts from
/// that period on (the output is written then): a brake released in period `k` is open
/// from period `k + release_periods` on, so [`Self::open`] and [`Self::gripping`] answer
/// for the coming period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrakeState {
    present: bool,
    /// The coil is energised (brake commanded open).
    released: bool,
    /// Periods since the command last changed (saturating). 16 bits hold a second at the
    /// highest control rate (50 000 periods; `MAX_BRAKE_TIME_S` × `MAX_RATE_HZ`), the
    /// longest time the brake's rules look back; they keep the servo's stack small.
    since: u16,
    engage_periods: u16,
    release_periods: u16,
}

impl BrakeState {
    /// Engaged (the boot state), with the timings of `cfg` in periods of `period_s`
    /// (rounded up, so the brake is never taken as gripping or open early; within a
    /// thousandth of a period, the f32 representation of the time: 0.07 s is 700 periods
    /// at 10 kHz, not 701).
    pub fn new(cfg: &BrakeConfig, period_s: f64) -> Self {
        let periods = |t: f32| {
            let n = libm::ceil(f64::from(t) / period_s - 1e-3);
            // (validated: t within 0..=1 s, period at least 20 µs, so n <= 50 000)
            if n.is_finite() && n > 0.0 {
                n.min(f64::from(u16::MAX)) as u16
            } else {
                0
            }
        };
        Self {
            present: cfg.present,
            released: false,
            // at boot the brake has gripped long ago
            since: u16::MAX,
            engage_periods: if cfg.present {
                periods(cfg.engage_s)
            } else {
                0
            },
            release_periods: if cfg.present {
                periods(cfg.release_s)
            } else {
                0
            },
        }
    }

    /// One period with the brake commanded `release` (ignored without a brake: its
    /// output stays de-energised).
    #[inline]
    pub fn update(&mut self, release: bool) {
        let release = release && self.present;
        if release == self.released {
            self.since = self.since.saturating_add(1);
        } else {
            self.released = release;
            self.since = 0;
        }
    }

    /// Engage now (an immediate stop), without counting a period.
    #[inline]
    pub fn engage_now(&mut self) {
        if self.released {
            self.released = false;
            self.since = 0;
        }
    }

    /// The command: coil energised, brake released.
    #[inline]
    pub fn released(&self) -> bool {
        self.released
    }

    /// The brake no longer holds the axis in the coming period: released `release_s` ago
    /// by then (or no brake).
    #[inline]
    pub fn open(&self) -> bool {
        !self.present || (self.released && self.since.saturating_add(1) >= self.release_periods)
    }

    /// The brake holds the axis in the coming period: engaged `engage_s` ago by then (or
    /// no brake).
    #[inline]
    pub fn gripping(&self) -> bool {
        !self.present || (!self.released && self.since.saturating_add(1) >= self.engage_periods)
    }

    /// The axis has a brake.
    #[inline]
    pub fn present(&self) -> bool {
        self.present
    }

    /// `engage_s` in periods (0 without a brake).
    #[inline]
    pub fn engage_periods(&self) -> u32 {
        u32::from(self.engage_periods)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timings_are_validated_by_name() {
        assert_eq!(validate_all(&[BrakeConfig::FITTED; AXES]), Ok(()));
        for bad in [f32::NAN, -0.001, 1.001, f32::INFINITY] {
            let b = BrakeConfig {
                engage_s: bad,
                ..BrakeConfig::FITTED
            };
            assert_eq!(
                b.validate(2),
                Err(ConfigError::OutOfRange(
                    "brakes.z.engage_s (finite, 0..=1 s)"
                ))
            );
            let b = BrakeConfig {
                release_s: bad,
                ..BrakeConfig::NONE
            };
            assert_eq!(
                b.validate(0),
                Err(ConfigError::OutOfRange(
                    "brakes.x.release_s (finite, 0..=1 s)"
                ))
            );
        }
    }

    #[test]
    fn a_brake_opens_release_s_and_grips_engage_s_after_its_command() {
        // 10 kHz: 30 ms = 300 periods, 70 ms = 700 periods; released at the end of
        // period 0, open from period 700 on (asked at the end of period 699)
        let mut b = BrakeState::new(&BrakeConfig::FITTED, 1e-4);
        assert!(!b.released() && b.gripping() && !b.open());
        let mut opened = None;
        for k in 0..1000 {
            b.update(true);
            if b.open() && opened.is_none() {
                opened = Some(k + 1);
            }
        }
        assert_eq!(opened, Some(700));
        let mut gripped = None;
        for k in 0..1000 {
            b.update(false);
            if b.gripping() && gripped.is_none() {
                gripped = Some(k + 1);
            }
        }
        assert_eq!(gripped, Some(300));
        // no brake: never released, always open and gripping
        let mut n = BrakeState::new(&BrakeConfig::NONE, 1e-4);
        n.update(true);
        assert!(!n.released() && n.open() && n.gripping());
    }
}
