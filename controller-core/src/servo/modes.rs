//! The servo's mode transitions: which command is valid when ([`check`]), what each
//! command does to the state ([`Servo::apply_command`]), latching a fault with the stop
//! its category asks for ([`Servo::trip`]), and the ends of stops, jogs and
//! identifications.

use super::checks::{ArmCheck, ArmPhase, Check};
use super::commands::{Command, CommandRefusal};
use super::faults::{Fault, FaultKind, FaultRecord, StopCategory};
use super::identify::{IdentifyKind, IdentifyRun};
use super::io::Inputs;
use super::snapshot::Snapshot;
use super::state::ServoState;
use super::step::Servo;
use crate::axes::{Axis, AXES};
use crate::motion::homing::Homing;
use crate::motion::jog::Jog;
use crate::motion::path::PathStart;
use crate::motion::reference::ReferenceMode;
use crate::motion::trajectory::RefSample;
use crate::sysid::AxisSample;
use crate::{Real, Vec3};

/// Whether `c` may run now, judged from the latest snapshot (state, latched faults, inputs,
/// homed and model masks). Checks that need the configuration (a path exists, the
/// identification window) are the servo's own, after this one.
pub fn check(s: &Snapshot, c: &Command) -> Result<(), CommandRefusal> {
    use ServoState as S;
    let faulted = s.fault_bits.0 != 0 || s.fault_bits.1.iter().any(|b| *b != 0);
    let needs_clear_inputs = || {
        if faulted {
            Err(CommandRefusal::FaultLatched)
        } else if s.inputs.estop {
            Err(CommandRefusal::EStopActive)
        } else if s.inputs.first_limit().is_some() {
            Err(CommandRefusal::LimitActive)
        } else {
            Ok(())
        }
    };
    let homed = |a: Axis| {
        if s.homed & (1 << a.index()) != 0 {
            Ok(())
        } else {
            Err(CommandRefusal::NotHomed { axis: a })
        }
    };
    match (c, s.state) {
        (Command::Arm, S::Disabled) => {
            needs_clear_inputs()?;
            match Axis::ALL
                .into_iter()
                .find(|a| s.model_missing & (1 << a.index()) != 0)
            {
                Some(axis) => Err(CommandRefusal::ModelMissing { axis }),
                None => Ok(()),
            }
        }
        (Command::Disarm, st) if st != S::Disabled && st != S::Fault => Ok(()),
        (Command::Reset, S::Fault) => Ok(()),
        (Command::StartPath, S::Idle | S::Run) => Ok(()),
        (Command::Home, S::Idle) => Ok(()),
        (Command::Jog { .. }, S::Idle | S::Jog) => Ok(()),
        (
            Command::Identify { axis, window_mm } | Command::MeasureResponse { axis, window_mm },
            S::Disabled | S::Idle,
        )
        | (Command::MeasureLoop { axis, window_mm }, S::Idle) => {
            needs_clear_inputs()?;
            if window_mm.is_none() {
                homed(*axis)?;
            }
            Ok(())
        }
        (Command::Run, S::Idle | S::Run) => {
            Axis::ALL.into_iter().try_for_each(homed)?;
            Ok(())
        }
        (Command::Stop, S::Run | S::Jog | S::Homing | S::Identify | S::Idle) => Ok(()),
        (Command::LinkLost | Command::LinkUp, _) => Ok(()),
        (
            Command::Arm
            | Command::Identify { .. }
            | Command::MeasureResponse { .. }
            | Command::MeasureLoop { .. },
            S::Fault,
        ) => Err(CommandRefusal::FaultLatched),
        _ => Err(CommandRefusal::WrongState),
    }
}

impl<R: Real> Servo<R> {
    /// Begin a controlled stop from `from`, ending in `then`.
    #[cold]
    #[inline(never)]
    pub(super) fn begin_stop(&mut self, from: &RefSample<R>, then: ServoState) {
        self.motion = ReferenceMode::stop_from(from, &self.stopping.decel);
        self.stopping.rest_periods = 0;
        self.stopping.braking = false;
        self.stopping.then = then;
        self.state = ServoState::Stopping;
    }

    /// Latch `f`; immediate faults switch the outputs off now, controlled ones start a stop
    /// from the current reference (`None` only for faults of the immediate category).
    #[cold]
    #[inline(never)]
    pub(super) fn trip(&mut self, f: Fault, value: f32, reference: Option<&RefSample<R>>) {
        self.faults.record(FaultRecord {
            fault: f,
            period: self.snapshot.period,
            value,
        });
        if f.kind.is_encoder() {
            // the position is no longer known for sure: home again
            if let Some(a) = f.axis {
                self.manual.homed &= !(1 << a.index());
            }
        }
        self.publish_faults();
        let moving = matches!(
            self.state,
            ServoState::Idle | ServoState::Run | ServoState::Jog | ServoState::Homing
        );
        let category = if f.kind == FaultKind::EStop && self.stopping.estop_controlled {
            StopCategory::Controlled
        } else {
            f.kind.stop()
        };
        if f.kind == FaultKind::EStop
            && self.stopping.estop_controlled
            && self.stopping.estop_left.is_none()
        {
            self.stopping.estop_left = Some(self.stopping.estop_periods);
        }
        match (category, self.state) {
            (_, ServoState::Fault) => {}
            (StopCategory::Controlled, _) if moving => {
                let here;
                let from = match reference {
                    Some(r) => r,
                    None => {
                        here = crate::motion::reference::sample(
                            &self.motion,
                            self.path.as_ref(),
                            &self.clock,
                        )
                        .0;
                        &here
                    }
                };
                self.begin_stop(from, ServoState::Fault);
            }
            (StopCategory::Controlled, ServoState::Stopping) => {
                self.stopping.then = ServoState::Fault;
            }
            _ => {
                self.state = ServoState::Fault;
                self.checks.check = None;
                self.ident.run = None;
            }
        }
    }

    /// Every latched cause gone? Encoder faults are cleared by the encoder check.
    pub(super) fn causes_gone(&self, inputs: &Inputs) -> bool {
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

    /// Hold where the axes are now, with fresh estimator, controller and monitor states.
    pub(super) fn hold_here(&mut self, counts: &[i64; AXES]) {
        self.estimators.reset(*counts);
        self.controller.reset();
        self.monitor.reset();
        self.hold_motor(self.position_of(counts));
    }

    /// Apply one operator command at the start of the period: refused when [`check`]
    /// says it is not valid now, or when the configuration cannot serve it (no path, no
    /// homing, an identification window that does not fit).
    #[cold]
    #[inline(never)]
    pub(super) fn apply_command(
        &mut self,
        c: &Command,
        inputs: &Inputs,
        counts: &[i64; AXES],
    ) -> Result<(), CommandRefusal> {
        self.snapshot.inputs = *inputs;
        self.snapshot.state = self.state;
        check(&self.snapshot, c)?;
        match *c {
            Command::Arm => self.arm(counts),
            Command::Disarm => self.disarm(),
            Command::Reset => return self.reset(inputs, counts),
            Command::StartPath => return self.start_path(counts),
            Command::Home => return self.home(counts),
            Command::Jog { axis, vel_mm_s } => self.jog(axis, vel_mm_s),
            Command::Identify { axis, window_mm } => {
                return self.start_identify(IdentifyKind::Model, axis, window_mm, counts)
            }
            Command::MeasureResponse { axis, window_mm } => {
                return self.start_identify(IdentifyKind::Response, axis, window_mm, counts)
            }
            Command::MeasureLoop { axis, window_mm } => {
                return self.start_identify(IdentifyKind::Loop, axis, window_mm, counts)
            }
            Command::Run => self.run_planner(),
            Command::Stop => self.stop(counts),
            Command::LinkLost => {
                self.link_down = true;
                // (identifying: the stop is immediate, as for any fault there)
                let r = self.here();
                self.trip(Fault::system(FaultKind::LinkLost), 0.0, Some(&r));
            }
            Command::LinkUp => self.link_down = false,
        }
        Ok(())
    }

    /// The reference of the motion under way, now.
    #[inline(always)]
    fn here(&self) -> RefSample<R> {
        crate::motion::reference::sample(&self.motion, self.path.as_ref(), &self.clock).0
    }

    /// Arm: hold where the axes are; with the arm check on, prove the encoders first.
    #[inline(always)]
    fn arm(&mut self, counts: &[i64; AXES]) {
        self.state = ServoState::Idle;
        self.hold_here(counts);
        if self.checks.arm_on {
            // the encoders proven before anything may move (a swapped A/B is a
            // wiring change made with the power off; holding still shows nothing)
            let brake = |i: usize| self.brakes.axes[i].present();
            self.checks.arm = Some(ArmCheck {
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

    /// Disarm: outputs off at once where nothing moves and every brake grips; else a
    /// controlled stop that ends with them off.
    #[inline(always)]
    fn disarm(&mut self) {
        match self.state {
            ServoState::Idle => {
                if self.brakes_gripping() {
                    self.state = ServoState::Disabled;
                } else {
                    // a released brake grips first: hold where the axes are (already at
                    // rest, so no settling), engage, then outputs off
                    let r = self.here();
                    self.begin_stop(&r, ServoState::Disabled);
                    self.stopping.rest_periods = self.stopping.settle_periods;
                    self.stopping.braking = true;
                }
            }
            ServoState::Identify => {
                self.end_identify(true);
                self.state = ServoState::Disabled;
            }
            ServoState::Run | ServoState::Jog | ServoState::Homing => {
                let r = self.here();
                self.begin_stop(&r, ServoState::Disabled);
            }
            ServoState::EncoderCheck if self.checks.arm.is_some() => {
                // an arm check given up: nothing was proven, nothing is latched
                let r = self.here();
                self.checks.arm = None;
                if self.brakes_gripping() {
                    self.state = ServoState::Disabled;
                } else {
                    self.begin_stop(&r, ServoState::Disabled);
                    self.stopping.rest_periods = self.stopping.settle_periods;
                    self.stopping.braking = true;
                }
            }
            ServoState::EncoderCheck => {
                self.checks.check = None;
                self.state = ServoState::Fault;
            }
            _ => {}
        }
    }

    /// Reset: refused while a cause remains; an encoder fault first runs the encoder
    /// check, anything else clears at once.
    #[inline(always)]
    fn reset(&mut self, inputs: &Inputs, counts: &[i64; AXES]) -> Result<(), CommandRefusal> {
        if !self.causes_gone(inputs) {
            return Err(CommandRefusal::FaultLatched);
        }
        match self.next_check(None) {
            Some(axis) => {
                self.checks.check = Some(Check {
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
        Ok(())
    }

    /// Follow the configured path (from where the axes are, when it says so).
    #[inline(always)]
    fn start_path(&mut self, counts: &[i64; AXES]) -> Result<(), CommandRefusal> {
        let Some((traj, _)) = &self.path else {
            return Err(CommandRefusal::NoPath);
        };
        let origin = match self.path_start {
            PathStart::Absolute => None,
            PathStart::FromCurrentPosition => {
                Some(self.position_of(counts) - traj.sample(R::ZERO).pos)
            }
        };
        self.motion = ReferenceMode::Path { k: 0, origin };
        self.state = ServoState::Run;
        Ok(())
    }

    /// Start homing: every homing axis must find its switch anew.
    #[inline(always)]
    fn home(&mut self, counts: &[i64; AXES]) -> Result<(), CommandRefusal> {
        let pos = self.position_of(counts).to_array().map(Real::to_f32);
        let Some(run) = Homing::start(&self.manual.homing, &pos) else {
            return Err(CommandRefusal::NoHoming);
        };
        // homing again: every homing axis must find its switch anew
        self.manual.homed = 0;
        self.snapshot.homed = self.manual.no_homing;
        self.motion = ReferenceMode::Homing {
            hold: self.here().pos,
            run,
        };
        self.state = ServoState::Homing;
        Ok(())
    }

    /// Jog `axis` at `vel_mm_s` (from Idle the jog starts where the reference is).
    #[inline(always)]
    fn jog(&mut self, axis: Axis, vel_mm_s: f32) {
        if self.state == ServoState::Idle {
            let pos = self.here().pos.to_array().map(Real::to_f32);
            self.motion = ReferenceMode::Jog(Jog::at(pos));
            self.state = ServoState::Jog;
        }
        if let ReferenceMode::Jog(j) = &mut self.motion {
            j.command(
                axis.index(),
                vel_mm_s,
                &self.manual.jog,
                self.manual.jog_timeout_periods,
            );
        }
    }

    /// Start identifying `axis` (its model or its frequency response) inside its travel
    /// (once referenced) or `window_mm`.
    #[inline(always)]
    fn start_identify(
        &mut self,
        kind: IdentifyKind,
        axis: Axis,
        window_mm: Option<[f32; 2]>,
        counts: &[i64; AXES],
    ) -> Result<(), CommandRefusal> {
        let st = self.state;
        // (`min`: lets the compiler drop the bounds checks below)
        let i = axis.index().min(AXES - 1);
        let pos = self.position_of(counts)[i].to_f32();
        let travel = if self.referenced(i) {
            self.travel.axes[i]
        } else {
            super::travel::AxisTravel::UNLIMITED
        };
        let run = IdentifyRun::start(
            &self.ident.cfg,
            kind,
            axis,
            pos,
            &travel,
            window_mm,
            self.full_scale[i].to_f32(),
            self.period_s as f32,
            self.count_len_f32[i],
            st == ServoState::Idle,
        )?;
        if st == ServoState::Disabled {
            self.hold_here(counts);
        }
        self.ident.run = Some(run);
        self.ident.runs = self.ident.runs.wrapping_add(1);
        self.ident.outcome = None;
        self.state = ServoState::Identify;
        Ok(())
    }

    /// Follow the planner's reference: until the first sample arrives the reference
    /// holds where the servo was.
    #[inline(always)]
    fn run_planner(&mut self) {
        let mut r = self.here();
        r.vel = Vec3::zero();
        r.acc = Vec3::zero();
        self.motion = ReferenceMode::Planner(r);
        self.state = ServoState::Run;
    }

    /// Stop: an identification ends (holding, or off when it started from Disabled);
    /// any other motion ends with a controlled stop to Idle.
    #[inline(always)]
    fn stop(&mut self, counts: &[i64; AXES]) {
        match self.state {
            ServoState::Identify => {
                let hold = self.ident.run.as_ref().is_some_and(|r| r.hold_others);
                self.end_identify(true);
                if hold {
                    self.hold_here(counts);
                    self.state = ServoState::Idle;
                } else {
                    self.state = ServoState::Disabled;
                }
            }
            ServoState::Idle => {}
            _ => {
                let r = self.here();
                self.begin_stop(&r, ServoState::Idle);
            }
        }
    }

    /// End the identification (aborted by the user when `aborted`), keeping its outcome.
    #[cold]
    #[inline(never)]
    pub(super) fn end_identify(&mut self, aborted: bool) {
        if let Some(mut run) = self.ident.run.take() {
            if aborted && !run.finished() {
                // a fault sample makes the identifier stop at once with zero effort
                let _ = run.step(
                    &AxisSample {
                        fault: true,
                        ..AxisSample::default()
                    },
                    0.0,
                );
            }
            self.ident.keep_outcome(&run);
        }
    }

    /// End a stop once at rest and settled; end a jog once at rest with nothing
    /// commanded.
    #[cold]
    #[inline(never)]
    pub(super) fn finish_motion(&mut self, reference: &RefSample<R>, vel: &[f32; AXES]) {
        match self.state {
            ServoState::Stopping => {
                if self.stopping.then != ServoState::Idle {
                    // the reference is at rest: the brakes engage while the axes settle
                    self.stopping.braking = true;
                }
                self.stopping.rest_periods = self.stopping.rest_periods.saturating_add(1);
                let settled = self.stopping.rest_periods >= self.stopping.settle_periods
                    && vel
                        .iter()
                        .zip(0..AXES)
                        .all(|(v, i)| v.abs() <= 0.02 * self.monitor.vel_max(i));
                if settled || self.stopping.rest_periods >= self.stopping.timeout_periods {
                    if self.stopping.then == ServoState::Idle {
                        self.state = ServoState::Idle;
                        self.motion = ReferenceMode::Hold(reference.pos);
                    } else if self.brakes_gripping() {
                        // the outputs go off only once every brake holds its axis
                        self.state = self.stopping.then;
                    }
                }
            }
            ServoState::Jog => {
                self.state = ServoState::Idle;
                self.motion = ReferenceMode::Hold(reference.pos);
            }
            _ => {}
        }
    }
}
