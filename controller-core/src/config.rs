//! Configuration errors and the validators every block uses.
//!
//! Configurations are plain `f32` values (what a settings file, a scenario or the host
//! link carries); each block converts them once, at construction, into its number type
//! and validates them there. A rejected configuration builds nothing and changes nothing.
//! "No limit" is written as `f32::INFINITY` (`inf` in TOML).

/// Why a configuration was rejected. Nothing is changed when a configuration is rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// The named parameter must be finite (or +inf where a limit is meant).
    NotFinite(&'static str),
    /// The named parameter must be > 0.
    NotPositive(&'static str),
    /// The named parameter must be >= 0.
    Negative(&'static str),
    /// The named exponent is outside the range the law is defined for.
    BadExponent(&'static str),
    /// The named parameters give an unstable discrete-time system at the configured
    /// sample period (e.g. an estimator bandwidth too high for the control rate).
    Unstable(&'static str),
    /// The named parameter is outside its documented range (or inconsistent with another).
    OutOfRange(&'static str),
    /// The configuration asks for something this build or target cannot do.
    Unsupported(&'static str),
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotFinite(n) => write!(f, "parameter `{n}` must be a finite number"),
            Self::NotPositive(n) => write!(f, "parameter `{n}` must be greater than zero"),
            Self::Negative(n) => write!(f, "parameter `{n}` must not be negative"),
            Self::BadExponent(n) => write!(f, "exponent `{n}` is out of range for this law"),
            Self::Unstable(n) => write!(f, "`{n}` is unstable at this sample period"),
            Self::OutOfRange(n) => write!(f, "parameter `{n}` is out of its allowed range"),
            Self::Unsupported(n) => write!(f, "`{n}` is not supported here"),
        }
    }
}

pub fn finite(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ConfigError::NotFinite(name))
    }
}

pub fn positive(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if finite(v, name)? > 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::NotPositive(name))
    }
}

pub fn non_negative(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if finite(v, name)? >= 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::Negative(name))
    }
}

/// A limit: positive, `+inf` allowed (no limit).
pub fn limit(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if v.is_nan() {
        Err(ConfigError::NotFinite(name))
    } else if v > 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::NotPositive(name))
    }
}

/// serde default for limits: no limit.
#[cfg(feature = "serde")]
pub(crate) fn inf() -> f32 {
    f32::INFINITY
}
