//! Fault detection: the checks the servo step runs every period, with their detection
//! bounds (docs/safety.md has the table).
//!
//! Per axis, on the wide encoder counts `n`, the velocity estimate `v`, the effort applied
//! in the previous period `u` and the reference:
//!
//! - **encoder jump**: the second difference `|n[k] - 2 n[k-1] + n[k-2]|` (counts per
//!   period²) beyond what the axis can physically do, `a_max T² / count + 3` (the `+3`
//!   absorbs the quantisation of three readings, ±2 counts, and one count of margin).
//!   Detected in the period it happens. When the counts *stop* with such a step, the
//!   encoder stopped while the axis moved: reported as stuck.
//! - **encoder stuck**: the effort has changed by at least `stuck_effort_change` since
//!   the last count change, and still no count for `stuck_time_s`. At rest, friction holds
//!   the axis only while `|u - load| <= f_s` (breakaway friction), and when it last moved
//!   `|u - load|` was about the friction level, so an effort change beyond `2 f_s` plus a
//!   margin must move it (whatever the static load: gravity, a cutting force); the margin
//!   sets how soon (docs/safety.md). A reading frozen while the effort stays where it was
//!   carries no information at all; it is caught as soon as the effort has to change (a
//!   commanded move, an integral winding up, a chattering law switching).
//! - **runaway** (reversed encoder or motor): the effort near its limit (`|u| >= 0.9` of
//!   the amplifier's full scale, and at least `stuck_effort_change`), `u` and `v` of
//!   opposite sign, `|v|` above 2 % of the maximum speed and larger than when this began,
//!   for `runaway_time_s`. A reversed encoder drives the effort to the limit while the
//!   measured speed keeps growing the wrong way; a healthy axis pushed by an outside force
//!   weaker than the motor decelerates once the effort is that strong (a stronger force
//!   dragging the axis is reported as the runaway it is).
//! - **following error** (LinuxCNC's rule): `|e| > min_ferror + (ferror - min_ferror) ×
//!   min(1, |v_ref| / vel_max)`, in the period it happens.
//! - **overspeed**: `|v| > overspeed_ratio × vel_max`.
//! - **deadline overrun**: `overrun_max` overruns within `overrun_window_s`.
//!
//! Every limit may be `inf` (the check is off): simulation studies only; a machine's
//! configuration is checked with [`SafetyConfig::check_for_machine`].

use crate::axes::{Axis, AXES};
use crate::config::{limit, positive, ConfigError};
use crate::servo::faults::{Fault, FaultKind};

/// One axis' limits and fault thresholds.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisSafetyConfig {
    /// Maximum speed of the axis, mm/s: scales the following error and bounds the speed.
    pub vel_max_mm_s: f32,
    /// Largest acceleration the axis can physically make, mm/s² (peak torque over
    /// inertia, with margin for external loads): bounds the count step per period.
    pub accel_max_mm_s2: f32,
    /// Following error allowed at rest, mm (LinuxCNC MIN_FERROR).
    pub min_ferror_mm: f32,
    /// Following error allowed at maximum speed, mm (LinuxCNC FERROR).
    pub ferror_mm: f32,
    /// Effort change (laws' units) that must move a resting axis: twice its breakaway
    /// friction plus a margin. The stuck-encoder and runaway threshold, and the encoder
    /// check's effort (which must also exceed the static load plus breakaway).
    pub stuck_effort_change: f32,
    /// Deceleration of a controlled stop, mm/s².
    pub stop_decel_mm_s2: f32,
}

impl AxisSafetyConfig {
    /// Every check off (simulation studies that compare figures, not trips).
    pub const OFF: Self = Self {
        vel_max_mm_s: f32::INFINITY,
        accel_max_mm_s2: f32::INFINITY,
        min_ferror_mm: f32::INFINITY,
        ferror_mm: f32::INFINITY,
        stuck_effort_change: f32::INFINITY,
        stop_decel_mm_s2: f32::INFINITY,
    };
}

/// The fault checks' configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct SafetyConfig {
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub axes: [AxisSafetyConfig; AXES],
    /// Overspeed trips above this multiple of `vel_max_mm_s`.
    #[cfg_attr(feature = "serde", serde(default = "d_overspeed"))]
    pub overspeed_ratio: f32,
    /// Effort at or above `stuck_effort` without a count for this long: encoder stuck.
    #[cfg_attr(feature = "serde", serde(default = "d_stuck"))]
    pub stuck_time_s: f32,
    /// Velocity growing against the effort for this long: runaway.
    #[cfg_attr(feature = "serde", serde(default = "d_runaway"))]
    pub runaway_time_s: f32,
    /// Overruns allowed within [`Self::overrun_window_s`] before the fault.
    #[cfg_attr(feature = "serde", serde(default = "d_overrun_max"))]
    pub overrun_max: u16,
    #[cfg_attr(feature = "serde", serde(default = "d_overrun_window"))]
    pub overrun_window_s: f32,
    /// After a controlled stop's reference is at rest, the outputs stay on this long.
    #[cfg_attr(feature = "serde", serde(default = "d_settle"))]
    pub stop_settle_s: f32,
    /// A controlled stop ends (outputs off) at the latest this long after its reference
    /// came to rest.
    #[cfg_attr(feature = "serde", serde(default = "d_stop_timeout"))]
    pub stop_timeout_s: f32,
    /// Length of each direction of the encoder check at reset.
    #[cfg_attr(feature = "serde", serde(default = "d_check_time"))]
    pub encoder_check_time_s: f32,
    /// Counts the axis must move in the commanded direction for the check to pass.
    #[cfg_attr(feature = "serde", serde(default = "d_check_counts"))]
    pub encoder_check_counts: u32,
    /// Largest deceleration a moving axis may undergo while neither its reference nor its
    /// effort asks for one (a change of outside load: a cutting force, the Stribeck excess
    /// of friction as it slows), mm/s². The moving-stuck check's model
    /// ([`Monitor::check_encoders`]): a count is due once the axis must have travelled
    /// more than one count at this deceleration.
    #[cfg_attr(feature = "serde", serde(default = "d_stuck_decel"))]
    pub stuck_decel_mm_s2: f32,
    /// Stop category of the e-stop (IEC 60204-1): 0, every output off in the period it is
    /// seen (the axes coast); 1, a controlled stop at the axes' `stop_decel_mm_s2`, then
    /// every output off, at the latest [`Self::estop_stop_time_s`] after the e-stop.
    #[cfg_attr(feature = "serde", serde(default))]
    pub estop_category: u8,
    /// Longest a category-1 e-stop keeps the outputs on, s.
    #[cfg_attr(feature = "serde", serde(default = "d_estop_time"))]
    pub estop_stop_time_s: f32,
    /// Edge noise the encoders show, counts peak to peak: a reading may sit up to half of
    /// it either side of where the position puts it (edge jitter, an encoder resting on an
    /// edge, phase errors of the two channels). The jump check widens by twice it and
    /// the counts-due check reads the counts through a dead band of half of it, so noise
    /// of this size never trips them (docs/safety.md, "Edge noise"). 0 to
    /// [`MAX_ENCODER_NOISE_COUNTS`].
    #[cfg_attr(feature = "serde", serde(default))]
    pub encoder_noise_counts: f32,
    /// Largest phase error at an index pulse that is corrected (counts lost or gained by
    /// glitches since the last pass); beyond it the fault `encoder_index`. 0 to
    /// [`crate::servo::index_check::MAX_INDEX_CORRECTION_COUNTS`] (`servo::index_check`).
    #[cfg_attr(feature = "serde", serde(default = "d_index_correction"))]
    pub index_max_correction_counts: u32,
    /// Arming checks every encoder before the machine is ready: with every axis holding
    /// under its law, each axis' hold point moves `encoder_check_counts` out and back
    /// both ways at [`crate::servo::ARM_CHECK_SPEED_MM_S`], and the reading must follow;
    /// a reading that goes the wrong way (swapped A/B) is `encoder_jump`, one that does
    /// not move is `encoder_stuck` (docs/safety.md, "Swapped A/B at rest"). Off by
    /// default: it makes arming move the axes (10 µm on the gantry), which only an
    /// explicit setting may.
    #[cfg_attr(feature = "serde", serde(default))]
    pub arm_encoder_check: bool,
}

/// Largest `encoder_noise_counts`: beyond 16 counts of noise the encoder or its wiring is
/// the fault, not something to tolerate.
pub const MAX_ENCODER_NOISE_COUNTS: f32 = 16.0;

/// Defaults, with their reasoning (docs/safety.md).
pub mod defaults {
    /// 10 % over the maximum speed: room for the controller's transient overshoot.
    pub const OVERSPEED_RATIO: f32 = 1.1;
    /// 5 ms: at 20 mN·m beyond breakaway, the heaviest gantry axis (Y, J = 0.18) moves
    /// its first count (0.625 µm) from rest within 3.4 ms.
    pub const STUCK_TIME_S: f32 = 0.005;
    /// 10 ms of velocity growing against the effort.
    pub const RUNAWAY_TIME_S: f32 = 0.01;
    /// 3 overruns within 100 ms: an occasional late period is survivable, a pattern is not.
    pub const OVERRUN_MAX: u16 = 3;
    pub const OVERRUN_WINDOW_S: f32 = 0.1;
    /// 20 ms of holding at the stop point before the outputs go off.
    pub const STOP_SETTLE_S: f32 = 0.02;
    /// 0.5 s at most beyond the stop reference reaching rest.
    pub const STOP_TIMEOUT_S: f32 = 0.5;
    /// 30 ms per direction, the effort ramping from 0 to `stuck_effort_change` over it: a
    /// healthy gantry axis moves its 16 counts within ~10 ms of breaking away, and a
    /// still-stuck encoder lets the axis move well under 0.5 mm (docs/safety.md).
    pub const ENCODER_CHECK_TIME_S: f32 = 0.03;
    /// 16 counts (10 µm at 1600 counts/mm).
    pub const ENCODER_CHECK_COUNTS: u32 = 16;
    /// 200 mm/s²: 13 mN·m of sudden load on X (J = 0.064), 36 on Y, 8 on Z, beyond what
    /// the effort answers within the couple of periods before the controller reacts; at
    /// this bound a stuck encoder is found within 20 periods down to 1 mm/s
    /// (docs/safety.md, the speed grid). A load step larger than this that stops a healthy
    /// axis slower than ~1.5 mm/s within one count reads as a stuck encoder: an immediate
    /// stop, and the encoder check lets the reset through.
    pub const STUCK_DECEL_MM_S2: f32 = 200.0;
    /// 0.3 s: from the gantry's 250 mm/s at the slowest stop deceleration (Y, 1500
    /// mm/s²) the stop takes 0.167 s, plus the 20 ms settle, with 50 % margin.
    pub const ESTOP_STOP_TIME_S: f32 = 0.3;
    /// 16 counts (10 µm at 1600 counts/mm) per index pass: several glitches of a few
    /// counts each, each too small for the jump check (3.5 counts per period² on X); a
    /// larger loss within one revolution is a mechanical or wiring fault, not noise.
    pub const INDEX_MAX_CORRECTION_COUNTS: u32 = 16;
}

#[cfg(feature = "serde")]
fn d_overspeed() -> f32 {
    defaults::OVERSPEED_RATIO
}
#[cfg(feature = "serde")]
fn d_stuck() -> f32 {
    defaults::STUCK_TIME_S
}
#[cfg(feature = "serde")]
fn d_runaway() -> f32 {
    defaults::RUNAWAY_TIME_S
}
#[cfg(feature = "serde")]
fn d_overrun_max() -> u16 {
    defaults::OVERRUN_MAX
}
#[cfg(feature = "serde")]
fn d_overrun_window() -> f32 {
    defaults::OVERRUN_WINDOW_S
}
#[cfg(feature = "serde")]
fn d_settle() -> f32 {
    defaults::STOP_SETTLE_S
}
#[cfg(feature = "serde")]
fn d_stop_timeout() -> f32 {
    defaults::STOP_TIMEOUT_S
}
#[cfg(feature = "serde")]
fn d_check_time() -> f32 {
    defaults::ENCODER_CHECK_TIME_S
}
#[cfg(feature = "serde")]
fn d_check_counts() -> u32 {
    defaults::ENCODER_CHECK_COUNTS
}
#[cfg(feature = "serde")]
fn d_estop_time() -> f32 {
    defaults::ESTOP_STOP_TIME_S
}
#[cfg(feature = "serde")]
fn d_index_correction() -> u32 {
    defaults::INDEX_MAX_CORRECTION_COUNTS
}
#[cfg(feature = "serde")]
fn d_stuck_decel() -> f32 {
    defaults::STUCK_DECEL_MM_S2
}

impl SafetyConfig {
    /// The given axis limits with the default timings.
    pub const fn with_axes(axes: [AxisSafetyConfig; AXES]) -> Self {
        Self {
            axes,
            overspeed_ratio: defaults::OVERSPEED_RATIO,
            stuck_time_s: defaults::STUCK_TIME_S,
            runaway_time_s: defaults::RUNAWAY_TIME_S,
            overrun_max: defaults::OVERRUN_MAX,
            overrun_window_s: defaults::OVERRUN_WINDOW_S,
            stop_settle_s: defaults::STOP_SETTLE_S,
            stop_timeout_s: defaults::STOP_TIMEOUT_S,
            encoder_check_time_s: defaults::ENCODER_CHECK_TIME_S,
            encoder_check_counts: defaults::ENCODER_CHECK_COUNTS,
            stuck_decel_mm_s2: defaults::STUCK_DECEL_MM_S2,
            estop_category: 0,
            estop_stop_time_s: defaults::ESTOP_STOP_TIME_S,
            encoder_noise_counts: 0.0,
            index_max_correction_counts: defaults::INDEX_MAX_CORRECTION_COUNTS,
            arm_encoder_check: false,
        }
    }

    /// Every check off.
    pub const OFF: Self = Self::with_axes([AxisSafetyConfig::OFF; AXES]);

    /// A machine may not run with a check switched off: every limit must be finite.
    pub fn check_for_machine(&self) -> Result<(), ConfigError> {
        for a in &self.axes {
            let all = [
                a.vel_max_mm_s,
                a.accel_max_mm_s2,
                a.min_ferror_mm,
                a.ferror_mm,
                a.stuck_effort_change,
                a.stop_decel_mm_s2,
            ];
            if all.iter().any(|v| !v.is_finite()) {
                return Err(ConfigError::NotFinite(
                    "safety.axes (every limit must be finite on a machine)",
                ));
            }
        }
        Ok(())
    }
}

/// Validated per-axis thresholds in the units the checks use.
#[derive(Clone, Copy, Debug, PartialEq)]
struct AxisLimits {
    vel_max: f32,
    overspeed: f32,
    min_ferror: f32,
    /// `(ferror - min_ferror) / vel_max`: following-error growth per mm/s.
    ferror_slope: f32,
    ferror_max: f32,
    stuck_effort: f32,
    /// Effort above which a speed growing against it is a runaway.
    runaway_effort: f32,
    /// Largest physical second difference of the counts, counts/period².
    jump_counts: f32,
    runaway_speed: f32,
    /// The counts-due check is on (the stuck check is: `stuck_effort_change` finite).
    due_on: bool,
    /// `stuck_decel_mm_s2` in counts/period².
    due_decel: f32,
    /// Deceleration per unit of effort dropped, counts/period² (`accel_max / full_scale`:
    /// at least `1 / J`).
    due_decel_per_effort: f32,
    /// mm/s to counts/period.
    vel_counts: f32,
    /// mm/s² to counts/period².
    acc_counts: f32,
    /// `encoder_noise_counts`: the counts-due check's claims give up this much travel.
    noise_counts: f32,
    /// Half-width of the counts-due check's dead band, counts (`ceil(noise / 2)`).
    noise_band: i32,
}

/// Per-axis memory of the checks. The count history is the previous step: a step between
/// successive readings is the counter's signed delta, within ±2^31 (half the 32-bit
/// counter's range; ±2^15 for a 16-bit one), so it is an exact `i32`
/// ([`crate::estimator::WideCounter::step`]) and the second difference needs no 64-bit
/// arithmetic.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct AxisWatch {
    /// The previous step `n[k-1] - n[k-2]`, counts.
    step1: i32,
    /// Readings since the last reset (the second difference needs two before).
    primed: u8,
    stuck: u32,
    /// Effort applied when the count last changed.
    u_ref: f32,
    runaway: u32,
    runaway_from: f32,
    /// The counts-due check's memory ([`Monitor::check_counts_due`]).
    due: CountsDue,
}

/// What the counts-due check knows since the last count change.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct CountsDue {
    /// Direction of the last change: +1, -1, or 0 (none yet, or a reversal: no claim).
    dir: i8,
    /// Readings since it.
    since: u32,
    /// Lower bound of the speed along `dir`, counts/period.
    v_lb: f32,
    /// Lower bound of the travel since it, counts.
    travel: f32,
    /// Effort applied when it happened.
    u_at: f32,
    /// The reading less the dead band's output, within `±noise_band`.
    resid: i32,
    /// Counts along `dir` since the run of changes this way began (at its first change).
    run_counts: f32,
    /// Periods since then.
    run_periods: u32,
    /// Sum of the decelerations the run may have had, each times the periods into the run
    /// it came, counts.
    run_decel: f32,
    /// Effort applied when the run began.
    run_u: f32,
}

/// A run of count changes one way is restarted (its claim begins again from the next
/// change) after this many periods: the run's deceleration allowance only grows, and a
/// speed from long ago says little about the speed now.
pub const RUN_MAX_PERIODS: u32 = 64;

/// Travel beyond the last count change, in counts, after which the next change is overdue:
/// the next edge is at most one count away, plus half a count for the edges' spacing
/// (duty cycle and phase errors of a real encoder).
pub const COUNTS_DUE_TRAVEL: f32 = 1.5;

/// Quantisation of three readings in a second difference (±2 counts) plus one of margin.
pub const JUMP_QUANTISATION_COUNTS: f32 = 3.0;

/// The fault checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Monitor {
    lim: [AxisLimits; AXES],
    watch: [AxisWatch; AXES],
    stuck_periods: u32,
    runaway_periods: u32,
    overrun_max: u16,
    overrun_window: u32,
    /// Periods of the most recent overruns (a ring of [`MAX_OVERRUNS`]).
    overruns: [u32; MAX_OVERRUNS],
    overrun_count: u32,
}

/// Largest `overrun_max` the window tracks.
pub const MAX_OVERRUNS: usize = 16;

/// One reading's step through a dead band (backlash) of `band` counts, `resid` the
/// reading's place inside the band: the output moves only by what leaves the band, so
/// noise within it never turns the output back; without a band the step is the reading's.
#[inline(always)]
fn dead_band(step: i32, resid: &mut i32, band: i32) -> i32 {
    if band == 0 {
        return step;
    }
    let r = resid.saturating_add(step);
    if r > band {
        *resid = band;
        r - band
    } else if r < -band {
        *resid = -band;
        r + band
    } else {
        *resid = r;
        0
    }
}

/// Periods in `s` at `period_s` (rounded up, but a duration within 0.1 % of a whole
/// number of periods, as `f32` seconds usually are, is that number), at least 1.
pub(crate) fn periods(s: f32, period_s: f64) -> u32 {
    let x = f64::from(s) / period_s;
    let near = libm::round(x);
    let p = if (x - near).abs() <= 1e-3 * near.max(1.0) {
        near
    } else {
        libm::ceil(x)
    };
    if p.is_finite() {
        p.clamp(1.0, f64::from(u32::MAX)) as u32
    } else {
        u32::MAX
    }
}

impl Monitor {
    /// `counts_per_mm` and the amplifiers' `full_scale` per axis, the control period.
    pub fn new(
        cfg: &SafetyConfig,
        counts_per_mm: [f32; AXES],
        full_scale: [f32; AXES],
        period_s: f64,
    ) -> Result<Self, ConfigError> {
        let mut lim = [AxisLimits {
            vel_max: 0.0,
            overspeed: 0.0,
            min_ferror: 0.0,
            ferror_slope: 0.0,
            ferror_max: 0.0,
            stuck_effort: 0.0,
            runaway_effort: 0.0,
            jump_counts: 0.0,
            runaway_speed: 0.0,
            due_on: false,
            due_decel: 0.0,
            due_decel_per_effort: 0.0,
            vel_counts: 0.0,
            acc_counts: 0.0,
            noise_counts: 0.0,
            noise_band: 0,
        }; AXES];
        let stuck_decel = positive(cfg.stuck_decel_mm_s2, "safety.stuck_decel_mm_s2")?;
        let ratio = positive(cfg.overspeed_ratio, "safety.overspeed_ratio")?;
        if ratio < 1.0 {
            return Err(ConfigError::OutOfRange("safety.overspeed_ratio (>= 1)"));
        }
        let noise = cfg.encoder_noise_counts;
        if !(0.0..=MAX_ENCODER_NOISE_COUNTS).contains(&noise) {
            return Err(ConfigError::OutOfRange(
                "safety.encoder_noise_counts (0 to 16)",
            ));
        }
        // `noise` is in 0..=16: the cast is exact
        let noise_band = libm::ceilf(0.5 * noise) as i32;
        let t2 = (period_s * period_s) as f32;
        for (((l, a), counts), fs) in lim
            .iter_mut()
            .zip(&cfg.axes)
            .zip(counts_per_mm)
            .zip(full_scale)
        {
            let vel_max = limit(a.vel_max_mm_s, "safety.vel_max_mm_s")?;
            let accel = limit(a.accel_max_mm_s2, "safety.accel_max_mm_s2")?;
            let min_fe = limit(a.min_ferror_mm, "safety.min_ferror_mm")?;
            let fe = limit(a.ferror_mm, "safety.ferror_mm")?;
            if fe < min_fe {
                return Err(ConfigError::OutOfRange(
                    "safety.ferror_mm (>= min_ferror_mm)",
                ));
            }
            limit(a.stop_decel_mm_s2, "safety.stop_decel_mm_s2")?;
            *l = AxisLimits {
                vel_max,
                overspeed: ratio * vel_max,
                min_ferror: min_fe,
                ferror_slope: if fe.is_finite() && vel_max.is_finite() {
                    (fe - min_fe) / vel_max
                } else {
                    0.0
                },
                ferror_max: fe,
                stuck_effort: limit(a.stuck_effort_change, "safety.stuck_effort_change")?,
                runaway_effort: if fs.is_finite() {
                    (0.9 * fs).max(a.stuck_effort_change)
                } else {
                    a.stuck_effort_change
                },
                // each of the three readings may be off by `noise / 2` more
                jump_counts: accel * t2 * counts + JUMP_QUANTISATION_COUNTS + 2.0 * noise,
                runaway_speed: 0.02 * vel_max,
                due_on: a.stuck_effort_change.is_finite() && stuck_decel.is_finite(),
                due_decel: stuck_decel * t2 * counts,
                due_decel_per_effort: if fs.is_finite() && fs > 0.0 {
                    accel / fs * t2 * counts
                } else {
                    f32::INFINITY
                },
                vel_counts: period_s as f32 * counts,
                acc_counts: t2 * counts,
                noise_counts: noise,
                noise_band,
            };
        }
        let window = periods(
            positive(cfg.overrun_window_s, "safety.overrun_window_s")?,
            period_s,
        );
        Ok(Self {
            lim,
            watch: [AxisWatch::default(); AXES],
            stuck_periods: periods(positive(cfg.stuck_time_s, "safety.stuck_time_s")?, period_s),
            runaway_periods: periods(
                positive(cfg.runaway_time_s, "safety.runaway_time_s")?,
                period_s,
            ),
            overrun_max: cfg.overrun_max.clamp(1, MAX_OVERRUNS as u16),
            overrun_window: window,
            overruns: [0; MAX_OVERRUNS],
            overrun_count: 0,
        })
    }

    /// Forget the history (when the outputs get enabled).
    pub fn reset(&mut self) {
        self.watch = [AxisWatch::default(); AXES];
        self.overrun_count = 0;
    }

    /// The speed-scaled following-error limit of `axis` at reference speed `v_ref`, mm.
    pub fn ferror_limit(&self, axis: usize, v_ref: f32) -> f32 {
        let l = &self.lim[axis];
        if l.ferror_slope == 0.0 {
            return l.min_ferror;
        }
        // `f32::min` is a libm call (`fminf`) on the Cortex-M4; a NaN speed gives the
        // maximum either way (`ferror_max` is never NaN)
        let limit = l.min_ferror + l.ferror_slope * v_ref.abs();
        if limit < l.ferror_max {
            limit
        } else {
            l.ferror_max
        }
    }

    /// The encoder checks of this period: the steps of the wide counts over the period
    /// (`n[k] - n[k-1]`, [`crate::estimator::WideCounter::step`]), velocity estimates
    /// (mm/s) and the efforts applied during the period that just ended.
    pub fn check_encoders(
        &mut self,
        steps: &[i32; AXES],
        vel: &[f32; AXES],
        effort: &[f32; AXES],
    ) -> Option<(Fault, f32)> {
        // written out per axis (each inlines with a constant index); every axis' history
        // is updated, the first fault in axis order is reported
        let x = self.check_encoder(0, steps[0], vel[0], effort[0]);
        let y = self.check_encoder(1, steps[1], vel[1], effort[1]);
        let z = self.check_encoder(2, steps[2], vel[2], effort[2]);
        x.or(y).or(z)
    }

    /// [`Self::check_encoders`] of axis `i`: the first of its jump, stuck and runaway
    /// faults.
    #[inline(always)]
    fn check_encoder(&mut self, i: usize, step: i32, v: f32, effort: f32) -> Option<(Fault, f32)> {
        let (l, w) = (&self.lim[i], &mut self.watch[i]);
        let axis = Axis::ALL[i];
        let mut found = None;
        if w.primed >= 2 {
            // the second difference of two `i32` steps: in `i32` (one hardware conversion
            // to f32) unless it overflows (steps of opposite sign beyond ±2^30, physically
            // impossible), then exactly as a 64-bit value: the same `f32` as the 64-bit
            // difference of the counts
            let d2f = match step.checked_sub(w.step1) {
                Some(d2) => d2 as f32,
                None => (i64::from(step) - i64::from(w.step1)) as f32,
            };
            if !(d2f.abs() <= l.jump_counts) {
                let kind = if step == 0 {
                    FaultKind::EncoderStuck
                } else {
                    FaultKind::EncoderJump
                };
                found = Some((Fault::on(kind, axis), d2f));
            }
        }
        if w.primed >= 1 {
            // an effort change that must move the axis, and no count
            if step != 0 {
                w.u_ref = effort;
                w.stuck = 0;
            } else if (effort - w.u_ref).abs() >= l.stuck_effort {
                w.stuck = w.stuck.saturating_add(1);
            } else {
                w.stuck = 0;
            }
            if w.stuck >= self.stuck_periods {
                found = found.or(Some((Fault::on(FaultKind::EncoderStuck, axis), effort)));
            }
            // velocity growing against the effort
            let against =
                effort.abs() >= l.runaway_effort && effort * v < 0.0 && v.abs() >= l.runaway_speed;
            if against {
                if w.runaway == 0 {
                    w.runaway_from = v.abs();
                }
                w.runaway = w.runaway.saturating_add(1);
                if w.runaway >= self.runaway_periods && v.abs() > w.runaway_from {
                    found = found.or(Some((Fault::on(FaultKind::EncoderRunaway, axis), v)));
                }
            } else {
                w.runaway = 0;
            }
        }
        w.step1 = step;
        w.primed = if w.primed >= 2 { 2 } else { w.primed + 1 };
        found
    }

    /// The counts-due check (encoder stuck or reversed while moving, at any speed): after a count
    /// change the axis was moving at least at the average speed the change shows (one
    /// count per interval, `c / (g + 1)` counts per period for `c` counts after `g`
    /// periods), and it can slow down only as fast as its reference decelerates, its
    /// effort along the motion drops (`accel_max / full_scale` per unit), or an outside
    /// load changes (`stuck_decel_mm_s2`), and never below the reference's speed along
    /// the motion (the controller keeps it there). Integrating that lower bound, once the
    /// axis must have moved [`COUNTS_DUE_TRAVEL`] counts with no new count, the encoder
    /// is stuck; a count the other way while that bound is still above zero is a count
    /// the axis cannot make (reported as a jump: swapped A/B). `steps` as in
    /// [`Self::check_encoders`]; reference velocity (mm/s) and
    /// acceleration (mm/s²); the efforts applied during the period that just ended.
    /// Forget what the counts-due check claims of the axes in `mask` (bit i: axis i): the
    /// compensation is taking up a nut's play there, and a motor side that crosses the
    /// gap alone and knocks into the spring of the frame behind it moves as no rigid
    /// model bounds (the check's claims are the rigid model's). The following-error,
    /// jump and runaway checks still watch it.
    #[cold]
    #[inline(never)]
    pub fn release_due_claims(&mut self, mask: u8) {
        for (i, w) in self.watch.iter_mut().enumerate() {
            if mask & (1 << i) != 0 {
                w.due.dir = 0;
                w.due.v_lb = 0.0;
            }
        }
    }

    pub fn check_counts_due(
        &mut self,
        steps: &[i32; AXES],
        v_ref: &[f32; AXES],
        a_ref: &[f32; AXES],
        effort: &[f32; AXES],
    ) -> Option<(Fault, f32)> {
        let x = self.count_due(0, steps[0], v_ref[0], a_ref[0], effort[0]);
        let y = self.count_due(1, steps[1], v_ref[1], a_ref[1], effort[1]);
        let z = self.count_due(2, steps[2], v_ref[2], a_ref[2], effort[2]);
        x.or(y).or(z)
    }

    #[inline(always)]
    fn count_due(
        &mut self,
        i: usize,
        step: i32,
        v_ref: f32,
        a_ref: f32,
        effort: f32,
    ) -> Option<(Fault, f32)> {
        let (l, d) = (&self.lim[i], &mut self.watch[i].due);
        if !l.due_on {
            return None;
        }
        // the dead band (backlash) of `noise_band` counts: its output moves only when the
        // reading leaves the band around it, so noise within `noise_counts` never turns
        // it back while the axis moves one way (a reversal of it is a reversal of the
        // axis); without noise it is the reading itself
        let step = dead_band(step, &mut d.resid, l.noise_band);
        // the deceleration this period may bring along the claimed direction, since the
        // last change (`decel`) and since the run began (`run_step`): the effort's drop
        // counts from when each began
        let s_old = f32::from(d.dir);
        let outside = l.due_decel + (-s_old * a_ref * l.acc_counts).max(0.0);
        let by_effort = |since: f32| {
            let dropped = -s_old * (effort - since);
            if dropped > 0.0 {
                dropped * l.due_decel_per_effort
            } else {
                0.0
            }
        };
        let decel = outside + by_effort(d.u_at);
        let run_step = outside + by_effort(d.run_u);
        if step != 0 {
            let dir: i8 = if step > 0 { 1 } else { -1 };
            let s = f32::from(dir);
            if d.dir == -dir && d.v_lb > 0.0 {
                // counts the wrong way while the axis must still be moving the other:
                // physically impossible (swapped A/B, a reversed counter)
                let v_lb = d.v_lb;
                d.dir = 0;
                return Some((Fault::on(FaultKind::EncoderJump, Axis::ALL[i]), -s * v_lb));
            }
            let c = step.unsigned_abs() as f32;
            let gap = d.since.saturating_add(1) as f32;
            let v = if d.dir == dir {
                // the average speed over the interval, less what the interval's
                // deceleration may have taken off by its end (speed falls at most
                // `decel`, so the average exceeds the end's speed by at most
                // `decel × length / 2`); the noise may have made up `noise_counts` of
                // the change
                let interval = (c - l.noise_counts) / (gap + 1.0) - 0.5 * decel * (gap + 1.0);
                // ... the same over the run of changes this way (the noise costs its
                // `noise_counts` once, not at every change), less every deceleration
                // the run may have had
                let run_c = d.run_counts + c;
                let run_p = d.run_periods as f32 + gap;
                // the average exceeds the end's speed by at most the decelerations
                // weighted by how far into the run they came (`∫ t a(t) dt / L`)
                let run_decel = d.run_decel + run_p * run_step;
                let run = (run_c - l.noise_counts - run_decel) / (run_p + 1.0);
                let restart = d.run_periods >= RUN_MAX_PERIODS;
                d.run_counts = if restart { 0.0 } else { run_c };
                d.run_periods = if restart { 0 } else { run_p as u32 };
                d.run_decel = if restart { 0.0 } else { run_decel };
                if restart {
                    d.run_u = effort;
                }
                // (not the bound carried from before the change: an axis that started
                // with its load unbalanced, as after arming, decelerates harder than the
                // model allows until the controller catches up, and a claim carried on
                // from then reads a healthy axis as stuck)
                interval.max(run)
            } else {
                // a first change or a reversal claims nothing, and starts a run
                d.run_counts = 0.0;
                d.run_periods = 0;
                d.run_decel = 0.0;
                d.run_u = effort;
                0.0
            };
            // never below the reference's speed along the motion (NaN ends the claim)
            let v = v.min(s * v_ref * l.vel_counts);
            d.dir = dir;
            d.since = 0;
            d.v_lb = if v > 0.0 { v } else { 0.0 };
            d.travel = 0.0;
            d.u_at = effort;
            return None;
        }
        d.since = d.since.saturating_add(1);
        let elapsed = d.run_periods.saturating_add(d.since) as f32;
        d.run_decel += elapsed * run_step;
        if d.dir == 0 || d.v_lb <= 0.0 {
            return None;
        }
        let v = (d.v_lb - decel).min(s_old * v_ref * l.vel_counts);
        d.v_lb = if v > 0.0 { v } else { 0.0 };
        d.travel += d.v_lb;
        // the band's output moves once the reading is past it: at most `noise_counts`
        // further (the reading at its last move may have been that much ahead)
        if d.travel > COUNTS_DUE_TRAVEL + l.noise_counts {
            let travel = d.travel;
            // one report per stall: the claim restarts at the next change
            d.dir = 0;
            return Some((Fault::on(FaultKind::EncoderStuck, Axis::ALL[i]), travel));
        }
        None
    }

    /// Following error (`error` mm, reference velocity `v_ref` mm/s; the limit is scaled
    /// by `scale`, 1 normally) and overspeed (`vel` mm/s).
    pub fn check_tracking(
        &self,
        error: &[f32; AXES],
        v_ref: &[f32; AXES],
        vel: &[f32; AXES],
        scale: f32,
    ) -> Option<(Fault, f32)> {
        for i in 0..AXES {
            let axis = Axis::ALL[i];
            // NaN trips as well: `!(x <= limit)`
            if !(error[i].abs() <= scale * self.ferror_limit(i, v_ref[i])) {
                return Some((Fault::on(FaultKind::FollowingError, axis), error[i]));
            }
            if !(vel[i].abs() <= self.lim[i].overspeed) {
                return Some((Fault::on(FaultKind::Overspeed, axis), vel[i]));
            }
        }
        None
    }

    /// Count a deadline overrun reported at `period`; the fault when `overrun_max` of them
    /// fall within the last `overrun_window` periods (a sliding window).
    pub fn check_overrun(&mut self, overran: bool, period: u32) -> Option<(Fault, f32)> {
        if !overran {
            return None;
        }
        let n = MAX_OVERRUNS as u32;
        self.overruns[(self.overrun_count % n) as usize] = period;
        self.overrun_count = self.overrun_count.saturating_add(1);
        let max = u32::from(self.overrun_max);
        if self.overrun_count >= max {
            // the overrun `max - 1` before this one
            let oldest = self.overruns[((self.overrun_count - max) % n) as usize];
            if period.wrapping_sub(oldest) < self.overrun_window {
                return Some((Fault::system(FaultKind::DeadlineOverrun), max as f32));
            }
        }
        None
    }

    /// The configured maximum speed of `axis`, mm/s.
    pub fn vel_max(&self, axis: usize) -> f32 {
        self.lim[axis].vel_max
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::gantry::{GANTRY_AMPLIFIERS, GANTRY_SAFETY};
    use proptest::prelude::*;

    /// The encoder checks as they were written on wide `i64` counts (the history two
    /// counts, 64-bit differences, `i64 -> f32` conversion): the reference the `i32`
    /// step version must agree with.
    struct CountsModel {
        n1: [i64; AXES],
        n2: [i64; AXES],
        primed: [u8; AXES],
        stuck: [u32; AXES],
        u_ref: [f32; AXES],
        runaway: [u32; AXES],
        runaway_from: [f32; AXES],
    }

    impl CountsModel {
        fn new() -> Self {
            Self {
                n1: [0; AXES],
                n2: [0; AXES],
                primed: [0; AXES],
                stuck: [0; AXES],
                u_ref: [0.0; AXES],
                runaway: [0; AXES],
                runaway_from: [0.0; AXES],
            }
        }

        fn check(
            &mut self,
            m: &Monitor,
            counts: &[i64; AXES],
            vel: &[f32; AXES],
            effort: &[f32; AXES],
        ) -> Option<(Fault, f32)> {
            let mut found = None;
            for i in 0..AXES {
                let l = &m.lim[i];
                let (n, axis) = (counts[i], Axis::ALL[i]);
                let step = n.saturating_sub(self.n1[i]);
                if self.primed[i] >= 2 {
                    let d2 = step.saturating_sub(self.n1[i].saturating_sub(self.n2[i]));
                    let d2f = d2 as f32;
                    if !(d2f.abs() <= l.jump_counts) {
                        let kind = if step == 0 {
                            FaultKind::EncoderStuck
                        } else {
                            FaultKind::EncoderJump
                        };
                        found = found.or(Some((Fault::on(kind, axis), d2f)));
                    }
                }
                if self.primed[i] >= 1 {
                    if step != 0 {
                        self.u_ref[i] = effort[i];
                        self.stuck[i] = 0;
                    } else if (effort[i] - self.u_ref[i]).abs() >= l.stuck_effort {
                        self.stuck[i] = self.stuck[i].saturating_add(1);
                    } else {
                        self.stuck[i] = 0;
                    }
                    if self.stuck[i] >= m.stuck_periods {
                        found =
                            found.or(Some((Fault::on(FaultKind::EncoderStuck, axis), effort[i])));
                    }
                    let v = vel[i];
                    let against = effort[i].abs() >= l.runaway_effort
                        && effort[i] * v < 0.0
                        && v.abs() >= l.runaway_speed;
                    if against {
                        if self.runaway[i] == 0 {
                            self.runaway_from[i] = v.abs();
                        }
                        self.runaway[i] = self.runaway[i].saturating_add(1);
                        if self.runaway[i] >= m.runaway_periods && v.abs() > self.runaway_from[i] {
                            found = found.or(Some((Fault::on(FaultKind::EncoderRunaway, axis), v)));
                        }
                    } else {
                        self.runaway[i] = 0;
                    }
                }
                self.n2[i] = self.n1[i];
                self.n1[i] = n;
                self.primed[i] = self.primed[i].saturating_add(1).min(2);
            }
            found
        }
    }

    proptest::proptest! {
        /// Fed the counts of `WideCounter`s (32-bit registers with every delta a counter
        /// can show, 16-bit ones, long runs of zero steps), the step version reports
        /// exactly the faults, in the same periods, with the same values as the version
        /// on 64-bit counts.
        #[test]
        fn step_checks_equal_the_checks_on_wide_counts(
            deltas in proptest::collection::vec(
                proptest::prop_oneof![
                    3 => -3i64..=3,
                    1 => Just(0i64),
                    1 => -40i64..=40,
                    1 => proptest::num::i32::ANY.prop_map(i64::from),
                ],
                3 * 60,
            ),
            efforts in proptest::collection::vec(-400.0f32..400.0, 60),
            vels in proptest::collection::vec(-600.0f32..600.0, 60),
            start in proptest::num::i64::ANY,
        ) {
            use crate::estimator::{CounterWidth, WideCounter};
            let full_scale = GANTRY_AMPLIFIERS.map(|a| a.full_scale);
            let mut m = Monitor::new(
                &SafetyConfig::with_axes(GANTRY_SAFETY), [1600.0; AXES], full_scale, 1.0e-4,
            ).unwrap();
            let mut model = CountsModel::new();
            let widths = [CounterWidth::Bits32, CounterWidth::Bits16, CounterWidth::Bits32];
            let mut raw = [0u32; AXES];
            // far from the origin: the 64-bit counts do not fit i32, their steps do
            let starts = [start / 4, 0, -start / 4];
            let mut counters = [0, 1, 2].map(|i| WideCounter::new(widths[i], 0, starts[i]));
            for k in 0..60 {
                let mut counts = [0i64; AXES];
                let mut steps = [0i32; AXES];
                for i in 0..AXES {
                    // a 16-bit counter shows deltas within ±2^15 only
                    let d = if i == 1 { deltas[3 * k + i].clamp(-32_768, 32_767) } else {
                        deltas[3 * k + i]
                    };
                    raw[i] = raw[i].wrapping_add(d as u32);
                    counts[i] = counters[i].update(raw[i]);
                    steps[i] = counters[i].step();
                }
                let effort = [efforts[k], -efforts[k], 0.5 * efforts[k]];
                let vel = [vels[k], 0.1 * vels[k], -vels[k]];
                let a = m.check_encoders(&steps, &vel, &effort);
                let b = model.check(&m, &counts, &vel, &effort);
                prop_assert_eq!(a, b, "period {}", k);
            }
        }
    }

    #[test]
    fn an_edge_noise_allowance_out_of_its_range_is_refused_by_name() {
        let full_scale = GANTRY_AMPLIFIERS.map(|a| a.full_scale);
        for bad in [-1.0, 16.5, f32::NAN, f32::INFINITY] {
            let mut cfg = SafetyConfig::with_axes(GANTRY_SAFETY);
            cfg.encoder_noise_counts = bad;
            assert_eq!(
                Monitor::new(&cfg, [1600.0; AXES], full_scale, 1.0e-4),
                Err(ConfigError::OutOfRange(
                    "safety.encoder_noise_counts (0 to 16)"
                )),
                "{bad}"
            );
        }
        let mut cfg = SafetyConfig::with_axes(GANTRY_SAFETY);
        cfg.encoder_noise_counts = 16.0;
        assert!(Monitor::new(&cfg, [1600.0; AXES], full_scale, 1.0e-4).is_ok());
    }

    #[test]
    fn a_jump_and_a_stop_are_found_in_the_period_they_happen() {
        let full_scale = GANTRY_AMPLIFIERS.map(|a| a.full_scale);
        let mut m = Monitor::new(
            &SafetyConfig::with_axes(GANTRY_SAFETY),
            [1600.0; AXES],
            full_scale,
            1.0e-4,
        )
        .unwrap();
        let (v, u) = ([0.0; AXES], [0.0; AXES]);
        // steady motion at 3 counts per period on X
        for _ in 0..3 {
            assert_eq!(m.check_encoders(&[3, 0, 0], &v, &u), None);
        }
        // a 40-count jump: second difference 37 counts/period²
        let f = m.check_encoders(&[40, 0, 0], &v, &u);
        assert_eq!(f, Some((Fault::on(FaultKind::EncoderJump, Axis::X), 37.0)));
        // the largest i32 steps of opposite sign: the second difference overflows i32
        // and is still exact
        let f = m.check_encoders(&[i32::MIN, 0, 0], &v, &u);
        let d2 = (i64::from(i32::MIN) - 40) as f32;
        assert_eq!(f, Some((Fault::on(FaultKind::EncoderJump, Axis::X), d2)));
    }
}
