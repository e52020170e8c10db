//! The per-period control sequence run by the control interrupt.
//!
//! [`ControlLoop::step`] is the whole body of the highest-priority task. In order:
//!
//! 1. sample e-stop and limits and update the safety state machine; if the outputs may
//!    not be driven, switch them off *before anything else* (same control period);
//! 2. read the encoder counters and extend them to wide counts (controller-core's
//!    [`WideCounter`]: the signed difference of successive readings modulo the counter
//!    width, so an overflow between two readings can neither be lost nor double counted;
//!    there is no overflow interrupt that could race with the read);
//! 3. convert counts to positions and estimate velocities (controller-core's
//!    [`Estimators3`], fed back with the output applied in the previous period);
//! 4. if enabled: sample the trajectory, run controller-core's 3-axis step (tracking
//!    error, contour error, cross-coupling, one law per axis, saturation), check the
//!    following error, and write the outputs, or switch them off on a trip;
//! 5. update the run figures (controller-core metrics) and the telemetry snapshot (plain
//!    copies, no formatting).
//!
//! The caller then calls [`GantryIo::period_end`] (which advances the simulated plant in
//! the QEMU build), outside the measured control time.
//!
//! All control mathematics is controller-core's; this module only sequences it. Nothing
//! here allocates, blocks, panics on data, or logs.

use controller_core::estimator::{
    CounterWidth, EstimatorConfig, EstimatorTiming, Estimators3, WideCounter,
};
use controller_core::gantry::{Gantry3, GantryConfig};
use controller_core::params::{ConfigError, PlantParams};
use controller_core::trajectory::{RefSample, Trajectory};
use controller_core::Vec3;

use crate::io::GantryIo;
use crate::safety::{Axis, FaultReason, Request, SafetyMonitor, SafetyState};
use crate::telemetry::{RunMetrics, Snapshot};
use crate::AXES;

/// Encoder counter widths of the board: TIM2 and TIM5 are 32-bit, TIM3 16-bit.
pub const COUNTER_WIDTHS: [CounterWidth; AXES] = [
    CounterWidth::Bits32,
    CounterWidth::Bits32,
    CounterWidth::Bits16,
];

/// Where the reference path is when the outputs get enabled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathPlan {
    /// The trajectory as given, in absolute machine coordinates (the QEMU scenario: the
    /// plant starts at rest at the origin, as in the paper).
    Absolute(Trajectory<f32>),
    /// A helix `x = r sin ωt, y = r cos ωt, z = z_rate t` translated so that it starts at
    /// the position measured when the outputs are enabled (no step on arming).
    HelixFromArmPosition {
        radius: f32,
        omega: f32,
        z_rate: f32,
    },
}

/// Everything the loop needs to know, fixed at build time (see `config`, `scenario`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopConfig {
    /// Law per axis, cross-coupling gain, contour direction source.
    pub gantry: GantryConfig,
    /// Velocity estimator per axis.
    pub estimator: [EstimatorConfig; AXES],
    /// Axis model giving the commanded acceleration to the estimators that use it
    /// (Kalman); `None`: not used.
    pub accel_model: [Option<PlantParams>; AXES],
    /// Control rate, Hz. The trajectory time is `k / rate` evaluated in `f64` and rounded
    /// once to `f32`: exact for any run length (an `f32` period count would lose whole
    /// periods after 2^24 of them, 28 min at 10 kHz) and identical to host-sim's.
    pub rate_hz: u32,
    /// Length of one encoder count in plant units (mm on the machine). Positions are
    /// `count × length` evaluated in `f64` and rounded once to `f32`, as host-sim does.
    pub length_per_count: f64,
    /// Period and count size as the velocity estimators see them.
    pub timing: EstimatorTiming,
    /// Reference path.
    pub path: PathPlan,
    /// Trip when |reference - measured| exceeds this, per axis.
    pub following_error_limit: [f32; AXES],
    /// Finite run: after this much trajectory time the loop disarms and reports
    /// `finished` (the QEMU scenario). `None` = continuous operation.
    pub horizon_s: Option<f32>,
    /// In continuous operation the path is followed for this long, then its end point
    /// is held.
    pub path_duration_s: f32,
}

/// The control loop state owned by the control interrupt.
pub struct ControlLoop {
    cfg: LoopConfig,
    period_s: f32,
    period_s_f64: f64,
    gantry: Gantry3<f32>,
    counters: [WideCounter; AXES],
    estimators: Estimators3<f32>,
    trajectory: Trajectory<f32>,
    safety: SafetyMonitor,
    /// Periods since the outputs were enabled.
    traj_periods: u32,
    metrics: RunMetrics,
    snapshot: Snapshot,
}

impl ControlLoop {
    /// Validates the configuration (controller-core rejects bad gains and unstable
    /// estimator tunings). `raw_counts` are the encoder registers at start-up: they define
    /// position zero.
    pub fn new(cfg: LoopConfig, raw_counts: [u32; AXES]) -> Result<Self, ConfigError> {
        let counters = [0, 1, 2].map(|i| WideCounter::new(COUNTER_WIDTHS[i], raw_counts[i], 0));
        let estimators =
            Estimators3::new(&cfg.estimator, &cfg.accel_model, &cfg.timing, [0; AXES])?;
        let trajectory = match cfg.path {
            PathPlan::Absolute(t) => t,
            PathPlan::HelixFromArmPosition {
                radius,
                omega,
                z_rate,
            } => helix_from(Vec3::zero(), radius, omega, z_rate),
        };
        Ok(Self {
            period_s: cfg.timing.period_s,
            period_s_f64: 1.0 / f64::from(cfg.rate_hz.max(1)),
            gantry: Gantry3::new(&cfg.gantry)?,
            counters,
            estimators,
            trajectory,
            safety: SafetyMonitor::new(cfg.following_error_limit),
            traj_periods: 0,
            metrics: RunMetrics::default(),
            snapshot: Snapshot::boot(),
            cfg,
        })
    }

    /// Latest snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        &self.snapshot
    }

    /// Safety state.
    pub fn state(&self) -> SafetyState {
        self.safety.state()
    }

    /// Records the interrupt's timing in the snapshot (called by the task after `step`).
    pub fn record_timing(&mut self, cycles: u32, overran: bool) {
        let t = &mut self.snapshot.timing;
        t.last_cycles = cycles;
        t.max_cycles = t.max_cycles.max(cycles);
        if overran {
            t.overruns = t.overruns.saturating_add(1);
        }
    }

    /// One control period. See the module documentation for the sequence.
    pub fn step<IO: GantryIo>(&mut self, io: &mut IO) -> &Snapshot {
        // 1. Safety first: decide before reading or computing anything else.
        let inputs = io.read_safety_inputs();
        let mut request = io.read_request();
        if self.horizon_reached() {
            request = Request::Disarm;
        }
        let was_enabled = self.safety.outputs_enabled();
        let mut state = self.safety.update(&inputs, request);
        if state != SafetyState::Enabled {
            io.disable_outputs();
        }

        // 2. Wide counts.
        let raw = io.read_encoder_raw();
        let mut counts = [0i64; AXES];
        for ((n, c), r) in counts.iter_mut().zip(self.counters.iter_mut()).zip(raw) {
            *n = c.update(r);
        }

        // 3. Positions and velocities (a fresh estimator start when the outputs get
        //    enabled).
        let enabling = state == SafetyState::Enabled && !was_enabled;
        if enabling {
            self.estimators.reset(counts);
        }
        let mut meas = self.estimators.update(counts);
        for (p, n) in counts.iter().enumerate() {
            meas.pos[p] = (*n as f64 * self.cfg.length_per_count) as f32;
        }

        // 4. Control.
        let mut effort = [0.0; AXES];
        let mut tracking = [0.0; AXES];
        let mut contour = 0.0;
        let mut reference = self.snapshot.reference;
        if state == SafetyState::Enabled {
            if enabling {
                self.on_enable(meas.pos);
            }
            let t_s = self.traj_time_s();
            let r = self.reference_at(t_s);
            let out = self.gantry.step(&r, &meas, self.period_s);
            tracking = out.errors.tracking.to_array();
            state = self.safety.check_following_error(&tracking);
            for (axis, u) in Axis::ALL.iter().zip(out.u.to_array()) {
                if !u.is_finite() {
                    self.safety
                        .trip(FaultReason::NonFiniteCommand { axis: *axis });
                    state = self.safety.state();
                }
            }
            if state == SafetyState::Enabled {
                effort = out.u.to_array();
                io.drive(&effort);
            } else {
                io.disable_outputs();
            }
            self.estimators.applied(Vec3::from_array(effort));
            contour = out.errors.contour.norm();
            reference = r.pos.to_array();
            self.metrics
                .add(t_s, self.period_s, &tracking, contour, &effort);
            self.traj_periods = self.traj_periods.saturating_add(1);
        } else {
            self.estimators.applied(Vec3::zero());
        }

        // 5. Telemetry (plain copies).
        let finished = self.horizon_reached();
        let traj_t_s = self.traj_time_s();
        let s = &mut self.snapshot;
        s.period = s.period.wrapping_add(1);
        s.traj_t_s = traj_t_s;
        s.state = state;
        s.pos = meas.pos.to_array();
        s.reference = reference;
        s.tracking = tracking;
        s.contour = contour;
        s.effort = effort;
        s.counts = counts;
        s.metrics = self.metrics;
        s.finished = finished;
        &self.snapshot
    }

    /// Trajectory time of the current period, seconds.
    fn traj_time_s(&self) -> f32 {
        (f64::from(self.traj_periods) * self.period_s_f64) as f32
    }

    fn horizon_reached(&self) -> bool {
        match self.cfg.horizon_s {
            Some(h) => self.traj_time_s() >= h,
            None => false,
        }
    }

    /// Fresh start of the path and of every integrator when the outputs get enabled.
    fn on_enable(&mut self, pos: Vec3<f32>) {
        self.gantry.reset();
        self.traj_periods = 0;
        self.metrics = RunMetrics::default();
        if let PathPlan::HelixFromArmPosition {
            radius,
            omega,
            z_rate,
        } = self.cfg.path
        {
            self.trajectory = helix_from(pos, radius, omega, z_rate);
        }
    }

    /// The path, or in continuous operation after `path_duration_s`, its end point held.
    fn reference_at(&self, t_s: f32) -> RefSample<f32> {
        if self.cfg.horizon_s.is_none() && t_s > self.cfg.path_duration_s {
            let end = self.trajectory.sample(self.cfg.path_duration_s).pos;
            Trajectory::Step {
                target: end,
                t0: 0.0,
            }
            .sample(t_s)
        } else {
            self.trajectory.sample(t_s)
        }
    }
}

/// The helix whose start point (t = 0: `center + (0, r, 0)`) is `start`.
fn helix_from(start: Vec3<f32>, radius: f32, omega: f32, z_rate: f32) -> Trajectory<f32> {
    Trajectory::Helix {
        center: Vec3::new(start.x, start.y - radius, start.z),
        radius,
        omega,
        z_rate,
    }
}
