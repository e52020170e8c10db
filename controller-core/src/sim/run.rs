//! A simulated run: a machine ([`Machine`], built from the run's servo configuration)
//! against the simulated world for a fixed number of periods, with the figures taken on
//! the true state. host-sim's discrete mode and the firmware's QEMU rig both drive one;
//! each period is [`SimRun::control`] (the machine's period, the part the board's
//! interrupt runs) followed by [`SimRun::finish_period`] (figures, then the world advances
//! one period).
//!
//! The operator's commands are scripted and reach the servo through the machine's panel
//! ([`Machine::local`]): arm (and, unless the run only holds, start the configured path)
//! in the first period. A fault can be injected at a given time ([`Injection`]): into the
//! world (sensors, inputs, plant) or, for a corrupted controller state, through the
//! machine's injection hook.

use core::ops::{Deref, DerefMut};

use crate::axes::AXES;
use crate::config::ConfigError;
use crate::machine::scope::Scope;
use crate::machine::{Machine, MachineError, MachineMemory};
use crate::motion::path::PathStart;
use crate::motion::planner::{
    ExecMode, Offer, PathSample, PlannerConfig, PlannerConfigError, PlannerHandle, RestartError,
    Segment, SegmentError, GANTRY_PLANNER,
};
use crate::motion::trajectory::Trajectory;
use crate::servo::snapshot::Snapshot;
use crate::servo::{Command, Servo, ServoConfig, ServoState};
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

/// The planner of a scripted run's machine: none. A scripted run follows the servo's own
/// path ([`Command::StartPath`]) or a reference planned outside the machine
/// ([`SimRun::set_planner_reference`]); a program it is sent is refused segment by
/// segment, and it holds its start.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoPlanner {
    start_mm: [f32; 3],
}

impl PlannerHandle for NoPlanner {
    const OFFERS_PER_PERIOD: usize = 1;
    fn restart(&mut self, _: &PlannerConfig, start_mm: [f32; 3]) -> Result<(), RestartError> {
        self.start_mm = start_mm;
        Ok(())
    }
    fn offer(&mut self, _: &Segment) -> Offer {
        Offer::Refused(SegmentError::QueueFull)
    }
    fn hold(&mut self) {}
    fn resume(&mut self) {}
    fn abort(&mut self) {}
    fn set_feed_override(&mut self, _: f32) -> Result<(), PlannerConfigError> {
        Ok(())
    }
    fn free_slots(&self) -> usize {
        0
    }
    fn tick(&mut self) -> PathSample {
        PathSample {
            pos_mm: Vec3::from_array(self.start_mm),
            vel_mm_s: Vec3::zero(),
            acc_mm_s2: Vec3::zero(),
            tangent: Vec3::zero(),
            path_speed_mm_s: 0.0,
            path_acc_mm_s2: 0.0,
            feed_ratio: 0.0,
            tag: 0,
            mode: ExecMode::Idle,
        }
    }
    fn is_idle(&self) -> bool {
        true
    }
}

/// A scripted run's machine memory, held in the run: its scope (no planner).
pub struct RunMemory(MachineMemory<NoPlanner>);

impl Deref for RunMemory {
    type Target = MachineMemory<NoPlanner>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl DerefMut for RunMemory {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.0
    }
}

/// The machine a scripted run drives.
pub type RunMachine<R> = Machine<RunMemory, NoPlanner, R>;

/// A run in progress.
pub struct SimRun<R> {
    machine: RunMachine<R>,
    world: World,
    truth: Truth,
    reference: Trajectory<f64>,
    periods: u32,
    k: u32,
    hold: bool,
    inject: Option<(u32, Injection)>,
    injected_at: Option<u32>,
    /// The run's period in which the servo started the path (it holds the start until the
    /// holding brakes are open): the figures' path time counts from there.
    path_from: Option<u32>,
}

impl<R: Real> SimRun<R> {
    /// Validates every part of `cfg` (nothing runs when one is rejected).
    pub fn new(cfg: &RunConfig) -> Result<Self, ConfigError> {
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
        let mem = RunMemory(MachineMemory {
            planner: NoPlanner::default(),
            scope: Scope::new(),
        });
        // (no program runs: the planner's configuration is the gantry's, at the run's rate)
        let planner = PlannerConfig {
            period_s: 1.0 / cfg.servo.rate_hz as f32,
            ..GANTRY_PLANNER
        };
        let machine =
            Machine::from_config(&cfg.servo, &planner, world.counter_registers(), counts, mem)
                .map_err(|e| match e {
                    MachineError::Servo(e) => e,
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
        Ok(Self {
            machine,
            world,
            truth: Truth::new(cfg.truth),
            reference,
            periods: cfg.periods,
            k: 0,
            hold: cfg.hold,
            inject,
            injected_at: None,
            path_from: None,
        })
    }

    /// The servo step of the current period (arm and start the path in the first one).
    pub fn control(&mut self) -> &Snapshot {
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

    /// The reference the servo follows in `Run` this period, planned outside the machine
    /// (host-sim's G-code runner runs a planner of its own).
    pub fn set_planner_reference(&mut self, s: &PathSample) {
        self.machine.set_planner_reference(s);
    }

    /// The run's period of the injection, once it happened.
    pub fn injected_at(&self) -> Option<u32> {
        self.injected_at
    }

    /// Record the period's figures, then advance the world over it. Returns the true
    /// contour error when it was sampled this period.
    pub fn finish_period(&mut self) -> Option<f64> {
        let s = self.world.state();
        let pos = Vec3::new(s[0].pos, s[1].pos, s[2].pos);
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
            self.truth.record(
                &self.reference,
                self.world.time_s() - from_s,
                period_s,
                pos,
                self.world.effort(),
            )
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

    pub fn figures(&self) -> TruthFigures {
        self.truth.figures()
    }

    pub fn servo(&self) -> &Servo<R> {
        self.machine.servo()
    }

    /// The machine that drives the servo.
    pub fn machine(&self) -> &RunMachine<R> {
        &self.machine
    }

    /// The machine, for what a board does between periods (a latched board fault, a
    /// forgotten home, a new servo configuration).
    pub fn machine_mut(&mut self) -> &mut RunMachine<R> {
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
