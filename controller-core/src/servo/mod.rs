//! The per-period servo step: the one control sequence the board's control interrupt, the
//! simulator's discrete mode and the firmware's QEMU rig all run.
//!
//! [`Servo::period`], in order:
//!
//! 1. sample e-stop and limits and apply the period's commands to the safety state
//!    machine; if the outputs may not be driven, switch them off *before anything else*;
//! 2. read the encoder counters and extend them to wide counts ([`WideCounter`]: the
//!    signed difference of successive readings modulo the counter width, so a wrap can be
//!    neither lost nor double counted);
//! 3. sample the reference (holding position, or the configured path);
//! 4. positions from counts and velocity estimates ([`EstimatorBank`]);
//! 5. if enabled: evaluate the 3-axis controller, saturate to the amplifiers' range,
//!    check the following error, write the outputs (or switch them off on a trip), and
//!    commit every controller and estimator state with the output actually applied;
//! 6. publish the telemetry [`Snapshot`] (plain copies).
//!
//! Nothing here allocates, blocks, formats or panics; every number that reaches an output
//! is finite and within the amplifier's range.

pub mod io;
pub mod safety;
pub mod snapshot;

use crate::axes::AXES;
use crate::config::{limit, ConfigError};
use crate::controller::{Controller3, ControllerConfig, Measured};
use crate::estimator::{EstimatorBank, EstimatorBankConfig, EstimatorTiming, WideCounter};
use crate::motion::path::{PathConfig, PathStart};
use crate::motion::trajectory::{RefSample, Trajectory};
use crate::{Real, Vec3};
use io::{AmplifierConfig, EncoderConfig, ServoIo};
use safety::{Request, SafetyMonitor, SafetyState};
use snapshot::Snapshot;

/// Highest control rate the servo accepts, Hz.
pub const MAX_RATE_HZ: u32 = 50_000;
/// Lowest control rate the servo accepts, Hz.
pub const MIN_RATE_HZ: u32 = 100;

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
    /// Following-error trip level per axis, mm (`inf` disables the check, simulation only).
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub following_error_mm: [f32; AXES],
    /// The path [`Command::StartPath`] starts, if any.
    #[cfg_attr(feature = "serde", serde(default))]
    pub path: Option<PathPlan>,
}

/// Operator commands, applied at the start of a period in the order given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Disabled -> Enabled (inputs clear), holding the current position.
    Arm,
    /// Enabled -> Disabled.
    Disarm,
    /// Fault -> Disabled once the cause is gone.
    Reset,
    /// Follow the configured path (while enabled).
    StartPath,
}

/// What produces the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Motion<R> {
    /// Hold a point.
    Hold(Vec3<R>),
    /// Follow the path: `k` periods since it started, shifted by `origin`.
    Path { k: u32, origin: Option<Vec3<R>> },
}

/// The servo step's state, owned by the control interrupt.
pub struct Servo<R> {
    period_s: f64,
    dt: R,
    counters: [WideCounter; AXES],
    count_len: [f64; AXES],
    full_scale: Vec3<R>,
    estimators: EstimatorBank<R>,
    controller: Controller3<R>,
    safety: SafetyMonitor,
    path: Option<(Trajectory<R>, PathStart, Option<u32>)>,
    motion: Motion<R>,
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
        for i in 0..AXES {
            count_len[i] = cfg.encoders[i].count_len()?;
            timing[i].count_size = count_len[i] as f32;
            full_scale[i] = R::from_f32(cfg.amplifiers[i].checked_full_scale()?);
            limit(cfg.following_error_mm[i], "following_error_mm")?;
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
                Some((p.path.build()?.cast(), p.start, duration))
            }
            None => None,
        };
        let counters =
            [0, 1, 2].map(|i| WideCounter::new(cfg.encoders[i].counter, raw[i], start_counts[i]));
        Ok(Self {
            period_s,
            dt: R::from_f64(period_s),
            counters,
            count_len,
            full_scale,
            estimators: EstimatorBank::new(&cfg.estimator, &timing, count_len, start_counts)?,
            controller: Controller3::new(&cfg.controller)?,
            safety: SafetyMonitor::new(cfg.following_error_mm),
            path,
            motion: Motion::Hold(Vec3::zero()),
            snapshot: Snapshot::boot(),
        })
    }

    /// The latest snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        &self.snapshot
    }

    /// Safety state.
    pub fn state(&self) -> SafetyState {
        self.safety.state()
    }

    /// The controller (e.g. to read the adaptive estimates).
    pub fn controller(&self) -> &Controller3<R> {
        &self.controller
    }

    /// Control period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    fn position_of(&self, counts: &[i64; AXES]) -> Vec3<R> {
        let mut p = Vec3::zero();
        for i in 0..AXES {
            p[i] = R::from_f64(counts[i] as f64 * self.count_len[i]);
        }
        p
    }

    /// The reference of this period, and the path time.
    fn reference(&self) -> (RefSample<R>, f64) {
        let hold = |pos| {
            let r = RefSample {
                pos,
                vel: Vec3::zero(),
                acc: Vec3::zero(),
            };
            (r, 0.0)
        };
        let (k, origin, traj, end) = match (self.motion, &self.path) {
            (Motion::Hold(p), _) => return hold(p),
            (Motion::Path { .. }, None) => return hold(Vec3::zero()),
            (Motion::Path { k, origin }, Some((traj, _, end))) => (k, origin, traj, *end),
        };
        // after the path's duration its point at that time is held
        let held_at = end.filter(|e| k > *e);
        let t = f64::from(held_at.unwrap_or(k)) * self.period_s;
        let mut r = traj.sample(R::from_f64(t));
        if held_at.is_some() {
            r.vel = Vec3::zero();
            r.acc = Vec3::zero();
        }
        if let Some(o) = origin {
            r.pos = r.pos + o;
        }
        (r, f64::from(k) * self.period_s)
    }

    /// One control period. See the module documentation for the sequence.
    pub fn period<IO: ServoIo<R>>(&mut self, io: &mut IO, commands: &[Command]) -> &Snapshot {
        // 1. Safety first: decide before reading or computing anything else.
        let inputs = io.read_inputs();
        let mut request = Request::None;
        let mut start_path = false;
        for c in commands {
            match c {
                Command::Arm | Command::Reset => request = Request::ArmOrReset,
                Command::Disarm => request = Request::Disarm,
                Command::StartPath => start_path = true,
            }
        }
        let was_enabled = self.safety.outputs_enabled();
        let mut state = self.safety.update(&inputs, request);
        if state != SafetyState::Enabled {
            io.disable_outputs();
        }

        // 2. Wide counts.
        let raw = io.read_counters();
        let mut counts = [0i64; AXES];
        for ((n, c), r) in counts.iter_mut().zip(self.counters.iter_mut()).zip(raw) {
            *n = c.update(r);
        }

        // 3. Reference: a fresh start of every state when the outputs get enabled, which
        //    then hold the position they are at.
        let enabled = state == SafetyState::Enabled;
        if enabled && !was_enabled {
            self.estimators.reset(counts);
            self.controller.reset();
            self.motion = Motion::Hold(self.position_of(&counts));
        }
        if enabled && start_path {
            if let Some((traj, start, _)) = &self.path {
                let origin = match start {
                    PathStart::Absolute => None,
                    PathStart::FromCurrentPosition => {
                        Some(self.position_of(&counts) - traj.sample(R::ZERO).pos)
                    }
                };
                self.motion = Motion::Path { k: 0, origin };
            }
        }
        let (reference, path_t) = if enabled {
            self.reference()
        } else {
            (RefSample::default(), 0.0)
        };

        // 4. Positions and velocities.
        let meas: Measured<R> = self
            .estimators
            .update(counts, reference.acc, io.true_velocity());

        // 5. Control.
        let mut applied = Vec3::zero();
        let mut snap_out = None;
        if enabled {
            let out = self.controller.evaluate(&reference, &meas);
            let mut u = out.u;
            for i in 0..AXES {
                u[i] = u[i].finite_or_zero().clamp_sym(self.full_scale[i]);
            }
            let tracking = out.errors.tracking.to_array().map(Real::to_f32);
            state = self.safety.check_following_error(&tracking);
            if state == SafetyState::Enabled {
                io.write_outputs(&u.to_array());
                applied = u;
            } else {
                io.disable_outputs();
            }
            self.controller
                .commit(&out, &reference, &meas, applied, self.dt);
            if let Motion::Path { k, .. } = &mut self.motion {
                *k = k.saturating_add(1);
            }
            snap_out = Some(out);
        }
        self.estimators.applied(applied);

        // 6. Telemetry (plain copies).
        let s = &mut self.snapshot;
        s.period = s.period.wrapping_add(1);
        s.path_t_s = path_t as f32;
        s.state = state;
        s.pos = meas.pos.to_array().map(Real::to_f32);
        s.vel = meas.vel.to_array().map(Real::to_f32);
        s.counts = counts;
        s.effort = applied.to_array().map(Real::to_f32);
        match snap_out {
            Some(out) => {
                s.reference = reference.pos.to_array().map(Real::to_f32);
                s.tracking = out.errors.tracking.to_array().map(Real::to_f32);
                s.contour = out.errors.contour.to_array().map(Real::to_f32);
                s.s = out.s.to_array().map(Real::to_f32);
            }
            None => {
                s.tracking = [0.0; AXES];
                s.contour = [0.0; AXES];
                s.s = [0.0; AXES];
            }
        }
        &self.snapshot
    }
}
