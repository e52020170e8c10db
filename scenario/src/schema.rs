//! The types of a scenario file (one run, after cases and variants are merged in).
//!
//! Every table rejects unknown keys. Per-axis values are tables `{ x, y, z }` (or arrays of
//! three); `all` gives their common part. Lengths in mm (the paper's normalised unit for
//! its axis), times in s, efforts in the laws' units (mN·m on the physical axes).

use controller_core::coupling::CouplingConfig;
use controller_core::estimator::EstimatorConfig;
use controller_core::law::adaptive_smc::AdaptiveSmcConfig;
use controller_core::law::dob_smc::DobSmcConfig;
use controller_core::law::pid::PidConfig;
use controller_core::law::smc::SmcConfig;
use controller_core::motion::homing::{AxisHomingConfig, HomingConfig};
use controller_core::motion::jog::{AxisJogConfig, JogConfig};
use controller_core::motion::path::{PathConfig, PathStart};
use controller_core::servo::brake::{BrakeConfig, DEFAULT_ENGAGE_S, DEFAULT_RELEASE_S};
use controller_core::servo::io::{AmplifierConfig, EncoderConfig};
use controller_core::servo::monitor::{AxisSafetyConfig, SafetyConfig};
use controller_core::servo::travel::AxisTravel;
use controller_core::sim::run::TimedInjection;
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    BrakePlantConfig, ImperfectionConfig, InitialState, PlantConfig, SwitchConfig,
};
use controller_core::sysid::{IdentifyConfig, IDENTIFY_DEFAULTS};
use serde::{Deserialize, Serialize};

/// Number type the controller runs in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Numeric {
    /// The firmware's float type.
    #[default]
    F32,
    /// Host reference precision.
    F64,
    /// Saturating fixed point Q32.32 (docs/fixed-point.md).
    Fixed,
    /// Saturating fixed point Q16.16, for comparison (too coarse for the integrator).
    FixedQ16,
}

impl Numeric {
    /// The name used in files and as a JSON key.
    pub const fn name(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::F64 => "f64",
            Self::Fixed => "fixed",
            Self::FixedQ16 => "fixed_q16",
        }
    }
}

/// How the controller is evaluated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// The servo step at the machine's control rate against the simulated world (zero-order
    /// hold, encoder counts, amplifier range and resolution): what the firmware does.
    #[default]
    Discrete,
    /// The controller evaluated at every RK4 stage of step `dt_s`, its integrals integrated
    /// with the plant: the paper's Matlab setting (PID and sliding-mode laws only).
    Continuous { dt_s: f64 },
}

/// One run.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// `[A-Za-z0-9_-]+`; names output files.
    pub name: String,
    #[serde(default)]
    pub description: Option<String>,
    /// Simulated time, s.
    pub horizon_s: f64,
    #[serde(default)]
    pub numeric: Numeric,
    #[serde(default)]
    pub mode: Mode,
    pub machine: MachineSpec,
    pub controller: ControllerSpec,
    pub estimator: EstimatorSpec,
    pub path: PathConfig,
    #[serde(default)]
    pub path_start: PathStart,
    #[serde(default)]
    pub metrics: TruthSpec,
    /// Arm and hold position instead of following the path.
    #[serde(default)]
    pub hold: bool,
    /// A fault injected during the run (the fault matrix).
    #[serde(default)]
    pub fault: Option<TimedInjection>,
    /// Run the path (a square or polyline) as a program through the machine's supervisor
    /// and planner instead of the servo's own path generator
    /// (controller-core `sim::run::RunConfig::program`).
    #[serde(default)]
    pub program: bool,
    /// Parameters of the study that interprets this file (each study checks its own).
    #[serde(default)]
    pub study: Option<toml::Value>,
}

/// The machine: control rate and the three axes.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineSpec {
    pub rate_hz: u32,
    /// RK4 steps of the plants per control period (discrete mode).
    #[serde(default = "four")]
    pub plant_substeps: u32,
    /// Start every axis on the path (its position and velocity at t = 0) instead of at
    /// `initial`. Such a run starts mid-motion, so its axes' holding brakes are left out
    /// (they would be open).
    #[serde(default)]
    pub start_on_path: bool,
    /// Timings of the fault checks (overspeed ratio, stuck and runaway times, overrun
    /// window, stop settling, encoder check); the per-axis limits are the axes' `safety`.
    #[serde(default)]
    pub safety: SafetyTimings,
    /// `false` switches every fault check off (studies that compare figures, not trips;
    /// never on a machine).
    #[serde(default = "yes")]
    pub fault_checks: bool,
    #[serde(with = "controller_core::axes::per_axis")]
    pub axes: [AxisSpec; 3],
    /// Without a new jog command for this long a jog stops, s.
    #[serde(default = "jog_timeout")]
    pub jog_timeout_s: f32,
    /// Identification's template (window and cap are set per run).
    #[serde(default = "identify_defaults")]
    pub identify: IdentifyConfig,
    /// Sensor noise and command delay of the simulated machine.
    #[serde(default)]
    pub imperfections: ImperfectionConfig,
}

fn jog_timeout() -> f32 {
    JogConfig::GANTRY.timeout_s
}

fn identify_defaults() -> IdentifyConfig {
    IDENTIFY_DEFAULTS
}

fn four() -> u32 {
    4
}

fn yes() -> bool {
    true
}

/// One axis of the machine.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    pub plant: PlantConfig,
    pub encoder: EncoderConfig,
    pub amplifier: AmplifierConfig,
    /// Limits and fault thresholds (default: every check off, for studies that compare
    /// figures rather than trips; a machine file gives real ones).
    #[serde(default = "safety_off")]
    pub safety: AxisSafetyConfig,
    #[serde(default)]
    pub initial: InitialState,
    /// Soft limits, machine coordinates (default: unlimited).
    #[serde(default = "unlimited")]
    pub travel: AxisTravel,
    /// Homing on the axis' switch (default: the axis does not home).
    #[serde(default = "no_homing")]
    pub homing: AxisHomingConfig,
    #[serde(default = "gantry_jog")]
    pub jog: AxisJogConfig,
    /// The simulated machine's limit switches and index (default: none).
    #[serde(default)]
    pub switches: SwitchConfig,
    /// The axis' model is known (identified or entered); a model-based law on an axis
    /// whose model is not known refuses to arm.
    #[serde(default = "yes")]
    pub model_known: bool,
    /// The axis' holding brake (default: none).
    #[serde(default)]
    pub brake: BrakeSpec,
    /// Coulomb pre-compensation and the frame's compliance and deflection
    /// (controller-core `motion::feedforward`; default: none).
    #[serde(default)]
    pub feedforward: controller_core::motion::feedforward::FeedForwardConfig,
    /// Notch and low-pass biquads on the axis' control output, a list of at most 4
    /// stages (controller-core `filter`; default: none), e.g.
    /// `filters = [{ notch = { freq_hz = 35.0, width_hz = 7.0, depth_db = 20.0 } }]`.
    #[serde(default)]
    pub filters: controller_core::filter::AxisFilterConfig,
}

/// An axis' holding brake: what the servo knows of it (`present`, the timings) and what
/// the simulated machine's brake does (the same timings, its holding torque).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BrakeSpec {
    /// The axis has a brake (the servo drives its output).
    pub present: bool,
    /// The brake grips this long after its coil is de-energised, s (0..=1).
    pub engage_s: f32,
    /// The brake opens this long after its coil is energised, s (0..=1).
    pub release_s: f32,
    /// Holding torque while it grips, mN·m (positive when `present`).
    pub holding_mnm: f32,
}

impl Default for BrakeSpec {
    fn default() -> Self {
        Self {
            present: false,
            engage_s: DEFAULT_ENGAGE_S,
            release_s: DEFAULT_RELEASE_S,
            holding_mnm: 0.0,
        }
    }
}

impl BrakeSpec {
    /// The servo's view.
    pub const fn servo(&self) -> BrakeConfig {
        BrakeConfig {
            present: self.present,
            engage_s: self.engage_s,
            release_s: self.release_s,
        }
    }

    /// The simulated machine's brake (none unless `present`).
    pub const fn plant(&self) -> BrakePlantConfig {
        BrakePlantConfig {
            holding_mnm: if self.present { self.holding_mnm } else { 0.0 },
            engage_s: self.engage_s,
            release_s: self.release_s,
        }
    }
}

fn unlimited() -> AxisTravel {
    AxisTravel::UNLIMITED
}

fn no_homing() -> AxisHomingConfig {
    HomingConfig::NONE.axes[0]
}

fn gantry_jog() -> AxisJogConfig {
    JogConfig::GANTRY.axes[0]
}

fn safety_off() -> AxisSafetyConfig {
    AxisSafetyConfig::OFF
}

/// The machine-wide part of [`SafetyConfig`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetyTimings {
    pub overspeed_ratio: f32,
    pub stuck_time_s: f32,
    pub runaway_time_s: f32,
    pub overrun_max: u16,
    pub overrun_window_s: f32,
    pub stop_settle_s: f32,
    pub stop_timeout_s: f32,
    pub encoder_check_time_s: f32,
    pub encoder_check_counts: u32,
    pub stuck_decel_mm_s2: f32,
    pub estop_category: u8,
    pub estop_stop_time_s: f32,
    pub encoder_noise_counts: f32,
    pub index_max_correction_counts: u32,
    pub arm_encoder_check: bool,
}

impl Default for SafetyTimings {
    fn default() -> Self {
        let d = SafetyConfig::OFF;
        Self {
            overspeed_ratio: d.overspeed_ratio,
            stuck_time_s: d.stuck_time_s,
            runaway_time_s: d.runaway_time_s,
            overrun_max: d.overrun_max,
            overrun_window_s: d.overrun_window_s,
            stop_settle_s: d.stop_settle_s,
            stop_timeout_s: d.stop_timeout_s,
            encoder_check_time_s: d.encoder_check_time_s,
            encoder_check_counts: d.encoder_check_counts,
            stuck_decel_mm_s2: d.stuck_decel_mm_s2,
            estop_category: d.estop_category,
            estop_stop_time_s: d.estop_stop_time_s,
            encoder_noise_counts: d.encoder_noise_counts,
            index_max_correction_counts: d.index_max_correction_counts,
            arm_encoder_check: d.arm_encoder_check,
        }
    }
}

impl SafetyTimings {
    /// The full safety configuration with these timings and the axes' limits.
    pub fn with_axes(&self, axes: [AxisSafetyConfig; 3]) -> SafetyConfig {
        SafetyConfig {
            axes,
            overspeed_ratio: self.overspeed_ratio,
            stuck_time_s: self.stuck_time_s,
            runaway_time_s: self.runaway_time_s,
            overrun_max: self.overrun_max,
            overrun_window_s: self.overrun_window_s,
            stop_settle_s: self.stop_settle_s,
            stop_timeout_s: self.stop_timeout_s,
            encoder_check_time_s: self.encoder_check_time_s,
            encoder_check_counts: self.encoder_check_counts,
            stuck_decel_mm_s2: self.stuck_decel_mm_s2,
            estop_category: self.estop_category,
            estop_stop_time_s: self.estop_stop_time_s,
            encoder_noise_counts: self.encoder_noise_counts,
            index_max_correction_counts: self.index_max_correction_counts,
            arm_encoder_check: self.arm_encoder_check,
        }
    }
}

/// The controller: a law per axis and the coupling.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSpec {
    #[serde(with = "controller_core::axes::per_axis")]
    pub laws: [LawSpec; 3],
    pub coupling: CouplingConfig,
}

/// A law with explicit parameters, or tuned from the axis' physical plant.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LawSpec {
    Pid(PidConfig),
    Smc(SmcConfig),
    DobSmc(DobSmcConfig),
    AdaptiveSmc(AdaptiveSmcConfig),
    /// Derived from the axis model by the tuning rules of
    /// `controller_core::presets::gantry` (physical plants only).
    Tuned(TunedLaw),
}

/// The laws the tuning rules derive from a physical axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TunedLaw {
    Pid,
    Dsmc,
    DobSmc,
    AdaptiveSmc,
    /// The adaptive law with its adaptation off (a fixed-parameter SMC with friction
    /// feed-forward from the initial estimates).
    AdaptiveSmcFrozen,
}

/// Velocity estimators.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EstimatorSpec {
    #[serde(with = "controller_core::axes::per_axis")]
    pub axes: [EstimatorConfig; 3],
    #[serde(default)]
    pub accel_input: AccelSpec,
}

/// The estimators' commanded acceleration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AccelSpec {
    #[default]
    None,
    /// The reference acceleration.
    Reference,
    /// Each axis' model (the plant's: paper `a, b, k`; physical `B/J, 0, 1/J`) times the
    /// applied output.
    Model,
}
