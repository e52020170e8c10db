//! The settings tree: one typed value per user setting, in the units its name says.
//!
//! The field names are the dotted keys' segments ([`super::keys`]): `axis.x.law.kind` is
//! `settings.axis[0].law.kind`, and the serde form (TOML export/import) uses the same
//! names (`[axis.x.law] kind = "dsmc"`). Per-axis blocks reuse the servo's own config
//! types where they exist ([`AxisTravel`], [`AxisHomingConfig`], [`AxisJogConfig`],
//! [`AxisModel`]), so a field has one definition.
//!
//! Layout changes (a field added, removed, retyped or moved) change the stored record:
//! bump [`SETTINGS_VERSION`] with them (the store then reports a version mismatch and
//! starts from the factory defaults instead of misreading an old record). The test
//! `store::tests::record_layout_is_pinned` fails when the record's bytes change without
//! that decision being made.

use crate::axes::AXES;
use crate::estimator::PllConfig;
use crate::filter::{FilterConfig, BUTTERWORTH_Q, MAX_STAGES};
use crate::link::watchdog::DEFAULT_WATCHDOG_CONFIG;
use crate::motion::feedforward::FeedForwardConfig;
use crate::motion::homing::AxisHomingConfig;
use crate::motion::jog::{AxisJogConfig, JogConfig};
use crate::motion::planner::{PlannerConfig, GANTRY_PLANNER};
use crate::motion::shaper::impulses::{DEFAULT_DAMPING_RATIO, DEFAULT_VIBRATION_TOLERANCE};
use crate::motion::shaper::{AxisShapers, ShaperConfig, ShaperKind};
use crate::plant::AxisModel;
use crate::presets::board::{BOARD_LAMBDA, BOARD_PLL};
use crate::presets::gantry::{
    GANTRY_AMPLIFIERS, GANTRY_BRAKES, GANTRY_ENCODERS, GANTRY_HOMING, GANTRY_SAFETY, GANTRY_TRAVEL,
    LOOP_OMEGA,
};
use crate::servo::brake::BrakeConfig;
use crate::servo::travel::AxisTravel;
use crate::sysid::IDENTIFY_DEFAULTS;

use super::offsets::{ToolTable, WorkOffsets};

/// Version of the tree's layout, stored with every record (see the module docs). 3: the
/// work offsets, the tool table and the planner's servo reserve; 4: the holding brakes
/// (`axis.<a>.brake`); 5: the machine's safety switches (`safety.*`); 6: the motor's and
/// the encoder's direction (`axis.<a>.motor.invert`, `axis.<a>.encoder.invert`); 7: the
/// input shapers (`shaper.<a>.*`); 8: the output filters and the feed-forward
/// (`axis.<a>.filter.*`, `axis.<a>.feedforward.*`).
pub const SETTINGS_VERSION: u16 = 8;

/// Which law an axis runs; its gains follow from the axis' model and the bandwidth
/// ([`crate::sysid::tuning`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum LawKind {
    /// PID by pole placement `(s + ω)³` on `J s²` ([`crate::sysid::tuning::pid`]).
    Pid,
    /// Double-power-reaching terminal SMC, the board's default ([`crate::sysid::tuning::dsmc`]).
    Dsmc,
    /// SMC with a disturbance observer ([`crate::sysid::tuning::dob_smc`]).
    DobSmc,
    /// SMC with online friction identification ([`crate::sysid::tuning::adaptive_smc`]).
    AdaptiveSmc,
}

impl LawKind {
    /// Every kind, in the order of [`Self::NAMES`].
    pub const ALL: [LawKind; 4] = [Self::Pid, Self::Dsmc, Self::DobSmc, Self::AdaptiveSmc];
    /// The names keys and files use.
    pub const NAMES: &'static [&'static str] = &["pid", "dsmc", "dob_smc", "adaptive_smc"];

    pub const fn name(self) -> &'static str {
        match self {
            Self::Pid => "pid",
            Self::Dsmc => "dsmc",
            Self::DobSmc => "dob_smc",
            Self::AdaptiveSmc => "adaptive_smc",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// Coupling between the axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum CouplingKind {
    /// Independent axes.
    None,
    /// The paper's 3-D contour coupling with gain [`CouplingSettings::lambda`].
    Contour,
}

impl CouplingKind {
    pub const ALL: [CouplingKind; 2] = [Self::None, Self::Contour];
    pub const NAMES: &'static [&'static str] = &["none", "contour"];

    pub const fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Contour => "contour",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// An axis' law and its tuning.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct LawSettings {
    pub kind: LawKind,
    /// Closed-loop bandwidth of the position loop the gains are tuned for, rad/s.
    pub bandwidth_rad_s: f32,
}

/// An axis' encoder scale.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct EncoderSettings {
    /// Quadrature counts per mm of travel (lines × 4 / screw lead).
    pub counts_per_mm: f32,
    /// The encoder counts down when the axis moves forward (A and B swapped, or mounted the
    /// other way): the servo counts it the other way round (bring-up, docs/bring-up.md).
    #[cfg_attr(feature = "serde", serde(default))]
    pub invert: bool,
}

/// An axis' motor as the amplifier drives it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct MotorSettings {
    /// A positive command turns the motor backwards (phases or the amplifier's direction
    /// input wired the other way): the servo writes every effort negated.
    #[cfg_attr(feature = "serde", serde(default))]
    pub invert: bool,
}

/// An axis' amplifier scale.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AmplifierSettings {
    /// Effort at full command (100 % duty), in the laws' unit (mN·m of motor torque):
    /// the saturation of every law and the tuning's torque limit.
    pub full_scale: f32,
}

/// Everything one axis has of its own.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisSettings {
    pub law: LawSettings,
    /// The axis' rigid-body model, identified or entered; `None`: never identified nor
    /// entered, so the model-based laws refuse to arm on this axis.
    #[cfg_attr(feature = "serde", serde(default))]
    pub model: Option<AxisModel>,
    pub encoder: EncoderSettings,
    /// (absent from files written before the motor's direction existed: not inverted)
    #[cfg_attr(feature = "serde", serde(default))]
    pub motor: MotorSettings,
    pub amplifier: AmplifierSettings,
    /// Following error allowed at rest, mm (LinuxCNC MIN_FERROR).
    pub min_ferror_mm: f32,
    /// Following error allowed at `vel_max_mm_s`, mm (LinuxCNC FERROR); it grows linearly
    /// from `min_ferror_mm` at rest.
    pub following_error_mm: f32,
    /// Largest speed of the axis, mm/s (overspeed trips 10 % above).
    pub vel_max_mm_s: f32,
    /// Largest acceleration the axis can physically make, mm/s² (bounds the count jump the
    /// encoder check accepts).
    pub accel_max_mm_s2: f32,
    /// Deceleration of a controlled stop, mm/s².
    pub stop_decel_mm_s2: f32,
    /// Effort change that must move a resting axis (stuck-encoder and runaway threshold),
    /// mN·m.
    pub stuck_effort_change: f32,
    /// Soft limits, machine coordinates.
    pub travel: AxisTravel,
    pub homing: AxisHomingConfig,
    pub jog: AxisJogConfig,
    /// What the motion planner may command on this axis.
    pub planner: AxisPlannerSettings,
    /// The axis' holding brake (absent from files written before brakes existed: none).
    #[cfg_attr(feature = "serde", serde(default))]
    pub brake: BrakeConfig,
    /// Feed-forward from the reference: Coulomb pre-compensation and the frame's
    /// compliance and deflection ([`crate::motion::feedforward`]; absent from files
    /// written before it existed: none).
    #[cfg_attr(feature = "serde", serde(default))]
    pub feedforward: FeedForwardConfig,
    /// Notch and low-pass filters on the control output ([`crate::filter`]; absent from
    /// files written before they existed: none).
    #[cfg_attr(feature = "serde", serde(default = "no_filters"))]
    pub filter: AxisFilterSettings,
}

/// What one filter stage on an axis' control output is ([`FilterConfig`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum FilterKind {
    /// A notch of finite depth at `freq_hz`, `width_hz` wide, `depth_db` deep.
    Notch,
    /// A second-order low-pass at `freq_hz` with quality `q`.
    LowPass,
}

impl FilterKind {
    pub const ALL: [FilterKind; 2] = [Self::Notch, Self::LowPass];

    pub const fn name(self) -> &'static str {
        match self {
            Self::Notch => "notch",
            Self::LowPass => "low_pass",
        }
    }
}

/// One filter stage of an axis (`axis.<a>.filter.stage<n>`). The fields a kind does not
/// use keep their values (a low-pass has no width or depth, a notch no `q`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct FilterStageSettings {
    /// `notch` or `low_pass`; `None` (key value `none`): the stage is off.
    #[cfg_attr(feature = "serde", serde(default))]
    pub kind: Option<FilterKind>,
    /// The notch's centre or the low-pass' cutoff, Hz (`cargo sim filters` places them
    /// from the measured response).
    pub freq_hz: f32,
    /// The notch's width (between the frequencies attenuated by half its depth in dB), Hz.
    pub width_hz: f32,
    /// The notch's attenuation at its centre, dB.
    pub depth_db: f32,
    /// The low-pass' quality (0.707: Butterworth).
    pub q: f32,
}

/// An axis' output filter stages, applied in order; stages that are off are skipped.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisFilterSettings {
    pub stage1: FilterStageSettings,
    pub stage2: FilterStageSettings,
    pub stage3: FilterStageSettings,
    pub stage4: FilterStageSettings,
}

// (one settings stage per stage the servo runs)
const _: () = assert!(MAX_STAGES == 4);

/// A stage that is off; a 100 Hz, 20 Hz wide, 20 dB notch or a Butterworth low-pass at
/// 100 Hz once a kind is chosen.
const NO_FILTER_STAGE: FilterStageSettings = FilterStageSettings {
    kind: None,
    freq_hz: 100.0,
    width_hz: 20.0,
    depth_db: 20.0,
    q: BUTTERWORTH_Q,
};

/// The factory's filters: none (a notch or a low-pass costs phase; they are placed from a
/// machine's measured response).
pub const NO_FILTERS: AxisFilterSettings = AxisFilterSettings {
    stage1: NO_FILTER_STAGE,
    stage2: NO_FILTER_STAGE,
    stage3: NO_FILTER_STAGE,
    stage4: NO_FILTER_STAGE,
};

#[cfg(feature = "serde")]
fn no_filters() -> AxisFilterSettings {
    NO_FILTERS
}

impl FilterStageSettings {
    /// The stage this describes (`None`: off).
    pub fn config(&self) -> Option<FilterConfig> {
        self.kind.map(|kind| match kind {
            FilterKind::Notch => FilterConfig::Notch {
                freq_hz: self.freq_hz,
                width_hz: self.width_hz,
                depth_db: self.depth_db,
            },
            FilterKind::LowPass => FilterConfig::LowPass {
                cutoff_hz: self.freq_hz,
                q: self.q,
            },
        })
    }
}

impl AxisFilterSettings {
    /// The stages in order, `stage1` first.
    pub fn stages(&self) -> [&FilterStageSettings; MAX_STAGES] {
        [&self.stage1, &self.stage2, &self.stage3, &self.stage4]
    }
}

/// The motion planner's limits of one axis (its velocity at most the axis' `vel_max_mm_s`,
/// which trips overspeed).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisPlannerSettings {
    /// Largest commanded speed, also the speed of rapid moves, mm/s.
    pub vel_max_mm_s: f32,
    /// Largest commanded acceleration, mm/s².
    pub acc_max_mm_s2: f32,
    /// Largest commanded jerk, mm/s³.
    pub jerk_max_mm_s3: f32,
}

/// The motion planner's path settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PlannerSettings {
    /// Path tolerance of G64 without P: the commanded path stays within this distance of
    /// the programmed one at blended corners, mm.
    pub tolerance_mm: f32,
    /// Share of each axis' acceleration and jerk kept for speeding up and slowing down
    /// along curves; the rest bounds the centripetal terms (0-1).
    pub tangential_share: f32,
    /// Share of each axis' jerk kept for the servo along the path (see
    /// `PlannerConfig::servo_reserve`).
    pub servo_reserve: f32,
}

/// Machine-wide safety switches.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct SafetySettings {
    /// Arming checks every encoder by moving each axis' hold point 16 counts out and back
    /// both ways (`SafetyConfig::arm_encoder_check`; off: arming moves nothing).
    pub arm_encoder_check: bool,
}

/// One axis' input shaper ([`crate::motion::shaper`]): the mode it cancels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisShaperSettings {
    /// Klipper's kind (`zv`, `mzv`, `zvd`, `ei`, `2hump_ei`, `3hump_ei`); `None` (key
    /// value `none`): the axis is not shaped.
    #[cfg_attr(feature = "serde", serde(default))]
    pub kind: Option<ShaperKind>,
    /// Frequency of the mode, Hz (`cargo sim freqresp` measures it).
    pub freq_hz: f32,
    /// Damping ratio of the mode (Klipper's default 0.1).
    pub damping_ratio: f32,
}

/// The input shapers of the planner's reference, `shaper.x`, `shaper.y`, `shaper.z`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ShaperSettings {
    pub x: AxisShaperSettings,
    pub y: AxisShaperSettings,
    pub z: AxisShaperSettings,
}

/// No shaping; a mode at 50 Hz with Klipper's damping once a kind is chosen.
const NO_SHAPER: AxisShaperSettings = AxisShaperSettings {
    kind: None,
    freq_hz: 50.0,
    damping_ratio: DEFAULT_DAMPING_RATIO,
};

/// The factory's shapers: none (shaping costs contour tolerance and acceleration; it is
/// tuned from a machine's measured modes).
pub const FACTORY_SHAPERS: ShaperSettings = ShaperSettings {
    x: NO_SHAPER,
    y: NO_SHAPER,
    z: NO_SHAPER,
};

#[cfg(feature = "serde")]
fn factory_shapers() -> ShaperSettings {
    FACTORY_SHAPERS
}

impl AxisShaperSettings {
    /// The shaper this describes (`None`: not shaped).
    pub fn config(&self) -> Option<ShaperConfig> {
        self.kind.map(|kind| ShaperConfig {
            kind,
            freq_hz: self.freq_hz,
            damping_ratio: self.damping_ratio,
            vibration_tolerance: DEFAULT_VIBRATION_TOLERANCE,
        })
    }
}

impl ShaperSettings {
    /// The shapers of the three axes, for [`crate::motion::shaper::ShaperStage`].
    pub fn shapers(&self) -> AxisShapers {
        AxisShapers {
            x: self.x.config(),
            y: self.y.config(),
            z: self.z.config(),
        }
    }
}

/// Jog settings shared by the axes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct JogSettings {
    /// Without a new jog command for this long the axis decelerates to rest, s.
    pub timeout_s: f32,
}

/// Coupling between the axes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct CouplingSettings {
    pub kind: CouplingKind,
    /// Contour coupling gain λ (kept while `kind` is `none`).
    pub lambda: f32,
}

/// The velocity estimator (a PLL on every axis).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct EstimatorSettings {
    /// PLL natural frequency ω, rad/s.
    pub pll_bandwidth_rad_s: f32,
    /// PLL damping ζ (1: critically damped).
    pub pll_damping: f32,
}

/// The host link.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct LinkSettings {
    /// Silence after which the link counts as lost (controlled stop, `LinkLost`), ms.
    pub watchdog_ms: u32,
}

/// What identification may do (the rest of its configuration is the firmware's
/// [`IDENTIFY_DEFAULTS`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct IdentifySettings {
    /// Hard limit on the effort identification commands, mN·m (never above the axis'
    /// amplifier full scale).
    pub torque_cap_mnm: f32,
    /// Distance the planned motion keeps from each end of the travel window, mm.
    pub edge_margin_mm: f32,
}

/// The settings tree (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Settings {
    /// Per axis, `axis.x`, `axis.y`, `axis.z`.
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub axis: [AxisSettings; AXES],
    pub jog: JogSettings,
    pub coupling: CouplingSettings,
    pub estimator: EstimatorSettings,
    pub link: LinkSettings,
    pub identify: IdentifySettings,
    pub planner: PlannerSettings,
    /// Machine-wide safety switches (absent from files written before they existed: the
    /// factory's).
    #[cfg_attr(feature = "serde", serde(default = "factory_safety"))]
    pub safety: SafetySettings,
    /// The work coordinate systems G54..G59.3 (`work.g54` .. `work.g59_3`).
    pub work: WorkOffsets,
    /// The tool table (`tool.1` .. `tool.8`).
    pub tool: ToolTable,
    /// The input shapers (absent from files written before they existed: none).
    #[cfg_attr(feature = "serde", serde(default = "factory_shapers"))]
    pub shaper: ShaperSettings,
}

/// One axis' factory settings: the designed gantry ([`crate::presets::gantry`]), no
/// model.
const fn factory_axis(i: usize) -> AxisSettings {
    let safety = GANTRY_SAFETY[i];
    AxisSettings {
        law: LawSettings {
            kind: LawKind::Dsmc,
            bandwidth_rad_s: LOOP_OMEGA,
        },
        model: None,
        encoder: EncoderSettings {
            counts_per_mm: GANTRY_ENCODERS[i].counts_per_mm,
            invert: false,
        },
        motor: MotorSettings { invert: false },
        amplifier: AmplifierSettings {
            full_scale: GANTRY_AMPLIFIERS[i].full_scale,
        },
        min_ferror_mm: safety.min_ferror_mm,
        following_error_mm: safety.ferror_mm,
        vel_max_mm_s: safety.vel_max_mm_s,
        accel_max_mm_s2: safety.accel_max_mm_s2,
        stop_decel_mm_s2: safety.stop_decel_mm_s2,
        stuck_effort_change: safety.stuck_effort_change,
        travel: GANTRY_TRAVEL.axes[i],
        homing: GANTRY_HOMING.axes[i],
        jog: JogConfig::GANTRY.axes[i],
        planner: AxisPlannerSettings {
            vel_max_mm_s: GANTRY_PLANNER.vel_max_mm_s[i],
            acc_max_mm_s2: GANTRY_PLANNER.acc_max_mm_s2[i],
            jerk_max_mm_s3: GANTRY_PLANNER.jerk_max_mm_s3[i],
        },
        brake: GANTRY_BRAKES[i],
        feedforward: FeedForwardConfig::NONE,
        filter: NO_FILTERS,
    }
}

/// The factory's safety switches: the arm check off (arming never moves an axis unless
/// the user asks for it).
const FACTORY_SAFETY: SafetySettings = SafetySettings {
    arm_encoder_check: false,
};

#[cfg(feature = "serde")]
fn factory_safety() -> SafetySettings {
    FACTORY_SAFETY
}

/// The factory settings: what a board runs before anything was stored, equal to
/// [`crate::presets::board::factory_config`] (tested): the designed gantry's DSMC at
/// [`LOOP_OMEGA`], contour coupling λ = [`BOARD_LAMBDA`], the PLL at [`BOARD_PLL`], the
/// gantry's limits, travel, homing, jog and Z brake, the link's default watchdog, identification's
/// default cap and margin — and no axis model, so the model-based laws refuse to arm
/// until the axes are identified or their models entered.
pub const FACTORY: Settings = Settings {
    axis: [factory_axis(0), factory_axis(1), factory_axis(2)],
    jog: JogSettings {
        timeout_s: JogConfig::GANTRY.timeout_s,
    },
    coupling: CouplingSettings {
        kind: CouplingKind::Contour,
        lambda: BOARD_LAMBDA,
    },
    estimator: EstimatorSettings {
        pll_bandwidth_rad_s: BOARD_PLL.bandwidth_rad_s,
        pll_damping: BOARD_PLL.damping,
    },
    link: LinkSettings {
        watchdog_ms: DEFAULT_WATCHDOG_CONFIG.timeout_ms,
    },
    identify: IdentifySettings {
        torque_cap_mnm: IDENTIFY_DEFAULTS.torque_cap_mnm,
        edge_margin_mm: IDENTIFY_DEFAULTS.edge_margin_mm,
    },
    planner: PlannerSettings {
        tolerance_mm: GANTRY_PLANNER.tolerance_mm,
        tangential_share: GANTRY_PLANNER.tangential_share,
        servo_reserve: GANTRY_PLANNER.servo_reserve,
    },
    safety: FACTORY_SAFETY,
    work: WorkOffsets::ZERO,
    tool: ToolTable::EMPTY,
    shaper: FACTORY_SHAPERS,
};

impl Settings {
    /// The motion planner's configuration at `rate_hz` (the arc-radius tolerance and the
    /// shortest segment are the planner's constants, not settings: grbl's rules).
    pub fn planner_config(&self, rate_hz: u32) -> PlannerConfig {
        PlannerConfig {
            period_s: 1.0 / rate_hz.max(1) as f32,
            vel_max_mm_s: self.axis.map(|a| a.planner.vel_max_mm_s),
            acc_max_mm_s2: self.axis.map(|a| a.planner.acc_max_mm_s2),
            jerk_max_mm_s3: self.axis.map(|a| a.planner.jerk_max_mm_s3),
            tolerance_mm: self.planner.tolerance_mm,
            tangential_share: self.planner.tangential_share,
            servo_reserve: self.planner.servo_reserve,
            arc_radius_tolerance_mm: GANTRY_PLANNER.arc_radius_tolerance_mm,
            min_segment_mm: GANTRY_PLANNER.min_segment_mm,
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        FACTORY
    }
}

impl EstimatorSettings {
    /// The PLL configuration.
    pub const fn pll(&self) -> PllConfig {
        PllConfig {
            bandwidth_rad_s: self.pll_bandwidth_rad_s,
            damping: self.pll_damping,
        }
    }
}

impl LinkSettings {
    /// The link's watchdog configuration (validated by [`Settings::servo_config`]).
    pub const fn watchdog(&self) -> crate::link::WatchdogConfig {
        crate::link::WatchdogConfig {
            timeout_ms: self.watchdog_ms,
        }
    }
}

const _: () = assert!(AXES == 3);
