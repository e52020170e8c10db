//! [`Servo`]: the servo step's state and its one control period ([`Servo::period`], the
//! sequence of the module documentation of [`super`], as named steps), and what it tells
//! its callers. Its construction and reconfiguration from a
//! [`ServoConfig`](super::ServoConfig) are in `build`, the mode transitions in
//! [`super::modes`]; the state of one concern is grouped with its parameters: the
//! controlled stop (`stop`), homing and jogging (`manual`, their periods in
//! `manual_period`), identification ([`super::identify`], its periods in
//! `identify_period`) and the encoder checks (`checks`, their periods in
//! `encoder_check`).

use super::brake::Brakes;
use super::checks::EncoderChecks;
use super::commands::Command;
use super::faults::{Fault, FaultKind, FaultLog, FaultRecord};
use super::identify::{Identification, IdentifyOutcome, ResponseOutcome};
use super::index_check::{IndexCheck, IndexVerdict};
use super::io::{Inputs, ServoIo};
use super::manual::ManualState;
use super::monitor::Monitor;
use super::snapshot::Snapshot;
use super::state::ServoState;
use super::stop::StopState;
use super::travel::TravelConfig;
use crate::axes::{Axis, AXES};
use crate::controller::{ControlOutput, Controller3, Measured};
use crate::estimator::{EstimatorBank, WideCounter};
use crate::filter::OutputFilters;
use crate::motion::compensation::{CompState, CompTables};
use crate::motion::feedforward::FeedForward;
use crate::motion::path::PathStart;
use crate::motion::planner::PathSample;
use crate::motion::reference::{Clock, ReferenceMode};
use crate::motion::trajectory::{RefSample, Trajectory};
use crate::{Real, Vec3};

/// During a controlled stop the following-error limit is this many times the normal one;
/// beyond it the stop becomes immediate.
pub const STOPPING_FERROR_SCALE: f32 = 2.0;

pub use super::checks::ARM_CHECK_SPEED_MM_S;

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
    /// The configured path and the period after which its end point is held.
    pub(super) path: Option<(Trajectory<R>, Option<u32>)>,
    pub(super) path_start: PathStart,
    pub(super) motion: ReferenceMode<R>,
    /// The state of the backlash and lead-screw compensation added to the reference the
    /// laws track ([`crate::motion::compensation`]; the tables are the caller's,
    /// [`Self::period_with`]).
    pub(super) comp: CompState,
    /// Coulomb pre-compensation and the frame's compliance and deflection
    /// ([`crate::motion::feedforward`]), and this period's Coulomb effort.
    pub(super) ff: FeedForward<R>,
    pub(super) ff_effort: Vec3<R>,
    /// The notch and low-pass filters of the control output ([`crate::filter`]): they
    /// run while the outputs are driven and rest at 0 otherwise, so that arming never
    /// replays the effort of before a stop.
    pub(super) filters: OutputFilters<R>,
    /// Some axis has a filter (one test in the period when none has).
    pub(super) filtered: bool,
    pub(super) travel: TravelConfig,
    /// Homing and jogging: their configuration and the axes referenced.
    pub(super) manual: ManualState,
    /// Identification: its configuration, the run under way and how the last one ended.
    pub(super) ident: Identification,
    /// The host link is lost (a `LinkLost` fault's cause).
    pub(super) link_down: bool,
    /// The controlled stop: its parameters and the one under way.
    pub(super) stopping: StopState,
    /// The encoder checks (after a reset, at arming): their parameters and progress.
    pub(super) checks: EncoderChecks<R>,
    pub(super) applied: Vec3<R>,
    /// The holding brakes ([`brake`]).
    pub(super) brakes: Brakes,
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
        self.state == ServoState::Stopping && self.stopping.then != ServoState::Idle
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
        self.ident.model_outcome()
    }

    /// How the last frequency-response measurement ended.
    pub fn response_outcome(&self) -> Option<ResponseOutcome> {
        self.ident.response_outcome()
    }

    /// The frequency-response measurement under way: its latest point and the point's
    /// index in the grid (a caller collects the points as they come: the servo keeps
    /// only the latest).
    pub fn response_point(&self) -> Option<(u8, crate::sysid::frequency::ResponsePoint)> {
        self.ident.run.as_ref().and_then(|r| r.response_point())
    }

    /// Identifications started since boot (wrapping): a new value is a new run (a
    /// refused command starts none).
    pub fn identify_runs(&self) -> u8 {
        self.ident.runs
    }

    /// Per axis: homed (or taking no part in homing), so that its soft limits apply.
    pub fn referenced(&self, axis: usize) -> bool {
        self.referenced_mask() & (1 << axis) != 0
    }

    /// [`Self::referenced`] of every axis as a bit set.
    pub(super) fn referenced_mask(&self) -> u8 {
        self.manual.referenced_mask()
    }

    /// Axes whose outputs the servo drives in the current state (bit i = axis i): every
    /// axis while armed, only the identified one when identification started from
    /// Disabled, only the checked one during an encoder check.
    pub(super) fn driven_mask(&self) -> u8 {
        match self.state {
            ServoState::Disabled | ServoState::Fault => 0,
            ServoState::Identify => match &self.ident.run {
                Some(r) if !r.hold_others => 1 << r.axis.min(AXES - 1),
                _ => 0b111,
            },
            ServoState::EncoderCheck if self.checks.arm.is_some() => 0b111,
            ServoState::EncoderCheck => self.checks.check.map_or(0, |c| 1 << c.axis.min(AXES - 1)),
            _ => 0b111,
        }
    }

    /// Every brake of the axes in `mask` is open in the coming period (or absent).
    pub(super) fn brakes_open(&self, mask: u8) -> bool {
        self.brakes.open(mask)
    }

    /// Every brake grips in the coming period (or is absent).
    pub(super) fn brakes_gripping(&self) -> bool {
        self.brakes.gripping()
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
        self.brakes.released()
    }

    /// The period's brake commands: released only on an axis driven now and in the
    /// previous period, and not while a stop ends with the brakes engaging; written out
    /// with the outputs, once per period.
    pub(super) fn write_brakes<IO: ServoIo<R>>(&mut self, io: &mut IO) {
        let driven = self.driven_mask();
        if self.state != ServoState::Stopping {
            self.stopping.braking = false;
        }
        self.brakes.update(driven, self.stopping.braking);
        let released = self.brakes_released();
        io.write_brakes(released);
        self.snapshot.brakes_released = released;
    }

    /// Longest engage time of the brakes fitted, periods (0 without any).
    pub(super) fn engage_periods(&self) -> u32 {
        self.brakes.engage_periods()
    }

    /// Latch a fault the board found outside the servo step (a failed crystal, a
    /// configuration rejected at boot, a corrupt settings store): always immediate,
    /// outputs off from the next period on (the caller switches them off now).
    pub fn latch_board_fault(&mut self, kind: FaultKind) {
        self.trip(Fault::system(kind), 0.0, None);
        if self.state.drives() {
            self.state = ServoState::Fault;
            self.ident.run = None;
        }
        self.publish_faults();
    }

    /// `axis`' position is no longer known for sure without a fault to latch (its counter
    /// may have wrapped unseen while the control loop could not run: a flash erase's
    /// stall, firmware `period::StallWatch`): it must be homed again before a program
    /// runs. An axis that takes no part in homing keeps its (power-up) reference.
    #[cold]
    pub fn forget_home(&mut self, axis: Axis) {
        self.manual.homed &= !(1 << axis.index());
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

    /// The compensation's state (offsets applied, axes taking up their play).
    pub fn compensation(&self) -> &CompState {
        &self.comp
    }

    /// Axes whose compensation applies this period: the referenced ones (the tables are
    /// in machine coordinates) while the laws track a reference; none while identifying
    /// or checking the encoders (their references are the motor's own).
    #[inline(always)]
    fn compensated_mask(&self) -> u8 {
        match self.state {
            ServoState::Idle
            | ServoState::Run
            | ServoState::Jog
            | ServoState::Homing
            | ServoState::Stopping => self.referenced_mask(),
            _ => 0,
        }
    }

    /// Axes whose laws track a reference (all of them) in the states that have one;
    /// none while identifying or checking the encoders (the feed-forward's axes).
    #[inline(always)]
    fn tracking_mask(&self) -> u8 {
        match self.state {
            ServoState::Idle
            | ServoState::Run
            | ServoState::Jog
            | ServoState::Homing
            | ServoState::Stopping => 0b111,
            _ => 0,
        }
    }

    /// Hold the axes where the motor positions `motor` are: at the nominal position
    /// that compensates to them (turned nominal before the next reference is sampled,
    /// when the period has the tables), so that holding there moves nothing.
    pub(super) fn hold_motor(&mut self, motor: Vec3<R>) {
        self.motion = ReferenceMode::Hold(motor);
        self.comp.pending_hold = true;
    }

    /// A hold at motor positions set since the last reference, turned nominal.
    #[cold]
    #[inline(never)]
    fn hold_nominal(&mut self, tables: &CompTables) {
        self.comp.pending_hold = false;
        let active = self.referenced_mask();
        if let ReferenceMode::Hold(p) = &mut self.motion {
            *p = self.comp.nominal_of(tables, *p, active);
        }
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
    /// ([`Snapshot::refused`]). No backlash or lead-screw compensation: [`Self::period_with`].
    pub fn period<IO: ServoIo<R>>(&mut self, io: &mut IO, commands: &[Command]) -> &Snapshot {
        self.period_with(io, commands, None)
    }

    /// [`Self::period`] with the machine's compensation `tables` (the machine keeps them
    /// in its memory: [`crate::machine::Machine::set_compensation`]).
    pub fn period_with<IO: ServoIo<R>>(
        &mut self,
        io: &mut IO,
        commands: &[Command],
        tables: Option<&CompTables>,
    ) -> &Snapshot {
        self.snapshot.period = self.snapshot.period.wrapping_add(1);

        // 1. Safety first: hard inputs and commands decide before anything is computed.
        let inputs = io.read_inputs();
        self.latch_hard_inputs(&inputs);
        self.outputs_off_unless_driving(io);
        if self.state != ServoState::EncoderCheck {
            // a fault or a stop ended the arm check
            self.checks.arm = None;
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
        let tables = tables.filter(|t| t.any());
        if self.comp.pending_hold {
            match tables {
                Some(t) => self.hold_nominal(t),
                None => self.comp.pending_hold = false,
            }
        }
        let (mut reference, motion_t, at_rest) = self.sample_reference(held);
        // the programmed position, before compensation (what stops hold and telemetry
        // shows)
        let nominal = reference.pos;
        let programmed = reference;
        if let Some(t) = tables {
            let active = self.compensated_mask();
            self.comp
                .apply(t, &mut reference, active, self.period_s as f32);
            let crossing = self.comp.crossing_mask();
            if crossing != 0 {
                self.monitor.release_due_claims(crossing);
            }
        }
        if self.ff.any() {
            let active = self.tracking_mask();
            self.ff_effort =
                self.ff
                    .apply(&programmed, &mut reference, active, self.period_s as f32);
            let turning = self.ff.turning_mask();
            if turning != 0 {
                self.monitor.release_due_claims(turning);
            }
        }

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
        let (applied, evaluated) =
            self.control(io, &sensed, &reference, nominal, index_fault, arm_checking);
        self.applied = applied;
        self.estimators.applied(applied);
        self.write_brakes(io);

        // 6. Telemetry (plain copies).
        self.publish(&sensed, nominal, applied, motion_t, evaluated);
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
        if let Some(left) = self.stopping.estop_left {
            // a category-1 e-stop: the stop gets a bounded time, then the outputs go off
            self.stopping.estop_left = match (self.state, left) {
                (ServoState::Stopping, 0) => {
                    self.state = ServoState::Fault;
                    None
                }
                (ServoState::Stopping, n) => {
                    // the brakes engage so that they grip by the deadline
                    if n <= self.engage_periods() {
                        self.stopping.braking = true;
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
        let arm_checking = self.state == ServoState::EncoderCheck && self.checks.arm.is_some();
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
        nominal: Vec3<R>,
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
        if !law && self.filtered {
            // the outputs are off or under the encoder check: the filters rest at 0
            self.filters.reset(Vec3::zero());
        }
        match self.state {
            _ if law => (
                self.closed_loop(io, s, reference, nominal, index_fault),
                true,
            ),
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
        nominal: Vec3<R>,
        index_fault: Option<(Fault, f32)>,
    ) -> Vec3<R> {
        let mut applied = Vec3::zero();
        self.check_sensors(s, reference, index_fault);
        let mut reference = *reference;
        let identifying = self.state == ServoState::Identify;
        let u = self.law_effort(s, &mut reference, identifying);
        self.check_motion_limits(s, &reference, identifying);
        if s.at_rest && matches!(self.state, ServoState::Stopping | ServoState::Jog) {
            // a stop holds the programmed position (the compensation is added again)
            let at = RefSample {
                pos: nominal,
                ..reference
            };
            self.finish_motion(&at, s.vel);
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
        if self.ff.any() {
            u = u + self.ff_effort;
        }
        if self.filtered {
            u = self.filter_output(u);
        }
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

    /// The control output through the axes' filters while the outputs are driven; at
    /// rest at 0 (and the output passed as it is: it is not applied) while they are not.
    #[inline(always)]
    fn filter_output(&mut self, u: Vec3<R>) -> Vec3<R> {
        if self.state.drives() {
            self.filters.process(u)
        } else {
            self.filters.reset(Vec3::zero());
            u
        }
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
        nominal: Vec3<R>,
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
            s.reference = nominal.to_array().map(Real::to_f32);
            s.tracking = o.tracking.to_array().map(Real::to_f32);
            s.contour = o.contour.to_array().map(Real::to_f32);
            s.s = o.s.to_array().map(Real::to_f32);
        } else {
            s.tracking = [0.0; AXES];
            s.contour = [0.0; AXES];
            s.s = [0.0; AXES];
        }
    }

    /// Publish the latched faults and the homed axes in the snapshot (they change only
    /// here and there; copying them every period would cost the control interrupt).
    pub(super) fn publish_faults(&mut self) {
        self.snapshot.fault = self.faults.first();
        self.snapshot.fault_bits = self.faults.bits();
        self.snapshot.homed = self.referenced_mask();
    }

    /// Progress of homing or identification, 0..=1.
    #[cold]
    #[inline(never)]
    pub(super) fn progress(&self) -> f32 {
        match (&self.ident.run, &self.motion) {
            (Some(run), _) => run.last().progress,
            (None, ReferenceMode::Homing { run, .. }) => {
                let total = (!self.manual.no_homing & 0b111).count_ones();
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
