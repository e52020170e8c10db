//! Backlash and lead-screw error compensation: what the motor must be told so that the
//! tool lands where the program says, on an axis whose screw's lead deviates along the
//! travel and whose nut has play.
//!
//! Per axis, a table of up to [`MAX_COMP_POINTS`] points, each a nominal (commanded)
//! position and a trim for each direction of travel, linearly interpolated between the
//! points and constant beyond the ends (LinuxCNC's `COMP_FILE` semantics, `motion/
//! control.c`: the trim is *added* to the commanded position, `trim = nominal - actual`
//! as measured with a laser or a gauge at the tool), plus an optional backlash added as
//! `±backlash/2` by direction (LinuxCNC's `BACKLASH`; LinuxCNC uses one or the other,
//! here both add, so a table measured in one direction can be completed by a backlash).
//!
//! The direction is the sign of the reference's velocity; at rest the last one holds
//! (LinuxCNC: "not moving, use whatever was there before"). The applied offset follows
//! its target at no more than the axis' `rate_mm_s` (LinuxCNC filters the backlash step
//! the same way), so a reversal crosses the nut's play in a few periods instead of as a
//! step the following-error check would trip on; the offset's rate is added to the
//! reference velocity so that the laws see a consistent reference.
//!
//! Tables are in machine coordinates: they apply only to axes that are referenced (homed,
//! or taking no part in homing), as in LinuxCNC. The servo applies the offset to the
//! reference its laws track (motor side) and holds nominal positions where it stops
//! ([`CompState::nominal_of`] turns a measured motor position into the nominal that
//! needs it, so that arming moves nothing).
//!
//! Storage: trims are kept as `i16` multiples of [`TRIM_UNIT_MM`] (0.1 µm, ±3.27 mm):
//! 8 bytes a point, 2 KiB an axis at 256 points (the board keeps three).

use crate::axes::AXES;
use crate::motion::trajectory::RefSample;
use crate::{Real, Vec3};

/// Most points in one axis' table: LinuxCNC's `EMCMOT_COMP_SIZE`.
pub const MAX_COMP_POINTS: usize = 256;

/// Resolution of a stored trim, mm (0.1 µm: far below an encoder count of the gantry's
/// axes and the 2 µm the compensation is judged by).
pub const TRIM_UNIT_MM: f32 = 1e-4;

/// Largest trim a table holds, mm (`i16::MAX` units).
pub const MAX_TRIM_MM: f32 = i16::MAX as f32 * TRIM_UNIT_MM;

/// Largest backlash accepted, mm: a gap beyond a millimetre is a broken nut, not
/// something to compensate.
pub const MAX_BACKLASH_MM: f32 = 1.0;

/// Default rate at which the applied offset may change, mm/s (LinuxCNC gives its backlash
/// filter the axis' velocity and acceleration headroom; fixed limits keep what the
/// compensation adds to the reference bounded and known).
pub const DEFAULT_COMP_RATE_MM_S: f32 = 20.0;

/// Default acceleration of the applied offset, mm/s²: 20 µm of backlash is crossed in
/// 4 ms at up to 10 mm/s, half the gantry's slowest axis' physical acceleration (Y:
/// 11,000 mm/s², presets/gantry.rs). While an axis takes up such a step the encoder
/// monitor's counts-due check releases its claims on it ([`CompState::crossing_mask`]):
/// a motor side crossing the play alone knocks into its frame's spring, which the rigid
/// model of that check does not bound (it tripped, a false `EncoderJump`, at a reversal
/// of the flexible gantry's Y before).
pub const DEFAULT_COMP_ACCEL_MM_S2: f32 = 5000.0;

/// One point of a table as it is entered: the nominal position and the trims to add when
/// moving forward (increasing position) and in reverse, mm. (Also a link message: the
/// host sends tables point by point, `machine::messages::Request::CompPoints`.)
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    serde::Serialize,
    serde::Deserialize,
    postcard_schema::Schema,
)]
pub struct CompPoint {
    pub nominal_mm: f32,
    pub fwd_trim_mm: f32,
    pub rev_trim_mm: f32,
}

/// Why a table was refused (index: the point, from 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CompError {
    /// More than [`MAX_COMP_POINTS`] points.
    TooManyPoints(usize),
    /// A value is not finite.
    NotFinite(usize),
    /// The nominal positions must increase strictly.
    NotIncreasing(usize),
    /// A trim beyond ±[`MAX_TRIM_MM`].
    TrimTooLarge(usize),
    /// The backlash is negative, not finite or above [`MAX_BACKLASH_MM`].
    BadBacklash,
    /// The rate or the acceleration is not a finite positive number.
    BadRate,
    /// Points entered out of order: the next one expected is this one.
    OutOfOrder(usize),
    /// Fewer points entered than announced.
    Incomplete { got: usize, expected: usize },
}

impl core::fmt::Display for CompError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::TooManyPoints(n) => write!(f, "{n} points: at most {MAX_COMP_POINTS}"),
            Self::NotFinite(i) => write!(f, "point {}: a value is not finite", i + 1),
            Self::NotIncreasing(i) => write!(
                f,
                "point {}: nominal positions must increase strictly",
                i + 1
            ),
            Self::TrimTooLarge(i) => {
                write!(f, "point {}: a trim beyond ±{MAX_TRIM_MM} mm", i + 1)
            }
            Self::BadBacklash => write!(f, "backlash must be in 0..={MAX_BACKLASH_MM} mm"),
            Self::BadRate => write!(
                f,
                "rate_mm_s and accel_mm_s2 must be finite positive numbers"
            ),
            Self::OutOfOrder(i) => write!(f, "points out of order: point {} expected", i + 1),
            Self::Incomplete { got, expected } => {
                write!(f, "{got} points entered of the {expected} announced")
            }
        }
    }
}

impl CompError {
    /// The refusal without its numbers, for the control interrupt (which never formats):
    /// the host knows which points it sent.
    pub const fn message(&self) -> &'static str {
        match self {
            Self::TooManyPoints(_) => "comp: more than 256 points",
            Self::NotFinite(_) => "comp: a value is not finite",
            Self::NotIncreasing(_) => "comp: nominal positions must increase strictly",
            Self::TrimTooLarge(_) => "comp: a trim beyond +-3.2767 mm",
            Self::BadBacklash => "comp: backlash must be in 0..=1 mm",
            Self::BadRate => "comp: rate_mm_s and accel_mm_s2 must be finite positive numbers",
            Self::OutOfOrder(_) => "comp: points out of order (send them from the first on)",
            Self::Incomplete { .. } => "comp: fewer points sent than announced",
        }
    }
}

/// A table entered in parts (the host link's transfer: `Request::CompBegin`, then the
/// points a few at a time in order, then `Request::CompCommit`), each part validated as
/// it comes, as [`AxisCompensation::with_limits`] validates a whole table (which is this
/// builder fed at once).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompBuilder {
    table: AxisCompensation,
    expected: u16,
}

impl CompBuilder {
    /// A builder with nothing announced (a blank memory's: [`Self::push`] and
    /// [`Self::finish`] of an empty table succeed).
    pub const NONE: Self = Self {
        table: AxisCompensation::NONE,
        expected: 0,
    };

    /// A table of `points` points, `backlash_mm` and the offset's limits: refused as
    /// [`AxisCompensation::with_limits`] refuses them.
    pub fn begin(
        points: usize,
        backlash_mm: f32,
        rate_mm_s: f32,
        accel_mm_s2: f32,
    ) -> Result<Self, CompError> {
        if points > MAX_COMP_POINTS {
            return Err(CompError::TooManyPoints(points));
        }
        if !(backlash_mm.is_finite() && (0.0..=MAX_BACKLASH_MM).contains(&backlash_mm)) {
            return Err(CompError::BadBacklash);
        }
        let good = |v: f32| v.is_finite() && v > 0.0;
        if !(good(rate_mm_s) && good(accel_mm_s2)) {
            return Err(CompError::BadRate);
        }
        Ok(Self {
            table: AxisCompensation {
                half_backlash_mm: 0.5 * backlash_mm,
                rate_mm_s,
                accel_mm_s2,
                ..AxisCompensation::NONE
            },
            expected: points as u16,
        })
    }

    /// Points entered so far.
    pub fn received(&self) -> usize {
        self.table.len()
    }

    /// Enter `points`, the first of them the table's point `first` (the next one due:
    /// parts come in order). On a refusal nothing of this part is kept.
    pub fn push(&mut self, first: usize, points: &[CompPoint]) -> Result<(), CompError> {
        let at = self.table.len();
        if first != at {
            return Err(CompError::OutOfOrder(at));
        }
        let end = at + points.len();
        if end > usize::from(self.expected) {
            return Err(CompError::TooManyPoints(end));
        }
        let units = |v: f32, i: usize| -> Result<i16, CompError> {
            if v.abs() > MAX_TRIM_MM {
                return Err(CompError::TrimTooLarge(i));
            }
            // round to the nearest unit: |v| ≤ MAX_TRIM_MM fits i16
            Ok(libm::roundf(v / TRIM_UNIT_MM) as i16)
        };
        // checked whole first, then written: a refused part leaves the table as it was
        let mut prev = at
            .checked_sub(1)
            .and_then(|i| self.table.nominal_mm.get(i).copied());
        for (k, p) in points.iter().enumerate() {
            let i = at + k;
            if !(p.nominal_mm.is_finite() && p.fwd_trim_mm.is_finite() && p.rev_trim_mm.is_finite())
            {
                return Err(CompError::NotFinite(i));
            }
            if prev.is_some_and(|x| p.nominal_mm <= x) {
                return Err(CompError::NotIncreasing(i));
            }
            units(p.fwd_trim_mm, i)?;
            units(p.rev_trim_mm, i)?;
            prev = Some(p.nominal_mm);
        }
        for (k, p) in points.iter().enumerate() {
            let i = at + k;
            if let (Some(x), Some(t)) =
                (self.table.nominal_mm.get_mut(i), self.table.trim.get_mut(i))
            {
                *x = p.nominal_mm;
                *t = [units(p.fwd_trim_mm, i)?, units(p.rev_trim_mm, i)?];
            }
        }
        self.table.len = end as u16;
        Ok(())
    }

    /// The table, once every announced point was entered.
    pub fn finish(&self) -> Result<AxisCompensation, CompError> {
        let (got, expected) = (self.table.len(), usize::from(self.expected));
        if got != expected {
            return Err(CompError::Incomplete { got, expected });
        }
        Ok(self.table)
    }
}

/// One axis' compensation: its table, its backlash and the rate of its offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisCompensation {
    len: u16,
    nominal_mm: [f32; MAX_COMP_POINTS],
    /// Forward and reverse trims, [`TRIM_UNIT_MM`] each.
    trim: [[i16; 2]; MAX_COMP_POINTS],
    half_backlash_mm: f32,
    rate_mm_s: f32,
    accel_mm_s2: f32,
}

impl AxisCompensation {
    /// No compensation (nothing is added, nothing is computed; the limits are unused).
    /// All zeros, so that a servo's tables start as zero-filled memory, not as a 6 KiB
    /// image copied from flash.
    pub const NONE: Self = Self {
        len: 0,
        nominal_mm: [0.0; MAX_COMP_POINTS],
        trim: [[0; 2]; MAX_COMP_POINTS],
        half_backlash_mm: 0.0,
        rate_mm_s: 0.0,
        accel_mm_s2: 0.0,
    };

    /// A table (may be empty) and a backlash with the default rate and acceleration
    /// ([`DEFAULT_COMP_RATE_MM_S`], [`DEFAULT_COMP_ACCEL_MM_S2`]), validated.
    pub fn new(points: &[CompPoint], backlash_mm: f32) -> Result<Self, CompError> {
        Self::with_limits(
            points,
            backlash_mm,
            DEFAULT_COMP_RATE_MM_S,
            DEFAULT_COMP_ACCEL_MM_S2,
        )
    }

    /// [`Self::new`] with the offset's rate (mm/s) and acceleration (mm/s²).
    pub fn with_limits(
        points: &[CompPoint],
        backlash_mm: f32,
        rate_mm_s: f32,
        accel_mm_s2: f32,
    ) -> Result<Self, CompError> {
        let mut b = CompBuilder::begin(points.len(), backlash_mm, rate_mm_s, accel_mm_s2)?;
        b.push(0, points)?;
        b.finish()
    }

    /// Nothing to add: no table and no backlash.
    pub fn is_none(&self) -> bool {
        self.len == 0 && self.half_backlash_mm == 0.0
    }

    /// Points in the table.
    pub fn len(&self) -> usize {
        usize::from(self.len).min(MAX_COMP_POINTS)
    }

    /// No table (a backlash alone may still apply).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The backlash, mm.
    pub fn backlash_mm(&self) -> f32 {
        2.0 * self.half_backlash_mm
    }

    /// The rate of the applied offset, mm/s.
    pub fn rate_mm_s(&self) -> f32 {
        self.rate_mm_s
    }

    /// The acceleration of the applied offset, mm/s².
    pub fn accel_mm_s2(&self) -> f32 {
        self.accel_mm_s2
    }

    /// The point `i` as entered (trims rounded to [`TRIM_UNIT_MM`]: the `f32` nearest to
    /// the whole number of units, so that 80 units read back as 0.008, not 0.007999999).
    pub fn point(&self, i: usize) -> Option<CompPoint> {
        const UNITS_PER_MM: f32 = 10_000.0;
        const _: () = assert!(UNITS_PER_MM * TRIM_UNIT_MM == 1.0);
        (i < self.len()).then(|| CompPoint {
            nominal_mm: self.nominal_mm[i],
            fwd_trim_mm: f32::from(self.trim[i][0]) / UNITS_PER_MM,
            rev_trim_mm: f32::from(self.trim[i][1]) / UNITS_PER_MM,
        })
    }

    /// The trim to add at nominal position `pos_mm` moving `forward` (or in reverse),
    /// backlash included, mm; `hint` is the table segment to look from (the last one
    /// used: the reference moves little between periods), updated.
    pub fn trim_mm(&self, pos_mm: f32, forward: bool, hint: &mut u16) -> f32 {
        let backlash = if forward {
            self.half_backlash_mm
        } else {
            -self.half_backlash_mm
        };
        let n = self.len();
        if n == 0 {
            return backlash;
        }
        // (every read through `get`: the control interrupt has no panic path, and the
        // indices below stay under `n` by construction)
        let at = |i: usize| {
            self.trim.get(i).map_or(0.0, |t| {
                f32::from(if forward { t[0] } else { t[1] }) * TRIM_UNIT_MM
            })
        };
        let x = |i: usize| self.nominal_mm.get(i).copied().unwrap_or(0.0);
        if n == 1 || pos_mm <= x(0) {
            return at(0) + backlash;
        }
        if pos_mm >= x(n - 1) {
            return at(n - 1) + backlash;
        }
        // segment k: nominal[k] <= pos < nominal[k + 1], walked to from the hint
        let mut k = usize::from(*hint).min(n - 2);
        while k > 0 && pos_mm < x(k) {
            k -= 1;
        }
        while k + 2 < n && pos_mm >= x(k + 1) {
            k += 1;
        }
        *hint = k as u16;
        let (x0, x1) = (x(k), x(k + 1));
        // x1 > x0 (validated strictly increasing); guarded all the same
        let f = if x1 > x0 {
            (pos_mm - x0) / (x1 - x0)
        } else {
            0.0
        };
        at(k) + f * (at(k + 1) - at(k)) + backlash
    }
}

/// How long after its offset last moved faster than [`STEP_RATE_MM_S`] an axis counts as
/// taking up its play ([`CompState::crossing_mask`]), s: the knock of a motor side
/// into its frame's spring rings for a few of the mode's periods (the gantry's slowest,
/// Y's 35 Hz: 29 ms each).
pub const CROSSING_HOLD_S: f32 = 0.1;

/// An offset rate above this is a step being taken up (the direction changed, or the axis
/// became referenced), not the table's slope followed at speed (20 µm/m of lead error at
/// 250 mm/s is 0.005 mm/s; a ±15 µm periodic error over 100 mm at 250 mm/s, 0.24 mm/s).
pub const STEP_RATE_MM_S: f32 = 0.5;

/// One axis' compensation state: the direction of travel, the offset applied, its rate,
/// the time left in which it counts as crossing its play, and the table segment last used.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct AxisState {
    reverse: bool,
    offset_mm: f32,
    rate_mm_s: f32,
    crossing_s: f32,
    hint: u16,
}

impl AxisState {
    /// Move the offset towards `target` within the rate and acceleration limits (a
    /// trapezoidal profile: the fastest rate that still stops at the target,
    /// `√(2 a |e|)`, never one that overshoots it within the period); returns the
    /// offset's rate and acceleration.
    fn track(&mut self, target: f32, rate: f32, accel: f32, dt_s: f32) -> (f32, f32) {
        let e = target - self.offset_mm;
        // the discrete stopping rate: from `v`, braking by `a dt` a period, the offset
        // covers `v²/(2a) + v dt/2`; the largest `v` that covers no more than `|e|`
        let half = 0.5 * accel * dt_s;
        let reach = (libm::sqrtf(half * half + 2.0 * accel * e.abs()) - half).min(rate);
        // (dt_s > 0: checked by the caller)
        let land = e.abs() / dt_s;
        let want = reach.min(land).copysign(e);
        let dv = accel * dt_s;
        // (max/min, not `clamp`: `clamp` panics on crossed bounds, a NaN `dv` included)
        let v = want.max(self.rate_mm_s - dv).min(self.rate_mm_s + dv);
        let a = (v - self.rate_mm_s) / dt_s;
        self.rate_mm_s = v;
        self.offset_mm += v * dt_s;
        (v, a)
    }
}

/// The three axes' tables (the machine's: the caller places them, e.g. in the board's
/// static machine memory; 6 KiB, too large to move through the stack with the servo).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompTables {
    axes: [AxisCompensation; AXES],
    /// Axes with something to add (bit i: axis i): none on the rigid, uncompensated
    /// machine, whose period then skips all of it.
    any: u8,
}

impl Default for CompTables {
    fn default() -> Self {
        Self::NONE
    }
}

impl CompTables {
    /// No compensation on any axis (all zeros: zero-filled memory is this).
    pub const NONE: Self = Self {
        axes: [AxisCompensation::NONE; AXES],
        any: 0,
    };

    /// Set `axis`' compensation.
    pub fn set(&mut self, axis: usize, c: AxisCompensation) {
        let Some(slot) = self.axes.get_mut(axis) else {
            return;
        };
        *slot = c;
        let bit = 1u8 << axis;
        if c.is_none() {
            self.any &= !bit;
        } else {
            self.any |= bit;
        }
    }

    /// `axis`' compensation.
    pub fn axis(&self, axis: usize) -> &AxisCompensation {
        &self.axes[axis.min(AXES - 1)]
    }

    /// The axes with something to add (bit i: axis i).
    pub fn axes_in_use(&self) -> u8 {
        self.any
    }

    /// Some axis has something to add.
    #[inline(always)]
    pub fn any(&self) -> bool {
        self.any != 0
    }
}

/// The compensation's state in the servo step: per axis the direction, the offset applied
/// and its rate; whether a hold set this period waits to be turned nominal.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompState {
    state: [AxisState; AXES],
    /// A hold at motor positions was set: [`Self::nominal_of`] turns it into the nominal
    /// position before the next reference is sampled.
    pub pending_hold: bool,
}

impl CompState {
    /// Nothing applied yet.
    pub const NONE: Self = Self {
        state: [AxisState {
            reverse: false,
            offset_mm: 0.0,
            rate_mm_s: 0.0,
            crossing_s: 0.0,
            hint: 0,
        }; AXES],
        pending_hold: false,
    };

    /// Axes taking up a step of their offset (a reversal's backlash), or within
    /// [`CROSSING_HOLD_S`] of one (bit i: axis i).
    #[inline(always)]
    pub fn crossing_mask(&self) -> u8 {
        let mut m = 0;
        for (i, s) in self.state.iter().enumerate() {
            if s.crossing_s > 0.0 {
                m |= 1 << i;
            }
        }
        m
    }

    /// The offset applied last period per axis, mm (motor reference − nominal).
    pub fn offsets_mm(&self) -> [f32; AXES] {
        core::array::from_fn(|i| self.state[i].offset_mm)
    }

    /// Add this period's offsets of `tables` to `r` (the nominal reference, in place): on
    /// the axes of `active` (referenced) towards their trims, each within its rate and
    /// acceleration over `dt_s`; elsewhere none (at once: those references are motor
    /// positions); the direction follows the reference's velocity on every axis. The
    /// offset's rate and acceleration are added to the velocity and the acceleration.
    pub fn apply<R: Real>(
        &mut self,
        tables: &CompTables,
        r: &mut RefSample<R>,
        active: u8,
        dt_s: f32,
    ) {
        if tables.any == 0 || !(dt_s > 0.0) {
            return;
        }
        for i in 0..AXES {
            if tables.any & (1 << i) == 0 {
                continue;
            }
            let (c, s) = (&tables.axes[i], &mut self.state[i]);
            let v = r.vel[i].to_f32();
            if v > 0.0 {
                s.reverse = false;
            } else if v < 0.0 {
                s.reverse = true;
            }
            if active & (1 << i) == 0 {
                // an uncompensated mode's reference is the motor's own: nothing is added
                // (arming, the encoder checks and identification hold motor positions)
                s.offset_mm = 0.0;
                s.rate_mm_s = 0.0;
                s.crossing_s = 0.0;
                continue;
            }
            let target = c.trim_mm(r.pos[i].to_f32(), !s.reverse, &mut s.hint);
            let (v, a) = s.track(target, c.rate_mm_s, c.accel_mm_s2, dt_s);
            s.crossing_s = if v.abs() > STEP_RATE_MM_S {
                CROSSING_HOLD_S
            } else {
                (s.crossing_s - dt_s).max(0.0)
            };
            r.pos[i] += R::from_f32(s.offset_mm);
            r.vel[i] += R::from_f32(v);
            r.acc[i] += R::from_f32(a);
        }
    }

    /// The nominal position that the motor position `motor` stands for on the axes of
    /// `active` (the inverse of [`Self::apply`] at rest), with the offsets set to match
    /// at once: holding there moves nothing. Inactive axes: the offset is zero.
    pub fn nominal_of<R: Real>(
        &mut self,
        tables: &CompTables,
        motor: Vec3<R>,
        active: u8,
    ) -> Vec3<R> {
        let mut n = motor;
        if tables.any == 0 {
            return n;
        }
        for i in 0..AXES {
            if tables.any & (1 << i) == 0 {
                continue;
            }
            let (c, s) = (&tables.axes[i], &mut self.state[i]);
            if active & (1 << i) == 0 {
                s.offset_mm = 0.0;
                s.rate_mm_s = 0.0;
                continue;
            }
            let m = motor[i].to_f32();
            // n + trim(n) = m: the trim's slope is tiny (µm per mm), two fixed-point
            // steps converge far below the trim's resolution
            let mut x = m - c.trim_mm(m, !s.reverse, &mut s.hint);
            x = m - c.trim_mm(x, !s.reverse, &mut s.hint);
            let trim = c.trim_mm(x, !s.reverse, &mut s.hint);
            s.offset_mm = trim;
            s.rate_mm_s = 0.0;
            n[i] = motor[i] - R::from_f32(trim);
        }
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> AxisCompensation {
        let pts = [
            CompPoint {
                nominal_mm: -100.0,
                fwd_trim_mm: 0.010,
                rev_trim_mm: -0.010,
            },
            CompPoint {
                nominal_mm: 0.0,
                fwd_trim_mm: 0.0,
                rev_trim_mm: -0.004,
            },
            CompPoint {
                nominal_mm: 100.0,
                fwd_trim_mm: -0.020,
                rev_trim_mm: -0.030,
            },
        ];
        AxisCompensation::new(&pts, 0.0).unwrap()
    }

    #[test]
    fn trims_interpolate_and_hold_beyond_the_ends() {
        let t = table();
        let mut h = 0;
        assert!((t.trim_mm(-50.0, true, &mut h) - 0.005).abs() < 1e-6);
        assert!((t.trim_mm(50.0, false, &mut h) - (-0.017)).abs() < 1e-6);
        assert!((t.trim_mm(-500.0, true, &mut h) - 0.010).abs() < 1e-6);
        assert!((t.trim_mm(500.0, false, &mut h) - (-0.030)).abs() < 1e-6);
        // the hint walks both ways
        assert!((t.trim_mm(-99.0, true, &mut h) - (0.010 - 0.0001)).abs() < 1e-6);
    }

    #[test]
    fn bad_tables_are_refused_with_the_point() {
        let p = |n, f| CompPoint {
            nominal_mm: n,
            fwd_trim_mm: f,
            rev_trim_mm: 0.0,
        };
        let r = |pts: &[CompPoint]| AxisCompensation::new(pts, 0.0).err();
        assert_eq!(
            r(&[p(0.0, 0.0), p(0.0, 0.0)]),
            Some(CompError::NotIncreasing(1))
        );
        assert_eq!(r(&[p(0.0, f32::NAN)]), Some(CompError::NotFinite(0)));
        assert_eq!(r(&[p(0.0, 4.0)]), Some(CompError::TrimTooLarge(0)));
        assert_eq!(
            AxisCompensation::new(&[], -0.1).err(),
            Some(CompError::BadBacklash)
        );
        assert_eq!(
            AxisCompensation::with_limits(&[], 0.1, 0.0, 1.0).err(),
            Some(CompError::BadRate)
        );
        assert_eq!(
            AxisCompensation::with_limits(&[], 0.1, 1.0, f32::NAN).err(),
            Some(CompError::BadRate)
        );
        let many = [p(0.0, 0.0); MAX_COMP_POINTS + 1];
        assert_eq!(r(&many), Some(CompError::TooManyPoints(257)));
    }

    #[test]
    fn a_table_entered_in_parts_equals_the_table_entered_whole_and_a_bad_part_is_not_kept() {
        let pts: [CompPoint; 20] = core::array::from_fn(|i| CompPoint {
            nominal_mm: -95.0 + 10.0 * i as f32,
            fwd_trim_mm: 0.001 * i as f32,
            rev_trim_mm: -0.0007 * i as f32,
        });
        let whole = AxisCompensation::with_limits(&pts, 0.02, 15.0, 4000.0).unwrap();
        let mut b = CompBuilder::begin(20, 0.02, 15.0, 4000.0).unwrap();
        // out of order: refused, nothing kept
        assert_eq!(b.push(8, &pts[8..16]), Err(CompError::OutOfOrder(0)));
        b.push(0, &pts[..8]).unwrap();
        assert_eq!(
            b.finish(),
            Err(CompError::Incomplete {
                got: 8,
                expected: 20
            })
        );
        // a part whose last point goes back: refused whole (its good points not kept)
        let mut bad = [pts[8], pts[9], pts[10]];
        bad[2].nominal_mm = pts[9].nominal_mm;
        assert_eq!(b.push(8, &bad), Err(CompError::NotIncreasing(10)));
        assert_eq!(b.received(), 8);
        // nor may a part go back from the last point kept
        assert_eq!(b.push(8, &[pts[0]]), Err(CompError::NotIncreasing(8)));
        b.push(8, &pts[8..16]).unwrap();
        // beyond the announced count
        let mut more = [pts[19]; 5];
        for (k, p) in more.iter_mut().enumerate() {
            p.nominal_mm += k as f32;
        }
        assert_eq!(b.push(16, &more), Err(CompError::TooManyPoints(21)));
        b.push(16, &pts[16..]).unwrap();
        assert_eq!(b.finish(), Ok(whole));
        assert_eq!(
            CompBuilder::begin(257, 0.0, 1.0, 1.0),
            Err(CompError::TooManyPoints(257))
        );
    }

    #[test]
    fn a_reversal_crosses_the_backlash_within_the_limits_and_holding_moves_nothing() {
        let mut t = CompTables::NONE;
        let mut c = CompState::NONE;
        let (rate, accel) = (10.0f32, 2000.0f32);
        t.set(
            0,
            AxisCompensation::with_limits(&[], 0.020, rate, accel).unwrap(),
        );
        let dt = 1e-4;
        let step = |c: &mut CompState, v: f32| {
            let mut r = RefSample::<f32>::default();
            r.vel[0] = v;
            c.apply(&t, &mut r, 0b111, dt);
            r
        };
        for _ in 0..200 {
            step(&mut c, 1.0);
        }
        assert!(
            (c.offsets_mm()[0] - 0.010).abs() < 1e-6,
            "{:?}",
            c.offsets_mm()
        );
        // reverse: to −10 µm, the added velocity and acceleration within the limits,
        // never beyond the target by more than nm, in about the triangular profile's
        // 2·√(d/a) = 6.3 ms
        let mut last = c.offsets_mm()[0];
        let mut k_done = None;
        for k in 0..400 {
            let r = step(&mut c, -1.0);
            let (o, v, a) = (c.offsets_mm()[0], r.vel[0] + 1.0, r.acc[0]);
            assert!(
                v.abs() <= rate + 1e-3 && a.abs() <= accel * 1.001,
                "{k}: {v} {a}"
            );
            // (the discrete profile lands within a few nm)
            assert!(
                o >= -0.010 - 5e-6 && o <= last + 5e-6,
                "{k}: {o} after {last}"
            );
            last = o;
            if k_done.is_none() && (o + 0.010).abs() < 1e-6 {
                k_done = Some(k);
            }
        }
        let k = k_done.expect("reached");
        assert!((60..=75).contains(&k), "{k} periods");
        // the nominal of a motor position, applied again, gives the motor position
        let motor = Vec3::new(5.0f32, 0.0, 0.0);
        let n = c.nominal_of(&t, motor, 0b111);
        let mut r = RefSample {
            pos: n,
            ..Default::default()
        };
        c.apply(&t, &mut r, 0b111, dt);
        assert!((r.pos[0] - 5.0).abs() < 1e-6, "{:?}", r.pos);
        // an inactive axis has no offset, at once
        let mut r = RefSample::<f32>::default();
        c.apply(&t, &mut r, 0, dt);
        assert_eq!(r.pos[0], 0.0);
        assert_eq!(c.crossing_mask(), 0);
    }

    #[test]
    fn nothing_configured_is_bit_exact_passthrough() {
        let mut c = CompState::NONE;
        let mut r = RefSample {
            pos: Vec3::new(1.25f32, -3.5, 7.0),
            vel: Vec3::new(0.5, 0.0, -1.0),
            acc: Vec3::zero(),
        };
        let before = r;
        c.apply(&CompTables::NONE, &mut r, 0b111, 1e-4);
        assert_eq!(r, before);
    }
}
