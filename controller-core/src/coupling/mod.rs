//! Cross-coupled contour control: how the three axes' errors are coupled so the tool
//! stays on the path, not only on time.
//!
//! - [`contour`]: the reference paper's 3-D contour-error coupling (paper eqs. 6-15,
//!   spec 3.1): each law sees the coupled error `C = E + λ e`;
//! - [`variable_gain`]: the patent's variable-gain cross-coupled PID (spec 3.2, seed 002
//!   claim 4; Koren & Lo 1991): a correction along the path normal added to the outputs.
//!
//! [`CouplingConfig`] selects one per controller (or none).

pub mod contour;
pub mod variable_gain;

use crate::config::{non_negative, ConfigError};
use crate::Real;
pub use contour::DirectionSource;
use variable_gain::{VariableGain, VariableGainConfig};

/// `|d|²` threshold below which a path direction counts as zero.
pub const DEFAULT_MIN_DIRECTION_NORM_SQ: f32 = 1e-12;

#[cfg(feature = "serde")]
fn default_min_dir() -> f32 {
    DEFAULT_MIN_DIRECTION_NORM_SQ
}

/// The paper's 3-D contour-error coupling.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ContourCouplingConfig {
    /// Cross-coupling gain λ (0 leaves the axes uncoupled but still estimates the contour
    /// error).
    pub lambda: f32,
    /// Local path direction: the analytic tangent (default) or the paper's chord.
    #[cfg_attr(feature = "serde", serde(default))]
    pub direction: DirectionSource,
    /// Directions with `|d|²` at or below this are treated as undefined.
    #[cfg_attr(feature = "serde", serde(default = "default_min_dir"))]
    pub min_direction_norm_sq: f32,
}

impl ContourCouplingConfig {
    /// Gain λ with the default (tangent) direction.
    pub const fn lambda(lambda: f32) -> Self {
        Self {
            lambda,
            direction: DirectionSource::Tangent,
            min_direction_norm_sq: DEFAULT_MIN_DIRECTION_NORM_SQ,
        }
    }
}

/// How the axes are coupled. TOML: `coupling = "none"`,
/// `coupling = { contour = { lambda = 0.01 } }`, `coupling = { variable_gain = { ... } }`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum CouplingConfig {
    /// Independent axes.
    None,
    Contour(ContourCouplingConfig),
    VariableGain(VariableGainConfig),
}

/// Validated contour coupling in number type `R`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContourCoupling<R> {
    pub lambda: R,
    pub direction: DirectionSource,
    pub min_dir_sq: R,
}

/// A validated coupling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coupling<R> {
    None,
    Contour(ContourCoupling<R>),
    VariableGain(VariableGain<R>),
}

impl<R: Real> Coupling<R> {
    pub fn new(cfg: &CouplingConfig) -> Result<Self, ConfigError> {
        Ok(match cfg {
            CouplingConfig::None => Self::None,
            CouplingConfig::Contour(c) => Self::Contour(ContourCoupling {
                lambda: R::from_f32(non_negative(c.lambda, "coupling.lambda")?),
                direction: c.direction,
                min_dir_sq: R::from_f32(non_negative(
                    c.min_direction_norm_sq,
                    "coupling.min_direction_norm_sq",
                )?),
            }),
            CouplingConfig::VariableGain(c) => Self::VariableGain(VariableGain::new(c)?),
        })
    }
}
