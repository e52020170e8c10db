//! Configuration types of the laws and the named parameter presets, each with its source.
//!
//! Configurations are plain `f32` values (what a settings file or the host link carries);
//! the laws convert them once, at construction, into their number type and validate them
//! there ([`ConfigError`]). "No limit" is written as `f32::INFINITY` (`inf` in TOML).

use crate::Exponent;

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

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
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotFinite(n) => write!(f, "parameter `{n}` must be a finite number"),
            Self::NotPositive(n) => write!(f, "parameter `{n}` must be greater than zero"),
            Self::Negative(n) => write!(f, "parameter `{n}` must not be negative"),
            Self::BadExponent(n) => write!(f, "exponent `{n}` is out of range for this law"),
            Self::Unstable(n) => write!(f, "`{n}` is unstable at this sample period"),
        }
    }
}

pub(crate) fn finite(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ConfigError::NotFinite(name))
    }
}

pub(crate) fn positive(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if finite(v, name)? > 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::NotPositive(name))
    }
}

pub(crate) fn non_negative(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if finite(v, name)? >= 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::Negative(name))
    }
}

/// A limit: positive, `+inf` allowed (no limit).
pub(crate) fn limit(v: f32, name: &'static str) -> Result<f32, ConfigError> {
    if v.is_nan() {
        Err(ConfigError::NotFinite(name))
    } else if v > 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::NotPositive(name))
    }
}

/// Coefficients of the normalised axis `θ'' = -a θ' - b θ + k u` (spec 1.1).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct PlantParams {
    pub a: f32,
    pub b: f32,
    pub k: f32,
}

/// Paper (seed 000, section 3): a = 10, b = 1, k = 1 for each of the three axes.
pub const PAPER_PLANT: PlantParams = PlantParams {
    a: 10.0,
    b: 1.0,
    k: 1.0,
};

/// PID with anti-windup and optional feed-forward (spec 2.1).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PidConfig {
    pub kp: f32,
    pub ki: f32,
    pub kd: f32,
    /// Velocity feed-forward gain on `q_d'`.
    #[cfg_attr(feature = "serde", serde(default))]
    pub kv_ff: f32,
    /// Acceleration feed-forward gain on `q_d''`.
    #[cfg_attr(feature = "serde", serde(default))]
    pub ka_ff: f32,
    /// Clamp on `|∫e dt|`.
    #[cfg_attr(feature = "serde", serde(default = "inf"))]
    pub integral_limit: f32,
    /// Output saturation `|u| <= u_max`.
    #[cfg_attr(feature = "serde", serde(default = "inf"))]
    pub u_max: f32,
}

#[cfg(feature = "serde")]
fn inf() -> f32 {
    f32::INFINITY
}

/// Paper Table 2: P = 600, I = 1, D = 10, no feed-forward, no limits.
pub const PAPER_PID: PidConfig = PidConfig {
    kp: 600.0,
    ki: 1.0,
    kd: 10.0,
    kv_ff: 0.0,
    ka_ff: 0.0,
    integral_limit: f32::INFINITY,
    u_max: f32::INFINITY,
};

/// Sliding surface (spec 2.2/2.3).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(tag = "kind", rename_all = "snake_case"))]
pub enum SurfaceConfig {
    /// `s = e' + α e + β sig(e)^(q/p)`, p, q odd, 0 < q < p. The `|e|^(q/p-1)` factor of the
    /// equivalent control is evaluated with `|e|` floored at `singular_floor`, which bounds
    /// it by `β (q/p) singular_floor^(q/p-1) |e'|`.
    Terminal {
        alpha: f32,
        beta: f32,
        p: i16,
        q: i16,
        singular_floor: f32,
    },
    /// Nonsingular terminal surface (Feng, Yu, Man 2002): `s = e + (1/β) sig(e')^(p/q)`,
    /// p, q odd, 1 < p/q < 2. Its equivalent control has only the positive power
    /// `sig(e')^(2-p/q)`, so nothing needs a floor.
    Nonsingular { beta: f32, p: i16, q: i16 },
}

/// Reaching law (spec 2.2/2.3).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(tag = "kind", rename_all = "snake_case"))]
pub enum ReachingConfig {
    /// `s' = -k s - ε sign(s)`; with `boundary_layer > 0`, `sign(s)` is replaced by
    /// `sat(s / boundary_layer)` (0 = the paper's pure sign).
    Exponential {
        k: f32,
        epsilon: f32,
        #[cfg_attr(feature = "serde", serde(default))]
        boundary_layer: f32,
    },
    /// `s' = -k1 sig(s)^(2-β2) - k2 sig(s)^β2 - k3 |e|^β3 s`, 0 < β2 < 1, β3 > 0.
    DoublePower {
        k1: f32,
        k2: f32,
        k3: f32,
        beta2: Exponent,
        beta3: Exponent,
    },
}

/// A sliding-mode law: surface, reaching law, optional integral compensation `k4 ∫e dt`
/// (spec 2.3). SMC is `k4 = 0` with the exponential law; DSMC the double-power law with
/// `k4 > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct SmcConfig {
    /// The model the equivalent control cancels.
    pub plant: PlantParams,
    pub surface: SurfaceConfig,
    pub reaching: ReachingConfig,
    #[cfg_attr(feature = "serde", serde(default))]
    pub k4: f32,
    #[cfg_attr(feature = "serde", serde(default = "inf"))]
    pub integral_limit: f32,
    #[cfg_attr(feature = "serde", serde(default = "inf"))]
    pub u_max: f32,
}

/// Floor on `|e|` in the singular factor `|e|^(q/p-1)`: 1e-4 plant units (0.1 µm when
/// the unit is mm). The factor `(5/9) |e|^(-4/9)` is then at most 33.
pub const DEFAULT_SINGULAR_FLOOR: f32 = 1e-4;

/// Paper Table 2 surface: α = 10, β = 1, p = 9, q = 5.
pub const PAPER_SURFACE: SurfaceConfig = SurfaceConfig::Terminal {
    alpha: 10.0,
    beta: 1.0,
    p: 9,
    q: 5,
    singular_floor: DEFAULT_SINGULAR_FLOOR,
};

/// Paper Table 2 "SMC": terminal surface + exponential law, k = 200, ε = 33.
pub const PAPER_SMC: SmcConfig = SmcConfig {
    plant: PAPER_PLANT,
    surface: PAPER_SURFACE,
    reaching: ReachingConfig::Exponential {
        k: 200.0,
        epsilon: 33.0,
        boundary_layer: 0.0,
    },
    k4: 0.0,
    integral_limit: f32::INFINITY,
    u_max: f32::INFINITY,
};

/// Paper Table 2 "DSMC": k1 = k2 = k4 = 20, k3 = 200, β1 = 5/3, β2 = 1/3, β3 = 1/3.
pub const PAPER_DSMC: SmcConfig = SmcConfig {
    plant: PAPER_PLANT,
    surface: PAPER_SURFACE,
    reaching: ReachingConfig::DoublePower {
        k1: 20.0,
        k2: 20.0,
        k3: 200.0,
        beta2: Exponent { num: 1, den: 3 },
        beta3: Exponent { num: 1, den: 3 },
    },
    k4: 20.0,
    integral_limit: f32::INFINITY,
    u_max: f32::INFINITY,
};

/// Paper cross-coupling gain λ = 0.01 (seed 000, section 4.2).
pub const PAPER_LAMBDA: f32 = 0.01;

/// Either law, as selected per axis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum LawConfig {
    Pid(PidConfig),
    Smc(SmcConfig),
}
