//! Cost kernels of the control step and the bit-exactness replay, generic over
//! controller-core's [`Real`].
//!
//! A *kernel* is a state built once (`setup`, not counted) and a step run on it (counted).
//! The thumb binary (`src/bin/kernels.rs`) exports every kernel as the C symbols
//! `insns_setup_<name>` / `insns_kernel_<name>`; `insns/count.py` finds them by that prefix
//! and prints `<name> instructions=<N> cycles_est=<M>`. See `insns/README.md` for adding one.
//!
//! The DSMC kernels run what the firmware's control interrupt runs for the paper's helix:
//! [`Trajectory::sample`] + [`Gantry3::step`] (tracking error, 3-D contour error,
//! cross-coupling, DSMC on three axes, integrator update).
#![no_std]

use controller_core::estimator::{EstimatorConfig, EstimatorTiming, Estimators3};
use controller_core::fixed::{FxQ16, FxQ32};
use controller_core::gantry::{Gantry3, GantryConfig, GantryOutput, Measured};
use controller_core::params::{LawConfig, PAPER_DSMC, PAPER_LAMBDA, PAPER_PLANT};
use controller_core::trajectory::Trajectory;
use controller_core::{LibmF32, Real, Vec3};

/// Control period of the cost kernels: the firmware's 20 kHz rate.
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
pub fn paper_dsmc_config() -> GantryConfig {
    GantryConfig::uniform(LawConfig::Smc(PAPER_DSMC), PAPER_LAMBDA)
}

/// State of one DSMC kernel.
pub struct Dsmc3<R> {
    gantry: Gantry3<R>,
    traj: Trajectory<R>,
    t: R,
    dt: R,
    meas: Measured<R>,
}

impl<R: Real> Dsmc3<R> {
    /// Paper helix and DSMC; the measurement is the reference at [`WORST_CASE_T_S`] minus
    /// the worst-case errors. One step is run so every state (integrals, previous
    /// reference) is populated as in steady operation.
    pub fn setup() -> Option<Self> {
        let gantry = Gantry3::new(&paper_dsmc_config()).ok()?;
        let traj = Trajectory::paper_helix();
        let t = R::from_f32(WORST_CASE_T_S);
        let r = traj.sample(t);
        let err = Vec3::new(
            R::from_f32(WORST_CASE_ERROR[0]),
            R::from_f32(WORST_CASE_ERROR[1]),
            R::from_f32(WORST_CASE_ERROR[2]),
        );
        let rate = Vec3::new(
            R::from_f32(WORST_CASE_RATE_ERROR[0]),
            R::from_f32(WORST_CASE_RATE_ERROR[1]),
            R::from_f32(WORST_CASE_RATE_ERROR[2]),
        );
        let mut k = Self {
            gantry,
            traj,
            t,
            dt: R::from_f32(KERNEL_PERIOD_S),
            meas: Measured {
                pos: r.pos - err,
                vel: r.vel - rate,
            },
        };
        k.step();
        Some(k)
    }

    /// One 3-axis control step: trajectory sample + `Gantry3::step`.
    #[inline(never)]
    pub fn step(&mut self) -> GantryOutput<R> {
        let r = self.traj.sample(self.t);
        self.gantry.step(&r, &self.meas, self.dt)
    }
}

/// Wide encoder counts of the estimator kernels' axes: different on every axis, one of
/// them far from the origin, as after long travel.
pub const ESTIMATOR_COUNTS: [i64; 3] = [12_345, -6_789, 50_000_000];

/// Count increments per period of the estimator kernels (a moving axis).
pub const ESTIMATOR_STEP_COUNTS: [i64; 3] = [3, -2, 5];

/// State of one estimator kernel: the three axes' velocity estimators exactly as the
/// control interrupt runs them ([`Estimators3`]: wide counts in, positions and velocities
/// out, the applied output fed back for the Kalman filter's commanded acceleration).
pub struct Estimator3<R> {
    bank: Estimators3<R>,
    counts: [i64; 3],
    u: Vec3<R>,
}

impl<R: Real> Estimator3<R> {
    /// The paper-simulation preset of `cfg` on all three axes with the paper plant as the
    /// acceleration model, at [`KERNEL_PERIOD_S`] and 1e-4-unit counts; one update is run
    /// so the state is populated.
    pub fn setup(cfg: EstimatorConfig) -> Option<Self> {
        let timing = EstimatorTiming {
            period_s: KERNEL_PERIOD_S,
            count_size: 1e-4,
        };
        let bank = Estimators3::new(
            &[cfg; 3],
            &[Some(PAPER_PLANT); 3],
            &timing,
            ESTIMATOR_COUNTS,
        )
        .ok()?;
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
        let m = self.bank.update(self.counts);
        self.bank.applied(self.u);
        m
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
    let Ok(mut g) = Gantry3::<R>::new(&paper_dsmc_config()) else {
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
            o.errors.contour.x,
            o.errors.contour.y,
            o.errors.contour.z,
        ];
        for (slot, v) in out.iter_mut().zip(vals) {
            *slot = v.raw_bits();
        }
        n += 1;
    }
    n
}
