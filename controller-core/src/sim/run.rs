//! A simulated run: the servo step against the simulated world for a fixed number of
//! periods, with the figures taken on the true state. host-sim's discrete mode and the
//! firmware's QEMU rig both drive one; each period is [`SimRun::control`] (the servo
//! step, the part the board's interrupt runs) followed by [`SimRun::finish_period`]
//! (figures, then the world advances one period).
//!
//! The operator's commands are scripted: arm (and, unless the run only holds, start the
//! configured path) in the first period. A fault can be injected at a given time
//! ([`Injection`]): into the world (sensors, inputs, plant) or, for a corrupted controller
//! state, through the servo's injection hook.

use crate::axes::AXES;
use crate::config::ConfigError;
use crate::motion::path::PathStart;
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

/// A run in progress.
pub struct SimRun<R> {
    servo: Servo<R>,
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
        let servo = Servo::new(&cfg.servo, world.counter_registers(), counts)?;
        let inject = match cfg.inject {
            Some(i) if i.at_s >= 0.0 && i.at_s.is_finite() => {
                let k = libm::round(i.at_s / servo.period_s()).min(f64::from(u32::MAX)) as u32;
                Some((k, i.fault))
            }
            Some(_) => return Err(ConfigError::Negative("inject.at_s")),
            None => None,
        };
        Ok(Self {
            servo,
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

    /// The servo step of the current period with the caller's commands (after the
    /// scripted injection, if due).
    pub fn control_with(&mut self, cmds: &[Command]) -> &Snapshot {
        if let Some((k, inj)) = self.inject {
            if self.k == k {
                match inj {
                    Injection::CorruptState { axis } => {
                        self.servo.inject_corrupt_state(axis.index())
                    }
                    other => self.world.inject(&other),
                }
                self.injected_at = Some(self.k);
            }
        }
        self.servo.period(&mut self.world, cmds)
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
        let held = self.servo.motion_held();
        if self.path_from.is_none() && !held && self.servo.state() == ServoState::Run {
            self.path_from = Some(self.k);
        }
        // the figures compare the machine with the path from the period the path started
        // (the same as the run's start without brakes); while a brake still opens there is
        // no path to compare with yet
        let d = if self.path_from.is_none() && held {
            None
        } else {
            let from_s = f64::from(self.path_from.unwrap_or(0)) * self.servo.period_s();
            self.truth.record(
                &self.reference,
                self.world.time_s() - from_s,
                self.servo.period_s(),
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

    /// The servo, to reconfigure it between periods (settings changes).
    pub fn servo_mut(&mut self) -> &mut Servo<R> {
        &mut self.servo
    }

    pub fn servo(&self) -> &Servo<R> {
        &self.servo
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
