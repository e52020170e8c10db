//! A simulated run: a machine ([`Machine`], built from the run's servo configuration)
//! against the simulated world for a fixed number of periods, with the figures taken on
//! the true state. host-sim's discrete mode and the firmware's QEMU rig both drive one;
//! each period is [`SimRun::control`] (the machine's period, the part the board's
//! interrupt runs) followed by [`SimRun::finish_period`] (figures, then the world advances
//! one period).
//!
//! The operator's commands are scripted. A run that follows the servo's own path gives
//! them on the machine's panel ([`Machine::local`]): arm (and, unless the run only holds,
//! start the path) in the first period. A program run ([`RunConfig::program`]) sends
//! requests as the link does: arm, run, the path's edges as line segments while the
//! machine's request queue has room, the end of the program; the machine's supervisor
//! and planner run it ([`super::program::ProgramFeed`]). A fault can be injected at a
//! given time ([`Injection`]): into the world (sensors, inputs, plant) or, for a corrupted
//! controller state, through the machine's injection hook.
//!
//! The machine's large parts (its planner and scope, [`MachineMemory`]) are where the
//! caller puts them ([`SimRun::with_memory`]); [`SimRun::new`] holds a scope and no
//! planner ([`RunMemory`]) in the run, enough for every run but a program run.

use core::ops::DerefMut;

use crate::axes::AXES;
use crate::config::ConfigError;
use crate::machine::{ControlSide, Machine, MachineError, MachineMemory, Seen};
use crate::motion::path::PathStart;
use crate::motion::planner::{PlannerConfig, PlannerHandle, GANTRY_PLANNER};
use crate::motion::trajectory::Trajectory;
use crate::servo::snapshot::Snapshot;
use crate::servo::{Command, Servo, ServoConfig, ServoState};
use crate::sim::program::ProgramFeed;
use crate::sim::run_memory::{NoPlanner, RunMemory};
use crate::sim::truth::{Truth, TruthFigures, TruthSpec};
use crate::sim::world::{Injection, World, WorldConfig};
use crate::{Real, Vec3};

/// Everything a simulated run needs.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct RunConfig {
    pub servo: ServoConfig,
    pub world: WorldConfig,
    pub truth: TruthSpec,
    /// Control periods to run.
    pub periods: u32,
    /// Arm and hold position instead of starting the path.
    #[cfg_attr(feature = "serde", serde(default))]
    pub hold: bool,
    /// A fault injected during the run.
    #[cfg_attr(feature = "serde", serde(default))]
    pub inject: Option<TimedInjection>,
    /// Run the path (a square or polyline) as a program through the machine: its edges
    /// streamed as line segments at the path's speed into the machine's planner (the
    /// factory planner's limits and blending, [`GANTRY_PLANNER`]), which the servo
    /// follows. The figures compare the true position with the planner's reference, and
    /// the contour error is the distance to the programmed path.
    #[cfg_attr(feature = "serde", serde(default))]
    pub program: bool,
}

/// A fault and when it is injected.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct TimedInjection {
    /// Simulated time of the injection, s.
    pub at_s: f64,
    pub fault: Injection,
}

/// The machine a scripted run drives: its memory at `P`, its planner `M`.
pub type RunMachine<R, P = RunMemory, M = NoPlanner> = Machine<P, M, R>;

/// A run in progress.
pub struct SimRun<R, P = RunMemory, M = NoPlanner>
where
    P: DerefMut<Target = MachineMemory<M>>,
    M: PlannerHandle,
{
    machine: RunMachine<R, P, M>,
    world: World,
    truth: Truth,
    reference: Trajectory<f64>,
    periods: u32,
    k: u32,
    hold: bool,
    /// A program run's segments still to send.
    program: Option<ProgramFeed>,
    inject: Option<(u32, Injection)>,
    injected_at: Option<u32>,
    /// The run's period in which the servo started the path (it holds the start until the
    /// holding brakes are open): the figures' path time counts from there.
    path_from: Option<u32>,
}

impl<R: Real> SimRun<R> {
    /// Validates every part of `cfg` (nothing runs when one is rejected). A program run
    /// needs a planner: [`Self::with_memory`].
    pub fn new(cfg: &RunConfig) -> Result<Self, ConfigError> {
        if cfg.program {
            return Err(ConfigError::Unsupported(
                "a program run without a planner (SimRun::with_memory)",
            ));
        }
        Self::with_memory(cfg, &factory_planner(cfg.servo.rate_hz), RunMemory::new())
    }
}

/// The factory planner ([`GANTRY_PLANNER`]) at `rate_hz`: a program run's.
pub fn factory_planner(rate_hz: u32) -> PlannerConfig {
    PlannerConfig {
        period_s: 1.0 / rate_hz as f32,
        ..GANTRY_PLANNER
    }
}

impl<R, P, M> SimRun<R, P, M>
where
    R: Real,
    P: DerefMut<Target = MachineMemory<M>>,
    M: PlannerHandle,
{
    /// [`Self::new`] with the machine's memory at `mem` (its planner runs a program run;
    /// a split planner's halves must be connected) and its planner configured as
    /// `planner` (a program run's: [`factory_planner`]).
    pub fn with_memory(
        cfg: &RunConfig,
        planner: &PlannerConfig,
        mem: P,
    ) -> Result<Self, ConfigError> {
        let mut slot = None;
        Self::with_memory_in(&mut slot, cfg, planner, mem)?;
        slot.ok_or(ConfigError::Unsupported("a simulated run"))
    }

    /// [`Self::with_memory`] built in `slot` (the QEMU rig's static): the run (the
    /// machine, 6 KiB, and the world) is written there once instead of being returned
    /// through the caller's frame, which on the board's 40 KiB boot stack could not hold
    /// its copies. Never inlined, so that its frame is not added to its caller's.
    #[inline(never)]
    pub fn with_memory_in<'s>(
        slot: &'s mut Option<Self>,
        cfg: &RunConfig,
        planner: &PlannerConfig,
        mem: P,
    ) -> Result<&'s mut Self, ConfigError> {
        let world = World::new(&cfg.world, &cfg.servo)?;
        let plan = cfg
            .servo
            .path
            .ok_or(ConfigError::Unsupported("a simulated run without a path"))?;
        let mut reference = plan.path.build()?;
        let counts = world.counts();
        if plan.start == PathStart::FromCurrentPosition {
            // the servo shifts the path to the measured start position; so do the figures
            let mut origin = Vec3::zero();
            let p0 = reference.sample(0.0).pos;
            for i in 0..AXES {
                origin[i] = counts[i] as f64 * cfg.servo.encoders[i].count_len()? - p0[i];
            }
            reference = shifted(reference, origin)?;
        }
        let program = match (cfg.program, &reference) {
            (false, _) => None,
            (true, Trajectory::Polyline(p)) if !cfg.hold => Some(ProgramFeed::new(p)),
            (true, _) => {
                return Err(ConfigError::Unsupported(
                    "program = true needs a square or polyline path, and no hold",
                ))
            }
        };
        let machine =
            Machine::from_config(&cfg.servo, planner, world.counter_registers(), counts, mem)
                .map_err(|e| match e {
                    MachineError::Servo(e) => e,
                    MachineError::PlannerDetached => {
                        ConfigError::Unsupported("a split planner whose halves are not connected")
                    }
                    _ => ConfigError::Unsupported("a machine for a simulated run"),
                })?;
        let inject = match cfg.inject {
            Some(i) if i.at_s >= 0.0 && i.at_s.is_finite() => {
                let period_s = machine.servo().period_s();
                let k = libm::round(i.at_s / period_s).min(f64::from(u32::MAX)) as u32;
                Some((k, i.fault))
            }
            Some(_) => return Err(ConfigError::Negative("inject.at_s")),
            None => None,
        };
        Ok(slot.insert(Self {
            machine,
            world,
            truth: Truth::new(cfg.truth),
            reference,
            periods: cfg.periods,
            k: 0,
            hold: cfg.hold,
            program,
            inject,
            injected_at: None,
            path_from: None,
        }))
    }

    /// A run of `machine` (built elsewhere, e.g. with its settings tree) in `world`,
    /// driven by a link ([`Self::linked_period`]; QEMU's link rig): no scripted commands,
    /// no injection, no end, and no figures ([`Self::advance`]; its reference holds where
    /// the machine starts).
    pub fn linked(machine: RunMachine<R, P, M>, world: World) -> Self {
        let start = machine.servo().snapshot().pos.map(f64::from);
        Self {
            machine,
            world,
            truth: Truth::new(TruthSpec::default()),
            reference: Trajectory::Line {
                start: Vec3::from_array(start),
                vel: Vec3::zero(),
            },
            periods: u32::MAX,
            k: 0,
            hold: true,
            program: None,
            inject: None,
            injected_at: None,
            path_from: None,
        }
    }

    /// A linked run's period: the link's events, the machine's period, its replies
    /// ([`Machine::linked_period_seen`]; `seen` is shown each event it takes).
    pub fn linked_period(
        &mut self,
        link: &mut ControlSide<'_>,
        seen: impl FnMut(Seen<'_>),
    ) -> &Snapshot {
        self.machine.linked_period_seen(&mut self.world, link, seen);
        self.machine.servo().snapshot()
    }

    /// The world advances over the period, without figures (a linked run's).
    pub fn advance(&mut self) {
        self.world.advance();
        self.k = self.k.saturating_add(1);
    }

    /// The machine's period (the scripted commands of the first one: arm and start the
    /// path; a program run's requests: see the module docs).
    pub fn control(&mut self) -> &Snapshot {
        if let Some(feed) = self.program.as_mut() {
            feed.send(&mut self.machine);
            return self.control_with(&[]);
        }
        let cmds: &[Command] = match (self.k, self.hold) {
            (0, false) => &[Command::Arm, Command::StartPath],
            (0, true) => &[Command::Arm],
            _ => &[],
        };
        self.control_with(cmds)
    }

    /// The machine's period with the caller's commands, given on its panel (after the
    /// scripted injection, if due). At most two commands a period: the panel holds two
    /// (a third would replace the second).
    pub fn control_with(&mut self, cmds: &[Command]) -> &Snapshot {
        if let Some((k, inj)) = self.inject {
            if self.k == k {
                match inj {
                    Injection::CorruptState { axis } => {
                        self.machine.inject_corrupt_state(axis.index())
                    }
                    other => self.world.inject(&other),
                }
                self.injected_at = Some(self.k);
            }
        }
        for c in cmds {
            self.machine.local(*c);
        }
        self.machine.period(&mut self.world);
        self.machine.servo().snapshot()
    }

    /// The run's period of the injection, once it happened.
    pub fn injected_at(&self) -> Option<u32> {
        self.injected_at
    }

    /// Record the period's figures, then advance the world over it. Returns the true
    /// contour error when it was sampled this period.
    pub fn finish_period(&mut self) -> Option<f64> {
        // (at the tool: a framed axis' encoder reads its motor side)
        let pos = Vec3::from_array(self.world.tool_pos());
        let servo = self.machine.servo();
        let (held, period_s) = (servo.motion_held(), servo.period_s());
        if self.path_from.is_none() && !held && servo.state() == ServoState::Run {
            self.path_from = Some(self.k);
        }
        // the figures compare the machine with the path from the period the path started
        // (the same as the run's start without brakes); while a brake still opens there is
        // no path to compare with yet
        let d = if self.path_from.is_none() && held {
            None
        } else {
            let from_s = f64::from(self.path_from.unwrap_or(0)) * period_s;
            let t = self.world.time_s() - from_s;
            let u = self.world.effort();
            match &self.reference {
                // a program: against the planner's reference, the contour error to the
                // programmed path
                Trajectory::Polyline(path) if self.program.is_some() => {
                    let r = self.machine.path_sample().pos_mm.cast::<f64>();
                    self.truth
                        .record_at(r, t, period_s, pos, u, || path.distance(pos))
                }
                _ => self.truth.record(&self.reference, t, period_s, pos, u),
            }
        };
        self.world.advance();
        self.k = self.k.saturating_add(1);
        d
    }

    /// All periods run.
    pub fn done(&self) -> bool {
        self.k >= self.periods
    }

    /// Periods run so far.
    pub fn periods_run(&self) -> u32 {
        self.k
    }

    /// A program run: every segment was sent and the program has ended.
    pub fn program_sent(&self) -> Option<bool> {
        self.program.as_ref().map(ProgramFeed::done)
    }

    pub fn figures(&self) -> TruthFigures {
        self.truth.figures()
    }

    pub fn servo(&self) -> &Servo<R> {
        self.machine.servo()
    }

    /// The machine that drives the servo.
    pub fn machine(&self) -> &RunMachine<R, P, M> {
        &self.machine
    }

    /// The machine, for what a board does between periods (a latched board fault, a
    /// forgotten home, a new servo configuration) and for a caller's own requests.
    pub fn machine_mut(&mut self) -> &mut RunMachine<R, P, M> {
        &mut self.machine
    }

    pub fn world(&self) -> &World {
        &self.world
    }

    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The path the figures are taken against (absolute coordinates).
    pub fn reference(&self) -> &Trajectory<f64> {
        &self.reference
    }
}

/// `traj` moved by `origin` (only the analytic paths that carry their own position).
fn shifted(traj: Trajectory<f64>, o: Vec3<f64>) -> Result<Trajectory<f64>, ConfigError> {
    Ok(match traj {
        Trajectory::Line { start, vel } => Trajectory::Line {
            start: start + o,
            vel,
        },
        Trajectory::Helix {
            center,
            radius,
            omega,
            z_rate,
        } => Trajectory::Helix {
            center: center + o,
            radius,
            omega,
            z_rate,
        },
        Trajectory::Sine {
            amp,
            omega,
            phase,
            offset,
        } => Trajectory::Sine {
            amp,
            omega,
            phase,
            offset: offset + o,
        },
        Trajectory::Step { .. } | Trajectory::Polyline(_) => {
            return Err(ConfigError::Unsupported(
                "path_start = from_current_position with a step or square path",
            ))
        }
    })
}
