//! [`Servo`]: the servo step's state and its one control period ([`Servo::period`], the
//! sequence of the module documentation of [`super`], as named steps), and what it tells
//! its callers. Its construction and reconfiguration from a
//! [`ServoConfig`](super::ServoConfig) are in `build`, the mode transitions in
//! [`super::modes`], the encoder checks' periods in `encoder_check`.

use super::brake::BrakeState;
use super::commands::Command;
use super::faults::{Fault, FaultKind, FaultLog, FaultRecord};
use super::identify::{IdentifyOutcome, IdentifyRun};
use super::index_check::{IndexCheck, IndexVerdict};
use super::io::{Inputs, ServoIo};
use super::monitor::Monitor;
use super::snapshot::Snapshot;
use super::state::ServoState;
use super::travel::TravelConfig;
use crate::axes::{Axis, AXES};
use crate::controller::{ControlOutput, Controller3, Measured};
use crate::estimator::{EstimatorBank, WideCounter};
use crate::motion::homing::{HomingConfig, HomingEvent, HomingInputs};
use crate::motion::jog::JogConfig;
use crate::motion::path::PathStart;
use crate::motion::planner::PathSample;
use crate::motion::reference::{Clock, ReferenceMode};
use crate::motion::trajectory::{RefSample, Trajectory};
use crate::sysid::{AxisSample, IdentifyConfig};
use crate::{Real, Vec3};

/// During a controlled stop the following-error limit is this many times the normal one;
/// beyond it the stop becomes immediate.
pub const STOPPING_FERROR_SCALE: f32 = 2.0;

/// Progress of an encoder check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Check {
    pub(super) axis: usize,
    pub(super) positive: bool,
    pub(super) k: u32,
    pub(super) n0: i64,
}

/// The closed-loop encoder check at arming ([`SafetyConfig::arm_encoder_check`]): every
/// axis' hold reference moves `encoder_check_counts` out and back each way at
/// [`ARM_CHECK_SPEED_MM_S`], all at once, under the laws; each reading must follow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ArmCheck<R> {
    /// Each axis' phase, and the periods it has been in it.
    pub(super) phase: [ArmPhase; AXES],
    pub(super) k: [u32; AXES],
    /// Every axis' counts where the check began (its hold point).
    pub(super) base: [i64; AXES],
    /// The hold point of every axis, mm.
    pub(super) hold: Vec3<R>,
    /// The reference's offset from the hold point, counts.
    pub(super) offset: [f32; AXES],
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum ArmPhase {
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
pub(super) const ARM_CHECK_WRONG_COUNTS: f32 = 2.0;

/// Counts an axis may stray from where it armed while the arm check lets it settle,
/// beyond the wrong-way margin: a braked axis' load sags the law's hold when the brake
/// lets go (6 counts, 3.8 µm, on the gantry's Z, whose law starts from zero effort); 10
/// counts is a runaway, not a sag.
pub(super) const ARM_CHECK_SETTLE_COUNTS: f32 = 8.0;

/// What the period sensed, for its control and telemetry steps: the inputs, the counts
/// and their steps, the estimates, and whether the motion waits for the brakes or its
/// reference is at rest. (References to the period's own values: a copy of them into one
/// value cost the period ~50 instructions of loads and stores.)
pub(super) struct Sensed<'a, R> {
    pub(super) inputs: &'a Inputs,
    pub(super) counts: &'a [i64; AXES],
    pub(super) steps: &'a [i32; AXES],
    pub(super) meas: &'a Measured<R>,
    pub(super) vel: &'a [f32; AXES],
    pub(super) held: bool,
    pub(super) at_rest: bool,
}

/// The servo step's state, owned by the control interrupt.
pub struct Servo<R> {
    pub(super) period_s: f64,
    pub(super) clock: Clock<R>,
    pub(super) dt: R,
    /// Wide counts in machine coordinates (homing moves their origin).
    pub(super) counters: [WideCounter; AXES],
    pub(super) count_len: [R; AXES],
    pub(super) count_len_f32: [f32; AXES],
    pub(super) counts_per_mm: [f32; AXES],
    pub(super) full_scale: Vec3<R>,
    /// Axes whose motor turns backwards for a positive command (bit i: axis i,
    /// `AmplifierConfig::invert`): their effort is negated as it is written.
    pub(super) motor_inverted: u8,
    pub(super) estimators: EstimatorBank<R>,
    pub(super) controller: Controller3<R>,
    pub(super) monitor: Monitor,
    /// Counts lost or gained between index pulses: corrected or faulted.
    pub(super) index: IndexCheck,
    pub(super) faults: FaultLog,
    pub(super) state: ServoState,
    /// The state a controlled stop ends in (Fault, Disabled after a disarm, Idle after a
    /// stop command).
    pub(super) stop_then: ServoState,
    /// The configured path and the period after which its end point is held.
    pub(super) path: Option<(Trajectory<R>, Option<u32>)>,
    pub(super) path_start: PathStart,
    pub(super) motion: ReferenceMode<R>,
    pub(super) travel: TravelConfig,
    pub(super) homing_cfg: HomingConfig,
    pub(super) jog_cfg: JogConfig,
    pub(super) jog_timeout_periods: u32,
    pub(super) identify_cfg: IdentifyConfig,
    pub(super) identify: Option<IdentifyRun>,
    pub(super) identify_outcome: Option<IdentifyOutcome>,
    /// Axes homed since power-up (bit i = axis i); lost with an encoder fault.
    pub(super) homed: u8,
    /// Axes that take no part in homing: referenced where they stand.
    pub(super) no_homing: u8,
    /// The host link is lost (a `LinkLost` fault's cause).
    pub(super) link_down: bool,
    /// Periods the stop reference has been at rest.
    pub(super) rest_periods: u32,
    pub(super) settle_periods: u32,
    pub(super) stop_timeout_periods: u32,
    /// The e-stop is a controlled stop (category 1).
    pub(super) estop_controlled: bool,
    pub(super) estop_stop_periods: u32,
    /// Periods a category-1 e-stop's stop may still take before the outputs go off.
    pub(super) estop_left: Option<u32>,
    pub(super) stop_decel: [f32; AXES],
    pub(super) check: Option<Check>,
    pub(super) check_periods: u32,
    pub(super) check_counts: i64,
    pub(super) check_effort: [f32; AXES],
    /// The arm check under way (state `EncoderCheck` after an arm), and whether arming
    /// runs it.
    pub(super) arm_check: Option<ArmCheck<R>>,
    pub(super) arm_check_on: bool,
    /// The arm check's reference step per period (counts) and wrong-way limit (counts).
    pub(super) arm_check_step: [f32; AXES],
    pub(super) arm_check_wrong: f32,
    pub(super) applied: Vec3<R>,
    /// The holding brakes ([`brake`]).
    pub(super) brakes: [BrakeState; AXES],
    /// Axes the servo drove in the previous period (bit i = axis i): a brake is released
    /// only once its axis' amplifier has held it for a period.
    pub(super) prev_driven: u8,
    /// The controlled stop under way ends with the brakes engaging: none is released, and
    /// the outputs go off once every brake grips.
    pub(super) braking: bool,
    /// The controller's evaluation of the current period (filled in place).
    pub(super) out: ControlOutput<R>,
    pub(super) snapshot: Snapshot,
}

impl<R: Real> Servo<R> {
    /// The efforts as the amplifiers take them: an inverted motor's negated (the servo's
    /// own efforts, in the snapshot, stay in machine directions).
    #[inline]
    pub(super) fn drive(&self, u: Vec3<R>) -> [R; AXES] {
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
        if let ReferenceMode::Planner(r) = &mut self.motion {
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
            (ServoState::Idle, ReferenceMode::Hold(p)) => Some(p.to_array().map(Real::to_f32)),
            (ServoState::Run, ReferenceMode::Planner(r)) => {
                Some(r.pos.to_array().map(Real::to_f32))
            }
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
    pub(super) fn referenced_mask(&self) -> u8 {
        self.homed | self.no_homing
    }

    /// Axes whose outputs the servo drives in the current state (bit i = axis i): every
    /// axis while armed, only the identified one when identification started from
    /// Disabled, only the checked one during an encoder check.
    pub(super) fn driven_mask(&self) -> u8 {
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
    pub(super) fn brakes_open(&self, mask: u8) -> bool {
        (0..AXES).all(|i| mask & (1 << i) == 0 || self.brakes[i].open())
    }

    /// Every brake grips in the coming period (or is absent).
    pub(super) fn brakes_gripping(&self) -> bool {
        self.brakes.iter().all(BrakeState::gripping)
    }

    /// The motion just started waits for the brakes to open: the reference is held (the
    /// path's, jog's and homing's clocks stand still, identification and the encoder
    /// check have not begun, planner samples are ignored). The machine's supervisor does
    /// not advance the planner's program while this holds, so the program starts where it
    /// was planned to once the brakes are open.
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
    pub(super) fn write_brakes<IO: ServoIo<R>>(&mut self, io: &mut IO) {
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
    pub(super) fn engage_periods(&self) -> u32 {
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
    pub(super) fn position_of(&self, counts: &[i64; AXES]) -> Vec3<R> {
        let mut p = Vec3::zero();
        for i in 0..AXES {
            p[i] = crate::estimator::counts_to_position(counts[i], self.count_len[i]);
        }
        p
    }

    /// Soft-limit bounds of each axis for a jog: the travel once referenced, else none.
    pub(super) fn jog_bounds(&self) -> [(f32, f32); AXES] {
        [0, 1, 2].map(|i| {
            if self.referenced(i) {
                (self.travel.axes[i].min_mm, self.travel.axes[i].max_mm)
            } else {
                (f32::NEG_INFINITY, f32::INFINITY)
            }
        })
    }

    /// Advance the jog or homing ramps for this period (before the reference is sampled);
    /// re-bases an axis when homing latched its switch.
    #[cold]
    #[inline(never)]
    pub(super) fn step_manual(
        &mut self,
        inputs: &Inputs,
        index: [Option<u32>; AXES],
        counts: &mut [i64; AXES],
    ) {
        let dt = self.period_s as f32;
        let bounds = self.jog_bounds();
        match &mut self.motion {
            ReferenceMode::Jog(j) => j.advance(&self.jog_cfg, &bounds, dt),
            ReferenceMode::Homing { hold, run } => {
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
                        self.motion = ReferenceMode::Hold(h);
                        self.state = ServoState::Idle;
                    }
                    HomingEvent::Failed { axis, .. } => {
                        let axis = Axis::ALL[axis.min(AXES - 1)];
                        let r = crate::motion::reference::sample(&self.motion, None, &self.clock).0;
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
    pub(super) fn check_index(
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

    /// One control period. See the module documentation of [`super`] for the sequence.
    /// Commands that are not valid now are refused: the refusal is in the snapshot
    /// ([`Snapshot::refused`]).
    pub fn period<IO: ServoIo<R>>(&mut self, io: &mut IO, commands: &[Command]) -> &Snapshot {
        self.snapshot.period = self.snapshot.period.wrapping_add(1);

        // 1. Safety first: hard inputs and commands decide before anything is computed.
        let inputs = io.read_inputs();
        self.latch_hard_inputs(&inputs);
        self.outputs_off_unless_driving(io);
        if self.state != ServoState::EncoderCheck {
            // a fault or a stop ended the arm check
            self.arm_check = None;
        }

        // 2. Wide and machine counts.
        let (mut counts, steps) = self.read_counts(io);
        self.apply_commands(commands, &inputs, &counts);
        self.outputs_off_unless_driving(io);
        // motion that starts waits for the brakes to open
        let held = self.motion_held();
        let (index, index_fault) = self.read_index(io, &steps, &mut counts);

        // 3. Reference.
        let arm_checking = self.step_reference(io, &inputs, index, held, &mut counts);
        let (reference, motion_t, at_rest) = self.sample_reference(held);

        // 4. Positions and velocities.
        let meas: Measured<R> = self
            .estimators
            .update(counts, reference.acc, io.true_velocity());
        let vel = meas.vel.to_array().map(Real::to_f32);

        // 5. Control.
        let sensed = Sensed {
            inputs: &inputs,
            counts: &counts,
            steps: &steps,
            meas: &meas,
            vel: &vel,
            held,
            at_rest,
        };
        let (applied, evaluated) = self.control(io, &sensed, &reference, index_fault, arm_checking);
        self.applied = applied;
        self.estimators.applied(applied);
        self.write_brakes(io);

        // 6. Telemetry (plain copies).
        self.publish(&sensed, &reference, applied, motion_t, evaluated);
        &self.snapshot
    }

    /// Step 1: the e-stop and the amplifier faults latch in any state, the limit switches
    /// while the outputs are on (homing's own switch excepted); a category-1 e-stop's
    /// stop counts down its bounded time.
    #[inline(always)]
    fn latch_hard_inputs(&mut self, inputs: &Inputs) {
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
                self.homing_limit(inputs)
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
    }

    /// Outputs and brake coils off now when the state may not drive them (recorded at
    /// the end of the period; the coil is off from now on).
    #[inline(always)]
    fn outputs_off_unless_driving<IO: ServoIo<R>>(&mut self, io: &mut IO) {
        if !self.state.drives() {
            io.disable_outputs();
            io.write_brakes([false; AXES]);
        }
    }

    /// Step 2: the counters extended to wide counts, and their steps (exact `i32`
    /// counter deltas) for the encoder checks.
    #[inline(always)]
    fn read_counts<IO: ServoIo<R>>(&mut self, io: &mut IO) -> ([i64; AXES], [i32; AXES]) {
        let raw = io.read_counters();
        let mut counts = [0i64; AXES];
        let mut steps = [0i32; AXES];
        for i in 0..AXES {
            counts[i] = self.counters[i].update(raw[i]);
            steps[i] = self.counters[i].step();
        }
        (counts, steps)
    }

    /// The period's commands, in order; the last refusal (if any) in the snapshot.
    #[inline(always)]
    fn apply_commands(&mut self, commands: &[Command], inputs: &Inputs, counts: &[i64; AXES]) {
        if !commands.is_empty() {
            self.snapshot.refused = None;
            for c in commands {
                if let Err(why) = self.apply_command(c, inputs, counts) {
                    self.snapshot.refused = Some((*c, why));
                }
            }
        }
    }

    /// The index pulses: glitches corrected (or faulted) before anything uses the counts
    /// (a fault waits for the encoder checks: a jump that lands on an index pass is
    /// reported as the jump it is). Returns the pulses read and the fault.
    #[inline(always)]
    fn read_index<IO: ServoIo<R>>(
        &mut self,
        io: &mut IO,
        steps: &[i32; AXES],
        counts: &mut [i64; AXES],
    ) -> ([Option<u32>; AXES], Option<(Fault, f32)>) {
        let mut index_fault = None;
        let index = if self.index.any() {
            let index = io.read_index();
            self.index.moved(steps);
            index_fault = self.check_index(&index, counts);
            index
        } else {
            [None; AXES]
        };
        (index, index_fault)
    }

    /// Step 3: jog's and homing's ramps and the arm check's reference advance (unless
    /// the motion waits for the brakes); returns whether the arm check runs.
    #[inline(always)]
    fn step_reference<IO: ServoIo<R>>(
        &mut self,
        io: &mut IO,
        inputs: &Inputs,
        index: [Option<u32>; AXES],
        held: bool,
        counts: &mut [i64; AXES],
    ) -> bool {
        if matches!(self.state, ServoState::Jog | ServoState::Homing) && !held {
            let index = if matches!(self.motion, ReferenceMode::Homing { .. }) {
                if self.index.any() {
                    index
                } else {
                    io.read_index()
                }
            } else {
                [None; AXES]
            };
            self.step_manual(inputs, index, counts);
        }
        let arm_checking = self.state == ServoState::EncoderCheck && self.arm_check.is_some();
        if arm_checking && !held {
            self.step_arm_check(counts);
        }
        arm_checking
    }

    /// The reference of this period, the time since its motion began and whether it is
    /// at rest.
    #[inline(always)]
    fn sample_reference(&self, held: bool) -> (RefSample<R>, R, bool) {
        let (mut reference, motion_t, at_rest) =
            crate::motion::reference::sample(&self.motion, self.path.as_ref(), &self.clock);
        if held {
            // held at its start: a path that starts moving (the helix) is held at rest
            reference.vel = Vec3::zero();
            reference.acc = Vec3::zero();
        }
        (reference, motion_t, at_rest)
    }

    /// Step 5: the period's effort by state, written out (or the outputs switched off);
    /// returns it and whether the laws were evaluated.
    #[inline(always)]
    fn control<IO: ServoIo<R>>(
        &mut self,
        io: &mut IO,
        s: &Sensed<'_, R>,
        reference: &RefSample<R>,
        index_fault: Option<(Fault, f32)>,
        arm_checking: bool,
    ) -> (Vec3<R>, bool) {
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
            _ if law => (self.closed_loop(io, s, reference, index_fault), true),
            ServoState::EncoderCheck => (self.encoder_check_period(io, s, index_fault), false),
            ServoState::Disabled | ServoState::Fault => {
                if let Some((f, v)) = index_fault {
                    self.trip(f, v, None);
                }
                (Vec3::zero(), false)
            }
            _ => (Vec3::zero(), false),
        }
    }

    /// Under the laws: the encoder checks, the controller, its saturation, the limits of
    /// the motion, the output written (or switched off) and every state committed with
    /// the effort applied. Returns that effort.
    #[inline(always)]
    fn closed_loop<IO: ServoIo<R>>(
        &mut self,
        io: &mut IO,
        s: &Sensed<'_, R>,
        reference: &RefSample<R>,
        index_fault: Option<(Fault, f32)>,
    ) -> Vec3<R> {
        let mut applied = Vec3::zero();
        self.check_sensors(s, reference, index_fault);
        let mut reference = *reference;
        let identifying = self.state == ServoState::Identify;
        let u = self.law_effort(s, &mut reference, identifying);
        self.check_motion_limits(s, &reference, identifying);
        if s.at_rest && matches!(self.state, ServoState::Stopping | ServoState::Jog) {
            self.finish_motion(&reference, s.vel);
        }
        if self.state.drives() {
            io.write_outputs(&self.drive(u));
            applied = u;
        } else {
            io.disable_outputs();
        }
        self.controller
            .commit(&self.out, &reference, s.meas, applied, self.dt);
        if !s.held {
            self.motion.advance();
        }
        applied
    }

    /// The encoder checks (jumps, counts due, index), and overruns of the period.
    #[inline(always)]
    fn check_sensors(
        &mut self,
        s: &Sensed<'_, R>,
        reference: &RefSample<R>,
        index_fault: Option<(Fault, f32)>,
    ) {
        let prev = self.applied.to_array().map(Real::to_f32);
        if let Some((f, v)) = self.monitor.check_encoders(s.steps, s.vel, &prev) {
            self.trip(f, v, Some(reference));
        }
        let v_ref = reference.vel.to_array().map(Real::to_f32);
        let a_ref = reference.acc.to_array().map(Real::to_f32);
        if let Some((f, v)) = self
            .monitor
            .check_counts_due(s.steps, &v_ref, &a_ref, &prev)
        {
            self.trip(f, v, Some(reference));
        }
        if let Some((f, v)) = index_fault {
            self.trip(f, v, Some(reference));
        }
        if let Some((f, v)) = self
            .monitor
            .check_overrun(s.inputs.overrun, self.snapshot.period)
        {
            self.trip(f, v, Some(reference));
        }
    }

    /// The controller's evaluation, checked finite and saturated to the amplifiers'
    /// range; the identified axis' effort in its place while identifying.
    #[inline(always)]
    fn law_effort(
        &mut self,
        s: &Sensed<'_, R>,
        reference: &mut RefSample<R>,
        identifying: bool,
    ) -> Vec3<R> {
        if identifying && !s.held {
            self.identify_reference(reference, s.meas);
        }
        self.controller
            .evaluate_into(reference, s.meas, &mut self.out);
        let bad = (0..AXES)
            .find(|&i| self.out.nonfinite[i])
            .or_else(|| self.controller.unhealthy_axis());
        if let Some(i) = bad {
            self.trip(
                Fault::on(FaultKind::NonFinite, Axis::ALL[i]),
                0.0,
                Some(reference),
            );
        }
        let mut u = self.out.u;
        for i in 0..AXES {
            // finite_or_zero, then clamp_sym (the in-range case first: it is the common
            // one, and the cheapest)
            u[i] = u[i].clamp_finite(self.full_scale[i]);
        }
        if identifying && self.state.drives() {
            if !s.held {
                u = self.identify_effort(u, s.meas, s.vel);
            } else if self.driven_mask() != 0b111 {
                // started from Disabled: nothing is driven before the run begins
                u = Vec3::zero();
            }
        }
        u
    }

    /// The soft limits of the referenced axes, the following error and the speed (not
    /// while identifying: the identified axis has no reference).
    #[inline(always)]
    fn check_motion_limits(
        &mut self,
        s: &Sensed<'_, R>,
        reference: &RefSample<R>,
        identifying: bool,
    ) {
        if self.referenced_mask() != 0 && self.state.drives() && !identifying {
            self.check_soft_limits(reference);
        }
        if self.state.drives() && !identifying {
            let tracking = self.out.tracking.to_array().map(Real::to_f32);
            let v_ref = reference.vel.to_array().map(Real::to_f32);
            let stopping = self.state == ServoState::Stopping;
            let scale = if stopping { STOPPING_FERROR_SCALE } else { 1.0 };
            if let Some((f, v)) = self.monitor.check_tracking(&tracking, &v_ref, s.vel, scale) {
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
                    self.trip(f, v, Some(reference));
                }
            }
        }
    }

    /// Step 6: the telemetry snapshot (plain copies).
    #[inline(always)]
    fn publish(
        &mut self,
        sensed: &Sensed<'_, R>,
        reference: &RefSample<R>,
        applied: Vec3<R>,
        motion_t: R,
        evaluated: bool,
    ) {
        if matches!(self.state, ServoState::Homing | ServoState::Identify) {
            self.snapshot.progress = self.progress();
        }
        let s = &mut self.snapshot;
        s.motion_t_s = motion_t.to_f32();
        s.state = self.state;
        s.inputs = *sensed.inputs;
        s.pos = sensed.meas.pos.to_array().map(Real::to_f32);
        s.vel = *sensed.vel;
        s.counts = *sensed.counts;
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
    }

    /// The identified axis' effort this period (the others: their laws' when holding,
    /// else zero); ends the identification when it is finished.
    #[cold]
    #[inline(never)]
    pub(super) fn identify_effort(
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
            self.motion = ReferenceMode::Hold(meas.pos);
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
    pub(super) fn homing_limit(&self, inputs: &Inputs) -> Option<(Axis, bool)> {
        let ReferenceMode::Homing { run, .. } = &self.motion else {
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
    pub(super) fn publish_faults(&mut self) {
        self.snapshot.fault = self.faults.first();
        self.snapshot.fault_bits = self.faults.bits();
        self.snapshot.homed = self.referenced_mask();
    }

    /// The identified axis has no reference: its law sees no error.
    #[cold]
    #[inline(never)]
    pub(super) fn identify_reference(&self, reference: &mut RefSample<R>, meas: &Measured<R>) {
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
    pub(super) fn progress(&self) -> f32 {
        match (&self.identify, &self.motion) {
            (Some(run), _) => run.last().progress,
            (None, ReferenceMode::Homing { run, .. }) => {
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
    pub(super) fn check_soft_limits(&mut self, reference: &RefSample<R>) {
        let homing_bit = match &self.motion {
            ReferenceMode::Homing { run, .. } => 1u8 << run.axis(),
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
}
