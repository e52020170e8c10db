//! Stability margins of the loop `L = C·F·P` from sampled frequency responses: the
//! measured plant `P(f)` (effort → position), the controller's linear part `C(f)` (e.g.
//! [`pid_response`]) and the output filters `F(f)`; and the rule that accepts a filter.
//!
//! The scan runs over the samples in order (strictly increasing frequencies), with the
//! phase unwrapped from sample to sample (the true phase must change by less than 180°
//! between neighbours: sample a lightly damped mode densely) and gain (dB) and phase
//! interpolated linearly in `log f` between neighbours:
//!
//! - **gain crossovers** (`|L| = 1`): the phase margin there is the angle between `L`
//!   and `-1`, `180° - |φ|` with `φ` in (-180°, 180°]; the reported margin is the
//!   smallest over all crossovers (a resonance peak above 0 dB adds crossovers);
//! - **phase crossovers** (`L` on the negative real axis): where `|L| < 1` the gain may
//!   rise by `-20 log|L|` before `L` reaches `-1` (the gain margin, smallest over the
//!   crossovers); where `|L| > 1` it may fall by `20 log|L|` (the lower gain margin of a
//!   conditionally stable loop, such as a PID on a double integrator);
//! - **stability** by the Nyquist criterion, for an open loop without right-half-plane
//!   poles other than its integrators (a stable axis and controller): the net number of
//!   clockwise crossings of the ray `(-∞, -1)` over the whole Nyquist contour must be 0.
//!   The negative frequencies mirror the positive ones (each crossing counts twice); the
//!   indentation around the `k` integrators at `s = 0` is an arc at infinity that sweeps
//!   clockwise from `-φ0` to `φ0`, `φ0` the low-frequency phase, anchored near `-90°·k`
//!   with `k` read from the gain's slope over the first octave of samples. Below the
//!   first sample the loop is taken to follow that asymptote; above the last its gain
//!   must stay below 1 ([`SampleError::NoRollOff`] when the last sample is not).
//!
//! The acceptance thresholds are the textbook ones: gain margin ≥ 6 dB and phase margin
//! ≥ 30° (K. Ogata, *Modern Control Engineering*, 5th ed., §7-6: "for satisfactory
//! performance, the phase margin should be between 30° and 60°, and the gain margin
//! should be greater than 6 dB").

use super::response::{FrequencyResponse, C64};
use core::f64::consts::PI;

/// Smallest accepted gain margin (upper and lower), dB (Ogata §7-6).
pub const MIN_GAIN_MARGIN_DB: f32 = 6.0;

/// Smallest accepted phase margin, degrees (Ogata §7-6).
pub const MIN_PHASE_MARGIN_DEG: f32 = 30.0;

/// Most integrators the low-frequency slope is read as (a PID on a double integrator
/// has 3).
const MAX_INTEGRATORS: i32 = 4;

/// The margins of a loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Margins {
    /// The closed loop is stable (Nyquist; see the module docs).
    pub stable: bool,
    /// How much the loop gain may rise, dB: the smallest over the phase crossovers where
    /// `|L| < 1`; `+inf` when there is none.
    pub gain_margin_db: f32,
    /// Where that smallest gain margin is, Hz.
    pub phase_crossover_hz: Option<f32>,
    /// How much the loop gain may fall, dB: the smallest over the phase crossovers where
    /// `|L| > 1`; `+inf` when there is none.
    pub lower_gain_margin_db: f32,
    /// The smallest phase margin over the gain crossovers, degrees; `+inf` when `|L|`
    /// never crosses 1 within the samples.
    pub phase_margin_deg: f32,
    /// Where that smallest phase margin is, Hz.
    pub gain_crossover_hz: Option<f32>,
    /// Number of gain crossovers (1 for a plain loop; more when a resonance peak pokes
    /// above 0 dB).
    pub gain_crossovers: u16,
}

/// Why the samples give no margins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleError {
    /// Fewer than two samples.
    TooFew,
    /// The frequency of this sample is not positive, finite and above the previous one.
    BadFrequency(usize),
    /// This sample's loop gain is zero or not finite.
    BadGain(usize),
    /// `|L| >= 1` at the last sample: the samples end before the loop gain falls below 1.
    NoRollOff,
}

/// Why [`accept`] rejects a loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    Unstable,
    GainMargin,
    LowerGainMargin,
    PhaseMargin,
}

/// Accept a loop when it is stable and its margins are at least `min_gm_db` (both gain
/// margins) and `min_pm_deg` ([`MIN_GAIN_MARGIN_DB`], [`MIN_PHASE_MARGIN_DEG`]).
pub fn accept(m: &Margins, min_gm_db: f32, min_pm_deg: f32) -> Result<(), Rejection> {
    if !m.stable {
        Err(Rejection::Unstable)
    } else if !(m.gain_margin_db >= min_gm_db) {
        Err(Rejection::GainMargin)
    } else if !(m.lower_gain_margin_db >= min_gm_db) {
        Err(Rejection::LowerGainMargin)
    } else if !(m.phase_margin_deg >= min_pm_deg) {
        Err(Rejection::PhaseMargin)
    } else {
        Ok(())
    }
}

/// The linear part of a PID-type law, `C(jω) = kp + kd·jω + ki/(jω)`, at `freq_hz`
/// (> 0; at 0 the integral term saturates to `-f32::MAX` in the imaginary part).
pub fn pid_response(kp: f32, ki: f32, kd: f32, freq_hz: f32) -> (f32, f32) {
    let w = 2.0 * PI * freq_hz as f64;
    let integral = if ki == 0.0 {
        0.0
    } else if w > 0.0 {
        ki as f64 / w
    } else {
        f64::INFINITY
    };
    C64::new(kp as f64, kd as f64 * w - integral).to_pair()
}

/// The margins of `L = C·F·P` from the plant's and the controller's responses sampled
/// at `freq_hz` (slices of equal length; extra samples of a longer one are ignored) and
/// the filter `filter` (e.g. a [`super::FilterChain`]).
pub fn loop_margins(
    freq_hz: &[f32],
    plant: &[(f32, f32)],
    controller: &[(f32, f32)],
    filter: &impl FrequencyResponse,
) -> Result<Margins, SampleError> {
    let n = freq_hz.len().min(plant.len()).min(controller.len());
    scan(n, |i| {
        let f = *freq_hz.get(i)?;
        let p = C64::from_pair(*plant.get(i)?);
        let c = C64::from_pair(*controller.get(i)?);
        Some((f, c.times(C64::from_pair(filter.response(f))).times(p)))
    })
}

/// The margins of a loop given as its samples `loop_gain` at `freq_hz`.
pub fn margins_of_samples(
    freq_hz: &[f32],
    loop_gain: &[(f32, f32)],
) -> Result<Margins, SampleError> {
    let n = freq_hz.len().min(loop_gain.len());
    scan(n, |i| {
        Some((*freq_hz.get(i)?, C64::from_pair(*loop_gain.get(i)?)))
    })
}

/// One sample of the loop: frequency, gain (dB), unwrapped phase (degrees).
#[derive(Clone, Copy, Debug)]
struct Point {
    f: f64,
    g: f64,
    phi: f64,
}

/// `x` wrapped into (-180, 180].
fn wrap180(x: f64) -> f64 {
    let y = x - 360.0 * libm::floor(x / 360.0); // [0, 360)
    if y > 180.0 {
        y - 360.0
    } else {
        y
    }
}

/// The running state of the scan.
struct Scan {
    m: Margins,
    /// Net clockwise crossings of (-∞, -1) at positive frequencies.
    crossings: i32,
}

impl Scan {
    /// The segment `a → b`: its gain crossover and its phase crossover, if any.
    fn segment(&mut self, a: &Point, b: &Point) {
        let at = |t: f64| libm::pow(b.f / a.f, t) * a.f;
        if (a.g >= 0.0) != (b.g >= 0.0) {
            let t = -a.g / (b.g - a.g);
            let pm = 180.0 - wrap180(a.phi + t * (b.phi - a.phi)).abs();
            self.m.gain_crossovers = self.m.gain_crossovers.saturating_add(1);
            if (pm as f32) < self.m.phase_margin_deg {
                self.m.phase_margin_deg = pm as f32;
                self.m.gain_crossover_hz = Some(at(t) as f32);
            }
        }
        // the odd multiple of 180° the phase may cross on this segment (|b - a| < 180°)
        let falling = b.phi < a.phi;
        let k = (a.phi - 180.0) / 360.0;
        let c = 180.0
            + 360.0
                * if falling {
                    libm::floor(k)
                } else {
                    libm::ceil(k)
                };
        let crossed = if falling {
            a.phi > c && c >= b.phi
        } else {
            a.phi < c && c <= b.phi
        };
        if !crossed {
            return;
        }
        let t = (c - a.phi) / (b.phi - a.phi);
        let g = a.g + t * (b.g - a.g);
        if g >= 0.0 {
            // left of -1: a crossing of the Nyquist ray (clockwise when falling)
            self.crossings += if falling { 1 } else { -1 };
            self.m.lower_gain_margin_db = self.m.lower_gain_margin_db.min(g as f32);
        } else if ((-g) as f32) < self.m.gain_margin_db {
            self.m.gain_margin_db = (-g) as f32;
            self.m.phase_crossover_hz = Some(at(t) as f32);
        }
    }
}

/// Number of odd multiples of 180° strictly between `phi` and 0.
fn odd_multiples_to_zero(phi: f64) -> i32 {
    let a = phi.abs();
    (0..2 * MAX_INTEGRATORS)
        .take_while(|m| (2 * m + 1) as f64 * 180.0 < a)
        .count() as i32
}

/// A sample checked: frequency above `prev_f`, gain finite and non-zero.
fn point(i: usize, f: f32, l: C64, prev_f: f64) -> Result<(f64, f64, f64), SampleError> {
    let f = f as f64;
    if !(f > prev_f) || !f.is_finite() {
        return Err(SampleError::BadFrequency(i));
    }
    let mag = l.abs();
    if !(mag > 0.0) || !mag.is_finite() {
        return Err(SampleError::BadGain(i));
    }
    Ok((f, 20.0 * libm::log10(mag), l.arg_deg()))
}

/// Integrators read from the gain's slope between the first sample and the first one an
/// octave above it (or the last).
fn integrators(n: usize, first: (f64, f64), sample: &impl Fn(usize) -> Option<(f32, C64)>) -> i32 {
    let (f0, g0) = first;
    let mut far = None;
    for i in 1..n {
        let Some((f, l)) = sample(i) else { break };
        far = Some((f as f64, 20.0 * libm::log10(l.abs())));
        if f as f64 >= 2.0 * f0 {
            break;
        }
    }
    let Some((f1, g1)) = far else { return 0 };
    let decades = libm::log10(f1 / f0);
    if !(decades > 0.0) || !g1.is_finite() {
        return 0;
    }
    let slope = (g1 - g0) / decades;
    (libm::round(-slope / 20.0) as i32).clamp(0, MAX_INTEGRATORS)
}

/// The scan over `n` samples given by `sample(i) = (freq_hz, L)`.
fn scan(n: usize, sample: impl Fn(usize) -> Option<(f32, C64)>) -> Result<Margins, SampleError> {
    if n < 2 {
        return Err(SampleError::TooFew);
    }
    let (f0, l0) = sample(0).ok_or(SampleError::TooFew)?;
    let (f0, g0, p0) = point(0, f0, l0, 0.0)?;
    let k = integrators(n, (f0, g0), &sample);
    let phi0 = p0 + 360.0 * libm::round((-90.0 * k as f64 - p0) / 360.0);
    // the arc around the integrators: clockwise from -phi0 to phi0 (counter-clockwise
    // when phi0 > 0), crossing the ray at every odd multiple of 180° in between
    let arc = 2 * odd_multiples_to_zero(phi0) * if phi0 < 0.0 { 1 } else { -1 };
    let mut s = Scan {
        m: Margins {
            stable: false,
            gain_margin_db: f32::INFINITY,
            phase_crossover_hz: None,
            lower_gain_margin_db: f32::INFINITY,
            phase_margin_deg: f32::INFINITY,
            gain_crossover_hz: None,
            gain_crossovers: 0,
        },
        crossings: 0,
    };
    let mut prev = Point {
        f: f0,
        g: g0,
        phi: phi0,
    };
    for i in 1..n {
        let (f, l) = sample(i).ok_or(SampleError::TooFew)?;
        let (f, g, p) = point(i, f, l, prev.f)?;
        let next = Point {
            f,
            g,
            phi: prev.phi + wrap180(p - prev.phi),
        };
        s.segment(&prev, &next);
        prev = next;
    }
    if prev.g >= 0.0 {
        return Err(SampleError::NoRollOff);
    }
    s.m.stable = arc + 2 * s.crossings == 0;
    Ok(s.m)
}
