//! Automatic placement of an axis' output filters from its measured resonances and the
//! loop's intended bandwidth.
//!
//! Rules (each constant below names its source):
//! 1. A resonance gets a notch when its peak above the rigid-body line is at least
//!    [`NOTCH_MIN_PEAK_DB`] and its frequency at least [`NOTCH_MIN_BANDWIDTH_RATIO`] times
//!    the bandwidth (and within the filters' range, below `0.45 fs`). A notch closer to
//!    the crossover costs more phase there than the margins allow; such a mode is
//!    counted in [`Placement::near_bandwidth`] (lower the bandwidth, or stiffen the
//!    machine).
//! 2. **The notch inverts the mode.** A peaking-EQ notch is
//!    `(s² + 2ζz ω s + ω²) / (s² + 2ζp ω s + ω²)` with depth `ζz/ζp`. Its zeros take the
//!    mode's damping, `ζz = max(ζ, NOTCH_MIN_ZERO_DAMPING)`, so they cancel the mode's
//!    poles; its depth is the peak plus [`NOTCH_DEPTH_MARGIN_DB`], so the filtered mode
//!    ends that far below the rigid-body line at its centre, with damping
//!    `ζp = ζz / 10^(-depth/20)` (0.5 for a pure mode, peak `1/(2ζ)`, and no margin). The
//!    width follows: `width = 2 ζz f / A`, `A = 10^(-depth/40)` (Q = `f/width`,
//!    `ζz = A/(2Q)`), at most [`NOTCH_MAX_WIDTH_RATIO`]` · f`. (Ellis, *Control System Design
//!    Guide*, 4th ed., ch. 16: a notch "cancels" the resonance's poles with its zeros; the
//!    drives' notch width and depth settings, e.g. Omron G5 Pn202-Pn204, are the same two
//!    numbers.)
//! 3. At most [`MAX_STAGES`] stages (one kept for the low-pass when asked): the highest
//!    peaks first; the others are counted in [`Placement::no_room`].
//! 4. Optionally a Butterworth low-pass at [`LOW_PASS_BANDWIDTH_RATIO`] times the
//!    bandwidth (when below `0.45 fs`), after the notches.
//!
//! Nothing here decides that the result is safe: the margins of the loop with these
//! filters, on the measured response, do ([`super::margins`]).

use super::design::{
    AxisFilterConfig, FilterConfig, MAX_DEPTH_DB, MAX_FREQ_RATIO, MAX_STAGES, MIN_FREQ_RATIO,
};
use crate::config::{finite, positive, ConfigError};

/// A measured resonance of an axis (what the frequency-response measurement reports).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resonance {
    /// The peak's frequency, Hz.
    pub freq_hz: f32,
    /// The mode's damping ratio (its half-power width is `2 ζ f`).
    pub damping_ratio: f32,
    /// The peak's height above the rigid-body line of the effort → position response, dB.
    pub peak_db: f32,
}

/// Notches go only to resonances at least this many times the loop's bandwidth (the
/// issue's rule, ≈ 1.5×). A notch at `r` times the crossover delays the phase there by
/// `atan(2 ζp u/(1-u²)) - atan(2 ζz u/(1-u²))`, `u = 1/r`: for the ζ 0.11 mode of the
/// tests 35° at `r = 1.5`, 13° at `r = 3.5`; the margin check rejects what the loop
/// cannot afford.
pub const NOTCH_MIN_BANDWIDTH_RATIO: f32 = 1.5;

/// Smallest peak above the rigid-body line that gets a notch, dB: a 3 dB bump is within
/// what a measured response's rigid-body line varies by (friction, amplitude), and a
/// notch that shallow buys little gain margin.
pub const NOTCH_MIN_PEAK_DB: f32 = 3.0;

/// How far below the rigid-body line the notch takes the peak's centre, dB (depth is
/// the peak plus this margin). None: a deeper notch has more damped poles (`ζp` grows by 1.41 per 3 dB),
/// whose phase lag reaches further down to the crossover and pulls the phase crossover
/// down to where the loop gain is higher. On the 35 Hz mode under a 10 Hz PD of the
/// tests (`placed_notch_passes_the_margin_check`), 0 dB gives 10.3 dB / 42°, 3 dB
/// 12.5 dB / 36°: the phase margin is the scarcer. The margin check covers a peak
/// under-read by a coarse frequency grid.
pub const NOTCH_DEPTH_MARGIN_DB: f32 = 0.0;

/// Smallest damping the notch's zeros take: a notch as narrow as a mode of ζ = 0.01
/// loses its depth when the mode moves by 1 % (load, position); ζz = 0.05 keeps half its
/// depth over ±5 %.
pub const NOTCH_MIN_ZERO_DAMPING: f32 = 0.05;

/// Widest notch, as a fraction of its centre (Q ≥ 1): wider notches reach down to the
/// crossover; Yaskawa's default notch Q is 0.7 (Pn40A = 70), ArduPilot's bandwidth half
/// the centre.
pub const NOTCH_MAX_WIDTH_RATIO: f32 = 1.0;

/// The optional low-pass' cutoff, times the bandwidth. Yaskawa's torque reference filter
/// guidance (Σ-V, Pn401 ≤ 1000/(2π · Pn100 · 4) ms): a first-order lag at ≥ 4× the speed
/// loop's gain, i.e. 14° of phase at the crossover; a Butterworth second order costs the
/// same 14° at 6×.
pub const LOW_PASS_BANDWIDTH_RATIO: f32 = 6.0;

/// What [`place`] placed, and which resonances it left.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The filters: notches by increasing frequency, then the low-pass.
    pub filters: AxisFilterConfig,
    /// Resonances with a peak that need a notch but sit below
    /// [`NOTCH_MIN_BANDWIDTH_RATIO`] × bandwidth.
    pub near_bandwidth: u8,
    /// Resonances that need a notch but found no free stage.
    pub no_room: u8,
    /// Resonances that need a notch but are outside the filters' range (`0.45 fs`).
    pub out_of_range: u8,
}

fn check(r: &Resonance) -> Result<(), ConfigError> {
    positive(r.freq_hz, "resonance.freq_hz")?;
    if !(positive(r.damping_ratio, "resonance.damping_ratio")? <= 1.0) {
        return Err(ConfigError::OutOfRange("resonance.damping_ratio"));
    }
    finite(r.peak_db, "resonance.peak_db").map(|_| ())
}

/// The notch rule 2 gives for resonance `r` (within the range checked by the caller).
pub fn notch_for(r: &Resonance, sample_hz: f32) -> FilterConfig {
    let depth_db = (r.peak_db + NOTCH_DEPTH_MARGIN_DB).clamp(NOTCH_MIN_PEAK_DB, MAX_DEPTH_DB);
    let zeta = r.damping_ratio.max(NOTCH_MIN_ZERO_DAMPING);
    let a = libm::powf(10.0, -depth_db / 40.0);
    let width_hz = (2.0 * zeta * r.freq_hz / a)
        .min(NOTCH_MAX_WIDTH_RATIO * r.freq_hz)
        .min(0.99 * MAX_FREQ_RATIO * sample_hz)
        .max(MIN_FREQ_RATIO * sample_hz);
    FilterConfig::Notch {
        freq_hz: r.freq_hz,
        width_hz,
        depth_db,
    }
}

/// Place an axis' filters for the resonances `modes` of its measured response, the
/// loop's intended `bandwidth_hz`, at the control period `period_s`, with a low-pass
/// when `low_pass`. See the module docs for the rules.
pub fn place(
    modes: &[Resonance],
    bandwidth_hz: f32,
    period_s: f32,
    low_pass: bool,
) -> Result<Placement, ConfigError> {
    let bw = positive(bandwidth_hz, "bandwidth_hz")?;
    let fs = 1.0 / positive(period_s, "period_s")?;
    modes.iter().try_for_each(check)?;
    let mut out = Placement {
        filters: AxisFilterConfig::NONE,
        near_bandwidth: 0,
        no_room: 0,
        out_of_range: 0,
    };
    let room = MAX_STAGES - low_pass as usize;
    // chosen: indices into `modes` of the notched resonances
    let mut chosen = [usize::MAX; MAX_STAGES];
    let mut n = 0;
    for (i, r) in modes.iter().enumerate() {
        if r.peak_db < NOTCH_MIN_PEAK_DB {
            continue;
        }
        if r.freq_hz < NOTCH_MIN_BANDWIDTH_RATIO * bw {
            out.near_bandwidth = out.near_bandwidth.saturating_add(1);
            continue;
        }
        if !(r.freq_hz < MAX_FREQ_RATIO * fs && r.freq_hz >= MIN_FREQ_RATIO * fs) {
            out.out_of_range = out.out_of_range.saturating_add(1);
            continue;
        }
        // keep the `room` highest peaks: insert in order, the lowest falls off the end
        let peak = |j: usize| modes.get(j).map_or(f32::NEG_INFINITY, |m| m.peak_db);
        let pos = chosen
            .iter()
            .take(n)
            .position(|&j| peak(j) < r.peak_db)
            .unwrap_or(n);
        if pos >= room {
            out.no_room = out.no_room.saturating_add(1);
            continue;
        }
        if n == room {
            out.no_room = out.no_room.saturating_add(1);
        } else {
            n += 1;
        }
        chosen
            .get_mut(pos..n)
            .into_iter()
            .for_each(|s| s.rotate_right(1));
        if let Some(slot) = chosen.get_mut(pos) {
            *slot = i;
        }
    }
    // notches by increasing frequency
    let mut notches: [Option<&Resonance>; MAX_STAGES] = [None; MAX_STAGES];
    for (slot, &j) in notches.iter_mut().zip(chosen.iter().take(n)) {
        *slot = modes.get(j);
    }
    notches.sort_unstable_by(|a, b| {
        let f = |r: &Option<&Resonance>| r.map_or(f32::INFINITY, |r| r.freq_hz);
        f(a).total_cmp(&f(b))
    });
    for r in notches.iter().flatten() {
        out.filters.push(notch_for(r, fs))?;
    }
    let cutoff_hz = LOW_PASS_BANDWIDTH_RATIO * bw;
    if low_pass && cutoff_hz < MAX_FREQ_RATIO * fs && cutoff_hz >= MIN_FREQ_RATIO * fs {
        out.filters.push(FilterConfig::low_pass(cutoff_hz))?;
    }
    Ok(out)
}
