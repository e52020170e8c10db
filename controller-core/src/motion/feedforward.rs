//! Feed-forward from the reference for what the laws cannot see coming (issue 24, item 5):
//! the Coulomb friction that flips at every reversal of an axis, and the frame between
//! the motor (where the encoder is) and the tool (where the contour is judged).
//!
//! Per axis, three terms, each zero unless configured:
//!
//! - **Coulomb pre-compensation** (an effort added to the law's): the friction torque of
//!   the direction the reference moves in, `f₊` or `f₋` (the identified model's
//!   `coulomb_pos_mnm`/`coulomb_neg_mnm`), scaled by `ρ(v) = x / √(1 + x²)`, `x = v / v_band` (the regularised sign of
//!   smooth friction models).
//!   Without it the integral action and the switching term must first wind through the
//!   whole step `f₊ − f₋` after a reversal, and the axis sticks meanwhile: the quadrant
//!   spike of the ISO 230-4 circle (8 µm on the rigid gantry at R 50 mm, F 3000). The
//!   sliding-mode laws' equivalent control already cancels `J q̈_d + B q̇` with their model;
//!   PID has its own velocity and acceleration feed-forward (`kv_ff`, `ka_ff`); the
//!   Coulomb term is what none of them carries.
//! - **Frame compliance** (added to the position the motor must reach): the tool side of
//!   a compliant axis lags its motor by `J_tool · a / k = a / ω_a²` under an acceleration
//!   `a`, `ω_a` the axis' anti-resonance (the tool side's own mode with the motor held,
//!   `host-sim freqresp` measures it): the motor is sent ahead by `compliance_s2 · a`.
//! - **Frame deflection under the tool-side viscous friction**: `B_tool v / k`, a lag of
//!   the tool behind the motor, `lag_s · v` (0.14 ms on the flexible gantry's Y, 0.04 ms
//!   on X: at 50 mm/s a 2.7 µm ellipse on the circle, the axes' lags differing).
//! - **Frame deflection under the tool-side friction** (added to the position too): the
//!   guides' friction bends the frame by `f_tool / k` while the axis moves, the other way
//!   after a reversal, unseen by the encoder. At rest the guides let go and the frame
//!   relaxes, so a table measured at rest (backlash, lead error: [`super::compensation`])
//!   does not hold it; it is `deflection · ρ(v)`, `deflection_pos_mm` or `deflection_neg_mm` by
//!   direction: the tool's lag while moving at the tool less its lag at rest (`host-sim
//!   compensation` measures both). On the flexible gantry it is 21 µm on Y: a 42 µm
//!   reversal spike on the circle.
//!
//! The position terms' rate is added to the reference velocity (`deflection · ρ'(v) ·
//! a`) so that the laws see a consistent reference. All three vanish at rest, so arming
//! or stopping moves nothing; with nothing configured the servo skips this entirely
//! (the rigid gantry's figures are bit-identical with and without this module).

use crate::axes::AXES;
use crate::config::{finite, non_negative, positive, ConfigError};
use crate::motion::trajectory::RefSample;
use crate::{Real, Vec3};

/// Reference speed over which the friction terms change sign when a configuration gives
/// none, mm/s: the regularisation speed of the simulated guides' and nut's friction
/// (`plant::physical`, `v_reg` = 0.5 mm/s), where a real ball screw's friction also
/// turns (its pre-sliding range is a few µm: at the circle's 50 mm/s² reversal, 5 ms).
pub const DEFAULT_REVERSAL_BAND_MM_S: f32 = 0.5;

/// Largest compliance accepted, s²: `1/ω_a²` at 5 Hz (a frame softer than that is not
/// a machine tool's; the gantry's lowest anti-resonance is 37 Hz, 1.9e-5 s²).
pub const MAX_COMPLIANCE_S2: f32 = 1.0e-3;

/// Largest viscous lag accepted, s (a hundred times the flexible gantry's 0.14 ms).
pub const MAX_LAG_S: f32 = 0.01;

/// Largest frame deflection accepted, mm (ten times the flexible gantry's 21 µm).
pub const MAX_DEFLECTION_MM: f32 = 0.25;

/// One axis' feed-forward (all zero: none).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct FeedForwardConfig {
    /// Coulomb torque added while the reference moves forward, mN·m (≥ 0; the model's
    /// `coulomb_pos_mnm`; 0: none).
    #[cfg_attr(feature = "serde", serde(default))]
    pub coulomb_pos_mnm: f32,
    /// Coulomb torque added while the reference moves backward, mN·m (≤ 0; the model's
    /// `coulomb_neg_mnm`; 0: none).
    #[cfg_attr(feature = "serde", serde(default))]
    pub coulomb_neg_mnm: f32,
    /// The frame's compliance as a lag per acceleration, s² (`1/ω_a²`; 0: a rigid axis).
    #[cfg_attr(feature = "serde", serde(default))]
    pub compliance_s2: f32,
    /// The frame's deflection under the tool-side viscous friction as a lag, s (`B_tool /
    /// k`: the tool trails the motor by `lag_s · v`; 0: none).
    #[cfg_attr(feature = "serde", serde(default))]
    pub lag_s: f32,
    /// The frame's deflection under the tool-side friction while moving forward, mm (≥ 0;
    /// 0: none).
    #[cfg_attr(feature = "serde", serde(default))]
    pub deflection_pos_mm: f32,
    /// The same while moving backward, mm (≤ 0; 0: none).
    #[cfg_attr(feature = "serde", serde(default))]
    pub deflection_neg_mm: f32,
    /// Reference speed over which the friction terms change sign, mm/s.
    #[cfg_attr(feature = "serde", serde(default = "default_band"))]
    pub reversal_band_mm_s: f32,
    /// Friction at rest over its level in motion (the Stribeck peak, ≥ 1; 1: none): the
    /// friction terms are scaled by `1 + (stiction_ratio − 1) / (1 + (v/v_s)²)`.
    #[cfg_attr(feature = "serde", serde(default = "one"))]
    pub stiction_ratio: f32,
    /// The speed over which the Stribeck peak decays, mm/s.
    #[cfg_attr(feature = "serde", serde(default = "default_v_stribeck"))]
    pub v_stribeck_mm_s: f32,
}

#[cfg(feature = "serde")]
fn one() -> f32 {
    1.0
}

#[cfg(feature = "serde")]
fn default_v_stribeck() -> f32 {
    DEFAULT_V_STRIBECK_MM_S
}

/// The Stribeck speed when a configuration gives none, mm/s: the simulated plant's
/// (typical of lubricated ball screws and profile rails).
pub const DEFAULT_V_STRIBECK_MM_S: f32 = crate::plant::physical::DEFAULT_V_STRIBECK_MM_S;

/// Largest Stribeck peak accepted (friction at rest over friction in motion).
pub const MAX_STICTION_RATIO: f32 = 3.0;

#[cfg(feature = "serde")]
fn default_band() -> f32 {
    DEFAULT_REVERSAL_BAND_MM_S
}

impl FeedForwardConfig {
    /// No feed-forward.
    pub const NONE: Self = Self {
        coulomb_pos_mnm: 0.0,
        coulomb_neg_mnm: 0.0,
        compliance_s2: 0.0,
        lag_s: 0.0,
        deflection_pos_mm: 0.0,
        deflection_neg_mm: 0.0,
        reversal_band_mm_s: DEFAULT_REVERSAL_BAND_MM_S,
        stiction_ratio: 1.0,
        v_stribeck_mm_s: DEFAULT_V_STRIBECK_MM_S,
    };

    /// Does this add anything?
    pub fn any(&self) -> bool {
        self.coulomb_pos_mnm != 0.0
            || self.coulomb_neg_mnm != 0.0
            || self.compliance_s2 != 0.0
            || self.lag_s != 0.0
            || self.deflection_pos_mm != 0.0
            || self.deflection_neg_mm != 0.0
    }

    /// Check the values (errors name the field).
    pub fn validate(&self) -> Result<(), ConfigError> {
        non_negative(self.coulomb_pos_mnm, "feedforward.coulomb_pos_mnm")?;
        if !(finite(self.coulomb_neg_mnm, "feedforward.coulomb_neg_mnm")? <= 0.0) {
            return Err(ConfigError::OutOfRange("feedforward.coulomb_neg_mnm (≤ 0)"));
        }
        if non_negative(self.compliance_s2, "feedforward.compliance_s2")? > MAX_COMPLIANCE_S2 {
            return Err(ConfigError::OutOfRange(
                "feedforward.compliance_s2 (0..1e-3 s²)",
            ));
        }
        if non_negative(self.lag_s, "feedforward.lag_s")? > MAX_LAG_S {
            return Err(ConfigError::OutOfRange("feedforward.lag_s (0..0.01 s)"));
        }
        if non_negative(self.deflection_pos_mm, "feedforward.deflection_pos_mm")?
            > MAX_DEFLECTION_MM
        {
            return Err(ConfigError::OutOfRange(
                "feedforward.deflection_pos_mm (0..0.25 mm)",
            ));
        }
        let neg = finite(self.deflection_neg_mm, "feedforward.deflection_neg_mm")?;
        if !(-MAX_DEFLECTION_MM..=0.0).contains(&neg) {
            return Err(ConfigError::OutOfRange(
                "feedforward.deflection_neg_mm (-0.25..0 mm)",
            ));
        }
        positive(self.reversal_band_mm_s, "feedforward.reversal_band_mm_s")?;
        let r = finite(self.stiction_ratio, "feedforward.stiction_ratio")?;
        if !(1.0..=MAX_STICTION_RATIO).contains(&r) {
            return Err(ConfigError::OutOfRange("feedforward.stiction_ratio (1..3)"));
        }
        positive(self.v_stribeck_mm_s, "feedforward.v_stribeck_mm_s")?;
        Ok(())
    }
}

impl Default for FeedForwardConfig {
    fn default() -> Self {
        Self::NONE
    }
}

/// One axis' validated terms in the servo's number type.
#[derive(Clone, Copy, Debug, PartialEq)]
struct AxisTerms<R> {
    coulomb_pos: R,
    coulomb_neg: R,
    compliance: R,
    lag: R,
    deflection_pos: R,
    deflection_neg: R,
    inv_band: R,
    /// `stiction_ratio − 1`, and `1/v_s`.
    stribeck: R,
    inv_v_stribeck: R,
}

/// How long after the deflection term last moved the motor faster than
/// [`TURN_RATE_MM_S`] an axis counts as turning ([`FeedForward::turning_mask`]), s: as a
/// compensation table's step ([`crate::motion::compensation::CROSSING_HOLD_S`]), the
/// motor side catching up with the term's step rings for a few of the frame's periods.
pub const TURN_HOLD_S: f32 = crate::motion::compensation::CROSSING_HOLD_S;

/// A deflection rate above this is the term turning with the friction (a reversal, or a
/// stop: up to 0.25 mm within the reversal band, tens of mm/s after a hard stop), not its
/// slow change at speed; the compensation's threshold for the same kind of step.
pub const TURN_RATE_MM_S: f32 = crate::motion::compensation::STEP_RATE_MM_S;

/// The three axes' feed-forward, validated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeedForward<R> {
    axes: [AxisTerms<R>; AXES],
    /// Axes with a term (bit i: axis i); none: the servo skips the block.
    any: u8,
    /// Per axis, time left in which the deflection term counts as turning, s.
    turning_s: [f32; AXES],
}

impl<R: Real> FeedForward<R> {
    /// Validate the axes' configurations.
    pub fn new(c: &[FeedForwardConfig; AXES]) -> Result<Self, ConfigError> {
        let mut any = 0;
        let mut axes = [AxisTerms {
            coulomb_pos: R::ZERO,
            coulomb_neg: R::ZERO,
            compliance: R::ZERO,
            lag: R::ZERO,
            deflection_pos: R::ZERO,
            deflection_neg: R::ZERO,
            inv_band: R::ZERO,
            stribeck: R::ZERO,
            inv_v_stribeck: R::ZERO,
        }; AXES];
        for (i, (c, a)) in c.iter().zip(axes.iter_mut()).enumerate() {
            c.validate()?;
            if c.any() {
                any |= 1 << i;
            }
            *a = AxisTerms {
                coulomb_pos: R::from_f32(c.coulomb_pos_mnm),
                coulomb_neg: R::from_f32(c.coulomb_neg_mnm),
                compliance: R::from_f32(c.compliance_s2),
                lag: R::from_f32(c.lag_s),
                deflection_pos: R::from_f32(c.deflection_pos_mm),
                deflection_neg: R::from_f32(c.deflection_neg_mm),
                inv_band: R::from_f32(1.0 / c.reversal_band_mm_s),
                stribeck: R::from_f32(c.stiction_ratio - 1.0),
                inv_v_stribeck: R::from_f32(1.0 / c.v_stribeck_mm_s),
            };
        }
        Ok(Self {
            axes,
            any,
            turning_s: [0.0; AXES],
        })
    }

    /// Axes whose deflection term turned within [`TURN_HOLD_S`] (bit i: axis i): it steps
    /// the motor by the frame's bend as the friction turns, which the counts-due check's
    /// rigid bounds do not describe (the servo releases its claims there, as for a
    /// compensation table's step; the following-error, jump and runaway checks still
    /// watch the axis).
    #[inline(always)]
    pub fn turning_mask(&self) -> u8 {
        let mut m = 0;
        for (i, t) in self.turning_s.iter().enumerate() {
            if *t > 0.0 {
                m |= 1 << i;
            }
        }
        m
    }

    /// Does any axis have a term?
    #[inline(always)]
    pub fn any(&self) -> bool {
        self.any != 0
    }

    /// Add to `r` what the motor must follow for the tool to follow the programmed
    /// reference `nominal`, on the axes of `active` (bit i: axis i); returns the Coulomb
    /// effort of `nominal`'s direction on them. (`r` is `nominal` plus what the
    /// compensation added: the terms are the nominal's, not the compensation offset's
    /// own rates.) `dt_s`, the period, counts down [`Self::turning_mask`]'s hold.
    #[inline]
    pub fn apply(
        &mut self,
        nominal: &RefSample<R>,
        r: &mut RefSample<R>,
        active: u8,
        dt_s: f32,
    ) -> Vec3<R> {
        let mut effort = Vec3::zero();
        let on = self.any & active;
        if on == 0 {
            return effort;
        }
        for (i, t) in self.axes.iter().enumerate() {
            if on & (1 << i) == 0 {
                continue;
            }
            let (v, a) = (nominal.vel[i], nominal.acc[i]);
            // the friction's shape h(v) = ρ(v/v_band) · P(v/v_s), P the Stribeck peak
            // 1 + (s − 1)/(1 + y²), and its derivative in v
            let (rho, d_rho) = reversal_shape(v * t.inv_band);
            let (p, d_p) = stribeck_peak(v * t.inv_v_stribeck, t.stribeck);
            let h = rho * p;
            let d_h = d_rho * t.inv_band * p + rho * d_p * t.inv_v_stribeck;
            let (coulomb, deflection) = if rho > R::ZERO {
                (t.coulomb_pos, t.deflection_pos)
            } else {
                (-t.coulomb_neg, -t.deflection_neg)
            };
            effort[i] = coulomb * h;
            r.pos[i] += t.compliance * a + t.lag * v + deflection * h;
            // the position terms' rates, so that the laws see a consistent reference:
            // the lag's and the deflection's, h'(v)·a. (Not their accelerations: the
            // deflection's, h''(v)·a², reaches 200 mm/s² as a reversal's friction turns,
            // and fed to the laws' equivalent control with the whole axis' inertia it
            // rang the flexible gantry's Y mode: G 6.8 -> 11.0 µm on the circle.)
            let turn_rate = deflection * d_h * a;
            r.vel[i] += t.lag * a + turn_rate;
            if let Some(left) = self.turning_s.get_mut(i) {
                *left = if turn_rate.abs().to_f32() > TURN_RATE_MM_S {
                    TURN_HOLD_S
                } else {
                    (*left - dt_s).max(0.0)
                };
            }
        }
        effort
    }
}

/// Beyond this many bands the shape is its sign (within 1.2e-4 of it; and `x²` stays
/// far inside every number type's range).
const SHAPE_SATURATED: f32 = 64.0;

/// The friction terms' shape `ρ(x) = x / √(1 + x²)` at `x = v / v_band` (the standard
/// regularised sign of smooth friction models, the simulated plant's among them), and
/// its slope `dρ/dx = (1 + x²)^(−3/2)`. A non-finite `x` gives zeros.
#[inline(always)]
fn reversal_shape<R: Real>(x: R) -> (R, R) {
    let big = R::from_f32(SHAPE_SATURATED);
    if !x.in_range(big) {
        // beyond the band (or not finite: clamp_finite makes that 0)
        return (x.clamp_finite(big).sign(), R::ZERO);
    }
    let q = (R::ONE + x * x).sqrt_pos();
    let inv_q = R::ONE.div_or(q, R::ZERO);
    (x * inv_q, inv_q * inv_q * inv_q)
}

/// The Stribeck peak `P(y) = 1 + e / (1 + y²)` at `y = v / v_s` (`e` = stiction ratio
/// − 1) and its derivative in `y`.
#[inline(always)]
fn stribeck_peak<R: Real>(y: R, e: R) -> (R, R) {
    if e == R::ZERO {
        return (R::ONE, R::ZERO);
    }
    let big = R::from_f32(SHAPE_SATURATED);
    if !y.in_range(big) {
        // far beyond v_s (or not finite): the peak has decayed (within e/4096)
        return (R::ONE, R::ZERO);
    }
    let w = R::ONE.div_or(R::ONE + y * y, R::ZERO);
    (R::ONE + e * w, -R::from_f32(2.0) * e * y * w * w)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::format;

    fn cfg() -> FeedForwardConfig {
        FeedForwardConfig {
            coulomb_pos_mnm: 60.0,
            coulomb_neg_mnm: -50.0,
            compliance_s2: 2.0e-5,
            lag_s: 0.0,
            deflection_pos_mm: 0.021,
            deflection_neg_mm: -0.018,
            reversal_band_mm_s: 0.5,
            stiction_ratio: 1.0,
            v_stribeck_mm_s: 2.0,
        }
    }

    fn sample(v: f32, a: f32) -> RefSample<f32> {
        RefSample {
            pos: Vec3::new(10.0, 10.0, 10.0),
            vel: Vec3::new(v, v, v),
            acc: Vec3::new(a, a, a),
        }
    }

    #[test]
    fn friction_and_deflection_follow_the_direction_and_vanish_at_rest() {
        let mut ff = FeedForward::<f32>::new(&[FeedForwardConfig::NONE, cfg(), cfg()]).unwrap();
        let mut r = sample(50.0, 0.0);
        let u = ff.apply(&{ r }, &mut r, 0b111, 1e-4);
        assert_eq!(u[0], 0.0);
        assert_eq!(r.pos[0], 10.0);
        assert_eq!(u[1], 60.0);
        assert!((r.pos[1] - 10.021).abs() < 1e-6);
        let mut r = sample(-50.0, 0.0);
        let u = ff.apply(&{ r }, &mut r, 0b111, 1e-4);
        assert_eq!(u[1], -50.0);
        assert!((r.pos[1] - 9.982).abs() < 1e-6);
        // half the band: ρ = 0.5/√1.25, its slope 1.25^(-3/2), the deflection's rate added
        let mut r = sample(0.25, 100.0);
        let u = ff.apply(&{ r }, &mut r, 0b111, 1e-4);
        let (rho, slope) = (0.5 / 1.25f32.sqrt(), 1.25f32.powf(-1.5));
        assert!((u[1] - 60.0 * rho).abs() < 1e-4, "{u:?}");
        let dpos = 2.0e-5 * 100.0 + 0.021 * rho;
        assert!((r.pos[1] - (10.0 + dpos)).abs() < 1e-6, "{r:?}");
        let dvel = 0.021 * slope / 0.5 * 100.0;
        assert!((r.vel[1] - (0.25 + dvel)).abs() < 1e-4, "{r:?}");
        // the shape is continuous where it turns into its sign
        let (a, _) = reversal_shape(SHAPE_SATURATED * 0.999f32);
        let (b, _) = reversal_shape(SHAPE_SATURATED * 1.001f32);
        assert!((a - b).abs() < 2e-4 && b == 1.0, "{a} {b}");
        // at rest nothing moves
        let mut r = sample(0.0, 0.0);
        let u = ff.apply(&{ r }, &mut r, 0b111, 1e-4);
        assert_eq!(u, Vec3::zero());
        assert_eq!(r, sample(0.0, 0.0));
        // an inactive axis gets nothing
        let mut r = sample(50.0, 10.0);
        let u = ff.apply(&{ r }, &mut r, 0b001, 1e-4);
        assert_eq!(u, Vec3::zero());
        assert_eq!(r, sample(50.0, 10.0));
    }

    #[test]
    fn a_stop_turns_the_deflection_and_the_mask_holds_it() {
        // Y with a deflection, X with the Coulomb term only (it never turns)
        let mut c = cfg();
        c.deflection_pos_mm = 0.0;
        c.deflection_neg_mm = 0.0;
        let mut ff = FeedForward::<f32>::new(&[c, cfg(), FeedForwardConfig::NONE]).unwrap();
        let dt = 1e-4;
        // at speed: the term stands still
        let mut r = sample(50.0, 0.0);
        ff.apply(&{ r }, &mut r, 0b111, dt);
        assert_eq!(ff.turning_mask(), 0);
        // a 2000 mm/s² stop through the reversal band: 0.021 mm · ρ'(v/0.5) / 0.5 · 2000,
        // 84 mm/s at v = 0, far above TURN_RATE_MM_S
        let mut r = sample(0.1, -2000.0);
        ff.apply(&{ r }, &mut r, 0b111, dt);
        assert_eq!(ff.turning_mask(), 0b010);
        // held for TURN_HOLD_S at rest, then released
        let periods = (TURN_HOLD_S / dt).round() as usize;
        for k in 0..periods + 2 {
            let mut r = sample(0.0, 0.0);
            ff.apply(&{ r }, &mut r, 0b111, dt);
            if k + 2 < periods {
                assert_eq!(ff.turning_mask(), 0b010, "period {k}");
            }
        }
        assert_eq!(ff.turning_mask(), 0);
        // slow through the band (5 mm/s²: 0.2 mm/s at most) is not a turn
        let mut r = sample(0.0, -5.0);
        ff.apply(&{ r }, &mut r, 0b111, dt);
        assert_eq!(ff.turning_mask(), 0);
    }

    #[test]
    fn the_offsets_rate_is_its_derivative_with_the_stribeck_peak() {
        let mut c = cfg();
        c.stiction_ratio = 1.3;
        c.compliance_s2 = 0.0;
        let mut ff = FeedForward::<f64>::new(&[c; AXES]).unwrap();
        let a = 50.0;
        let mut at = |v: f64| {
            let n = RefSample {
                pos: Vec3::new(0.0, 0.0, 0.0),
                vel: Vec3::new(v, v, v),
                acc: Vec3::new(a, a, a),
            };
            let mut r = n;
            let u = ff.apply(&n, &mut r, 0b111, 1e-4);
            (r.pos[1], r.vel[1] - v, u[1])
        };
        for v in [-3.0, -1.0, -0.3, 0.2, 0.7, 2.5, 6.0] {
            // the reference moves at v and accelerates at a: the offset's rate is
            // d(offset)/dv · a
            let dv = 1e-6;
            let numeric = (at(v + dv).0 - at(v - dv).0) / (2.0 * dv) * a;
            let (_, rate, u) = at(v);
            assert!(
                (rate - numeric).abs() < 1e-6 * numeric.abs().max(1.0),
                "{v}: {rate} {numeric}"
            );
            // the Stribeck peak raises the friction at low speed, up to 1.3 times
            let level = if v > 0.0 { 60.0 } else { 50.0 };
            assert!(u.abs() <= 1.3 * level + 1e-9, "{v}: {u}");
        }
        assert!(
            at(1.0).2 > 60.0 * 0.7 && at(20.0).2 < 60.3,
            "{} {}",
            at(1.0).2,
            at(20.0).2
        );
    }

    #[test]
    fn a_non_finite_reference_adds_nothing_unbounded() {
        let mut ff = FeedForward::<f32>::new(&[cfg(); AXES]).unwrap();
        let mut r = sample(f32::NAN, 0.0);
        let u = ff.apply(&{ r }, &mut r, 0b111, 1e-4);
        for i in 0..AXES {
            assert!(u[i].is_finite() && u[i].abs() <= 60.0, "{u:?}");
        }
    }

    #[test]
    fn bad_values_are_refused_by_name() {
        let bad = |f: fn(&mut FeedForwardConfig)| {
            let mut c = cfg();
            f(&mut c);
            FeedForward::<f32>::new(&[c; AXES]).unwrap_err()
        };
        assert!(format!("{:?}", bad(|c| c.coulomb_pos_mnm = -1.0)).contains("coulomb_pos"));
        assert!(format!("{:?}", bad(|c| c.coulomb_neg_mnm = 1.0)).contains("coulomb_neg"));
        assert!(format!("{:?}", bad(|c| c.compliance_s2 = 1.0)).contains("compliance"));
        assert!(format!("{:?}", bad(|c| c.deflection_pos_mm = f32::NAN)).contains("deflection"));
        assert!(format!("{:?}", bad(|c| c.deflection_neg_mm = 0.01)).contains("deflection_neg"));
        assert!(format!("{:?}", bad(|c| c.reversal_band_mm_s = 0.0)).contains("band"));
        assert!(!FeedForward::<f32>::new(&[FeedForwardConfig::NONE; AXES])
            .unwrap()
            .any());
    }
}
