//! The filters' configuration ([`FilterConfig`], up to [`MAX_STAGES`] per axis in an
//! [`AxisFilterConfig`]) and its validation against the control period into biquad
//! coefficients.
//!
//! In a settings or scenario file an axis' filters are a list of tables:
//!
//! ```toml
//! y = [{ notch = { freq_hz = 35.0, width_hz = 14.0, depth_db = 20.0 } },
//!      { low_pass = { cutoff_hz = 400.0 } }]
//! ```
//!
//! Validation: every frequency (centre, cutoff, width) within
//! `[MIN_FREQ_RATIO·fs, MAX_FREQ_RATIO·fs)`, depths in `(0, MAX_DEPTH_DB]`, low-pass `q` in
//! `(0, MAX_LOW_PASS_Q]`, everything finite. A rejected configuration names its field.

use super::cookbook::{low_pass, notch, Coefficients};
use crate::config::{positive, ConfigError};

/// Stages per axis: four biquads bound the period's cost (`filters3_f32`); Yaskawa's
/// Σ-V drives have two notches and two torque low-passes (Pn408-Pn410), the issue's plan
/// two biquads per axis.
pub const MAX_STAGES: usize = 4;

/// Highest centre, cutoff or width as a fraction of the sample rate: below Nyquist (0.5)
/// with room for the pre-warping, whose `tan(π f/fs)` grows without bound at 0.5 (the
/// issue's `(0, 0.45 fs)`).
pub const MAX_FREQ_RATIO: f32 = 0.45;

/// Lowest centre, cutoff or width as a fraction of the sample rate (1 Hz at 10 kHz): at
/// `f/fs = 1e-4` the poles sit `≈ 6e-4` inside the unit circle, 10⁴ `f32` ulps of the
/// coefficients; much lower and the rounded `f32` coefficients move them visibly. No
/// mechanical mode of a gantry is that low.
pub const MIN_FREQ_RATIO: f32 = 1.0e-4;

/// Deepest notch: 60 dB (a factor 1000) is beyond any resonance peak a servo measures;
/// ArduPilot's harmonic notch defaults to 40 dB (`INS_HNTCH_ATT`), Omron's G5 notch
/// table goes to -40 dB before "cut off".
pub const MAX_DEPTH_DB: f32 = 60.0;

/// Highest low-pass quality: above 10 the low-pass peaks by 20 dB at its cutoff, which
/// no control output wants.
pub const MAX_LOW_PASS_Q: f32 = 10.0;

/// The Butterworth quality `1/√2`: maximally flat, -3.01 dB at the cutoff.
pub const BUTTERWORTH_Q: f32 = core::f32::consts::FRAC_1_SQRT_2;

#[cfg(feature = "serde")]
fn butterworth_q() -> f32 {
    BUTTERWORTH_Q
}

/// One filter stage on an axis' control output.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(rename_all = "snake_case", deny_unknown_fields)
)]
pub enum FilterConfig {
    /// A notch of finite depth (the Audio EQ Cookbook's peaking EQ with negative gain).
    Notch {
        /// Centre frequency, Hz.
        freq_hz: f32,
        /// Width between the two frequencies attenuated by half the depth (in dB), Hz.
        width_hz: f32,
        /// Attenuation at the centre, dB (> 0).
        depth_db: f32,
    },
    /// A second-order low-pass (the cookbook's LPF).
    LowPass {
        /// Cutoff, Hz: the gain there is `q` (-3.01 dB for the default Butterworth).
        cutoff_hz: f32,
        /// Quality; default [`BUTTERWORTH_Q`].
        #[cfg_attr(feature = "serde", serde(default = "butterworth_q"))]
        q: f32,
    },
}

/// A frequency of a stage: positive, finite, within the ratios of the sample rate.
fn frequency(v: f32, sample_hz: f32, name: &'static str) -> Result<f64, ConfigError> {
    let v = positive(v, name)?;
    if v < MIN_FREQ_RATIO * sample_hz || v >= MAX_FREQ_RATIO * sample_hz {
        return Err(ConfigError::OutOfRange(name));
    }
    Ok(v as f64)
}

impl FilterConfig {
    /// A Butterworth low-pass at `cutoff_hz`.
    pub const fn low_pass(cutoff_hz: f32) -> Self {
        Self::LowPass {
            cutoff_hz,
            q: BUTTERWORTH_Q,
        }
    }

    /// Validate against the control period and design the biquad.
    pub fn design(&self, period_s: f32) -> Result<Coefficients, ConfigError> {
        let fs = 1.0 / positive(period_s, "period_s")?;
        if !fs.is_finite() {
            return Err(ConfigError::OutOfRange("period_s"));
        }
        match *self {
            Self::Notch {
                freq_hz,
                width_hz,
                depth_db,
            } => {
                let f = frequency(freq_hz, fs, "notch.freq_hz")?;
                let w = frequency(width_hz, fs, "notch.width_hz")?;
                let d = positive(depth_db, "notch.depth_db")?;
                if d > MAX_DEPTH_DB {
                    return Err(ConfigError::OutOfRange("notch.depth_db"));
                }
                Ok(notch(f, w, d as f64, fs as f64))
            }
            Self::LowPass { cutoff_hz, q } => {
                let f = frequency(cutoff_hz, fs, "low_pass.cutoff_hz")?;
                let q = positive(q, "low_pass.q")?;
                if q > MAX_LOW_PASS_Q {
                    return Err(ConfigError::OutOfRange("low_pass.q"));
                }
                Ok(low_pass(f, q as f64, fs as f64))
            }
        }
    }
}

/// What fills the unused slots of an [`AxisFilterConfig`] (never designed nor compared:
/// the slots past `count` always hold it).
const UNUSED: FilterConfig = FilterConfig::low_pass(0.0);

/// The filter stages of one axis, applied in order: none (the default) to [`MAX_STAGES`].
/// A plain `Copy` value; its serde form is the list of stages.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisFilterConfig {
    stages: [FilterConfig; MAX_STAGES],
    count: u8,
}

impl Default for AxisFilterConfig {
    fn default() -> Self {
        Self::NONE
    }
}

impl AxisFilterConfig {
    /// No filter: the axis' output passes unchanged.
    pub const NONE: Self = Self {
        stages: [UNUSED; MAX_STAGES],
        count: 0,
    };

    /// The stages of `list`, in order; more than [`MAX_STAGES`] is rejected (`filters`).
    pub fn new(list: &[FilterConfig]) -> Result<Self, ConfigError> {
        let mut c = Self::NONE;
        for s in list {
            c.push(*s)?;
        }
        Ok(c)
    }

    /// Append a stage; `Err(OutOfRange("filters"))` when the axis has [`MAX_STAGES`].
    pub fn push(&mut self, stage: FilterConfig) -> Result<(), ConfigError> {
        let slot = self
            .stages
            .get_mut(self.count as usize)
            .ok_or(ConfigError::OutOfRange("filters"))?;
        *slot = stage;
        self.count += 1;
        Ok(())
    }

    /// The configured stages, in order.
    pub fn stages(&self) -> &[FilterConfig] {
        self.stages.get(..self.count as usize).unwrap_or(&[])
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Validate every stage against the control period.
    pub fn validate(&self, period_s: f32) -> Result<(), ConfigError> {
        positive(period_s, "period_s")?;
        self.stages()
            .iter()
            .try_for_each(|s| s.design(period_s).map(|_| ()))
    }
}

#[cfg(feature = "serde")]
impl serde::Serialize for AxisFilterConfig {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.stages().serialize(s)
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for AxisFilterConfig {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        // heapless rejects a list longer than its capacity
        let list = heapless::Vec::<FilterConfig, MAX_STAGES>::deserialize(d)?;
        Self::new(&list).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f32 = 1.0e-4;

    fn notch_cfg(freq_hz: f32, width_hz: f32, depth_db: f32) -> FilterConfig {
        FilterConfig::Notch {
            freq_hz,
            width_hz,
            depth_db,
        }
    }

    #[test]
    fn validation_names_the_field() {
        let e = |c: FilterConfig| c.design(T).err();
        assert_eq!(e(notch_cfg(35.0, 8.0, 20.0)), None);
        assert_eq!(
            e(notch_cfg(0.0, 8.0, 20.0)),
            Some(ConfigError::NotPositive("notch.freq_hz"))
        );
        assert_eq!(
            e(notch_cfg(4500.0, 8.0, 20.0)),
            Some(ConfigError::OutOfRange("notch.freq_hz"))
        );
        assert_eq!(e(notch_cfg(4499.0, 8.0, 20.0)), None);
        assert_eq!(
            e(notch_cfg(0.5, 8.0, 20.0)),
            Some(ConfigError::OutOfRange("notch.freq_hz"))
        );
        assert_eq!(
            e(notch_cfg(35.0, -1.0, 20.0)),
            Some(ConfigError::NotPositive("notch.width_hz"))
        );
        assert_eq!(
            e(notch_cfg(35.0, f32::NAN, 20.0)),
            Some(ConfigError::NotFinite("notch.width_hz"))
        );
        assert_eq!(
            e(notch_cfg(35.0, 8.0, 0.0)),
            Some(ConfigError::NotPositive("notch.depth_db"))
        );
        assert_eq!(
            e(notch_cfg(35.0, 8.0, 61.0)),
            Some(ConfigError::OutOfRange("notch.depth_db"))
        );
        assert_eq!(
            e(FilterConfig::low_pass(f32::INFINITY)),
            Some(ConfigError::NotFinite("low_pass.cutoff_hz"))
        );
        let q = |q| FilterConfig::LowPass {
            cutoff_hz: 400.0,
            q,
        };
        assert_eq!(e(q(0.0)), Some(ConfigError::NotPositive("low_pass.q")));
        assert_eq!(e(q(11.0)), Some(ConfigError::OutOfRange("low_pass.q")));
        assert_eq!(
            FilterConfig::low_pass(400.0).design(0.0).err(),
            Some(ConfigError::NotPositive("period_s"))
        );
        // the same cutoff is fine at 10 kHz and out of range at 1 kHz
        assert_eq!(FilterConfig::low_pass(450.0).design(1e-4).err(), None);
        assert_eq!(
            FilterConfig::low_pass(450.0).design(1e-3).err(),
            Some(ConfigError::OutOfRange("low_pass.cutoff_hz"))
        );
    }

    #[test]
    fn at_most_max_stages() {
        let s = FilterConfig::low_pass(400.0);
        let four = AxisFilterConfig::new(&[s; MAX_STAGES]).unwrap();
        assert_eq!(four.stages().len(), MAX_STAGES);
        assert_eq!(
            AxisFilterConfig::new(&[s; MAX_STAGES + 1]),
            Err(ConfigError::OutOfRange("filters"))
        );
        assert!(AxisFilterConfig::default().is_empty());
        assert_eq!(AxisFilterConfig::NONE.stages(), &[]);
        let mut bad = AxisFilterConfig::NONE;
        bad.push(notch_cfg(35.0, 8.0, -3.0)).unwrap();
        assert_eq!(
            bad.validate(T),
            Err(ConfigError::NotPositive("notch.depth_db"))
        );
    }

    /// The serde form is the list of stages; a list longer than [`MAX_STAGES`] is refused.
    #[cfg(feature = "serde")]
    #[test]
    fn serde_form_is_the_list() {
        let list = [notch_cfg(35.0, 8.0, 20.0), FilterConfig::low_pass(400.0)];
        let c = AxisFilterConfig::new(&list).unwrap();
        let mut buf = [0u8; 128];
        let bytes = postcard::to_slice(&c, &mut buf).unwrap();
        let mut buf2 = [0u8; 128];
        assert_eq!(&*bytes, &*postcard::to_slice(&list[..], &mut buf2).unwrap());
        let back: AxisFilterConfig = postcard::from_bytes(bytes).unwrap();
        assert_eq!(back, c);
        let five = [list[0]; MAX_STAGES + 1];
        let long = postcard::to_slice(&five[..], &mut buf).unwrap();
        assert!(postcard::from_bytes::<AxisFilterConfig>(long).is_err());
    }
}
