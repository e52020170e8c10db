//! Homing: finding each axis' machine origin on its limit switch (grbl's and LinuxCNC's
//! sequence), so that positions, soft limits and programs mean the same place on every
//! power-up.
//!
//! Per axis, one at a time in the configured order:
//!
//! 1. **seek**: toward the switch at `seek_mm_s` until it closes (fails after
//!    `max_seek_mm` without it);
//! 2. **release**: back at `locate_mm_s` until it opens, then `backoff_mm` further;
//! 3. **locate**: toward it again at `locate_mm_s`; the count where it closes is the
//!    switch's position, `switch_pos_mm` in machine coordinates — or, with `use_index`,
//!    the count latched at the encoder's next index pulse (repeatable to one count, where
//!    a switch repeats to a few µm), which becomes `switch_pos_mm` plus the distance from
//!    switch to index measured in this cycle;
//! 4. **settle**: brake to rest; the axis' coordinates are re-based there;
//! 5. **pull-off**: move to `pulloff_mm` away from the switch. The axis is homed.
//!
//! While homing, the homed axis' own switch on the homing side is the sensor, not a
//! fault; every other switch still trips. A failure (switch not found, never released,
//! no index) is the `HomingFailed` fault with a controlled stop.

use super::ramp::Ramp;
use crate::axes::AXES;
use crate::config::{positive, ConfigError};

/// Which end of the axis the home switch is at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum HomeDirection {
    Min,
    Max,
}

impl HomeDirection {
    /// +1 toward the max end, -1 toward the min end.
    pub const fn sign(self) -> f32 {
        match self {
            Self::Min => -1.0,
            Self::Max => 1.0,
        }
    }

    /// Index of the switch in `Inputs::limits[axis]`.
    pub const fn switch(self) -> usize {
        match self {
            Self::Min => 0,
            Self::Max => 1,
        }
    }
}

/// One axis' homing.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisHomingConfig {
    /// The axis takes part in homing (an axis without a switch does not, and counts as
    /// homed where it stands).
    pub enabled: bool,
    /// Axes home one after the other in increasing `order` (ties: X, Y, Z); Z usually
    /// first, to lift the tool clear.
    pub order: u8,
    pub direction: HomeDirection,
    /// Search speed toward the switch, mm/s.
    pub seek_mm_s: f32,
    /// Slow speed of the release and the locate passes, mm/s: the switch's repeatability
    /// is its hysteresis plus this speed times its response time.
    pub locate_mm_s: f32,
    /// Acceleration of every homing move, mm/s².
    pub accel_mm_s2: f32,
    /// After the switch opens, move this much further before locating, mm.
    pub backoff_mm: f32,
    /// Final distance from the switch, mm.
    pub pulloff_mm: f32,
    /// Machine coordinate of the switch's trigger point, mm.
    pub switch_pos_mm: f32,
    /// The seek fails after this distance without the switch, mm (the axis' length plus
    /// a margin: the switch must be somewhere in the travel).
    pub max_seek_mm: f32,
    /// Latch the encoder's index pulse after the switch (a fault if none comes within
    /// one lead of the screw, [`AxisHomingConfig::index_search_mm`]).
    #[cfg_attr(feature = "serde", serde(default))]
    pub use_index: bool,
    /// Distance within which the index must follow the switch, mm (one screw lead).
    #[cfg_attr(feature = "serde", serde(default = "default_index_search"))]
    pub index_search_mm: f32,
}

#[cfg(feature = "serde")]
fn default_index_search() -> f32 {
    AxisHomingConfig::INDEX_SEARCH_MM
}

impl AxisHomingConfig {
    /// One 5 mm lead of the gantry's screws plus 10 %.
    pub const INDEX_SEARCH_MM: f32 = 5.5;

    pub fn validate(&self) -> Result<(), ConfigError> {
        if !self.enabled {
            return Ok(());
        }
        positive(self.seek_mm_s, "homing.seek_mm_s")?;
        positive(self.locate_mm_s, "homing.locate_mm_s")?;
        positive(self.accel_mm_s2, "homing.accel_mm_s2")?;
        positive(self.backoff_mm, "homing.backoff_mm")?;
        positive(self.pulloff_mm, "homing.pulloff_mm")?;
        crate::config::finite(self.switch_pos_mm, "homing.switch_pos_mm")?;
        positive(self.max_seek_mm, "homing.max_seek_mm")?;
        positive(self.index_search_mm, "homing.index_search_mm")?;
        if self.locate_mm_s > self.seek_mm_s {
            return Err(ConfigError::OutOfRange(
                "homing.locate_mm_s (at most seek_mm_s)",
            ));
        }
        Ok(())
    }

    /// Where the axis rests when homed, mm.
    pub fn home_mm(&self) -> f32 {
        self.switch_pos_mm - self.direction.sign() * self.pulloff_mm
    }
}

/// Homing of the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct HomingConfig {
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub axes: [AxisHomingConfig; AXES],
}

impl HomingConfig {
    /// No axis homes: every axis counts as homed where it is armed (simulation studies,
    /// machines without switches). Programs then run in the coordinates of power-up.
    pub const NONE: Self = Self {
        axes: [AxisHomingConfig {
            enabled: false,
            order: 0,
            direction: HomeDirection::Min,
            seek_mm_s: 1.0,
            locate_mm_s: 1.0,
            accel_mm_s2: 1.0,
            backoff_mm: 1.0,
            pulloff_mm: 1.0,
            switch_pos_mm: 0.0,
            max_seek_mm: 1.0,
            use_index: false,
            index_search_mm: AxisHomingConfig::INDEX_SEARCH_MM,
        }; AXES],
    };

    pub fn validate(&self) -> Result<(), ConfigError> {
        self.axes.iter().try_for_each(AxisHomingConfig::validate)
    }

    /// Any axis homes.
    pub fn enabled(&self) -> bool {
        self.axes.iter().any(|a| a.enabled)
    }

    /// The next axis to home after `done` (bit set of axes already homed in this cycle).
    pub fn next_axis(&self, done: u8) -> Option<usize> {
        (0..AXES)
            .filter(|&i| self.axes[i].enabled && done & (1 << i) == 0)
            .min_by_key(|&i| (self.axes[i].order, i))
    }
}

impl Default for HomingConfig {
    fn default() -> Self {
        Self::NONE
    }
}

/// Why homing failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HomingError {
    /// The seek travelled `max_seek_mm` without the switch closing.
    SwitchNotFound,
    /// The switch did not open again within `max_seek_mm` of backing off.
    SwitchStuck,
    /// No index pulse within `index_search_mm` of the switch.
    IndexNotFound,
}

/// Phase of the axis being homed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Seek,
    Release,
    Backoff { from_mm: f32 },
    Locate,
    Index { from_mm: f32, switch_counts: i64 },
    Settle { latched_counts: i64, at_mm: f32 },
    PullOff,
}

/// What the sequence asks of the servo this period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingEvent {
    /// Keep following [`Homing::ramp`].
    Moving,
    /// At rest after the latch: re-base the axis so that the count `latched_counts` is
    /// at `at_mm` (the servo resets the axis' estimator and the ramp follows).
    Rebase {
        axis: usize,
        latched_counts: i64,
        at_mm: f32,
    },
    /// Every axis is homed.
    Done,
    Failed {
        axis: usize,
        error: HomingError,
    },
}

/// The homing sequence in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homing {
    axis: usize,
    phase: Phase,
    /// Axes homed in this cycle (bit set).
    done: u8,
    /// Reference of the axis being homed (the others hold).
    pub ramp: Ramp,
    start_mm: f32,
}

/// What the sequence sees of the axis being homed each period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingInputs {
    /// The homing switch of the axis is closed.
    pub switch: bool,
    /// Measured (machine) counts of the axis.
    pub counts: i64,
    /// Counts latched at an index pulse since the last period, if any.
    pub index_counts: Option<i64>,
}

impl Homing {
    /// Start with the first axis in order, its reference at rest at `pos_mm`; `None` when
    /// no axis homes.
    pub fn start(cfg: &HomingConfig, pos_mm: &[f32; AXES]) -> Option<Self> {
        let axis = cfg.next_axis(0)?;
        Some(Self {
            axis,
            phase: Phase::Seek,
            done: 0,
            ramp: Ramp::at(pos_mm[axis]),
            start_mm: pos_mm[axis],
        })
    }

    /// The axis being homed.
    pub fn axis(&self) -> usize {
        self.axis
    }

    /// The switch of `axis` on side `side` is the homing sensor right now (not a fault).
    pub fn masks_switch(&self, cfg: &HomingConfig, axis: usize, side: usize) -> bool {
        axis == self.axis
            && cfg
                .axes
                .get(axis)
                .is_some_and(|a| a.direction.switch() == side)
    }

    /// The axis finished re-basing: its reference is now at `pos_mm` in the new
    /// coordinates, at rest.
    pub fn rebased(&mut self, pos_mm: f32) {
        self.ramp = Ramp::at(pos_mm);
        self.phase = Phase::PullOff;
    }

    /// Fraction of the axes homed (progress for the user).
    pub fn axes_done(&self) -> u8 {
        self.done
    }

    /// One period for the axis being homed; `pos_of_counts` converts machine counts to mm.
    pub fn step(
        &mut self,
        cfg: &HomingConfig,
        inp: &HomingInputs,
        count_mm: f32,
        dt_s: f32,
    ) -> HomingEvent {
        let Some(a) = cfg.axes.get(self.axis).copied() else {
            return HomingEvent::Done;
        };
        let toward = a.direction.sign();
        let unl = (f32::NEG_INFINITY, f32::INFINITY);
        let r = &mut self.ramp;
        let fail = |error| HomingEvent::Failed {
            axis: self.axis,
            error,
        };
        match self.phase {
            Phase::Seek => {
                if inp.switch {
                    self.phase = Phase::Release;
                } else if (r.pos_mm - self.start_mm).abs() > a.max_seek_mm {
                    return fail(HomingError::SwitchNotFound);
                }
                r.step_velocity(toward * a.seek_mm_s, a.accel_mm_s2, unl.0, unl.1, dt_s);
            }
            Phase::Release => {
                if !inp.switch {
                    self.phase = Phase::Backoff { from_mm: r.pos_mm };
                } else if (r.pos_mm - self.start_mm).abs() > 2.0 * a.max_seek_mm {
                    return fail(HomingError::SwitchStuck);
                }
                r.step_velocity(-toward * a.locate_mm_s, a.accel_mm_s2, unl.0, unl.1, dt_s);
            }
            Phase::Backoff { from_mm } => {
                let target = from_mm - toward * a.backoff_mm;
                if r.step_to(target, a.locate_mm_s, a.accel_mm_s2, dt_s) {
                    self.phase = Phase::Locate;
                }
            }
            Phase::Locate => {
                if inp.switch {
                    if a.use_index {
                        self.phase = Phase::Index {
                            from_mm: r.pos_mm,
                            switch_counts: inp.counts,
                        };
                    } else {
                        self.phase = Phase::Settle {
                            latched_counts: inp.counts,
                            at_mm: a.switch_pos_mm,
                        };
                    }
                } else if (r.pos_mm - self.start_mm).abs() > 3.0 * a.max_seek_mm {
                    return fail(HomingError::SwitchNotFound);
                }
                r.step_velocity(toward * a.locate_mm_s, a.accel_mm_s2, unl.0, unl.1, dt_s);
            }
            Phase::Index {
                from_mm,
                switch_counts,
            } => {
                if let Some(n) = inp.index_counts {
                    // the index position in the new coordinates: the switch's, plus the
                    // distance travelled from the switch to the index in this cycle
                    let offset_mm = (n - switch_counts) as f32 * count_mm;
                    self.phase = Phase::Settle {
                        latched_counts: n,
                        at_mm: a.switch_pos_mm + offset_mm,
                    };
                } else if (r.pos_mm - from_mm).abs() > a.index_search_mm {
                    return fail(HomingError::IndexNotFound);
                }
                r.step_velocity(toward * a.locate_mm_s, a.accel_mm_s2, unl.0, unl.1, dt_s);
            }
            Phase::Settle {
                latched_counts,
                at_mm,
            } => {
                r.step_velocity(0.0, a.accel_mm_s2, unl.0, unl.1, dt_s);
                if r.at_rest() {
                    return HomingEvent::Rebase {
                        axis: self.axis,
                        latched_counts,
                        at_mm,
                    };
                }
            }
            Phase::PullOff => {
                if r.step_to(a.home_mm(), a.seek_mm_s, a.accel_mm_s2, dt_s) {
                    self.done |= 1 << self.axis;
                    match cfg.next_axis(self.done) {
                        Some(next) => {
                            // the next axis starts from where the servo holds it: the
                            // caller passes it in `next_axis_at`
                            self.axis = next;
                            self.phase = Phase::Seek;
                            return HomingEvent::Moving;
                        }
                        None => return HomingEvent::Done,
                    }
                }
            }
        }
        HomingEvent::Moving
    }

    /// After the axis changed (a `Moving` event where [`Homing::axis`] differs from
    /// before), start its ramp at rest at `pos_mm`.
    pub fn next_axis_at(&mut self, pos_mm: f32) {
        self.ramp = Ramp::at(pos_mm);
        self.start_mm = pos_mm;
    }
}
