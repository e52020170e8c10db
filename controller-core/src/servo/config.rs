//! What the servo step is configured with ([`ServoConfig`]), the path it can be told to
//! follow ([`PathPlan`]), the control rates it accepts, and why a reconfiguration is
//! refused ([`ReconfigureError`]).

use super::brake::BrakeConfig;
use super::io::{AmplifierConfig, EncoderConfig};
use super::monitor::SafetyConfig;
use super::travel::TravelConfig;
use crate::axes::AXES;
use crate::config::ConfigError;
use crate::controller::ControllerConfig;
use crate::estimator::EstimatorBankConfig;
use crate::filter::AxisFilterConfig;
use crate::motion::feedforward::FeedForwardConfig;
use crate::motion::homing::HomingConfig;
use crate::motion::jog::JogConfig;
use crate::motion::path::{PathConfig, PathStart};
use crate::sysid::IdentifyConfig;
#[cfg(feature = "serde")]
use crate::sysid::IDENTIFY_DEFAULTS;

/// Highest control rate the servo accepts, Hz.
pub const MAX_RATE_HZ: u32 = 50_000;
/// Lowest control rate the servo accepts, Hz.
pub const MIN_RATE_HZ: u32 = 100;

/// A path the servo can be told to follow ([`Command::StartPath`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PathPlan {
    pub path: PathConfig,
    #[cfg_attr(feature = "serde", serde(default))]
    pub start: PathStart,
    /// After this long the path's point at that time is held (`None`: follow forever).
    #[cfg_attr(feature = "serde", serde(default))]
    pub duration_s: Option<f64>,
}

/// Everything the servo step needs to know about the machine and its control.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ServoConfig {
    /// Control rate, Hz.
    pub rate_hz: u32,
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub encoders: [EncoderConfig; AXES],
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub amplifiers: [AmplifierConfig; AXES],
    /// Per axis: the holding brake ([`brake`]; default: none, so configurations written
    /// before brakes existed keep working).
    #[cfg_attr(feature = "serde", serde(default, with = "crate::axes::per_axis"))]
    pub brakes: [BrakeConfig; AXES],
    pub controller: ControllerConfig,
    pub estimator: EstimatorBankConfig,
    /// Limits and fault thresholds.
    pub safety: SafetyConfig,
    /// The path [`Command::StartPath`] starts, if any.
    #[cfg_attr(feature = "serde", serde(default))]
    pub path: Option<PathPlan>,
    /// Soft limits (default: unlimited).
    #[cfg_attr(feature = "serde", serde(default))]
    pub travel: TravelConfig,
    /// Homing (default: no axis homes).
    #[cfg_attr(feature = "serde", serde(default))]
    pub homing: HomingConfig,
    #[cfg_attr(feature = "serde", serde(default))]
    pub jog: JogConfig,
    /// Identification's template: window and cap are set per run ([`identify`]).
    #[cfg_attr(feature = "serde", serde(default = "default_identify"))]
    pub identify: IdentifyConfig,
    /// Per axis: is the plant model of the axis' law known (identified or entered)? A
    /// model-based law on an axis without one cannot be armed (default: known, as in
    /// every simulation whose plant is configured).
    #[cfg_attr(
        feature = "serde",
        serde(default = "default_models_known", with = "crate::axes::per_axis")
    )]
    pub model_known: [bool; AXES],
    /// Per axis: Coulomb pre-compensation and the frame's compliance and deflection
    /// ([`crate::motion::feedforward`]; default: none).
    #[cfg_attr(feature = "serde", serde(default, with = "crate::axes::per_axis"))]
    pub feedforward: [FeedForwardConfig; AXES],
    /// Per axis: notch and low-pass biquads on the control output, after the laws and
    /// the feed-forward, before the amplifiers' saturation ([`crate::filter`]; default:
    /// none, the output passes bit for bit).
    #[cfg_attr(feature = "serde", serde(default, with = "crate::axes::per_axis"))]
    pub filters: [AxisFilterConfig; AXES],
}

#[cfg(feature = "serde")]
fn default_identify() -> IdentifyConfig {
    IDENTIFY_DEFAULTS
}

#[cfg(feature = "serde")]
fn default_models_known() -> [bool; AXES] {
    [true; AXES]
}

/// Why [`Servo::reconfigure`] refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReconfigureError {
    /// The outputs are on: disarm first.
    OutputsOn,
    /// The configuration is invalid (names the field).
    Config(ConfigError),
}
