//! Cost kernels of the control period and the bit-exactness replay, generic over
//! controller-core's [`Real`].
//!
//! A *kernel* is a state built once (`setup`, not counted) and a step run on it (counted).
//! The thumb binary (`src/bin/kernels.rs`) exports every kernel as the C symbols
//! `insns_setup_<name>` / `insns_kernel_<name>`; `insns/count.py` finds them by that prefix
//! and prints `<name> instructions=<N> cycles_est=<M>`. See `insns/README.md` for adding one.
//!
//! - [`Dsmc3`]: the paper's helix sample + [`Controller3::step`] with the paper's DSMC
//!   and its contour coupling, in every number type;
//! - [`Law3`]: one 3-axis controller step with one law on every axis, no coupling;
//! - [`Estimator3`]: the estimator bank as the servo step runs it;
//! - [`ServoPeriod`]: the whole control period as the board's interrupt runs it
//!   ([`Servo::period`] with the board's configuration, `presets::board`);
//! - [`parts`]: the blocks of that period one by one (`servo_part_*`);
//! - [`filters`]: the three axes' output filters (notches, a low-pass) for one period;
//! - [`machine_period`]: the core's whole control period behind the link
//!   (`Machine::linked_period` of the board's machine, `machine_period_*`);
//! - [`shaper`]: the input shaper on three axes (`shaper3_f32`).
#![no_std]

pub mod filters;
pub mod link;
pub mod machine_period;
pub mod parts;
pub mod plan_task;
pub mod planner;
pub mod shaper;

use controller_core::axes::AXES;
use controller_core::controller::{ControlOutput, Controller3, ControllerConfig, Measured};
use controller_core::coupling::CouplingConfig;
use controller_core::estimator::{
    AccelInput, CounterWidth, EstimatorBank, EstimatorBankConfig, EstimatorConfig, EstimatorTiming,
};
use controller_core::law::LawConfig;
use controller_core::motion::trajectory::{RefSample, Trajectory};
use controller_core::num::fixed::{FxQ16, FxQ32};
use controller_core::presets::board::{servo_config, BOARD_PATH, BOARD_RATE_HZ};
use controller_core::presets::gantry::{adaptive_for, dob_smc_for, GANTRY_X, GANTRY_Y, GANTRY_Z};
use controller_core::presets::paper::{PAPER_DSMC, PAPER_LAMBDA, PAPER_PID, PAPER_PLANT};
use controller_core::servo::io::{Inputs, ServoIo};
use controller_core::servo::ServoState;
use controller_core::servo::{Command, Servo, ServoConfig};
use controller_core::{LibmF32, Real, Vec3};

/// Control period of the controller and estimator kernels: the firmware's 20 kHz rate.
pub const KERNEL_PERIOD_S: f32 = 5.0e-5;

/// Time of the measured sample: far enough into the helix that `sin`/`cos` take their
/// argument-reduction path (17.3 rad > π/4), as they do for all but the first 0.8 s.
pub const WORST_CASE_T_S: f32 = 17.3;

/// Tracking error `q_d - q` fed to the kernels (plant units): non-zero and of different
/// size on every axis so no power takes its `0^e` shortcut, and above the singular floor
/// (1e-4) so `|e|^(-4/9)` is evaluated on the error itself.
pub const WORST_CASE_ERROR: [f32; 3] = [2.0e-3, -1.5e-3, 3.0e-3];

/// Tracking-rate error `q_d' - q'` fed to the kernels.
pub const WORST_CASE_RATE_ERROR: [f32; 3] = [5.0e-2, -3.0e-2, 8.0e-2];

/// The paper's DSMC on all three axes with its cross-coupling gain (Table 2, λ = 0.01).
pub fn paper_dsmc_config() -> ControllerConfig {
    ControllerConfig::uniform(LawConfig::Smc(PAPER_DSMC), PAPER_LAMBDA)
}

fn vec3<R: Real>(v: [f32; 3]) -> Vec3<R> {
    Vec3::new(R::from_f32(v[0]), R::from_f32(v[1]), R::from_f32(v[2]))
}

/// The measurement that leaves the worst-case errors on reference `r`.
fn measured_off<R: Real>(r: &RefSample<R>) -> Measured<R> {
    Measured {
        pos: r.pos - vec3(WORST_CASE_ERROR),
        vel: r.vel - vec3(WORST_CASE_RATE_ERROR),
    }
}

/// State of one DSMC kernel.
pub struct Dsmc3<R> {
    controller: Controller3<R>,
    traj: Trajectory<R>,
    t: R,
    dt: R,
    meas: Measured<R>,
    out: ControlOutput<R>,
}

impl<R: Real> Dsmc3<R> {
    /// Paper helix and DSMC; the measurement is the reference at [`WORST_CASE_T_S`] minus
    /// the worst-case errors. One step is run so every state (integrals, previous
    /// reference) is populated as in steady operation.
    pub fn setup() -> Option<Self> {
        let controller = Controller3::new(&paper_dsmc_config()).ok()?;
        let traj = Trajectory::paper_helix();
        let t = R::from_f32(WORST_CASE_T_S);
        let meas = measured_off(&traj.sample(t));
        let mut k = Self {
            controller,
            traj,
            t,
            dt: R::from_f32(KERNEL_PERIOD_S),
            meas,
            out: ControlOutput::default(),
        };
        k.step();
        Some(k)
    }

    /// One 3-axis control step: trajectory sample + `Controller3::step` (evaluated in
    /// place, as the servo step does); returns the outputs.
    #[inline(never)]
    pub fn step(&mut self) -> Vec3<R> {
        let r = self.traj.sample(self.t);
        self.controller
            .step_into(&r, &self.meas, self.dt, &mut self.out);
        self.out.u
    }
}

/// Which law a [`Law3`] kernel runs on every axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LawKind {
    /// The paper's PID (Table 2).
    Pid,
    /// The paper's DSMC (Table 2).
    Dsmc,
    /// DOB-SMC tuned for the gantry's X, Y, Z axes (`presets::gantry::dob_smc_for`).
    DobSmc,
    /// Adaptive friction SMC tuned for the gantry's axes (`presets::gantry::adaptive_for`).
    AdaptiveSmc,
}

impl LawKind {
    /// The controller: this law on every axis, no coupling.
    pub fn config(self) -> ControllerConfig {
        let axes = [GANTRY_X, GANTRY_Y, GANTRY_Z];
        let laws = match self {
            Self::Pid => [LawConfig::Pid(PAPER_PID); AXES],
            Self::Dsmc => [LawConfig::Smc(PAPER_DSMC); AXES],
            Self::DobSmc => axes.map(|a| LawConfig::DobSmc(dob_smc_for(&a))),
            Self::AdaptiveSmc => axes.map(|a| LawConfig::AdaptiveSmc(adaptive_for(&a))),
        };
        ControllerConfig {
            laws,
            coupling: CouplingConfig::None,
        }
    }
}

/// The reference of the law kernels: the contouring scenarios' 20 mm circle at 50 mm/s
/// (with a 5 mm/s rise on Z) at [`WORST_CASE_T_S`]: every position, velocity and
/// acceleration non-zero.
pub fn law_reference<R: Real>() -> RefSample<R> {
    let traj = Trajectory::Helix {
        center: Vec3::new(R::ZERO, R::from_f32(-20.0), R::ZERO),
        radius: R::from_f32(20.0),
        omega: R::from_f32(2.5),
        z_rate: R::from_f32(5.0),
    };
    traj.sample(R::from_f32(WORST_CASE_T_S))
}

/// State of one law kernel: one 3-axis controller step with the same law on every axis.
pub struct Law3<R> {
    controller: Controller3<R>,
    reference: RefSample<R>,
    meas: Measured<R>,
    dt: R,
    out: ControlOutput<R>,
}

impl<R: Real> Law3<R> {
    /// The law on every axis; the measurement is [`law_reference`] minus the worst-case
    /// errors: every law works off its boundary layers' edges, the adaptive law outside
    /// its dead zone (it adapts). Two steps are run so the observer and the estimates are
    /// in operation.
    pub fn setup(kind: LawKind) -> Option<Self> {
        let controller = Controller3::new(&kind.config()).ok()?;
        let reference = law_reference();
        let mut k = Self {
            controller,
            meas: measured_off(&reference),
            reference,
            dt: R::from_f32(KERNEL_PERIOD_S),
            out: ControlOutput::default(),
        };
        k.step();
        k.step();
        Some(k)
    }

    /// One step: `Controller3::step` (evaluate every law in place, commit every state);
    /// returns the outputs.
    #[inline(never)]
    pub fn step(&mut self) -> Vec3<R> {
        self.controller
            .step_into(&self.reference, &self.meas, self.dt, &mut self.out);
        self.out.u
    }
}

/// Wide encoder counts of the estimator kernels' axes: different on every axis, one of
/// them far from the origin, as after long travel.
pub const ESTIMATOR_COUNTS: [i64; 3] = [12_345, -6_789, 50_000_000];

/// Count increments per period of the estimator kernels (a moving axis).
pub const ESTIMATOR_STEP_COUNTS: [i64; 3] = [3, -2, 5];

/// State of one estimator kernel: the three axes' velocity estimators exactly as the
/// servo step runs them ([`EstimatorBank`]: wide counts in, positions and velocities out,
/// the applied output fed back for the Kalman filter's commanded acceleration).
pub struct Estimator3<R> {
    bank: EstimatorBank<R>,
    counts: [i64; 3],
    u: Vec3<R>,
}

impl<R: Real> Estimator3<R> {
    /// `cfg` on all three axes with the paper plant as the acceleration model, at
    /// [`KERNEL_PERIOD_S`] and 1e-4-unit counts; one update is run so the state is
    /// populated.
    pub fn setup(cfg: EstimatorConfig) -> Option<Self> {
        let timing = EstimatorTiming {
            period_s: KERNEL_PERIOD_S,
            count_size: 1e-4,
        };
        let bank_cfg = EstimatorBankConfig {
            axes: [cfg; 3],
            accel_input: AccelInput::Model([PAPER_PLANT; 3]),
        };
        let bank = EstimatorBank::new(&bank_cfg, &[timing; 3], [1e-4; 3], ESTIMATOR_COUNTS).ok()?;
        let mut k = Self {
            bank,
            counts: ESTIMATOR_COUNTS,
            u: Vec3::new(R::from_f32(120.0), R::from_f32(-80.0), R::from_f32(40.0)),
        };
        k.step();
        Some(k)
    }

    /// One period on three axes: advance the counts, update, feed back the output.
    #[inline(never)]
    pub fn step(&mut self) -> Measured<R> {
        for (c, d) in self.counts.iter_mut().zip(ESTIMATOR_STEP_COUNTS) {
            *c += d;
        }
        let m = self.bank.update(self.counts, Vec3::zero(), None);
        self.bank.applied(self.u);
        m
    }
}

/// Periods the uncounted setup of [`ServoPeriod`] runs (arm, start the path, follow it):
/// long enough for the PLL (100 Hz) to settle on the path's velocity.
pub const SERVO_SETUP_PERIODS: usize = 400;

/// The board's servo configuration as the servo kernels count it: the board's, with its
/// holding brakes opening in the first period. The counted period runs with the brakes
/// open either way (the brake logic costs the same per period); the board's 70 ms release
/// of Z's brake would only add 700 held periods to the uncounted setup, in which the stub's
/// encoder table and every kernel that replays it would have to stand still.
pub fn kernel_servo_config() -> ServoConfig {
    let mut cfg = servo_config(BOARD_RATE_HZ);
    for b in cfg.brakes.iter_mut() {
        b.release_s = 0.0;
    }
    cfg
}

/// Tracking error the [`ServoIo`] stub leaves per axis once it has grown in, mm (tens of
/// counts: every error, power and sliding variable is non-zero, far below the 2 mm trip).
pub const SERVO_STUB_ERROR_MM: [f64; 3] = [0.02, -0.015, 0.03];

/// Periods over which the stub's error grows from 0 to [`SERVO_STUB_ERROR_MM`].
const SERVO_STUB_ERROR_RAMP: usize = 100;

/// The machine of the [`ServoPeriod`] kernel: encoder registers precomputed for every
/// period (in the uncounted setup), so reading them costs what reading a timer costs;
/// inputs healthy; outputs recorded.
pub struct StubIo {
    raw: [[u32; AXES]; SERVO_SETUP_PERIODS + 2],
    next: usize,
    /// The last efforts written (0 after a switch-off).
    pub effort: [f32; AXES],
}

impl StubIo {
    /// The board's helix from the origin, as the encoders would count it with the stub's
    /// error, at the board's rate and 1600 counts/mm (Z on its 16-bit timer).
    pub(crate) fn new() -> Option<Self> {
        let cfg = kernel_servo_config();
        let traj = BOARD_PATH.path.build().ok()?;
        let p0 = traj.sample(0.0).pos;
        let period_s = 1.0 / f64::from(BOARD_RATE_HZ);
        let mut raw = [[0u32; AXES]; SERVO_SETUP_PERIODS + 2];
        for (k, r) in raw.iter_mut().enumerate() {
            // period k reads row k + 1 (row 0 is the register value at boot)
            let t = k.saturating_sub(1) as f64 * period_s;
            let p = traj.sample(t).pos;
            let ramp = (k.min(SERVO_STUB_ERROR_RAMP) as f64) / SERVO_STUB_ERROR_RAMP as f64;
            for i in 0..AXES {
                let mm = p[i] - p0[i] - SERVO_STUB_ERROR_MM[i] * ramp;
                let counts = libm::round(mm * f64::from(cfg.encoders[i].counts_per_mm)) as i64;
                r[i] = match cfg.encoders[i].counter {
                    CounterWidth::Bits16 => (counts as u32) & 0xFFFF,
                    CounterWidth::Bits32 => counts as u32,
                };
            }
        }
        Some(Self {
            raw,
            next: 0,
            effort: [0.0; AXES],
        })
    }

    pub(crate) fn boot_registers(&mut self) -> [u32; AXES] {
        self.next = 1;
        self.raw[0]
    }
}

impl ServoIo<f32> for StubIo {
    fn read_inputs(&mut self) -> Inputs {
        Inputs::default()
    }

    fn read_counters(&mut self) -> [u32; AXES] {
        let r = self.raw.get(self.next).copied().unwrap_or_default();
        self.next += 1;
        r
    }

    fn write_outputs(&mut self, effort: &[f32; AXES]) {
        self.effort = *effort;
    }

    fn disable_outputs(&mut self) {
        self.effort = [0.0; AXES];
    }
}

/// State of the `servo_period` kernel: the board's servo (controller-core
/// `presets::board`: DSMC + contour coupling, PLL, helix) on the stub.
pub struct ServoPeriod {
    servo: Servo<f32>,
    io: StubIo,
}

impl ServoPeriod {
    /// Arms, starts the path and follows it for [`SERVO_SETUP_PERIODS`]; `None` unless
    /// the servo is then enabled and following the path.
    pub fn setup() -> Option<Self> {
        Self::setup_with(&kernel_servo_config())
    }

    /// The same with the output filters of the `filters3_f32` kernel on every axis
    /// (`servo_period_filtered`: the servo step as the interrupt runs it with filters).
    pub fn setup_filtered() -> Option<Self> {
        let mut cfg = kernel_servo_config();
        cfg.filters = filters::flexible_filters()?;
        Self::setup_with(&cfg)
    }

    fn setup_with(cfg: &ServoConfig) -> Option<Self> {
        let mut io = StubIo::new()?;
        let raw = io.boot_registers();
        let mut servo = Servo::<f32>::new(cfg, raw, [0; AXES]).ok()?;
        servo.period(&mut io, &[Command::Arm, Command::StartPath]);
        for _ in 1..SERVO_SETUP_PERIODS {
            servo.period(&mut io, &[]);
        }
        let s = servo.snapshot();
        let following = s.motion_t_s > 0.0 && s.tracking.iter().all(|e| *e != 0.0);
        (servo.state() == ServoState::Run && following).then_some(Self { servo, io })
    }

    /// One control period with no new command; returns the X effort (the snapshot stays
    /// in the servo, as on the board).
    #[inline(never)]
    pub fn step(&mut self) -> f32 {
        self.servo.period(&mut self.io, &[]).effort[0]
    }
}

/// Raw bit pattern of a number, for bit-exact comparisons.
pub trait RawBits: Real {
    fn raw_bits(self) -> u64;
}

impl RawBits for f32 {
    fn raw_bits(self) -> u64 {
        self.to_bits() as u64
    }
}

impl RawBits for LibmF32 {
    fn raw_bits(self) -> u64 {
        self.0.to_bits() as u64
    }
}

impl RawBits for FxQ16 {
    fn raw_bits(self) -> u64 {
        self.to_bits() as u32 as u64
    }
}

impl RawBits for FxQ32 {
    fn raw_bits(self) -> u64 {
        self.to_bits() as u64
    }
}

/// `f32` values per replay input record: `t`, measured position x y z, velocity x y z.
pub const REPLAY_IN: usize = 7;
/// Raw values per replay output record: `u`, `s`, contour error (x y z each).
pub const REPLAY_OUT: usize = 9;

/// Feed a recorded input sequence to a fresh paper-DSMC controller in `R`, one control
/// step (period [`KERNEL_PERIOD_S`]) per record, writing the raw bits of every output.
/// Records beyond the shorter of the two buffers are ignored. Returns the number of
/// steps run (0 if the configuration were rejected).
pub fn replay<R: RawBits>(inputs: &[f32], outputs: &mut [u64]) -> usize {
    let Ok(mut g) = Controller3::<R>::new(&paper_dsmc_config()) else {
        return 0;
    };
    let traj = Trajectory::<R>::paper_helix();
    let dt = R::from_f32(KERNEL_PERIOD_S);
    let mut n = 0;
    for (inp, out) in inputs
        .chunks_exact(REPLAY_IN)
        .zip(outputs.chunks_exact_mut(REPLAY_OUT))
    {
        let f = R::from_f32;
        let meas = Measured {
            pos: Vec3::new(f(inp[1]), f(inp[2]), f(inp[3])),
            vel: Vec3::new(f(inp[4]), f(inp[5]), f(inp[6])),
        };
        let r = traj.sample(f(inp[0]));
        let o = g.step(&r, &meas, dt);
        let vals = [
            o.u.x,
            o.u.y,
            o.u.z,
            o.s.x,
            o.s.y,
            o.s.z,
            o.contour.x,
            o.contour.y,
            o.contour.z,
        ];
        for (slot, v) in out.iter_mut().zip(vals) {
            *slot = v.raw_bits();
        }
        n += 1;
    }
    n
}
