//! The encoder checks' state: the check a reset after an encoder fault runs (state
//! `EncoderCheck`: one axis follows a small effort both ways) and the closed-loop check at
//! arming ([`ArmCheck`]), with their parameters. Their periods are in `encoder_check`, how
//! they start in [`super::modes`].

use crate::axes::AXES;
use crate::Vec3;

/// The encoder checks' parameters (from the safety configuration) and the one under way.
pub(super) struct EncoderChecks<R> {
    /// The reset's check under way.
    pub(super) check: Option<Check>,
    /// Periods the reset's check ramps its effort over (and may take per direction).
    pub(super) periods: u32,
    /// Counts the axis must follow each way.
    pub(super) counts: i64,
    /// Full effort of the ramp per axis.
    pub(super) effort: [f32; AXES],
    /// The arm check under way (state `EncoderCheck` after an arm), and whether arming
    /// runs it.
    pub(super) arm: Option<ArmCheck<R>>,
    pub(super) arm_on: bool,
    /// The arm check's reference step per period (counts) and wrong-way limit (counts).
    pub(super) arm_step: [f32; AXES],
    pub(super) arm_wrong: f32,
}

/// Progress of an encoder check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Check {
    pub(super) axis: usize,
    pub(super) positive: bool,
    pub(super) k: u32,
    pub(super) n0: i64,
}

/// The closed-loop encoder check at arming ([`SafetyConfig::arm_encoder_check`]): every
/// axis' hold reference moves `encoder_check_counts` out and back each way at
/// [`ARM_CHECK_SPEED_MM_S`], all at once, under the laws; each reading must follow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ArmCheck<R> {
    /// Each axis' phase, and the periods it has been in it.
    pub(super) phase: [ArmPhase; AXES],
    pub(super) k: [u32; AXES],
    /// Every axis' counts where the check began (its hold point).
    pub(super) base: [i64; AXES],
    /// The hold point of every axis, mm.
    pub(super) hold: Vec3<R>,
    /// The reference's offset from the hold point, counts.
    pub(super) offset: [f32; AXES],
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum ArmPhase {
    /// An axis with a brake holds for the stop's settle time once the brakes are open
    /// (the load the brake held settles onto the law), then its hold point is taken.
    Settle,
    /// Out the positive way: the axis must reach half the check counts.
    Out,
    /// Back and out the negative way: the axis must reach minus half the check counts.
    Back,
    /// Back to the hold point.
    Home,
    /// Followed both ways, holding.
    Done,
}

/// Speed of the arm check's reference, mm/s: 5 mm/s moves the 16 check counts (10 µm on
/// the gantry) in 2 ms, slow enough that the law follows with about a count of lag.
pub const ARM_CHECK_SPEED_MM_S: f32 = 5.0;

/// Counts a healthy axis may stray the wrong way while the arm check's reference moves
/// out, beyond the configured edge noise: one count of holding dither and one of a
/// settling load. A swapped A/B moves the reading the wrong way from the first push on.
pub(super) const ARM_CHECK_WRONG_COUNTS: f32 = 2.0;

/// Counts an axis may stray from where it armed while the arm check lets it settle,
/// beyond the wrong-way margin: a braked axis' load sags the law's hold when the brake
/// lets go (6 counts, 3.8 µm, on the gantry's Z, whose law starts from zero effort); 10
/// counts is a runaway, not a sag.
pub(super) const ARM_CHECK_SETTLE_COUNTS: f32 = 8.0;
