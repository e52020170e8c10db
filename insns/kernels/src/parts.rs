//! The parts of the control period as separate kernels (`servo_part_*`): each runs one
//! block of [`Servo::period`] on its own, built from the board's configuration exactly as
//! `Servo::new` builds it and driven with the values the whole period sees at the counted
//! instant (taken from a run of the board's servo on the stub, see [`BoardRun`]).
//!
//! A part measured on its own pays its own call and state loads, and the compiler cannot
//! share work with its neighbours: the parts do not add up to `servo_period` exactly.
//! `cargo insns parts` attributes the instructions of the real `servo_period` to the same
//! parts instead (exact sum); docs/performance.md shows both.

use crate::{kernel_servo_config, StubIo, SERVO_SETUP_PERIODS};
use controller_core::axes::AXES;
use controller_core::controller::{ControlOutput, Controller3, ControllerConfig, Measured};
use controller_core::coupling::contour::{cross_couple, Coupled};
use controller_core::coupling::CouplingConfig;
use controller_core::estimator::{EstimatorBank, EstimatorTiming, WideCounter};
use controller_core::motion::reference::{self, Clock, ReferenceMode};
use controller_core::motion::trajectory::{RefSample, Trajectory};
use controller_core::servo::io::ServoIo;
use controller_core::servo::monitor::Monitor;
use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::{Command, Servo, ServoConfig};
use controller_core::Vec3;

/// Snapshots kept from the end of the board run: the counted period's inputs and the
/// periods before it (the encoder checks need two earlier readings).
const KEPT: usize = 3;

/// The board's servo on the stub, followed as in the `servo_period` kernel's setup: the
/// snapshots of its last [`KEPT`] periods, the last one being the counted period.
pub struct BoardRun {
    cfg: ServoConfig,
    snaps: [Snapshot; KEPT],
    /// The path origin `StartPath` set (the arm position minus the path's start).
    origin: Vec3<f32>,
}

impl BoardRun {
    /// Arms, starts the path and runs `SERVO_SETUP_PERIODS + 1` periods (the last is the
    /// one the `servo_period` kernel counts).
    pub fn record() -> Option<Self> {
        let cfg = kernel_servo_config();
        let mut io = StubIo::new()?;
        let raw = io.boot_registers();
        let mut servo = Servo::<f32>::new(&cfg, raw, [0; AXES]).ok()?;
        let mut snaps = [*servo.snapshot(); KEPT];
        for k in 0..=SERVO_SETUP_PERIODS {
            let cmds: &[Command] = if k == 0 {
                &[Command::Arm, Command::StartPath]
            } else {
                &[]
            };
            let s = *servo.period(&mut io, cmds);
            snaps.rotate_left(1);
            snaps[KEPT - 1] = s;
        }
        let traj = cfg.path?.path.build().ok()?;
        let p0 = traj.sample(0.0).pos;
        // the arm position is wide count 0 on every axis (the stub's boot registers)
        let origin = Vec3::new(-p0.x as f32, -p0.y as f32, -p0.z as f32);
        Some(Self { cfg, snaps, origin })
    }

    /// The counted period's snapshot.
    fn now(&self) -> &Snapshot {
        &self.snaps[KEPT - 1]
    }

    /// Periods since the path started at the counted period.
    fn path_k(&self) -> u32 {
        SERVO_SETUP_PERIODS as u32
    }

    fn period_s(&self) -> f64 {
        1.0 / f64::from(self.cfg.rate_hz)
    }

    fn motion(&self) -> ReferenceMode<f32> {
        ReferenceMode::Path {
            k: self.path_k(),
            origin: Some(self.origin),
        }
    }

    fn path(&self) -> Option<(Trajectory<f32>, Option<u32>)> {
        let p = self.cfg.path?;
        let end = p
            .duration_s
            .map(|d| libm::round(d / self.period_s()) as u32);
        Some((p.path.build().ok()?.cast(), end))
    }

    /// The counted period's reference, as `Servo::period` samples it.
    fn reference(&self) -> Option<RefSample<f32>> {
        let path = self.path()?;
        let clock = Clock::new(self.cfg.rate_hz);
        Some(reference::sample(&self.motion(), Some(&path), &clock).0)
    }

    fn measured(&self) -> Measured<f32> {
        let s = self.now();
        Measured {
            pos: Vec3::from_array(s.pos),
            vel: Vec3::from_array(s.vel),
        }
    }

    /// The board's laws without coupling (the coupling is its own part).
    fn laws_only(&self) -> ControllerConfig {
        ControllerConfig {
            coupling: CouplingConfig::None,
            ..self.cfg.controller
        }
    }
}

/// `servo_part_estimators`: step 2 and 4 of the period: the counters' wrap extension and
/// the estimator bank (positions from counts, the PLL velocity of every axis).
pub struct PartEstimators {
    counters: [WideCounter; AXES],
    bank: EstimatorBank<f32>,
    io: StubIo,
    acc: Vec3<f32>,
}

impl PartEstimators {
    /// Built as `Servo::new` builds them, then fed the stub's registers for the setup
    /// periods (with the efforts the servo applied).
    pub fn setup() -> Option<Self> {
        let run = BoardRun::record()?;
        let cfg = &run.cfg;
        let mut io = StubIo::new()?;
        let raw = io.boot_registers();
        let period_s = run.period_s();
        let mut count_len = [0.0; AXES];
        let mut timing = [EstimatorTiming {
            period_s: period_s as f32,
            count_size: 0.0,
        }; AXES];
        for i in 0..AXES {
            count_len[i] = cfg.encoders[i].count_len().ok()?;
            timing[i].count_size = count_len[i] as f32;
        }
        let counters = [0, 1, 2].map(|i| WideCounter::new(cfg.encoders[i].counter, raw[i], 0));
        let bank = EstimatorBank::new(&cfg.estimator, &timing, count_len, [0; AXES]).ok()?;
        let mut k = Self {
            counters,
            bank,
            io,
            acc: run.reference()?.acc,
        };
        for _ in 0..SERVO_SETUP_PERIODS {
            k.step();
            k.bank.applied(Vec3::from_array(run.now().effort));
        }
        Some(k)
    }

    /// Read the counters, extend them, update the three estimators.
    #[inline(never)]
    pub fn step(&mut self) -> Measured<f32> {
        let raw = self.io.read_counters();
        let mut counts = [0i64; AXES];
        for ((n, c), r) in counts.iter_mut().zip(self.counters.iter_mut()).zip(raw) {
            *n = c.update(r);
        }
        self.bank.update(counts, self.acc, None)
    }
}

/// `servo_part_reference`: step 3, the reference of the board's path at the counted period
/// (`reference::sample`: clock, helix with sin/cos, origin shift, hold check).
pub struct PartReference {
    motion: ReferenceMode<f32>,
    path: (Trajectory<f32>, Option<u32>),
    clock: Clock<f32>,
}

impl PartReference {
    pub fn setup() -> Option<Self> {
        let run = BoardRun::record()?;
        Some(Self {
            motion: run.motion(),
            path: run.path()?,
            clock: Clock::new(run.cfg.rate_hz),
        })
    }

    #[inline(never)]
    pub fn step(&mut self) -> RefSample<f32> {
        reference::sample(&self.motion, Some(&self.path), &self.clock).0
    }
}

/// `servo_part_coupling`: the contour error and the coupled errors of the board's contour
/// coupling (λ = 1) at the counted period.
pub struct PartCoupling {
    tracking: Vec3<f32>,
    rate: Vec3<f32>,
    dir: Vec3<f32>,
    lambda: f32,
    min_dir_sq: f32,
}

impl PartCoupling {
    pub fn setup() -> Option<Self> {
        let run = BoardRun::record()?;
        let r = run.reference()?;
        let m = run.measured();
        let CouplingConfig::Contour(c) = run.cfg.controller.coupling else {
            return None;
        };
        Some(Self {
            tracking: r.pos - m.pos,
            rate: r.vel - m.vel,
            dir: r.vel,
            lambda: c.lambda,
            min_dir_sq: c.min_direction_norm_sq,
        })
    }

    #[inline(never)]
    pub fn step(&mut self) -> Coupled<f32> {
        cross_couple(
            self.tracking,
            self.rate,
            self.dir,
            self.dir,
            self.lambda,
            self.min_dir_sq,
        )
    }
}

/// `servo_part_laws`: the board's three laws (DSMC per axis) evaluated in place and
/// committed, as `Controller3` runs them, without the coupling.
pub struct PartLaws {
    controller: Controller3<f32>,
    reference: RefSample<f32>,
    meas: Measured<f32>,
    dt: f32,
    out: ControlOutput<f32>,
}

impl PartLaws {
    pub fn setup() -> Option<Self> {
        let run = BoardRun::record()?;
        let mut k = Self {
            controller: Controller3::new(&run.laws_only()).ok()?,
            reference: run.reference()?,
            meas: run.measured(),
            dt: run.period_s() as f32,
            out: ControlOutput::default(),
        };
        k.step();
        Some(k)
    }

    #[inline(never)]
    pub fn step(&mut self) -> Vec3<f32> {
        self.controller
            .step_into(&self.reference, &self.meas, self.dt, &mut self.out);
        self.out.u
    }
}

/// The count steps between two snapshots.
fn steps(now: &[i64; AXES], before: &[i64; AXES]) -> [i32; AXES] {
    [0, 1, 2].map(|i| now[i].wrapping_sub(before[i]) as i32)
}

/// `servo_part_checks`: the supervisor's per-period checks on the board's thresholds:
/// encoder jump/stuck/runaway, deadline overrun, following error and overspeed, and the
/// controller's state health.
pub struct PartChecks {
    monitor: Monitor,
    controller: Controller3<f32>,
    /// The counted period's count steps (what the servo's counters report).
    steps: [i32; AXES],
    now: Snapshot,
    prev_effort: [f32; AXES],
    v_ref: [f32; AXES],
}

impl PartChecks {
    /// The monitor primed with the two periods before the counted one.
    pub fn setup() -> Option<Self> {
        let run = BoardRun::record()?;
        let cfg = &run.cfg;
        let counts_per_mm = cfg.encoders.map(|e| e.counts_per_mm);
        let full_scale = cfg.amplifiers.map(|a| a.full_scale);
        let mut monitor =
            Monitor::new(&cfg.safety, counts_per_mm, full_scale, run.period_s()).ok()?;
        let [s0, s1, _] = &run.snaps;
        monitor.check_encoders(&steps(&s0.counts, &s0.counts), &s0.vel, &s0.effort);
        monitor.check_encoders(&steps(&s1.counts, &s0.counts), &s1.vel, &s0.effort);
        Some(Self {
            monitor,
            controller: Controller3::new(&cfg.controller).ok()?,
            steps: steps(&run.now().counts, &s1.counts),
            now: *run.now(),
            prev_effort: s1.effort,
            v_ref: run.reference()?.vel.to_array(),
        })
    }

    #[inline(never)]
    pub fn step(&mut self) -> bool {
        let s = &self.now;
        let a = self
            .monitor
            .check_encoders(&self.steps, &s.vel, &self.prev_effort);
        let b = self.monitor.check_overrun(false, s.period);
        let c = self
            .monitor
            .check_tracking(&s.tracking, &self.v_ref, &s.vel, 1.0);
        let d = self.controller.unhealthy_axis();
        a.is_some() || b.is_some() || c.is_some() || d.is_some()
    }
}
