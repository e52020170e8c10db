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
//! 6. publish the telemetry [`Snapshot`] (plain copies).
//!
//! States ([`ServoState`]): `Disabled` (boot; outputs off) → arm → `Idle` (holding the
//! position it armed at: arming never starts motion) → start path → `Run`. A fault of the
//! immediate category goes straight to `Fault` (outputs off in that period); a controlled
//! one goes through `Stopping`. `Fault` → reset → `Disabled` only once every cause is
//! gone; an encoder fault first runs the encoder check (`EncoderCheck`): the axis must
//! follow a small effort in both directions, or the reset is refused.
//!
//! Nothing here allocates, blocks, formats or panics; every number that reaches an output
//! is finite and within the amplifier's range.

pub mod faults;
pub mod io;
pub mod monitor;
pub mod motion;
pub mod snapshot;

use crate::axes::{Axis, AXES};
use crate::config::ConfigError;
use crate::controller::{ControlOutput, Controller3, ControllerConfig, Measured};
use crate::estimator::{EstimatorBank, EstimatorBankConfig, EstimatorTiming, WideCounter};
use crate::motion::path::{PathConfig, PathStart};
use crate::motion::trajectory::{RefSample, Trajectory};
use crate::{Real, Vec3};
use faults::{Fault, FaultKind, FaultLog, FaultRecord, StopCategory};
use io::{AmplifierConfig, EncoderConfig, Inputs, ServoIo};
use monitor::{Monitor, SafetyConfig};
use motion::{Clock, Motion};
use snapshot::Snapshot;

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
    pub controller: ControllerConfig,
    pub estimator: EstimatorBankConfig,
    /// Limits and fault thresholds.
    pub safety: SafetyConfig,
    /// The path [`Command::StartPath`] starts, if any.
    #[cfg_attr(feature = "serde", serde(default))]
    pub path: Option<PathPlan>,
}

/// Operator commands, applied at the start of a period in the order given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Disabled -> Idle (inputs clear, no fault latched), holding the current position.
    Arm,
    /// Idle -> Disabled; Run -> controlled stop -> Disabled.
    Disarm,
    /// Fault -> Disabled once every cause is gone (an encoder fault runs the encoder
    /// check first).
    Reset,
    /// Follow the configured path (from Idle or Run).
    StartPath,
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
    /// Outputs on, following the path.
    Run,
    /// Outputs on, decelerating to rest (after a controlled-stop fault, or a disarm while
    /// moving); then outputs off.
    Stopping,
    /// Reset of an encoder fault: a small effort on the faulted axes must move them.
    EncoderCheck,
    /// Outputs off, fault latched.
    Fault,
}

impl ServoState {
    /// The outputs are driven in this state.
    pub const fn drives(self) -> bool {
        matches!(
            self,
            Self::Idle | Self::Run | Self::Stopping | Self::EncoderCheck
        )
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

/// The servo step's state, owned by the control interrupt.
pub struct Servo<R> {
    period_s: f64,
    clock: Clock<R>,
    dt: R,
    counters: [WideCounter; AXES],
    count_len: [R; AXES],
    full_scale: Vec3<R>,
    estimators: EstimatorBank<R>,
    controller: Controller3<R>,
    monitor: Monitor,
    faults: FaultLog,
    state: ServoState,
    /// The state a controlled stop ends in (Fault, or Disabled after a disarm).
    stop_then: ServoState,
    /// The configured path and the period after which its end point is held.
    path: Option<(Trajectory<R>, Option<u32>)>,
    path_start: PathStart,
    motion: Motion<R>,
    /// Periods the stop reference has been at rest.
    rest_periods: u32,
    settle_periods: u32,
    stop_timeout_periods: u32,
    stop_decel: [f32; AXES],
    check: Option<Check>,
    check_periods: u32,
    check_counts: i64,
    check_effort: [f32; AXES],
    applied: Vec3<R>,
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
        let path_start = cfg.path.map_or(PathStart::Absolute, |p| p.start);
        let s = &cfg.safety;
        let positive = |v: f32, n| crate::config::positive(v, n);
        let counters =
            [0, 1, 2].map(|i| WideCounter::new(cfg.encoders[i].counter, raw[i], start_counts[i]));
        Ok(Self {
            period_s,
            clock: Clock::new(cfg.rate_hz),
            dt: R::from_f64(period_s),
            counters,
            count_len: count_len.map(R::from_f64),
            full_scale,
            estimators: EstimatorBank::new(&cfg.estimator, &timing, count_len, start_counts)?,
            controller: Controller3::new(&cfg.controller)?,
            monitor: Monitor::new(
                s,
                counts_per_mm,
                full_scale.to_array().map(Real::to_f32),
                period_s,
            )?,
            faults: FaultLog::new(),
            state: ServoState::Disabled,
            stop_then: ServoState::Fault,
            path,
            path_start,
            motion: Motion::Hold(Vec3::zero()),
            rest_periods: 0,
            settle_periods: monitor::periods(
                positive(s.stop_settle_s, "safety.stop_settle_s")?,
                period_s,
            ),
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
            applied: Vec3::zero(),
            out: ControlOutput::default(),
            snapshot: Snapshot::boot(),
        })
    }

    /// The latest snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        &self.snapshot
    }

    pub fn state(&self) -> ServoState {
        self.state
    }

    /// Latched faults, the first one, and the history.
    pub fn faults(&self) -> &FaultLog {
        &self.faults
    }

    /// The controller (e.g. to read the adaptive estimates).
    pub fn controller(&self) -> &Controller3<R> {
        &self.controller
    }

    /// Latch a fault the board found outside the servo step (a failed crystal, a
    /// configuration rejected at boot): always immediate, outputs off from the next period
    /// on (the caller switches them off now).
    pub fn latch_board_fault(&mut self, kind: FaultKind) {
        self.trip(Fault::system(kind), 0.0, None);
        if self.state.drives() {
            self.state = ServoState::Fault;
        }
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

    /// Latch `f`; immediate faults switch the outputs off now, controlled ones start a stop
    /// from the current reference (`None` only for faults of the immediate category).
    fn trip(&mut self, f: Fault, value: f32, reference: Option<&RefSample<R>>) {
        self.faults.record(FaultRecord {
            fault: f,
            period: self.snapshot.period,
            value,
        });
        match (f.kind.stop(), self.state) {
            (_, ServoState::Fault) => {}
            (StopCategory::Controlled, ServoState::Idle | ServoState::Run) => {
                let here;
                let from = match reference {
                    Some(r) => r,
                    None => {
                        here = motion::sample(&self.motion, self.path.as_ref(), &self.clock).0;
                        &here
                    }
                };
                self.motion = Motion::stop_from(from, &self.stop_decel);
                self.rest_periods = 0;
                self.stop_then = ServoState::Fault;
                self.state = ServoState::Stopping;
            }
            (StopCategory::Controlled, ServoState::Stopping) => {
                self.stop_then = ServoState::Fault;
            }
            _ => {
                self.state = ServoState::Fault;
                self.check = None;
            }
        }
    }

    /// Every latched cause gone? Encoder faults are cleared by the encoder check.
    fn causes_gone(&self, inputs: &Inputs) -> bool {
        let still = |k: FaultKind, a: Option<Axis>| self.faults.is_latched(k, a);
        if inputs.estop && still(FaultKind::EStop, None) {
            return false;
        }
        if still(FaultKind::ConfigInvalid, None) || still(FaultKind::ClockFault, None) {
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
        // the link's watchdog clears LinkLost when a new session starts (not here)
        !still(FaultKind::LinkLost, None)
    }

    fn next_check(&self, after: Option<usize>) -> Option<usize> {
        let from = after.map_or(0, |a| a + 1);
        (from..AXES).find(|&i| {
            FaultKind::ALL
                .iter()
                .any(|k| k.is_encoder() && self.faults.is_latched(*k, Axis::from_index(i)))
        })
    }

    fn apply_command(&mut self, c: Command, inputs: &Inputs, counts: &[i64; AXES]) {
        match (c, self.state) {
            (Command::Arm, ServoState::Disabled)
                if !self.faults.any() && !inputs.estop && inputs.first_limit().is_none() =>
            {
                self.state = ServoState::Idle;
                self.estimators.reset(*counts);
                self.controller.reset();
                self.monitor.reset();
                self.motion = Motion::Hold(self.position_of(counts));
            }
            (Command::Disarm, ServoState::Idle) => self.state = ServoState::Disabled,
            (Command::Disarm, ServoState::Run) => {
                let (r, _, _) = motion::sample(&self.motion, self.path.as_ref(), &self.clock);
                self.motion = Motion::stop_from(&r, &self.stop_decel);
                self.rest_periods = 0;
                self.stop_then = ServoState::Disabled;
                self.state = ServoState::Stopping;
            }
            (Command::Disarm, ServoState::EncoderCheck) => {
                self.check = None;
                self.state = ServoState::Fault;
            }
            (Command::Reset, ServoState::Fault) if self.causes_gone(inputs) => {
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
                        self.state = ServoState::Disabled;
                    }
                }
            }
            (Command::StartPath, ServoState::Idle | ServoState::Run) => {
                if let Some((traj, _)) = &self.path {
                    let origin = match self.path_start {
                        PathStart::Absolute => None,
                        PathStart::FromCurrentPosition => {
                            Some(self.position_of(counts) - traj.sample(R::ZERO).pos)
                        }
                    };
                    self.motion = Motion::Path { k: 0, origin };
                    self.state = ServoState::Run;
                }
            }
            _ => {}
        }
    }

    /// One control period. See the module documentation for the sequence.
    pub fn period<IO: ServoIo<R>>(&mut self, io: &mut IO, commands: &[Command]) -> &Snapshot {
        self.snapshot.period = self.snapshot.period.wrapping_add(1);

        // 1. Safety first: hard inputs and commands decide before anything is computed.
        let inputs = io.read_inputs();
        if inputs.estop {
            self.trip(Fault::system(FaultKind::EStop), 0.0, None);
        }
        for a in Axis::ALL {
            if inputs.amp_fault[a.index()] {
                self.trip(Fault::on(FaultKind::AmplifierFault, a), 0.0, None);
            }
        }
        if self.state.drives() {
            if let Some((i, high)) = inputs.first_limit() {
                let kind = if high {
                    FaultKind::LimitMax
                } else {
                    FaultKind::LimitMin
                };
                self.trip(Fault::on(kind, Axis::ALL[i]), 0.0, None);
            }
        }
        if !self.state.drives() {
            io.disable_outputs();
        }

        // 2. Wide counts.
        let raw = io.read_counters();
        let mut counts = [0i64; AXES];
        // the steps of the wide counts (exact i32 counter deltas) for the encoder checks
        let mut steps = [0i32; AXES];
        for i in 0..AXES {
            counts[i] = self.counters[i].update(raw[i]);
            steps[i] = self.counters[i].step();
        }
        for &c in commands {
            self.apply_command(c, &inputs, &counts);
        }
        if !self.state.drives() {
            io.disable_outputs();
        }

        // 3. Reference.
        let (reference, motion_t, at_rest) =
            motion::sample(&self.motion, self.path.as_ref(), &self.clock);

        // 4. Positions and velocities.
        let meas: Measured<R> = self
            .estimators
            .update(counts, reference.acc, io.true_velocity());
        let vel = meas.vel.to_array().map(Real::to_f32);

        // 5. Control.
        let mut applied = Vec3::zero();
        let mut evaluated = false;
        match self.state {
            ServoState::Idle | ServoState::Run | ServoState::Stopping => {
                let prev = self.applied.to_array().map(Real::to_f32);
                if let Some((f, v)) = self.monitor.check_encoders(&steps, &vel, &prev) {
                    self.trip(f, v, Some(&reference));
                }
                if let Some((f, v)) = self
                    .monitor
                    .check_overrun(inputs.overrun, self.snapshot.period)
                {
                    self.trip(f, v, Some(&reference));
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
                if self.state.drives() {
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
                            self.state = ServoState::Fault;
                        } else {
                            self.trip(f, v, Some(&reference));
                        }
                    }
                }
                if self.state == ServoState::Stopping && at_rest {
                    self.rest_periods = self.rest_periods.saturating_add(1);
                    let settled = self.rest_periods >= self.settle_periods
                        && vel
                            .iter()
                            .zip(0..AXES)
                            .all(|(v, i)| v.abs() <= 0.02 * self.monitor.vel_max(i));
                    if settled || self.rest_periods >= self.stop_timeout_periods {
                        self.state = self.stop_then;
                    }
                }
                if self.state.drives() {
                    io.write_outputs(&u.to_array());
                    applied = u;
                } else {
                    io.disable_outputs();
                }
                self.controller
                    .commit(&self.out, &reference, &meas, applied, self.dt);
                self.motion.advance();
                evaluated = true;
            }
            ServoState::EncoderCheck => {
                applied = self.encoder_check(&counts);
                if self.state.drives() {
                    io.write_outputs(&applied.to_array());
                } else {
                    applied = Vec3::zero();
                    io.disable_outputs();
                }
            }
            ServoState::Disabled | ServoState::Fault => {}
        }
        self.applied = applied;
        self.estimators.applied(applied);

        // 6. Telemetry (plain copies).
        let s = &mut self.snapshot;
        s.motion_t_s = motion_t.to_f32();
        s.state = self.state;
        s.fault = self.faults.first();
        s.fault_bits = self.faults.bits();
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

    /// One period of the encoder check: the effort on the checked axis (others zero).
    fn encoder_check(&mut self, counts: &[i64; AXES]) -> Vec3<R> {
        let mut u = Vec3::zero();
        let Some(mut c) = self.check else {
            self.state = ServoState::Fault;
            return u;
        };
        let moved = counts[c.axis].saturating_sub(c.n0);
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
