//! The per-period servo step: the one control sequence the board's control interrupt, the
//! simulator's discrete mode and the firmware's QEMU rig all run, with its supervisor
//! (states, fault detection, stops, reset rules).
//!
//! [`Servo::period`], in order:
//!
//! 1. sample the inputs; e-stop and amplifier faults latch in any state, limit switches
//!    while the outputs are on; apply the period's commands; if the outputs may not be
//!    driven, switch them off *before anything else*;
//! 2. read the encoder counters and extend them to wide counts ([`WideCounter`]: the
//!    signed difference of successive readings modulo the counter width, so a wrap can be
//!    neither lost nor double counted);
//! 3. sample the reference ([`motion::Motion`]: hold, path, controlled stop);
//! 4. positions from counts and velocity estimates ([`EstimatorBank`]);
//! 5. while enabled: the encoder checks ([`monitor`]); evaluate the 3-axis controller and
//!    check its outputs and states are finite; saturate to the amplifiers' range; check
//!    following error and speed; write the outputs, or switch them off on an immediate
//!    fault, or start a controlled stop; commit every controller and estimator state with
//!    the output actually applied;
//! 6. the holding brakes' commands ([`brake`]: released only on an axis driven now and in
//!    the previous period, engaged at the end of a controlled stop), written out once;
//!    then publish the telemetry [`Snapshot`] (plain copies).
//!
//! States ([`ServoState`]): `Disabled` (boot; outputs off) → arm → `Idle` (holding the
//! position it armed at: arming never starts motion) → `Run` (a path or the planner's
//! program), `Jog`, `Homing` or `Identify`, each back to `Idle` (a stop command ends the
//! motion with a controlled stop). A fault of the immediate category goes straight to
//! `Fault` (outputs off in that period); a controlled one goes through `Stopping`.
//! `Fault` → reset → `Disabled` only once every cause is gone; an encoder fault first runs
//! the encoder check (`EncoderCheck`): the axis must follow a small effort in both
//! directions, or the reset is refused. Which command is valid when: [`commands::check`].
//!
//! Holding brakes ([`brake`]): motion commanded while a brake still opens is accepted and
//! held at rest until it is open ([`Servo::motion_held`]); a controlled stop ends with the
//! brakes gripping before the outputs go off; an immediate one engages them in the period
//! the outputs go off.
//!
//! Coordinates: the servo works in machine coordinates, the wide encoder counts whose
//! origin homing moves ([`homing`], [`WideCounter::rebase`]); the encoder checks see the
//! steps between readings, so re-basing never looks like a jump. Soft limits ([`travel`]) apply to axes
//! that are homed (or take no part in homing).
//!
//! Nothing here allocates, blocks, formats or panics; every number that reaches an output
//! is finite and within the amplifier's range.

pub mod brake;
pub mod commands;
pub mod faults;
pub mod homing;
pub mod identify;
pub mod index_check;
pub mod io;
pub mod jog;
pub mod monitor;
pub mod motion;
pub mod ramp;
pub mod snapshot;
pub mod travel;

use crate::axes::{Axis, AXES};
use crate::config::ConfigError;
use crate::controller::{ControlOutput, Controller3, ControllerConfig, Measured};
use crate::estimator::{EstimatorBank, EstimatorBankConfig, EstimatorTiming, WideCounter};
use crate::motion::path::{PathConfig, PathStart};
use crate::motion::planner::PathSample;
use crate::motion::trajectory::{RefSample, Trajectory};
#[cfg(feature = "serde")]
use crate::sysid::IDENTIFY_DEFAULTS;
use crate::sysid::{AxisSample, IdentifyConfig};
use crate::{Real, Vec3};
use brake::{BrakeConfig, BrakeState};
pub use commands::{Command, Refusal};
use faults::{Fault, FaultKind, FaultLog, FaultRecord, StopCategory};
use homing::{Homing, HomingConfig, HomingEvent, HomingInputs};
use identify::{IdentifyOutcome, IdentifyRun};
use index_check::{IndexCheck, IndexVerdict};
use io::{AmplifierConfig, EncoderConfig, Inputs, ServoIo};
use jog::{Jog, JogConfig};
use monitor::{Monitor, SafetyConfig};
use motion::{Clock, Motion};
use snapshot::Snapshot;
use travel::TravelConfig;

/// Highest control rate the servo accepts, Hz.
pub const MAX_RATE_HZ: u32 = 50_000;
/// Lowest control rate the servo accepts, Hz.
pub const MIN_RATE_HZ: u32 = 100;
/// During a controlled stop the following-error limit is this many times the normal one;
/// beyond it the stop becomes immediate.
pub const STOPPING_FERROR_SCALE: f32 = 2.0;

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

/// State of the servo and its outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ServoState {
    /// Outputs off, waiting for an explicit arm.
    Disabled,
    /// Outputs on, holding position.
    Idle,
    /// Outputs on, following the path or the planner's program.
    Run,
    /// Outputs on, jogging.
    Jog,
    /// Outputs on, running the homing sequence.
    Homing,
    /// Identifying an axis (the others hold, or are off when started from Disabled).
    Identify,
    /// Outputs on, decelerating to rest (after a controlled-stop fault, or a disarm while
    /// moving); then outputs off.
    Stopping,
    /// Reset of an encoder fault: a small effort on the faulted axes must move them.
    EncoderCheck,
    /// Outputs off, fault latched.
    Fault,
}

impl ServoState {
    /// The outputs are driven in this state (in `Identify` at least the identified axis').
    pub const fn drives(self) -> bool {
        !matches!(self, Self::Disabled | Self::Fault)
    }
}

/// Progress of an encoder check.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Check {
    axis: usize,
    positive: bool,
    k: u32,
    n0: i64,
}

/// The closed-loop encoder check at arming ([`SafetyConfig::arm_encoder_check`]): every
/// axis' hold reference moves `encoder_check_counts` out and back each way at
/// [`ARM_CHECK_SPEED_MM_S`], all at once, under the laws; each reading must follow.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ArmCheck<R> {
    /// Each axis' phase, and the periods it has been in it.
    phase: [ArmPhase; AXES],
    k: [u32; AXES],
    /// Every axis' counts where the check began (its hold point).
    base: [i64; AXES],
    /// The hold point of every axis, mm.
    hold: Vec3<R>,
    /// The reference's offset from the hold point, counts.
    offset: [f32; AXES],
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum ArmPhase {
    /// An axis with a brake holds for the stop's settle time once the brakes are open
    /// (the load the brake held settles onto the law), then its hold point is taken.
    Settle,
    /// Out the positive way: the axis must reach half the check counts.
    Out,
    /// Back and out the negative way: the axis must reach minus half the check counts.
    Back,
    /// Back to the hold point.
    Home,
    /// Followed both ways, holding.
    Done,
}

/// Speed of the arm check's reference, mm/s: 5 mm/s moves the 16 check counts (10 µm on
/// the gantry) in 2 ms, slow enough that the law follows with about a count of lag.
pub const ARM_CHECK_SPEED_MM_S: f32 = 5.0;

/// Counts a healthy axis may stray the wrong way while the arm check's reference moves
/// out, beyond the configured edge noise: one count of holding dither and one of a
/// settling load. A swapped A/B moves the reading the wrong way from the first push on.
const ARM_CHECK_WRONG_COUNTS: f32 = 2.0;

/// Counts an axis may stray from where it armed while the arm check lets it settle,
/// beyond the wrong-way margin: a braked axis' load sags the law's hold when the brake
/// lets go (6 counts, 3.8 µm, on the gantry's Z, whose law starts from zero effort); 10
/// counts is a runaway, not a sag.
const ARM_CHECK_SETTLE_COUNTS: f32 = 8.0;

/// The servo step's state, owned by the control interrupt.
pub struct Servo<R> {
    period_s: f64,
    clock: Clock<R>,
    dt: R,
    /// Wide counts in machine coordinates (homing moves their origin).
    counters: [WideCounter; AXES],
    count_len: [R; AXES],
    count_len_f32: [f32; AXES],
    counts_per_mm: [f32; AXES],
    full_scale: Vec3<R>,
    /// Axes whose motor turns backwards for a positive command (bit i: axis i,
    /// `AmplifierConfig::invert`): their effort is negated as it is written.
    motor_inverted: u8,
    estimators: EstimatorBank<R>,
    controller: Controller3<R>,
    monitor: Monitor,
    /// Counts lost or gained between index pulses: corrected or faulted.
    index: IndexCheck,
    faults: FaultLog,
    state: ServoState,
    /// The state a controlled stop ends in (Fault, Disabled after a disarm, Idle after a
    /// stop command).
    stop_then: ServoState,
    /// The configured path and the period after which its end point is held.
    path: Option<(Trajectory<R>, Option<u32>)>,
    path_start: PathStart,
    motion: Motion<R>,
    travel: TravelConfig,
    homing_cfg: HomingConfig,
    jog_cfg: JogConfig,
    jog_timeout_periods: u32,
    identify_cfg: IdentifyConfig,
    identify: Option<IdentifyRun>,
    identify_outcome: Option<IdentifyOutcome>,
    /// Axes homed since power-up (bit i = axis i); lost with an encoder fault.
    homed: u8,
    /// Axes that take no part in homing: referenced where they stand.
    no_homing: u8,
    /// The host link is lost (a `LinkLost` fault's cause).
    link_down: bool,
    /// Periods the stop reference has been at rest.
    rest_periods: u32,
    settle_periods: u32,
    stop_timeout_periods: u32,
    /// The e-stop is a controlled stop (category 1).
    estop_controlled: bool,
    estop_stop_periods: u32,
    /// Periods a category-1 e-stop's stop may still take before the outputs go off.
    estop_left: Option<u32>,
    stop_decel: [f32; AXES],
    check: Option<Check>,
    check_periods: u32,
    check_counts: i64,
    check_effort: [f32; AXES],
    /// The arm check under way (state `EncoderCheck` after an arm), and whether arming
    /// runs it.
    arm_check: Option<ArmCheck<R>>,
    arm_check_on: bool,
    /// The arm check's reference step per period (counts) and wrong-way limit (counts).
    arm_check_step: [f32; AXES],
    arm_check_wrong: f32,
    applied: Vec3<R>,
    /// The holding brakes ([`brake`]).
    brakes: [BrakeState; AXES],
    /// Axes the servo drove in the previous period (bit i = axis i): a brake is released
    /// only once its axis' amplifier has held it for a period.
    prev_driven: u8,
    /// The controlled stop under way ends with the brakes engaging: none is released, and
    /// the outputs go off once every brake grips.
    braking: bool,
    /// The controller's evaluation of the current period (filled in place).
    out: ControlOutput<R>,
    snapshot: Snapshot,
}

impl<R: Real> Servo<R> {
    /// Validates `cfg` (every block rejects its bad parameters; nothing is built then).
    /// `raw` are the encoder registers now, which stand for wide counts `start_counts`
    /// (0 on a board at boot; the simulated machine's absolute counts).
    pub fn new(
        cfg: &ServoConfig,
        raw: [u32; AXES],
        start_counts: [i64; AXES],
    ) -> Result<Self, ConfigError> {
        if !(MIN_RATE_HZ..=MAX_RATE_HZ).contains(&cfg.rate_hz) {
            return Err(ConfigError::OutOfRange("rate_hz (100..=50000)"));
        }
        let period_s = 1.0 / f64::from(cfg.rate_hz);
        let mut count_len = [0.0; AXES];
        let mut timing = [EstimatorTiming {
            period_s: period_s as f32,
            count_size: 0.0,
        }; AXES];
        let mut full_scale = Vec3::zero();
        let mut counts_per_mm = [0.0; AXES];
        for i in 0..AXES {
            count_len[i] = cfg.encoders[i].count_len()?;
            counts_per_mm[i] = cfg.encoders[i].counts_per_mm;
            timing[i].count_size = count_len[i] as f32;
            full_scale[i] = R::from_f32(cfg.amplifiers[i].checked_full_scale()?);
        }
        let path = match &cfg.path {
            Some(p) => {
                let duration = match p.duration_s {
                    Some(d) if d >= 0.0 && d.is_finite() => {
                        Some(libm::round(d / period_s).min(f64::from(u32::MAX)) as u32)
                    }
                    Some(_) => return Err(ConfigError::Negative("path.duration_s")),
                    None => None,
                };
                Some((p.path.build()?.cast(), duration))
            }
            None => None,
        };
        cfg.travel.validate()?;
        brake::validate_all(&cfg.brakes)?;
        cfg.homing.validate()?;
        cfg.jog.validate()?;
        for (i, a) in cfg.homing.axes.iter().enumerate() {
            if a.enabled && !cfg.travel.axes[i].contains(a.home_mm()) {
                return Err(ConfigError::OutOfRange(
                    "homing: switch_pos_mm -/+ pulloff_mm must lie inside the travel",
                ));
            }
        }
        let path_start = cfg.path.map_or(PathStart::Absolute, |p| p.start);
        let s = &cfg.safety;
        let positive = |v: f32, n| crate::config::positive(v, n);
        // (`from_fn`, not `[0, 1, 2].map`: its indices are provably in range, so no panic
        // path reaches the control interrupt, which rebuilds the servo on a settings change)
        let counters = core::array::from_fn(|i| {
            let mut c = WideCounter::new(cfg.encoders[i].counter, raw[i], start_counts[i]);
            c.set_inverted(cfg.encoders[i].invert);
            c
        });
        let motor_inverted = commands::axis_mask(cfg.amplifiers.map(|a| a.invert));
        let model_missing = commands::axis_mask(core::array::from_fn(|i| {
            cfg.controller.laws[i].is_model_based() && !cfg.model_known[i]
        }));
        let mut snapshot = Snapshot::boot();
        snapshot.model_missing = model_missing;
        snapshot.homed = commands::axis_mask(cfg.homing.axes.map(|a| !a.enabled));
        Ok(Self {
            period_s,
            clock: Clock::new(cfg.rate_hz),
            dt: R::from_f64(period_s),
            counters,
            count_len: count_len.map(R::from_f64),
            count_len_f32: count_len.map(|l| l as f32),
            counts_per_mm,
            full_scale,
            motor_inverted,
            estimators: EstimatorBank::new(&cfg.estimator, &timing, count_len, start_counts)?,
            controller: Controller3::new(&cfg.controller)?,
            monitor: Monitor::new(
                s,
                counts_per_mm,
                full_scale.to_array().map(Real::to_f32),
                period_s,
            )?,
            index: IndexCheck::new(
                core::array::from_fn(|i| cfg.encoders[i].index_period_counts),
                s.encoder_noise_counts,
                s.index_max_correction_counts,
            )?,
            faults: FaultLog::new(),
            state: ServoState::Disabled,
            stop_then: ServoState::Fault,
            path,
            path_start,
            motion: Motion::Hold(Vec3::zero()),
            travel: cfg.travel,
            homing_cfg: cfg.homing,
            jog_cfg: cfg.jog,
            jog_timeout_periods: monitor::periods(cfg.jog.timeout_s, period_s),
            identify_cfg: cfg.identify,
            identify: None,
            identify_outcome: None,
            homed: 0,
            no_homing: commands::axis_mask(cfg.homing.axes.map(|a| !a.enabled)),
            link_down: false,
            rest_periods: 0,
            settle_periods: monitor::periods(
                positive(s.stop_settle_s, "safety.stop_settle_s")?,
                period_s,
            ),
            estop_controlled: match s.estop_category {
                0 => false,
                1 => true,
                _ => return Err(ConfigError::OutOfRange("safety.estop_category (0 or 1)")),
            },
            estop_stop_periods: monitor::periods(
                positive(s.estop_stop_time_s, "safety.estop_stop_time_s")?,
                period_s,
            ),
            estop_left: None,
            stop_timeout_periods: monitor::periods(
                positive(s.stop_timeout_s, "safety.stop_timeout_s")?,
                period_s,
            ),
            stop_decel: s.axes.map(|a| a.stop_decel_mm_s2),
            check: None,
            check_periods: monitor::periods(
                positive(s.encoder_check_time_s, "safety.encoder_check_time_s")?,
                period_s,
            ),
            check_counts: i64::from(s.encoder_check_counts.max(1)),
            check_effort: s.axes.map(|a| a.stuck_effort_change),
            arm_check: None,
            arm_check_on: s.arm_encoder_check,
            arm_check_step: core::array::from_fn(|i| {
                (f64::from(ARM_CHECK_SPEED_MM_S)
                    * f64::from(cfg.encoders[i].counts_per_mm)
                    * period_s) as f32
            }),
            arm_check_wrong: s.encoder_noise_counts + ARM_CHECK_WRONG_COUNTS,
            applied: Vec3::zero(),
            brakes: cfg.brakes.map(|b| BrakeState::new(&b, period_s)),
            prev_driven: 0,
            braking: false,
            out: ControlOutput::default(),
            snapshot,
        })
    }

    /// Swap in a new configuration at this period boundary (settings changed by the
    /// user): only while the outputs are off, since new gains or a new model could jump
    /// the output. The encoder counters, the homed axes and their origins, the latched
    /// faults and the period count carry over; `cfg` is validated whole first and
    /// nothing changes when it is rejected.
    pub fn reconfigure(&mut self, cfg: &ServoConfig) -> Result<(), ReconfigureError> {
        if self.state.drives() {
            return Err(ReconfigureError::OutputsOn);
        }
        let counts = self.counters.map(|c| c.count());
        let mut next = Self::new(cfg, [0; AXES], counts).map_err(ReconfigureError::Config)?;
        // the counters' register history, so that the next reading extends them as before
        // (in the direction the new settings give)
        let same_direction = core::array::from_fn::<_, AXES, _>(|i| {
            self.counters[i].inverted() == next.counters[i].inverted()
        });
        next.counters = core::array::from_fn(|i| {
            let mut c = self.counters[i];
            c.set_inverted(next.counters[i].inverted());
            c
        });
        if next.counts_per_mm == self.counts_per_mm
            && next.homing_cfg == self.homing_cfg
            && same_direction.iter().all(|s| *s)
            && next.motor_inverted == self.motor_inverted
        {
            // the same encoders and switches: the origins still hold
            next.homed = self.homed;
        }
        if next.counts_per_mm == self.counts_per_mm && same_direction.iter().all(|s| *s) {
            // the same count frame: the index references still hold
            next.index.carry_over(&self.index);
        }
        next.faults = self.faults;
        next.link_down = self.link_down;
        next.state = self.state;
        next.identify_outcome = self.identify_outcome;
        let mut snap = self.snapshot;
        snap.model_missing = next.snapshot.model_missing;
        next.snapshot = snap;
        next.publish_faults();
        *self = next;
        Ok(())
    }

    /// The efforts as the amplifiers take them: an inverted motor's negated (the servo's
    /// own efforts, in the snapshot, stay in machine directions).
    #[inline]
    fn drive(&self, u: Vec3<R>) -> [R; AXES] {
        let mut out = u.to_array();
        for (i, o) in out.iter_mut().enumerate() {
            if self.motor_inverted & (1 << i) != 0 {
                *o = -*o;
            }
        }
        out
    }

    /// The latest snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        &self.snapshot
    }

    pub fn state(&self) -> ServoState {
        self.state
    }

    /// A stop is under way that ends with the outputs off (a disarm whose brakes still
    /// engage, a category-1 e-stop, a fault's controlled stop): they go off within the
    /// stop's bounded time without another command.
    pub fn switching_off(&self) -> bool {
        self.state == ServoState::Stopping && self.stop_then != ServoState::Idle
    }

    /// Latched faults, the first one, and the history.
    pub fn faults(&self) -> &FaultLog {
        &self.faults
    }

    /// The controller (e.g. to read the adaptive estimates).
    pub fn controller(&self) -> &Controller3<R> {
        &self.controller
    }

    /// The planner's reference for the coming period (call once per period, before
    /// [`Self::period`], with the executor's sample). Ignored unless the servo runs the
    /// planner (`Run` after [`Command::Run`]); a non-finite sample is ignored too (the
    /// reference keeps the last good one, and the following-error check acts).
    pub fn set_planner_reference(&mut self, s: &PathSample) {
        if self.motion_held() {
            // the program starts once the brakes are open; until then the start is held
            return;
        }
        if let Motion::Planner(r) = &mut self.motion {
            let ok = s
                .pos_mm
                .to_array()
                .iter()
                .chain(&s.vel_mm_s.to_array())
                .chain(&s.acc_mm_s2.to_array())
                .all(|x| x.is_finite());
            if ok {
                let f =
                    |v: Vec3<f32>| Vec3::new(R::from_f32(v.x), R::from_f32(v.y), R::from_f32(v.z));
                *r = RefSample {
                    pos: f(s.pos_mm),
                    vel: f(s.vel_mm_s),
                    acc: f(s.acc_mm_s2),
                };
            }
        }
    }

    /// Where the planner must start a program: the reference the servo holds (Idle), or
    /// follows; `None` outside Idle and Run.
    pub fn planner_start_mm(&self) -> Option<[f32; AXES]> {
        match (self.state, &self.motion) {
            (ServoState::Idle, Motion::Hold(p)) => Some(p.to_array().map(Real::to_f32)),
            (ServoState::Run, Motion::Planner(r)) => Some(r.pos.to_array().map(Real::to_f32)),
            _ => None,
        }
    }

    /// How the last identification ended (its result, if it finished).
    pub fn identify_outcome(&self) -> Option<&IdentifyOutcome> {
        self.identify_outcome.as_ref()
    }

    /// Per axis: homed (or taking no part in homing), so that its soft limits apply.
    pub fn referenced(&self, axis: usize) -> bool {
        self.referenced_mask() & (1 << axis) != 0
    }

    /// [`Self::referenced`] of every axis as a bit set.
    fn referenced_mask(&self) -> u8 {
        self.homed | self.no_homing
    }

    /// Axes whose outputs the servo drives in the current state (bit i = axis i): every
    /// axis while armed, only the identified one when identification started from
    /// Disabled, only the checked one during an encoder check.
    fn driven_mask(&self) -> u8 {
        match self.state {
            ServoState::Disabled | ServoState::Fault => 0,
            ServoState::Identify => match &self.identify {
                Some(r) if !r.hold_others => 1 << r.axis.min(AXES - 1),
                _ => 0b111,
            },
            ServoState::EncoderCheck if self.arm_check.is_some() => 0b111,
            ServoState::EncoderCheck => self.check.map_or(0, |c| 1 << c.axis.min(AXES - 1)),
            _ => 0b111,
        }
    }

    /// Every brake of the axes in `mask` is open in the coming period (or absent).
    fn brakes_open(&self, mask: u8) -> bool {
        (0..AXES).all(|i| mask & (1 << i) == 0 || self.brakes[i].open())
    }

    /// Every brake grips in the coming period (or is absent).
    fn brakes_gripping(&self) -> bool {
        self.brakes.iter().all(BrakeState::gripping)
    }

    /// The motion just started waits for the brakes to open: the reference is held (the
    /// path's, jog's and homing's clocks stand still, identification and the encoder
    /// check have not begun, planner samples are ignored). The supervisor does not advance
    /// the planner's program while this holds, so the program starts where it was
    /// planned to once the brakes are open.
    pub fn motion_held(&self) -> bool {
        matches!(
            self.state,
            ServoState::Run
                | ServoState::Jog
                | ServoState::Homing
                | ServoState::Identify
                | ServoState::EncoderCheck
        ) && !self.brakes_open(self.driven_mask())
    }

    /// Per axis: the brake is commanded released (coil energised), as written last period.
    pub fn brakes_released(&self) -> [bool; AXES] {
        self.brakes.map(|b| b.released())
    }

    /// The period's brake commands: released only on an axis driven now and in the
    /// previous period, and not while a stop ends with the brakes engaging; written out
    /// with the outputs, once per period.
    fn write_brakes<IO: ServoIo<R>>(&mut self, io: &mut IO) {
        let driven = self.driven_mask();
        if self.state != ServoState::Stopping {
            self.braking = false;
        }
        for (i, b) in self.brakes.iter_mut().enumerate() {
            let bit = 1 << i;
            b.update(!self.braking && driven & self.prev_driven & bit != 0);
        }
        self.prev_driven = driven;
        let released = self.brakes_released();
        io.write_brakes(released);
        self.snapshot.brakes_released = released;
    }

    /// Longest engage time of the brakes fitted, periods (0 without any).
    fn engage_periods(&self) -> u32 {
        self.brakes
            .iter()
            .map(BrakeState::engage_periods)
            .max()
            .unwrap_or(0)
    }

    /// Latch a fault the board found outside the servo step (a failed crystal, a
    /// configuration rejected at boot, a corrupt settings store): always immediate,
    /// outputs off from the next period on (the caller switches them off now).
    pub fn latch_board_fault(&mut self, kind: FaultKind) {
        self.trip(Fault::system(kind), 0.0, None);
        if self.state.drives() {
            self.state = ServoState::Fault;
            self.identify = None;
        }
        self.publish_faults();
    }

    /// `axis`' position is no longer known for sure without a fault to latch (its counter
    /// may have wrapped unseen while the control loop could not run: a flash erase's
    /// stall, firmware `period::StallWatch`): it must be homed again before a program
    /// runs. An axis that takes no part in homing keeps its (power-up) reference.
    #[cold]
    pub fn forget_home(&mut self, axis: Axis) {
        self.homed &= !(1 << axis.index());
        self.publish_faults();
    }

    /// Fault injection for the fault matrix (simulator and QEMU test builds): corrupt the
    /// state of `axis`' law.
    pub fn inject_corrupt_state(&mut self, axis: usize) {
        self.controller.inject_corrupt_state(axis);
    }

    /// Control period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The measured position of `counts` (the estimators' formula: what the controller
    /// sees).
    fn position_of(&self, counts: &[i64; AXES]) -> Vec3<R> {
        let mut p = Vec3::zero();
        for i in 0..AXES {
            p[i] = crate::estimator::counts_to_position(counts[i], self.count_len[i]);
        }
        p
    }

    /// Soft-limit bounds of each axis for a jog: the travel once referenced, else none.
    fn jog_bounds(&self) -> [(f32, f32); AXES] {
        [0, 1, 2].map(|i| {
            if self.referenced(i) {
                (self.travel.axes[i].min_mm, self.travel.axes[i].max_mm)
            } else {
                (f32::NEG_INFINITY, f32::INFINITY)
            }
        })
    }

    /// Begin a controlled stop from `from`, ending in `then`.
    #[cold]
    #[inline(never)]
    fn begin_stop(&mut self, from: &RefSample<R>, then: ServoState) {
        self.motion = Motion::stop_from(from, &self.stop_decel);
        self.rest_periods = 0;
        self.braking = false;
        self.stop_then = then;
        self.state = ServoState::Stopping;
    }

    /// Latch `f`; immediate faults switch the outputs off now, controlled ones start a stop
    /// from the current reference (`None` only for faults of the immediate category).
    #[cold]
    #[inline(never)]
    fn trip(&mut self, f: Fault, value: f32, reference: Option<&RefSample<R>>) {
        self.faults.record(FaultRecord {
            fault: f,
            period: self.snapshot.period,
            value,
        });
        if f.kind.is_encoder() {
            // the position is no longer known for sure: home again
            if let Some(a) = f.axis {
                self.homed &= !(1 << a.index());
            }
        }
        self.publish_faults();
        let moving = matches!(
            self.state,
            ServoState::Idle | ServoState::Run | ServoState::Jog | ServoState::Homing
        );
        let category = if f.kind == FaultKind::EStop && self.estop_controlled {
            StopCategory::Controlled
        } else {
            f.kind.stop()
        };
        if f.kind == FaultKind::EStop && self.estop_controlled && self.estop_left.is_none() {
            self.estop_left = Some(self.estop_stop_periods);
        }
        match (category, self.state) {
            (_, ServoState::Fault) => {}
            (StopCategory::Controlled, _) if moving => {
                let here;
                let from = match reference {
                    Some(r) => r,
                    None => {
                        here = motion::sample(&self.motion, self.path.as_ref(), &self.clock).0;
                        &here
                    }
                };
                self.begin_stop(from, ServoState::Fault);
            }
            (StopCategory::Controlled, ServoState::Stopping) => {
                self.stop_then = ServoState::Fault;
            }
            _ => {
                self.state = ServoState::Fault;
                self.check = None;
                self.identify = None;
            }
        }
    }

    /// Every latched cause gone? Encoder faults are cleared by the encoder check.
    fn causes_gone(&self, inputs: &Inputs) -> bool {
        let still = |k: FaultKind, a: Option<Axis>| self.faults.is_latched(k, a);
        if inputs.estop && still(FaultKind::EStop, None) {
            return false;
        }
        if still(FaultKind::ConfigInvalid, None)
            || still(FaultKind::ClockFault, None)
            || still(FaultKind::BoardConfig, None)
        {
            return false;
        }
        for a in Axis::ALL {
            let i = a.index();
            if inputs.amp_fault[i] && still(FaultKind::AmplifierFault, Some(a)) {
                return false;
            }
            if (inputs.limits[i][0] && still(FaultKind::LimitMin, Some(a)))
                || (inputs.limits[i][1] && still(FaultKind::LimitMax, Some(a)))
            {
                return false;
            }
        }
        // a new link session (Command::LinkUp) removes LinkLost's cause
        !(self.link_down && still(FaultKind::LinkLost, None))
    }

    fn next_check(&self, after: Option<usize>) -> Option<usize> {
        let from = after.map_or(0, |a| a + 1);
        (from..AXES).find(|&i| {
            FaultKind::ALL
                .iter()
                .any(|k| k.is_encoder() && self.faults.is_latched(*k, Axis::from_index(i)))
        })
    }

    /// Hold where the axes are now, with fresh estimator, controller and monitor states.
    fn hold_here(&mut self, counts: &[i64; AXES]) {
        self.estimators.reset(*counts);
        self.controller.reset();
        self.monitor.reset();
        self.motion = Motion::Hold(self.position_of(counts));
    }

    #[cold]
    #[inline(never)]
    fn apply_command(
        &mut self,
        c: &Command,
        inputs: &Inputs,
        counts: &[i64; AXES],
    ) -> Result<(), Refusal> {
        self.snapshot.inputs = *inputs;
        self.snapshot.state = self.state;
        commands::check(&self.snapshot, c)?;
        let here = || motion::sample(&self.motion, self.path.as_ref(), &self.clock).0;
        match (*c, self.state) {
            (Command::Arm, _) => {
                self.state = ServoState::Idle;
                self.hold_here(counts);
                if self.arm_check_on {
                    // the encoders proven before anything may move (a swapped A/B is a
                    // wiring change made with the power off; holding still shows nothing)
                    let brake = |i: usize| self.brakes[i].present();
                    self.arm_check = Some(ArmCheck {
                        phase: core::array::from_fn(|i| {
                            if brake(i) {
                                ArmPhase::Settle
                            } else {
                                ArmPhase::Out
                            }
                        }),
                        k: [0; AXES],
                        base: *counts,
                        hold: self.position_of(counts),
                        offset: [0.0; AXES],
                    });
                    self.state = ServoState::EncoderCheck;
                }
            }
            (Command::Disarm, ServoState::Idle) => {
                if self.brakes_gripping() {
                    self.state = ServoState::Disabled;
                } else {
                    // a released brake grips first: hold where the axes are (already at
                    // rest, so no settling), engage, then outputs off
                    let r = here();
                    self.begin_stop(&r, ServoState::Disabled);
                    self.rest_periods = self.settle_periods;
                    self.braking = true;
                }
            }
            (Command::Disarm, ServoState::Identify) => {
                self.end_identify(true);
                self.state = ServoState::Disabled;
            }
            (Command::Disarm, ServoState::Run | ServoState::Jog | ServoState::Homing) => {
                let r = here();
                self.begin_stop(&r, ServoState::Disabled);
            }
            (Command::Disarm, ServoState::EncoderCheck) if self.arm_check.is_some() => {
                // an arm check given up: nothing was proven, nothing is latched
                let r = here();
                self.arm_check = None;
                if self.brakes_gripping() {
                    self.state = ServoState::Disabled;
                } else {
                    self.begin_stop(&r, ServoState::Disabled);
                    self.rest_periods = self.settle_periods;
                    self.braking = true;
                }
            }
            (Command::Disarm, ServoState::EncoderCheck) => {
                self.check = None;
                self.state = ServoState::Fault;
            }
            (Command::Disarm, _) => {}
            (Command::Reset, _) => {
                if !self.causes_gone(inputs) {
                    return Err(Refusal::FaultLatched);
                }
                match self.next_check(None) {
                    Some(axis) => {
                        self.check = Some(Check {
                            axis,
                            positive: true,
                            k: 0,
                            n0: counts[axis],
                        });
                        self.state = ServoState::EncoderCheck;
                    }
                    None => {
                        self.faults.clear();
                        self.publish_faults();
                        self.state = ServoState::Disabled;
                    }
                }
            }
            (Command::StartPath, _) => {
                let Some((traj, _)) = &self.path else {
                    return Err(Refusal::NoPath);
                };
                let origin = match self.path_start {
                    PathStart::Absolute => None,
                    PathStart::FromCurrentPosition => {
                        Some(self.position_of(counts) - traj.sample(R::ZERO).pos)
                    }
                };
                self.motion = Motion::Path { k: 0, origin };
                self.state = ServoState::Run;
            }
            (Command::Home, _) => {
                let pos = self.position_of(counts).to_array().map(Real::to_f32);
                let Some(run) = Homing::start(&self.homing_cfg, &pos) else {
                    return Err(Refusal::NoHoming);
                };
                // homing again: every homing axis must find its switch anew
                self.homed = 0;
                self.snapshot.homed = self.no_homing;
                self.motion = Motion::Homing {
                    hold: here().pos,
                    run,
                };
                self.state = ServoState::Homing;
            }
            (Command::Jog { axis, vel_mm_s }, st) => {
                if st == ServoState::Idle {
                    let pos = here().pos.to_array().map(Real::to_f32);
                    self.motion = Motion::Jog(Jog::at(pos));
                    self.state = ServoState::Jog;
                }
                if let Motion::Jog(j) = &mut self.motion {
                    j.command(
                        axis.index(),
                        vel_mm_s,
                        &self.jog_cfg,
                        self.jog_timeout_periods,
                    );
                }
            }
            (Command::Identify { axis, window_mm }, st) => {
                // (`min`: lets the compiler drop the bounds checks below)
                let i = axis.index().min(AXES - 1);
                let pos = self.position_of(counts)[i].to_f32();
                let travel = if self.referenced(i) {
                    self.travel.axes[i]
                } else {
                    travel::AxisTravel::UNLIMITED
                };
                let run = IdentifyRun::start(
                    &self.identify_cfg,
                    axis,
                    pos,
                    &travel,
                    window_mm,
                    self.full_scale[i].to_f32(),
                    self.period_s as f32,
                    st == ServoState::Idle,
                )?;
                if st == ServoState::Disabled {
                    self.hold_here(counts);
                }
                self.identify = Some(run);
                self.identify_outcome = None;
                self.state = ServoState::Identify;
            }
            (Command::Run, _) => {
                // until the first sample arrives the reference holds where the servo was
                let mut r = here();
                r.vel = Vec3::zero();
                r.acc = Vec3::zero();
                self.motion = Motion::Planner(r);
                self.state = ServoState::Run;
            }
            (Command::Stop, ServoState::Identify) => {
                let hold = self.identify.as_ref().is_some_and(|r| r.hold_others);
                self.end_identify(true);
                if hold {
                    self.hold_here(counts);
                    self.state = ServoState::Idle;
                } else {
                    self.state = ServoState::Disabled;
                }
            }
            (Command::Stop, ServoState::Idle) => {}
            (Command::LinkLost, _) => {
                self.link_down = true;
                // (identifying: the stop is immediate, as for any fault there)
                let r = here();
                self.trip(Fault::system(FaultKind::LinkLost), 0.0, Some(&r));
            }
            (Command::LinkUp, _) => self.link_down = false,
            (Command::Stop, _) => {
                let r = here();
                self.begin_stop(&r, ServoState::Idle);
            }
        }
        Ok(())
    }

    /// End the identification (aborted by the user when `aborted`), keeping its outcome.
    #[cold]
    #[inline(never)]
    fn end_identify(&mut self, aborted: bool) {
        if let Some(mut run) = self.identify.take() {
            if aborted && !run.finished() {
                // a fault sample makes the identifier stop at once with zero effort
                let _ = run.step(&AxisSample {
                    fault: true,
                    ..AxisSample::default()
                });
            }
            self.identify_outcome = Some(run.outcome());
        }
    }

    /// Advance the jog or homing ramps for this period (before the reference is sampled);
    /// re-bases an axis when homing latched its switch.
    #[cold]
    #[inline(never)]
    fn step_manual(
        &mut self,
        inputs: &Inputs,
        index: [Option<u32>; AXES],
        counts: &mut [i64; AXES],
    ) {
        let dt = self.period_s as f32;
        let bounds = self.jog_bounds();
        match &mut self.motion {
            Motion::Jog(j) => j.advance(&self.jog_cfg, &bounds, dt),
            Motion::Homing { hold, run } => {
                let axis = run.axis().min(AXES - 1);
                let side = self.homing_cfg.axes[axis].direction.switch();
                let inp = HomingInputs {
                    switch: inputs.limits[axis][side],
                    counts: counts[axis],
                    index_counts: index[axis].map(|raw| self.counters[axis].extend(raw)),
                };
                match run.step(&self.homing_cfg, &inp, self.count_len_f32[axis], dt) {
                    HomingEvent::Moving => {
                        if run.axis() != axis {
                            // the next axis: hold the finished one at its home point
                            hold[axis] = R::from_f32(run.ramp.pos_mm);
                            let next = run.axis().min(AXES - 1);
                            run.next_axis_at(hold[next].to_f32());
                        }
                    }
                    HomingEvent::Rebase {
                        axis,
                        latched_counts,
                        at_mm,
                    } => {
                        let axis = axis.min(AXES - 1);
                        let target = libm::roundf(at_mm * self.counts_per_mm[axis]) as i64;
                        let shift = latched_counts - target;
                        self.counters[axis].rebase(shift);
                        self.index.rebased(axis, shift);
                        counts[axis] = self.counters[axis].count();
                        let delta_mm = -(shift as f32) * self.count_len_f32[axis];
                        run.rebased(run.ramp.pos_mm + delta_mm);
                        hold[axis] = R::from_f32(run.ramp.pos_mm);
                        let mut d = Vec3::zero();
                        d[axis] = R::from_f32(delta_mm);
                        self.controller.shift_reference(d);
                        self.estimators.reset(*counts);
                        self.homed |= 1 << axis;
                    }
                    HomingEvent::Done => {
                        let i = run.axis().min(AXES - 1);
                        self.homed |= 1 << i;
                        hold[i] = R::from_f32(run.ramp.pos_mm);
                        let h = *hold;
                        self.motion = Motion::Hold(h);
                        self.state = ServoState::Idle;
                    }
                    HomingEvent::Failed { axis, .. } => {
                        let axis = Axis::ALL[axis.min(AXES - 1)];
                        let r = motion::sample(&self.motion, None, &self.clock).0;
                        self.trip(Fault::on(FaultKind::HomingFailed, axis), 0.0, Some(&r));
                    }
                }
            }
            _ => {}
        }
        self.publish_faults();
    }

    /// The index pulses captured this period: a count off from its index's place is
    /// corrected (the counter re-based, this period's count with it) or, beyond what
    /// glitches explain, the `EncoderIndex` fault (returned, with the error in counts).
    fn check_index(
        &mut self,
        index: &[Option<u32>; AXES],
        counts: &mut [i64; AXES],
    ) -> Option<(Fault, f32)> {
        let mut fault = None;
        for axis in 0..AXES {
            let Some(raw) = index[axis] else { continue };
            let captured = self.counters[axis].extend(raw);
            match self.index.capture(axis, captured) {
                IndexVerdict::Agrees => {}
                IndexVerdict::Correct(shift) => {
                    self.counters[axis].rebase(shift);
                    counts[axis] = self.counters[axis].count();
                }
                IndexVerdict::Fault(off) => {
                    // the count frame is lost (home again): the next pass is a new reference
                    self.index.forget(axis);
                    let f = Fault::on(FaultKind::EncoderIndex, Axis::ALL[axis]);
                    fault = fault.or(Some((f, off as f32)));
                }
            }
        }
        self.snapshot.index_corrected_counts = self.index.corrected_counts();
        fault
    }

    /// One control period. See the module documentation for the sequence. Commands that
    /// are not valid now are refused: the refusal is in the snapshot
    /// ([`Snapshot::refused`]).
    pub fn period<IO: ServoIo<R>>(&mut self, io: &mut IO, commands: &[Command]) -> &Snapshot {
        self.snapshot.period = self.snapshot.period.wrapping_add(1);

        // 1. Safety first: hard inputs and commands decide before anything is computed.
        let inputs = io.read_inputs();
        if inputs.estop {
            self.trip(Fault::system(FaultKind::EStop), 0.0, None);
        }
        if let Some(left) = self.estop_left {
            // a category-1 e-stop: the stop gets a bounded time, then the outputs go off
            self.estop_left = match (self.state, left) {
                (ServoState::Stopping, 0) => {
                    self.state = ServoState::Fault;
                    None
                }
                (ServoState::Stopping, n) => {
                    // the brakes engage so that they grip by the deadline
                    if n <= self.engage_periods() {
                        self.braking = true;
                    }
                    Some(n - 1)
                }
                _ => None,
            };
        }
        for a in Axis::ALL {
            if inputs.amp_fault[a.index()] {
                self.trip(Fault::on(FaultKind::AmplifierFault, a), 0.0, None);
            }
        }
        if self.state.drives() {
            let tripped = if self.state == ServoState::Homing {
                self.homing_limit(&inputs)
            } else {
                inputs.first_limit()
            };
            if let Some((axis, high)) = tripped {
                let kind = if high {
                    FaultKind::LimitMax
                } else {
                    FaultKind::LimitMin
                };
                self.trip(Fault::on(kind, axis), 0.0, None);
            }
        }
        if !self.state.drives() {
            io.disable_outputs();
            // (recorded at the end of the period; the coil is off from now on)
            io.write_brakes([false; AXES]);
        }

        if self.state != ServoState::EncoderCheck {
            // a fault or a stop ended the arm check
            self.arm_check = None;
        }

        // 2. Wide and machine counts.
        let raw = io.read_counters();
        let mut counts = [0i64; AXES];
        // the steps of the wide counts (exact i32 counter deltas) for the encoder checks
        let mut steps = [0i32; AXES];
        for i in 0..AXES {
            counts[i] = self.counters[i].update(raw[i]);
            steps[i] = self.counters[i].step();
        }
        if !commands.is_empty() {
            self.snapshot.refused = None;
            for c in commands {
                if let Err(why) = self.apply_command(c, &inputs, &counts) {
                    self.snapshot.refused = Some((*c, why));
                }
            }
        }
        if !self.state.drives() {
            io.disable_outputs();
            io.write_brakes([false; AXES]);
        }
        // motion that starts waits for the brakes to open
        let held = self.motion_held();

        // the index pulses: glitches corrected (or faulted) before anything uses the counts
        // (a fault waits for the encoder checks: a jump that lands on an index pass is
        // reported as the jump it is)
        let mut index_fault = None;
        let index = if self.index.any() {
            let index = io.read_index();
            self.index.moved(&steps);
            index_fault = self.check_index(&index, &mut counts);
            index
        } else {
            [None; AXES]
        };

        // 3. Reference.
        if matches!(self.state, ServoState::Jog | ServoState::Homing) && !held {
            let index = if matches!(self.motion, Motion::Homing { .. }) {
                if self.index.any() {
                    index
                } else {
                    io.read_index()
                }
            } else {
                [None; AXES]
            };
            self.step_manual(&inputs, index, &mut counts);
        }
        let arm_checking = self.state == ServoState::EncoderCheck && self.arm_check.is_some();
        if arm_checking && !held {
            self.step_arm_check(&counts);
        }
        let (mut reference, motion_t, at_rest) =
            motion::sample(&self.motion, self.path.as_ref(), &self.clock);
        if held {
            // held at its start: a path that starts moving (the helix) is held at rest
            reference.vel = Vec3::zero();
            reference.acc = Vec3::zero();
        }

        // 4. Positions and velocities.
        let meas: Measured<R> = self
            .estimators
            .update(counts, reference.acc, io.true_velocity());
        let vel = meas.vel.to_array().map(Real::to_f32);

        // 5. Control.
        let mut applied = Vec3::zero();
        let mut evaluated = false;
        let law = arm_checking
            || matches!(
                self.state,
                ServoState::Idle
                    | ServoState::Run
                    | ServoState::Jog
                    | ServoState::Homing
                    | ServoState::Identify
                    | ServoState::Stopping
            );
        match self.state {
            _ if law => {
                let prev = self.applied.to_array().map(Real::to_f32);
                if let Some((f, v)) = self.monitor.check_encoders(&steps, &vel, &prev) {
                    self.trip(f, v, Some(&reference));
                }
                let v_ref = reference.vel.to_array().map(Real::to_f32);
                let a_ref = reference.acc.to_array().map(Real::to_f32);
                if let Some((f, v)) = self.monitor.check_counts_due(&steps, &v_ref, &a_ref, &prev) {
                    self.trip(f, v, Some(&reference));
                }
                if let Some((f, v)) = index_fault.take() {
                    self.trip(f, v, Some(&reference));
                }
                if let Some((f, v)) = self
                    .monitor
                    .check_overrun(inputs.overrun, self.snapshot.period)
                {
                    self.trip(f, v, Some(&reference));
                }
                let mut reference = reference;
                let identifying = self.state == ServoState::Identify;
                if identifying && !held {
                    self.identify_reference(&mut reference, &meas);
                }
                self.controller
                    .evaluate_into(&reference, &meas, &mut self.out);
                let bad = (0..AXES)
                    .find(|&i| self.out.nonfinite[i])
                    .or_else(|| self.controller.unhealthy_axis());
                if let Some(i) = bad {
                    self.trip(
                        Fault::on(FaultKind::NonFinite, Axis::ALL[i]),
                        0.0,
                        Some(&reference),
                    );
                }
                let mut u = self.out.u;
                for i in 0..AXES {
                    // finite_or_zero, then clamp_sym (in-range case first: issue 14)
                    u[i] = u[i].clamp_finite(self.full_scale[i]);
                }
                if identifying && self.state.drives() {
                    if !held {
                        u = self.identify_effort(u, &meas, &vel);
                    } else if self.driven_mask() != 0b111 {
                        // started from Disabled: nothing is driven before the run begins
                        u = Vec3::zero();
                    }
                }
                if self.referenced_mask() != 0 && self.state.drives() && !identifying {
                    self.check_soft_limits(&reference);
                }
                if self.state.drives() && !identifying {
                    let tracking = self.out.tracking.to_array().map(Real::to_f32);
                    let v_ref = reference.vel.to_array().map(Real::to_f32);
                    let stopping = self.state == ServoState::Stopping;
                    let scale = if stopping { STOPPING_FERROR_SCALE } else { 1.0 };
                    if let Some((f, v)) =
                        self.monitor.check_tracking(&tracking, &v_ref, &vel, scale)
                    {
                        if stopping && f.kind == FaultKind::FollowingError {
                            // the stop itself cannot be followed: off at once
                            self.faults.record(FaultRecord {
                                fault: f,
                                period: self.snapshot.period,
                                value: v,
                            });
                            self.publish_faults();
                            self.state = ServoState::Fault;
                        } else {
                            self.trip(f, v, Some(&reference));
                        }
                    }
                }
                if at_rest && matches!(self.state, ServoState::Stopping | ServoState::Jog) {
                    self.finish_motion(&reference, &vel);
                }
                if self.state.drives() {
                    io.write_outputs(&self.drive(u));
                    applied = u;
                } else {
                    io.disable_outputs();
                }
                self.controller
                    .commit(&self.out, &reference, &meas, applied, self.dt);
                if !held {
                    self.motion.advance();
                }
                evaluated = true;
            }
            ServoState::EncoderCheck => {
                if let Some((f, v)) = index_fault.take() {
                    self.trip(f, v, None);
                }
                applied = if held {
                    Vec3::zero()
                } else {
                    self.encoder_check(&counts)
                };
                if self.state.drives() {
                    io.write_outputs(&self.drive(applied));
                } else {
                    applied = Vec3::zero();
                    io.disable_outputs();
                }
            }
            ServoState::Disabled | ServoState::Fault => {
                if let Some((f, v)) = index_fault.take() {
                    self.trip(f, v, None);
                }
            }
            _ => {}
        }
        self.applied = applied;
        self.estimators.applied(applied);
        self.write_brakes(io);

        // 6. Telemetry (plain copies).
        if matches!(self.state, ServoState::Homing | ServoState::Identify) {
            self.snapshot.progress = self.progress();
        }
        let s = &mut self.snapshot;
        s.motion_t_s = motion_t.to_f32();
        s.state = self.state;
        s.inputs = inputs;
        s.pos = meas.pos.to_array().map(Real::to_f32);
        s.vel = vel;
        s.counts = counts;
        s.effort = applied.to_array().map(Real::to_f32);
        s.outputs_on = self.state.drives();
        if evaluated {
            let o = &self.out;
            s.reference = reference.pos.to_array().map(Real::to_f32);
            s.tracking = o.tracking.to_array().map(Real::to_f32);
            s.contour = o.contour.to_array().map(Real::to_f32);
            s.s = o.s.to_array().map(Real::to_f32);
        } else {
            s.tracking = [0.0; AXES];
            s.contour = [0.0; AXES];
            s.s = [0.0; AXES];
        }
        &self.snapshot
    }

    /// The identified axis' effort this period (the others: their laws' when holding,
    /// else zero); ends the identification when it is finished.
    #[cold]
    #[inline(never)]
    fn identify_effort(
        &mut self,
        mut u: Vec3<R>,
        meas: &Measured<R>,
        vel: &[f32; AXES],
    ) -> Vec3<R> {
        let faulted = self.faults.any();
        let Some(run) = &mut self.identify else {
            self.state = ServoState::Fault;
            return Vec3::zero();
        };
        let i = run.axis.min(AXES - 1);
        let sample = AxisSample {
            pos_mm: meas.pos[i].to_f32(),
            vel_mm_s: vel[i],
            effort_applied_mnm: self.applied[i].to_f32(),
            fault: faulted,
        };
        let out = run.step(&sample);
        if !run.hold_others {
            u = Vec3::zero();
        }
        u[i] = R::from_f32(out.effort_mnm)
            .finite_or_zero()
            .clamp_sym(self.full_scale[i]);
        if run.finished() {
            let hold = run.hold_others;
            self.end_identify(false);
            self.state = if hold {
                ServoState::Idle
            } else {
                ServoState::Disabled
            };
            // holding: from here on the identified axis holds where it came to rest
            self.motion = Motion::Hold(meas.pos);
            self.controller.reset();
            if !hold {
                u = Vec3::zero();
            }
        }
        u
    }

    /// The first active limit switch while homing: the homed axis' switch on its homing
    /// side is the sensor, not a fault.
    #[cold]
    #[inline(never)]
    fn homing_limit(&self, inputs: &Inputs) -> Option<(Axis, bool)> {
        let Motion::Homing { run, .. } = &self.motion else {
            return inputs.first_limit();
        };
        Axis::ALL
            .into_iter()
            .zip(inputs.limits)
            .find_map(|(axis, sides)| {
                (0..2).zip(sides).find_map(|(side, on)| {
                    let sensor = run.masks_switch(&self.homing_cfg, axis.index(), side);
                    (on && !sensor).then_some((axis, side == 1))
                })
            })
    }

    /// Publish the latched faults and the homed axes in the snapshot (they change only
    /// here and there; copying them every period would cost the control interrupt).
    fn publish_faults(&mut self) {
        self.snapshot.fault = self.faults.first();
        self.snapshot.fault_bits = self.faults.bits();
        self.snapshot.homed = self.referenced_mask();
    }

    /// The identified axis has no reference: its law sees no error.
    #[cold]
    #[inline(never)]
    fn identify_reference(&self, reference: &mut RefSample<R>, meas: &Measured<R>) {
        if let Some(run) = &self.identify {
            let i = run.axis.min(AXES - 1);
            reference.pos[i] = meas.pos[i];
            reference.vel[i] = meas.vel[i];
            reference.acc[i] = R::ZERO;
        }
    }

    /// Progress of homing or identification, 0..=1.
    #[cold]
    #[inline(never)]
    fn progress(&self) -> f32 {
        match (&self.identify, &self.motion) {
            (Some(run), _) => run.last().progress,
            (None, Motion::Homing { run, .. }) => {
                let total = (!self.no_homing & 0b111).count_ones();
                run.axes_done().count_ones() as f32 / total.max(1) as f32
            }
            _ => 0.0,
        }
    }

    /// The soft-limit check of this period's reference: the referenced axes, but not the
    /// one being homed (it works beyond its travel, on its switch).
    #[cold]
    #[inline(never)]
    fn check_soft_limits(&mut self, reference: &RefSample<R>) {
        let homing_bit = match &self.motion {
            Motion::Homing { run, .. } => 1u8 << run.axis(),
            _ => 0,
        };
        let checked = self.referenced_mask() & !homing_bit;
        if let Some((i, p)) = self.travel.violation_of(&reference.pos, checked) {
            self.trip(
                Fault::on(FaultKind::SoftLimit, Axis::ALL[i]),
                p,
                Some(reference),
            );
        }
    }

    /// End a stop once at rest and settled; end a jog once at rest with nothing
    /// commanded.
    #[cold]
    #[inline(never)]
    fn finish_motion(&mut self, reference: &RefSample<R>, vel: &[f32; AXES]) {
        match self.state {
            ServoState::Stopping => {
                if self.stop_then != ServoState::Idle {
                    // the reference is at rest: the brakes engage while the axes settle
                    self.braking = true;
                }
                self.rest_periods = self.rest_periods.saturating_add(1);
                let settled = self.rest_periods >= self.settle_periods
                    && vel
                        .iter()
                        .zip(0..AXES)
                        .all(|(v, i)| v.abs() <= 0.02 * self.monitor.vel_max(i));
                if settled || self.rest_periods >= self.stop_timeout_periods {
                    if self.stop_then == ServoState::Idle {
                        self.state = ServoState::Idle;
                        self.motion = Motion::Hold(reference.pos);
                    } else if self.brakes_gripping() {
                        // the outputs go off only once every brake holds its axis
                        self.state = self.stop_then;
                    }
                }
            }
            ServoState::Jog => {
                self.state = ServoState::Idle;
                self.motion = Motion::Hold(reference.pos);
            }
            _ => {}
        }
    }

    /// One period of the encoder check: the effort on the checked axis (others zero).
    #[cold]
    #[inline(never)]
    /// One period of the arm check: each axis' reference one step further along its
    /// phase's way and its reading judged; armed once every axis is done.
    fn step_arm_check(&mut self, counts: &[i64; AXES]) {
        let Some(mut c) = self.arm_check else {
            return;
        };
        let full = self.check_counts as f32;
        let half = 0.5 * full;
        let mut hold = c.hold;
        let mut done = true;
        for (i, axis) in Axis::ALL.into_iter().enumerate() {
            let moved = counts[i].saturating_sub(c.base[i]) as f32;
            let phase = c.phase[i];
            let k = c.k[i].saturating_add(1);
            // (a wrong-way reading, and a reading that never follows: the fault and the
            // counts it moved)
            let (next, fault) = match phase {
                // a healthy axis settles within a couple of counts of where it armed once
                // its brake lets go; a swapped A/B turns the hold into positive feedback
                // and runs away from it (Z under gravity)
                ArmPhase::Settle
                    if moved.abs() > ARM_CHECK_SETTLE_COUNTS + self.arm_check_wrong =>
                {
                    (phase, Some(FaultKind::EncoderJump))
                }
                ArmPhase::Settle if k >= self.settle_periods => {
                    // from here the reading must follow the reference
                    c.base[i] = counts[i];
                    (ArmPhase::Out, None)
                }
                ArmPhase::Out if moved <= -self.arm_check_wrong => {
                    // counts the wrong way while the law pushes the axis out: swapped A/B
                    (phase, Some(FaultKind::EncoderJump))
                }
                ArmPhase::Out if moved >= half => (ArmPhase::Back, None),
                // (from the positive end, where the law may overshoot by part of the step:
                // twice the way out is no overshoot but the wrong way)
                ArmPhase::Back if moved >= 2.0 * full + self.arm_check_wrong => {
                    (phase, Some(FaultKind::EncoderJump))
                }
                ArmPhase::Back if moved <= -half => (ArmPhase::Home, None),
                // back at the hold point, settled for the stop's settle time
                ArmPhase::Home if c.offset[i] == 0.0 && k >= self.settle_periods => {
                    (ArmPhase::Done, None)
                }
                ArmPhase::Out | ArmPhase::Back
                    if k >= self.check_periods.saturating_add(self.settle_periods) =>
                {
                    // the reference moved and the reading did not follow
                    (phase, Some(FaultKind::EncoderStuck))
                }
                _ => (phase, None),
            };
            if let Some(kind) = fault {
                self.arm_check = None;
                self.trip(Fault::on(kind, axis), moved, None);
                return;
            }
            c.k[i] = if next == phase { k } else { 0 };
            c.phase[i] = next;
            let target = match phase {
                ArmPhase::Out => full,
                ArmPhase::Back => -full,
                ArmPhase::Settle | ArmPhase::Home | ArmPhase::Done => 0.0,
            };
            let (o, step) = (c.offset[i], self.arm_check_step[i]);
            c.offset[i] = if o < target {
                (o + step).min(target)
            } else {
                (o - step).max(target)
            };
            hold[i] = c.hold[i] + R::from_f32(c.offset[i] * self.count_len_f32[i]);
            done &= next == ArmPhase::Done;
        }
        if done {
            // every axis followed both ways: armed, holding where it armed
            self.arm_check = None;
            self.motion = Motion::Hold(c.hold);
            self.state = ServoState::Idle;
            return;
        }
        self.motion = Motion::Hold(hold);
        self.arm_check = Some(c);
    }

    fn encoder_check(&mut self, counts: &[i64; AXES]) -> Vec3<R> {
        let mut u = Vec3::zero();
        let Some(mut c) = self.check else {
            self.state = ServoState::Fault;
            return u;
        };
        // (`get`: the axis always comes from `next_check`, but an index the optimiser
        // cannot bound would leave a panic path in the control interrupt)
        let Some(&now) = counts.get(c.axis) else {
            self.check = None;
            self.state = ServoState::Fault;
            return u;
        };
        let moved = now.saturating_sub(c.n0);
        let sign: i64 = if c.positive { 1 } else { -1 };
        if moved * sign >= self.check_counts {
            // followed: the other direction, or the next axis, or done
            if c.positive {
                c = Check {
                    positive: false,
                    k: 0,
                    n0: counts[c.axis],
                    ..c
                };
            } else {
                match self.next_check(Some(c.axis)) {
                    Some(axis) => {
                        c = Check {
                            axis,
                            positive: true,
                            k: 0,
                            n0: counts[axis],
                        }
                    }
                    None => {
                        self.check = None;
                        self.faults.clear();
                        self.publish_faults();
                        self.state = ServoState::Disabled;
                        return u;
                    }
                }
            }
        } else if moved * sign <= -self.check_counts || c.k >= self.check_periods {
            // moved the wrong way, or not at all: the encoder is still faulty
            self.check = None;
            self.state = ServoState::Fault;
            return u;
        }
        // ramp from 0 to the check effort over the check: breakaway is reached late, so a
        // still-stuck encoder lets the axis move little
        let ramp = c.k.min(self.check_periods) as f32 / self.check_periods.max(1) as f32;
        let effort = ramp * self.check_effort[c.axis] * sign as f32;
        u[c.axis] = R::from_f32(effort).clamp_sym(self.full_scale[c.axis]);
        c.k += 1;
        self.check = Some(c);
        u
    }
}
