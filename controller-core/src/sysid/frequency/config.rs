//! Configuration of a frequency-response measurement ([`ResponseConfig`]), validated once
//! into [`ValidResponseConfig`] with the frequency grid's derived quantities.

use super::super::config::{IdentifyConfig, MAX_LOOP_BANDWIDTH_PERIODS, MAX_PERIOD_S};
use crate::config::{non_negative, positive, ConfigError};

/// Most frequencies of one measurement: the grid, the results and the mode finder's
/// arrays are this long (a fixed size: nothing allocates).
pub const MAX_POINTS: usize = 128;

/// What a frequency-response measurement of one axis may do, and its frequency grid.
/// Lengths mm, speeds mm/s, efforts mN·m (the axis' effort unit), times s, frequencies
/// Hz. The defaults ([`RESPONSE_DEFAULTS`]) suit the gantry's ball-screw axes at 10 kHz;
/// the window, the cap, the period and the velocity limit come from the identification's
/// configuration when the servo runs it ([`ResponseConfig::from_identify`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ResponseConfig {
    /// Control period, s.
    pub period_s: f32,
    /// Travel window (machine coordinates, mm): the axis must never leave it.
    pub window_min_mm: f32,
    pub window_max_mm: f32,
    /// Distance the planned motion keeps from each end of the window, mm.
    pub edge_margin_mm: f32,
    /// Hard limit on the commanded effort, mN·m.
    pub torque_cap_mnm: f32,
    /// Abort (zero effort) above this |velocity|, mm/s.
    pub velocity_limit_mm_s: f32,
    /// The grid: `points` frequencies spaced evenly on a log scale from `freq_min_hz` to
    /// `freq_max_hz` (each moved by less than half a per cent so that its measurement
    /// holds a whole number of cycles).
    pub freq_min_hz: f32,
    pub freq_max_hz: f32,
    pub points: u8,
    /// Speed the axis travels at while it is measured (the sine rides on it), mm/s; moved
    /// to the nearest speed whose counts per period have the golden ratio's fraction
    /// (see the module docs of [`super`]).
    pub bias_mm_s: f32,
    /// Amplitudes the sine aims at, as a rigid body would answer it: the sine's effort
    /// is `Ĵ · max(accel_amp_mm_s2, ω vel_amp_mm_s, ω² pos_amp_mm)` (the acceleration
    /// at low frequencies, the velocity in the middle, the position at high ones),
    /// mm/s², mm/s, mm.
    pub accel_amp_mm_s2: f32,
    pub vel_amp_mm_s: f32,
    pub pos_amp_mm: f32,
    /// Amplitude of a uniform random effort added to the sine, mN·m: at least one step
    /// of the amplifier, whose quantisation it makes linear on average (a sine of a few
    /// steps on a constant friction effort would otherwise be quantised to a few levels,
    /// an error of tens of per cent). It is part of the effort applied, so it adds no
    /// error of its own.
    pub dither_mnm: f32,
    /// Share of the cap the sine may use (the rest is the holding loop's).
    pub excitation_fraction: f32,
    /// Rough inertia for the first frequency and the loop until the first frequency has
    /// measured it, mN·m/(mm/s²).
    pub inertia_guess: f32,
    /// Crossover of the holding velocity loop, rad/s: below the lowest frequency, so
    /// that the loop hardly answers the sine.
    pub loop_bandwidth_rad_s: f32,
    /// Crossover of the velocity loop that brakes to rest at the end or on an abort, rad/s.
    pub brake_bandwidth_rad_s: f32,
    /// Acceleration of the ramps (start, reversals, stop), mm/s².
    pub accel_mm_s2: f32,
    /// Settling before each frequency's measurement: `settle_cycles` cycles, but at least
    /// `settle_min_s` and at most `settle_max_s`; after a reversal at least
    /// `reverse_settle_s`, after the start at least `start_settle_s` (the holding loop
    /// learns the friction there).
    pub settle_cycles: f32,
    pub settle_min_s: f32,
    pub settle_max_s: f32,
    pub reverse_settle_s: f32,
    pub start_settle_s: f32,
    /// Measurement of each frequency: the whole number of cycles nearest above
    /// `measure_s` (at least `measure_min_cycles`).
    pub measure_s: f32,
    pub measure_min_cycles: u8,
    /// The whole measurement must end within this machine time, s.
    pub time_budget_s: f32,
}

/// Defaults for the gantry's axes at 10 kHz (reasoning in docs/identification.md,
/// "Frequency response"): 5-300 Hz in 64 points (6.7 % apart: nine points within ±30 %
/// of a mode), 27 mm/s travel (far above the friction's Stribeck region, so the friction
/// stays a constant force: the sine never reverses the motion); 40 mm/s², 0.15 mm/s or
/// 0.3 µm of rigid-body amplitude (a few mN·m at the gantry's modes: the tool's swing
/// there stays below what the guides' friction preloads the nut with, so a nut with
/// backlash stays on its flank; the 0.5 mm/s tried first pulled X's 90 Hz mode 6 % low;
/// above ~80 Hz half a count of the encoder, whose counts are coarse there); 1 mN·m of
/// dither (one step of the 12-bit amplifiers: 0.49 mN·m on X and Z, 0.98 on Y); 20
/// settling cycles (a mode of 2 % damping decays to 8 % of its transient in them, one
/// of 4 % to 0.7 %); 1 s measured per frequency (0.3 s left ±2 dB of scatter above 150 Hz
/// with ±1 count of encoder noise, 1 s 0.5 dB); 99 s of machine time per axis, in a
/// ±50 mm window from its middle.
pub const RESPONSE_DEFAULTS: ResponseConfig = ResponseConfig {
    period_s: 1e-4,
    window_min_mm: -50.0,
    window_max_mm: 50.0,
    edge_margin_mm: 5.0,
    torque_cap_mnm: 500.0,
    velocity_limit_mm_s: 250.0,
    freq_min_hz: 5.0,
    freq_max_hz: 300.0,
    points: 64,
    bias_mm_s: 27.0,
    accel_amp_mm_s2: 40.0,
    vel_amp_mm_s: 0.15,
    pos_amp_mm: 3e-4,
    dither_mnm: 1.0,
    excitation_fraction: 0.5,
    inertia_guess: 0.09,
    loop_bandwidth_rad_s: 20.0,
    brake_bandwidth_rad_s: 150.0,
    accel_mm_s2: 1000.0,
    settle_cycles: 20.0,
    settle_min_s: 0.1,
    settle_max_s: 0.6,
    reverse_settle_s: 0.3,
    start_settle_s: 0.5,
    measure_s: 1.0,
    measure_min_cycles: 2,
    time_budget_s: 180.0,
};

impl ResponseConfig {
    /// The defaults with the identification's period, window, cap, velocity limit and
    /// inertia guess: what the servo's measurement runs with.
    pub fn from_identify(c: &IdentifyConfig) -> Self {
        Self::from_identify_over(c, &RESPONSE_DEFAULTS)
    }

    /// `defaults` with the identification's window, torque cap, speed limit and inertia
    /// guess.
    pub fn from_identify_over(c: &IdentifyConfig, defaults: &Self) -> Self {
        Self {
            period_s: c.period_s,
            window_min_mm: c.window_min_mm,
            window_max_mm: c.window_max_mm,
            edge_margin_mm: c.edge_margin_mm,
            torque_cap_mnm: c.torque_cap_mnm,
            velocity_limit_mm_s: c.velocity_limit_mm_s,
            inertia_guess: c.inertia_guess,
            ..*defaults
        }
    }
}

/// Why a configuration (or the start) was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ResponseConfigError {
    /// A single field is not finite / not positive / out of its range.
    Param(ConfigError),
    /// The window (less its margins) cannot hold the longest frequency's settling and
    /// measurement at the travel speed plus a stop (or, from the start, the first
    /// frequency's).
    WindowTooShort { needed_mm: f32, usable_mm: f32 },
    /// The start is not inside the window by the edge margin.
    StartOutsideWindow,
}

impl From<ConfigError> for ResponseConfigError {
    fn from(e: ConfigError) -> Self {
        Self::Param(e)
    }
}

/// The validated configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ValidResponseConfig {
    pub(crate) c: ResponseConfig,
    pub(crate) turn_min_mm: f32,
    pub(crate) turn_max_mm: f32,
    pub(crate) points: usize,
    /// `ln(freq_max / freq_min) / (points - 1)`.
    pub(crate) log_step: f32,
}

fn range(v: f32, name: &'static str, lo: f32, hi: f32) -> Result<f32, ConfigError> {
    if v >= lo && v <= hi {
        Ok(v)
    } else {
        Err(ConfigError::OutOfRange(name))
    }
}

impl ValidResponseConfig {
    pub(crate) fn new(c: &ResponseConfig) -> Result<Self, ResponseConfigError> {
        let t = range(
            positive(c.period_s, "period_s")?,
            "period_s",
            0.0,
            MAX_PERIOD_S,
        )?;
        let (lo, hi) = (c.window_min_mm, c.window_max_mm);
        crate::config::finite(lo, "window_min_mm")?;
        crate::config::finite(hi, "window_max_mm")?;
        let margin = non_negative(c.edge_margin_mm, "edge_margin_mm")?;
        positive(c.torque_cap_mnm, "torque_cap_mnm")?;
        let f_lo = positive(c.freq_min_hz, "freq_min_hz")?;
        let f_hi = positive(c.freq_max_hz, "freq_max_hz")?;
        // a sine of at least 8 samples per cycle
        range(f_hi * t, "freq_max_hz * period_s (at most 1/8)", 0.0, 0.125)?;
        if !(f_lo < f_hi) {
            return Err(ConfigError::OutOfRange("freq_min_hz < freq_max_hz").into());
        }
        let n = range(f32::from(c.points), "points", 2.0, MAX_POINTS as f32)? as usize;
        let bias = positive(c.bias_mm_s, "bias_mm_s")?;
        positive(c.accel_amp_mm_s2, "accel_amp_mm_s2")?;
        positive(c.vel_amp_mm_s, "vel_amp_mm_s")?;
        non_negative(c.pos_amp_mm, "pos_amp_mm")?;
        let dither = non_negative(c.dither_mnm, "dither_mnm")?;
        range(
            dither,
            "dither_mnm (at most a tenth of torque_cap_mnm)",
            0.0,
            0.1 * c.torque_cap_mnm,
        )?;
        range(
            positive(c.excitation_fraction, "excitation_fraction")?,
            "excitation_fraction",
            0.0,
            0.9,
        )?;
        positive(c.inertia_guess, "inertia_guess")?;
        for (w, name) in [
            (c.loop_bandwidth_rad_s, "loop_bandwidth_rad_s * period_s"),
            (c.brake_bandwidth_rad_s, "brake_bandwidth_rad_s * period_s"),
        ] {
            range(
                positive(w, name)? * t,
                name,
                0.0,
                MAX_LOOP_BANDWIDTH_PERIODS,
            )?;
        }
        let a = positive(c.accel_mm_s2, "accel_mm_s2")?;
        positive(c.settle_cycles, "settle_cycles")?;
        let s_min = non_negative(c.settle_min_s, "settle_min_s")?;
        let s_max = positive(c.settle_max_s, "settle_max_s")?;
        if !(s_min <= s_max) {
            return Err(ConfigError::OutOfRange("settle_min_s <= settle_max_s").into());
        }
        let rev = non_negative(c.reverse_settle_s, "reverse_settle_s")?;
        non_negative(c.start_settle_s, "start_settle_s")?;
        let meas = positive(c.measure_s, "measure_s")?;
        range(
            f32::from(c.measure_min_cycles),
            "measure_min_cycles",
            1.0,
            100.0,
        )?;
        positive(c.time_budget_s, "time_budget_s")?;
        // the sine and the travel together stay below the velocity limit
        let vlim = positive(c.velocity_limit_mm_s, "velocity_limit_mm_s")?;
        if !(2.0 * (bias + c.vel_amp_mm_s) < vlim) {
            return Err(ConfigError::OutOfRange(
                "2 (bias_mm_s + vel_amp_mm_s) < velocity_limit_mm_s",
            )
            .into());
        }
        let (turn_min, turn_max) = (lo + margin, hi - margin);
        let usable = turn_max - turn_min;
        // the longest frequency (the lowest: its measured cycles and settling), after a
        // reversal (into an unknown friction at worst), then a stop
        let longest = s_max.max(rev).max(c.start_settle_s)
            + meas.max(f32::from(c.measure_min_cycles) / f_lo)
            + 1.0 / f_lo;
        let needed = 1.1 * bias * (1.25 * bias / a + longest);
        if !(needed <= usable) {
            return Err(ResponseConfigError::WindowTooShort {
                needed_mm: needed,
                usable_mm: usable,
            });
        }
        Ok(Self {
            c: *c,
            turn_min_mm: turn_min,
            turn_max_mm: turn_max,
            points: n,
            log_step: libm::logf(f_hi / f_lo) / (n - 1) as f32,
        })
    }
}
