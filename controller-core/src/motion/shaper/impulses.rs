//! The impulse sequences of the shapers, as Klipper defines them.
//!
//! Source: Klipper, `klippy/extras/shaper_defs.py` (Klipper3d/klipper, Dmitry Butyugin,
//! GPLv3; read at commit 1819369886bac3e5210674c0e9b36ae60619ce82). The formulas are
//! re-derived here, not copied: with `df = √(1 − ζ²)`, `t_d = 1 / (f · df)` (the damped
//! period of the mode) and `K = exp(−ζπ / df)`:
//!
//! | kind | amplitudes (before normalisation) | times |
//! |---|---|---|
//! | `zv` | `1, K` | `0, t_d/2` |
//! | `mzv` | `1 − 1/√2, (√2 − 1)·K', (1 − 1/√2)·K'²`, `K' = exp(−0.75·ζπ / df)` | `0, 0.375·t_d, 0.75·t_d` |
//! | `zvd` | `1, 2K, K²` | `0, t_d/2, t_d` |
//! | `ei` | `a1, 1 − a1 − a3, a3` (Klipper's fits in `v_tol` and ζ) | `0, t2·t_d, t_d` |
//! | `2hump_ei`, `3hump_ei` | cubic polynomials in ζ (Klipper's tables) | cubic polynomials in ζ, times `1/f` (not `t_d`) |
//!
//! Klipper computes `mzv` as the general `get_mzv_coeffs(n = 3, t = 0.75)` (times
//! `i·t/(n−1)`, amplitudes from the pseudo-inverse that places the shaper's zeros). For
//! n = 3 that system solves by hand: with times `0, 3/8, 3/4` (in `t_d`) the zero at the
//! design frequency asks `A0 = A1/√2 = A2` and `Σ A = 1`, so `A1 = √2 − 1`,
//! `A0 = A2 = 1 − 1/√2` (the second zero's equations, at 5/3 of the design frequency,
//! are the same two): the closed form above, which is also Klipper's earlier definition.
//! The damping factor is `K'^i` on impulse i (Klipper: `exp(−2tζπ / ((n − 1)·df))`).
//!
//! Klipper keeps the amplitudes unnormalised (its step compression divides by their sum);
//! here they are divided by their sum, so they add up to 1, and every one must be
//! positive (a fit evaluated outside its range could give a negative one: refused).

use crate::config::{finite, ConfigError};

/// Most impulses of any kind (`3hump_ei`).
pub const MAX_IMPULSES: usize = 5;

/// Klipper's default damping ratio of the shaped mode (`DEFAULT_DAMPING_RATIO`).
pub const DEFAULT_DAMPING_RATIO: f32 = 0.1;

/// Klipper's default residual vibration of the EI family, `1/SHAPER_VIBRATION_REDUCTION`
/// = 1/20: the EI shaper leaves 5 % of the unshaped vibration at its design frequency and
/// keeps it below 5 % over a wide band around it.
pub const DEFAULT_VIBRATION_TOLERANCE: f32 = 0.05;

/// Largest `vibration_tolerance` accepted for `ei`. Klipper does not state the range of
/// its fit; up to 0.2 its amplitudes stay positive for every damping ratio up to the
/// kind's maximum (0.4), which the validation checks anyway.
pub const MAX_VIBRATION_TOLERANCE: f32 = 0.2;

/// The shaper's family. The serde names are Klipper's (`shaper_type_x = mzv`, …).
///
/// The band of each kind is where its residual vibration V (Klipper's measure, relative
/// to the unshaped move) stays ≤ 5.1 % on a mode of damping ratio 0.1, in units of the
/// design frequency (Klipper's EI fits overshoot their 5 % by up to 0.1 % at ζ = 0.1;
/// computed from the impulses, tests/shaper.rs checks them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum ShaperKind {
    /// Zero vibration: 2 impulses over half the mode's period. Shortest; band
    /// 0.963 … 1.037.
    Zv,
    /// Modified ZV: 3 impulses 3/8 of a period apart (0.75 periods); band 0.94 … 1.073.
    Mzv,
    /// ZV derivative: 3 impulses over one period; band 0.835 … 1.174.
    Zvd,
    /// Extra insensitive: 3 impulses over one period, V = `vibration_tolerance` at the
    /// design frequency and below it either side; band 0.768 … 1.241.
    Ei,
    /// Two-hump EI: 4 impulses over 1.5 periods; band 0.598 … 1.459.
    #[cfg_attr(feature = "serde", serde(rename = "2hump_ei"))]
    TwoHumpEi,
    /// Three-hump EI: 5 impulses over 2 periods; band 0.476 … 1.337.
    #[cfg_attr(feature = "serde", serde(rename = "3hump_ei"))]
    ThreeHumpEi,
}

impl ShaperKind {
    /// Every kind, shortest first.
    pub const ALL: [ShaperKind; 6] = [
        Self::Zv,
        Self::Mzv,
        Self::Zvd,
        Self::Ei,
        Self::TwoHumpEi,
        Self::ThreeHumpEi,
    ];

    /// Klipper's name.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Zv => "zv",
            Self::Mzv => "mzv",
            Self::Zvd => "zvd",
            Self::Ei => "ei",
            Self::TwoHumpEi => "2hump_ei",
            Self::ThreeHumpEi => "3hump_ei",
        }
    }

    /// Klipper's `max_damping_ratio` of the kind (beyond it the fits do not hold).
    pub const fn max_damping_ratio(self) -> f32 {
        match self {
            Self::Zv | Self::Mzv | Self::Zvd => 0.99,
            Self::Ei => 0.4,
            Self::TwoHumpEi => 0.3,
            Self::ThreeHumpEi => 0.2,
        }
    }

    /// Index in [`Self::ALL`].
    pub const fn index(self) -> usize {
        self as usize
    }
}

/// One axis' shaper: the mode it cancels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ShaperConfig {
    pub kind: ShaperKind,
    /// Frequency of the mode (Hz), e.g. from the measured frequency response.
    pub freq_hz: f32,
    /// Damping ratio of the mode, `0 ≤ ζ ≤` the kind's maximum (Klipper's default 0.1).
    #[cfg_attr(feature = "serde", serde(default = "default_damping"))]
    pub damping_ratio: f32,
    /// Residual vibration the EI shaper leaves at its design frequency (fraction, `ei`
    /// only, `0 < v ≤ 0.2`). Klipper fits `2hump_ei` and `3hump_ei` for its default 0.05
    /// only: those kinds refuse any other value. Ignored by `zv`, `mzv`, `zvd`.
    #[cfg_attr(feature = "serde", serde(default = "default_tolerance"))]
    pub vibration_tolerance: f32,
}

#[cfg(feature = "serde")]
fn default_damping() -> f32 {
    DEFAULT_DAMPING_RATIO
}

#[cfg(feature = "serde")]
fn default_tolerance() -> f32 {
    DEFAULT_VIBRATION_TOLERANCE
}

impl ShaperConfig {
    /// A shaper of `kind` at `freq_hz` with Klipper's default damping ratio and tolerance.
    pub const fn new(kind: ShaperKind, freq_hz: f32) -> Self {
        Self {
            kind,
            freq_hz,
            damping_ratio: DEFAULT_DAMPING_RATIO,
            vibration_tolerance: DEFAULT_VIBRATION_TOLERANCE,
        }
    }

    /// The validated impulse sequence (amplitudes summing to 1, times from the first
    /// impulse). Errors name the parameter without an axis (`shaper.freq_hz`, …).
    pub fn impulses(&self) -> Result<Impulses, ConfigError> {
        self.impulses_named(&ParamNames::GENERIC)
    }

    pub(super) fn impulses_named(&self, n: &ParamNames) -> Result<Impulses, ConfigError> {
        let f = f64::from(finite(self.freq_hz, n.freq_hz)?);
        if !(f > 0.0) {
            return Err(ConfigError::NotPositive(n.freq_hz));
        }
        let z = f64::from(finite(self.damping_ratio, n.damping_ratio)?);
        if !(z >= 0.0 && z <= f64::from(self.kind.max_damping_ratio())) {
            return Err(ConfigError::OutOfRange(n.damping_ratio));
        }
        let v = f64::from(finite(self.vibration_tolerance, n.vibration_tolerance)?);
        let v_ok = match self.kind {
            ShaperKind::Ei => v > 0.0 && v <= f64::from(MAX_VIBRATION_TOLERANCE),
            // Klipper's hump fits are for 5 % (1e-6: a value read back from f32 text).
            ShaperKind::TwoHumpEi | ShaperKind::ThreeHumpEi => {
                (v - f64::from(DEFAULT_VIBRATION_TOLERANCE)).abs() <= 1e-6
            }
            ShaperKind::Zv | ShaperKind::Mzv | ShaperKind::Zvd => true,
        };
        if !v_ok {
            return Err(ConfigError::OutOfRange(n.vibration_tolerance));
        }
        let raw = raw_impulses(self.kind, f, z, v);
        raw.normalised()
            .ok_or(ConfigError::OutOfRange(n.damping_ratio))
    }
}

/// An impulse sequence: `len` impulses of amplitude `amp[i]` at `time_s[i]` (s from the
/// first impulse, increasing). Computed in `f64` at configuration time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Impulses {
    pub len: usize,
    pub amp: [f64; MAX_IMPULSES],
    pub time_s: [f64; MAX_IMPULSES],
}

impl Impulses {
    fn from_slices(amp: &[f64], time_s: &[f64]) -> Self {
        let mut s = Self {
            len: amp.len().min(time_s.len()).min(MAX_IMPULSES),
            amp: [0.0; MAX_IMPULSES],
            time_s: [0.0; MAX_IMPULSES],
        };
        for (d, a) in s.amp.iter_mut().zip(amp) {
            *d = *a;
        }
        for (d, t) in s.time_s.iter_mut().zip(time_s) {
            *d = *t;
        }
        s
    }

    /// `(amplitude, time)` of each impulse.
    pub fn iter(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.amp
            .iter()
            .copied()
            .zip(self.time_s.iter().copied())
            .take(self.len)
    }

    /// Divided by the amplitudes' sum; `None` unless every amplitude is positive and
    /// every time finite, non-negative and not before the previous one.
    fn normalised(mut self) -> Option<Self> {
        let sum: f64 = self.iter().map(|(a, _)| a).sum();
        let mut prev = 0.0;
        for (a, t) in self.iter() {
            if !(a > 0.0 && a.is_finite() && t.is_finite() && t >= prev) {
                return None;
            }
            prev = t;
        }
        if !(sum > 0.0) {
            return None;
        }
        for a in self.amp.iter_mut().take(self.len) {
            *a /= sum;
        }
        Some(self)
    }

    /// Time of the last impulse (s): the shaper's duration.
    pub fn duration_s(&self) -> f64 {
        self.iter().map(|(_, t)| t).fold(0.0, f64::max)
    }

    /// `Σ Aᵢ tᵢ` (s): the shaper's delay of a slow signal (amplitudes summing to 1).
    pub fn centroid_s(&self) -> f64 {
        self.iter().map(|(a, t)| a * t).sum()
    }

    /// `Σ Aᵢ (tᵢ − c)²` about the centroid `c` (s²): what sets the contour deviation.
    pub fn second_moment_s2(&self) -> f64 {
        let c = self.centroid_s();
        self.iter().map(|(a, t)| a * (t - c) * (t - c)).sum()
    }
}

/// Names of a shaper's parameters in errors.
pub(super) struct ParamNames {
    pub freq_hz: &'static str,
    pub damping_ratio: &'static str,
    pub vibration_tolerance: &'static str,
}

impl ParamNames {
    const GENERIC: Self = Self {
        freq_hz: "shaper.freq_hz",
        damping_ratio: "shaper.damping_ratio (0..=the kind's maximum)",
        vibration_tolerance: "shaper.vibration_tolerance (ei: 0..=0.2; hump ei: 0.05)",
    };
}

/// Klipper's impulses, unnormalised (see the module's table).
fn raw_impulses(kind: ShaperKind, f: f64, z: f64, v: f64) -> Impulses {
    let df = libm::sqrt(1.0 - z * z);
    let t_d = 1.0 / (f * df);
    let k = libm::exp(-z * core::f64::consts::PI / df);
    match kind {
        ShaperKind::Zv => Impulses::from_slices(&[1.0, k], &[0.0, 0.5 * t_d]),
        ShaperKind::Zvd => Impulses::from_slices(&[1.0, 2.0 * k, k * k], &[0.0, 0.5 * t_d, t_d]),
        ShaperKind::Mzv => {
            let k = libm::exp(-0.75 * z * core::f64::consts::PI / df);
            let a1 = 1.0 - core::f64::consts::FRAC_1_SQRT_2;
            let a2 = (core::f64::consts::SQRT_2 - 1.0) * k;
            Impulses::from_slices(&[a1, a2, a1 * k * k], &[0.0, 0.375 * t_d, 0.75 * t_d])
        }
        ShaperKind::Ei => {
            let a1 = (0.24968 + 0.24961 * v)
                + ((0.80008 + 1.23328 * v) + (0.49599 + 3.17316 * v) * z) * z;
            let a3 = (0.25149 + 0.21474 * v)
                + ((-0.83249 + 1.41498 * v) + (0.85181 - 4.90094 * v) * z) * z;
            let t2 = 0.4999
                + (((0.46159 + 8.57843 * v) * v)
                    + (((4.26169 - 108.644 * v) * v) + ((1.75601 + 336.989 * v) * v) * z) * z)
                    * z;
            Impulses::from_slices(&[a1, 1.0 - a1 - a3, a3], &[0.0, t2 * t_d, t_d])
        }
        ShaperKind::TwoHumpEi => expansion(f, z, &TWO_HUMP_T, &TWO_HUMP_A),
        ShaperKind::ThreeHumpEi => expansion(f, z, &THREE_HUMP_T, &THREE_HUMP_A),
    }
}

/// `2hump_ei` times (in `1/f`) and amplitudes: cubic coefficients in ζ, lowest first
/// (Klipper `get_2hump_ei_shaper`).
const TWO_HUMP_T: [[f64; 4]; 4] = [
    [0., 0., 0., 0.],
    [0.49890, 0.16270, -0.54262, 6.16180],
    [0.99748, 0.18382, -1.58270, 8.17120],
    [1.49920, -0.09297, -0.28338, 1.85710],
];
const TWO_HUMP_A: [[f64; 4]; 4] = [
    [0.16054, 0.76699, 2.26560, -1.22750],
    [0.33911, 0.45081, -2.58080, 1.73650],
    [0.34089, -0.61533, -0.68765, 0.42261],
    [0.15997, -0.60246, 1.00280, -0.93145],
];
/// `3hump_ei` (Klipper `get_3hump_ei_shaper`).
const THREE_HUMP_T: [[f64; 4]; 5] = [
    [0., 0., 0., 0.],
    [0.49974, 0.23834, 0.44559, 12.4720],
    [0.99849, 0.29808, -2.36460, 23.3990],
    [1.49870, 0.10306, -2.01390, 17.0320],
    [1.99960, -0.28231, 0.61536, 5.40450],
];
const THREE_HUMP_A: [[f64; 4]; 5] = [
    [0.11275, 0.76632, 3.29160, -1.44380],
    [0.23698, 0.61164, -2.57850, 4.85220],
    [0.30008, -0.19062, -2.14560, 0.13744],
    [0.23775, -0.73297, 0.46885, -2.08650],
    [0.11244, -0.45439, 0.96382, -1.46000],
];

/// Klipper's `_get_shaper_from_expansion_coeffs`: each time and amplitude a cubic in ζ,
/// times in units of `1/f`.
fn expansion(f: f64, z: f64, t: &[[f64; 4]], a: &[[f64; 4]]) -> Impulses {
    let cubic = |c: &[f64; 4]| ((c[3] * z + c[2]) * z + c[1]) * z + c[0];
    let mut s = Impulses::from_slices(&[], &[]);
    for ((dt, da), (ct, ca)) in s
        .time_s
        .iter_mut()
        .zip(s.amp.iter_mut())
        .zip(t.iter().zip(a))
    {
        *dt = cubic(ct) / f;
        *da = cubic(ca);
    }
    s.len = t.len().min(a.len()).min(MAX_IMPULSES);
    s
}

/// Lowest `freq_hz` at which a shaper of `kind` (at `damping_ratio`) fits a history of
/// `capacity` periods of `period_s` on its own: its duration within `capacity − 1`
/// periods (its last impulse, rounded to the nearest period, is then at most
/// `capacity − 1` periods back). An axis sharing the common delay with a longer shaper
/// can need more (validated at construction). `None` for an invalid damping ratio or a
/// capacity below 2.
pub fn min_freq_hz(
    kind: ShaperKind,
    damping_ratio: f32,
    period_s: f32,
    capacity: usize,
) -> Option<f32> {
    let mut c = ShaperConfig::new(kind, 1.0);
    c.damping_ratio = damping_ratio;
    let dur_at_1hz = c.impulses().ok()?.duration_s();
    let room_s = f64::from(period_s) * (capacity.checked_sub(1)? as f64);
    (room_s > 0.0).then(|| (dur_at_1hz / room_s) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// ZV at 35 Hz, ζ = 0.1, computed by hand (Klipper `get_zv_shaper`):
    /// df = √0.99 = 0.9949874, K = exp(−0.1π/df) = 0.7292476,
    /// t_d = 1/(35·df) = 0.02871536 s; A = [1, K]/(1 + K) = [0.5782862, 0.4217138],
    /// T = [0, t_d/2] = [0, 0.01435768] s.
    #[test]
    fn zv_matches_klippers_formula_by_hand() {
        let s = ShaperConfig::new(ShaperKind::Zv, 35.0).impulses().unwrap();
        assert_eq!(s.len, 2);
        assert!(close(s.amp[0], 0.5782862, 1e-6), "{:?}", s.amp);
        assert!(close(s.amp[1], 0.4217138, 1e-6), "{:?}", s.amp);
        assert_eq!(s.time_s[0], 0.0);
        assert!(close(s.time_s[1], 0.01435768, 1e-8), "{:?}", s.time_s);
    }

    /// ZVD at 55 Hz, ζ = 0.1: K = 0.7292476, A = [1, 2K, K²]/(1 + K)² =
    /// [0.3344149, 0.4877425, 0.1778425], T = [0, t_d/2, t_d], t_d = 1/(55·df) = 0.01827341.
    #[test]
    fn zvd_matches_klippers_formula_by_hand() {
        let s = ShaperConfig::new(ShaperKind::Zvd, 55.0).impulses().unwrap();
        let want_a = [0.3344149, 0.4877425, 0.1778425];
        let want_t = [0.0, 0.009136707, 0.01827341];
        for i in 0..3 {
            assert!(close(s.amp[i], want_a[i], 1e-6), "{:?}", s.amp);
            assert!(close(s.time_s[i], want_t[i], 1e-8), "{:?}", s.time_s);
        }
    }

    /// MZV at 90 Hz, ζ = 0.1, from the n = 3 closed form (module docs): K' = exp(−0.075π/df)
    /// = 0.7891440, A ∝ [0.2928932, 0.4142136·K', 0.2928932·K'²], T = [0, 3/8, 3/4]·t_d with
    /// t_d = 1/(90·df) = 0.01116709 s.
    #[test]
    fn mzv_matches_the_closed_form() {
        let s = ShaperConfig::new(ShaperKind::Mzv, 90.0).impulses().unwrap();
        let df = (0.99f64).sqrt();
        let k = (-0.075 * core::f64::consts::PI / df).exp();
        let raw = [0.2928932, 0.4142136 * k, 0.2928932 * k * k];
        let sum: f64 = raw.iter().sum();
        for (a, r) in s.amp.iter().zip(raw) {
            assert!(close(*a, r / sum, 1e-6), "{:?}", s.amp);
        }
        assert!(close(s.time_s[1], 0.375 * 0.01116709, 1e-8));
        assert!(close(s.time_s[2], 0.75 * 0.01116709, 1e-8));
    }

    #[test]
    fn every_kind_sums_to_one_with_positive_increasing_impulses() {
        for kind in ShaperKind::ALL {
            for z in [0.0f32, 0.05, 0.1, kind.max_damping_ratio()] {
                let mut c = ShaperConfig::new(kind, 40.0);
                c.damping_ratio = z;
                let s = c.impulses().unwrap();
                let sum: f64 = s.iter().map(|(a, _)| a).sum();
                assert!(close(sum, 1.0, 1e-12), "{kind:?} {z}: {sum}");
                let mut prev = -1.0;
                for (a, t) in s.iter() {
                    assert!(a > 0.0 && t > prev, "{kind:?} {z}: {s:?}");
                    prev = t;
                }
                assert_eq!(s.time_s[0], 0.0);
            }
        }
    }

    #[test]
    fn bad_parameters_are_refused() {
        let c = ShaperConfig::new(ShaperKind::Ei, 35.0);
        let with = |f: fn(&mut ShaperConfig)| {
            let mut c = c;
            f(&mut c);
            c.impulses()
        };
        assert_eq!(
            with(|c| c.freq_hz = 0.0),
            Err(ConfigError::NotPositive("shaper.freq_hz"))
        );
        assert_eq!(
            with(|c| c.freq_hz = f32::NAN),
            Err(ConfigError::NotFinite("shaper.freq_hz"))
        );
        assert!(matches!(
            with(|c| c.damping_ratio = 0.41),
            Err(ConfigError::OutOfRange(_))
        ));
        assert!(matches!(
            with(|c| c.vibration_tolerance = 0.0),
            Err(ConfigError::OutOfRange(_))
        ));
        assert!(with(|c| c.vibration_tolerance = 0.2).is_ok());
        let mut h = ShaperConfig::new(ShaperKind::TwoHumpEi, 35.0);
        assert!(h.impulses().is_ok());
        h.vibration_tolerance = 0.1;
        assert!(matches!(h.impulses(), Err(ConfigError::OutOfRange(_))));
    }
}

#[cfg(all(test, feature = "serde"))]
mod serde_tests {
    use super::ShaperKind;
    use serde::de::value::{Error, StrDeserializer};
    use serde::de::IntoDeserializer;
    use serde::Deserialize;

    /// The kinds read and write as Klipper names them.
    #[test]
    fn kinds_have_klippers_names() {
        for kind in ShaperKind::ALL {
            let de: StrDeserializer<'_, Error> = kind.name().into_deserializer();
            assert_eq!(ShaperKind::deserialize(de), Ok(kind));
        }
        let de: StrDeserializer<'_, Error> = "two_hump_ei".into_deserializer();
        assert!(ShaperKind::deserialize(de).is_err());
    }
}
