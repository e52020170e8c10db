//! Simulated axis for the identification tests: what the board would see of a
//! [`PhysicalAxis`].
//!
//! Per 100 µs control period: the true position is quantised to 0.625 µm counts, a
//! zero-mean dither of -1/0/+1 count is added (measurement noise), the counts go through
//! the board's velocity PLL (100 Hz, `firmware::config::BOARD_PLL`), and the identifier
//! gets `counts × 0.625 µm`, the PLL velocity and the effort it commanded last period.
//! The plant receives each command one period late, quantised to a 12-bit amplifier
//! (`2 T_max / 4096` per step), and is integrated by RK4 at 4 substeps per period. The
//! truth has a Stribeck peak and a regularised friction sign the model does not contain.
#![allow(dead_code)]

use controller_core::estimator::{EstimatorConfig, EstimatorTiming, PllConfig, VelocityEstimator};
use controller_core::plant::physical::{PhysicalAxis, PhysicalAxisConfig};
use controller_core::plant::state::{rk4_step, AxisState};
use controller_core::plant::AxisModel;
use controller_core::presets::gantry::{COUNT_MM, FIRMWARE_PERIOD_S, GANTRY_X};
use controller_core::sysid::{
    AxisSample, Identifier, IdentifyConfig, IdentifyOutput, IdentifyResult, IdentifyStatus,
    IDENTIFY_DEFAULTS,
};

pub use controller_core::sim::rng::SplitMix64 as Rng;

/// The documented range of random machines (docs/identification.md):
/// J 0.02–0.4 mN·m/(mm/s²) and B 0.05–1.0 mN·m/(mm/s) log-uniform, f+ 10–80 and
/// f- −8..−80 mN·m uniform and independent (asymmetric), Stribeck ratio 1.0–1.5 at
/// 1–3 mm/s, peak torque 1–3 N·m, and on every third machine a constant load of
/// ±(5–30) mN·m (gravity).
pub fn random_machine(rng: &mut Rng, index: usize) -> PhysicalAxisConfig {
    controller_core::sim::random::random_axis(rng, index % 3 == 2, &GANTRY_X)
}

/// Identification cap used on the random machines: half the motor's peak torque.
pub fn cap_for(axis: &PhysicalAxisConfig) -> f32 {
    0.5 * axis.torque_max_mnm
}

/// The board's velocity PLL: 628 rad/s (100 Hz), critically damped.
pub const BOARD_PLL: PllConfig = PllConfig {
    bandwidth_rad_s: 628.3,
    damping: 1.0,
};

pub const RK4_SUBSTEPS: u32 = 4;
pub const AMPLIFIER_BITS: u32 = 12;

/// One simulated axis as the board sees it.
pub struct SimAxis {
    pub axis: PhysicalAxis<f64>,
    pub state: AxisState<f64>,
    pub t_s: f64,
    estimator: VelocityEstimator<f32>,
    torque_step: f64,
    /// Command waiting one period before it reaches the amplifier.
    pending_mnm: f32,
    dither: Rng,
    /// Extra torque on the axis (tests of the safety checks), mN·m.
    pub external_mnm: f64,
    /// Torque per unit of command (1; tests of a failing amplifier lower it).
    pub torque_scale: f64,
}

impl SimAxis {
    pub fn new(cfg: &PhysicalAxisConfig, start_mm: f64, seed: u64) -> Self {
        Self::with_estimator(cfg, start_mm, seed, &EstimatorConfig::Pll(BOARD_PLL))
    }

    /// With another velocity estimator (it gets no acceleration input: the identifier
    /// does not publish one).
    pub fn with_estimator(
        cfg: &PhysicalAxisConfig,
        start_mm: f64,
        seed: u64,
        estimator: &EstimatorConfig,
    ) -> Self {
        let timing = EstimatorTiming {
            period_s: FIRMWARE_PERIOD_S,
            count_size: COUNT_MM,
        };
        let count = (start_mm / COUNT_MM as f64).round() as i64;
        Self {
            axis: PhysicalAxis::new(cfg).expect("valid axis"),
            state: AxisState {
                pos: start_mm,
                vel: 0.0,
            },
            t_s: 0.0,
            estimator: VelocityEstimator::new(estimator, &timing, count).expect("valid estimator"),
            torque_step: 2.0 * cfg.torque_max_mnm as f64 / (1u64 << AMPLIFIER_BITS) as f64,
            pending_mnm: 0.0,
            dither: Rng::new(seed ^ 0xD1CE),
            external_mnm: 0.0,
            torque_scale: 1.0,
        }
    }

    /// What the board measures now; `effort_applied` is the command of last period.
    pub fn measure(&mut self, effort_applied_mnm: f32) -> AxisSample {
        let dither = (self.dither.next_u64() % 3) as i64 - 1;
        let count = (self.state.pos / COUNT_MM as f64).round() as i64 + dither;
        let est = self.estimator.update(count, 0.0);
        AxisSample {
            pos_mm: (count as f64 * COUNT_MM as f64) as f32,
            vel_mm_s: est.vel,
            effort_applied_mnm,
            fault: false,
        }
    }

    /// Advance one period: the command of the previous period reaches the amplifier now
    /// (one period of delay), quantised; `command` waits for the next period.
    pub fn advance(&mut self, command_mnm: f32) {
        let applied = (self.pending_mnm as f64 / self.torque_step).round()
            * self.torque_step
            * self.torque_scale;
        self.pending_mnm = command_mnm;
        let h = FIRMWARE_PERIOD_S as f64 / RK4_SUBSTEPS as f64;
        let axes = [self.axis];
        let mut s = [self.state];
        let ext = self.external_mnm;
        for i in 0..RK4_SUBSTEPS {
            rk4_step(&axes, &mut s, self.t_s + i as f64 * h, h, |_, _| {
                [applied - ext]
            });
        }
        self.state = s[0];
        self.t_s += FIRMWARE_PERIOD_S as f64;
    }
}

/// What a run produced.
pub struct Run {
    pub status: IdentifyStatus,
    pub result: Option<IdentifyResult>,
    pub machine_time_s: f64,
    /// Extremes of the true position, mm.
    pub pos_min_mm: f64,
    pub pos_max_mm: f64,
    pub max_abs_effort_mnm: f32,
    pub all_finite: bool,
    pub final_speed_mm_s: f64,
}

/// Largest number of periods a run may take before the harness gives up (the
/// identifier's own budget stops it far earlier).
pub const MAX_PERIODS: u32 = 200_000;

pub fn identify_config(axis: &PhysicalAxisConfig) -> IdentifyConfig {
    IdentifyConfig {
        torque_cap_mnm: cap_for(axis),
        ..IDENTIFY_DEFAULTS
    }
}

/// Run identification on `sim` with `cfg`; `hook(k, sample, sim)` may alter the sample
/// or the simulation each period (fault injection).
pub fn run_with(
    sim: &mut SimAxis,
    cfg: &IdentifyConfig,
    mut hook: impl FnMut(u32, &mut AxisSample, &mut SimAxis),
    mut on_output: impl FnMut(u32, &AxisSample, &IdentifyOutput),
) -> Run {
    let start = sim.state.pos;
    let mut id = Identifier::new(cfg, start as f32).expect("valid identify config");
    let mut last = 0.0_f32;
    let mut run = Run {
        status: IdentifyStatus::Running,
        result: None,
        machine_time_s: 0.0,
        pos_min_mm: start,
        pos_max_mm: start,
        max_abs_effort_mnm: 0.0,
        all_finite: true,
        final_speed_mm_s: 0.0,
    };
    for k in 0..MAX_PERIODS {
        let mut sample = sim.measure(last);
        hook(k, &mut sample, sim);
        let out = id.step(&sample);
        on_output(k, &sample, &out);
        run.all_finite &= out.effort_mnm.is_finite() && out.progress.is_finite();
        run.max_abs_effort_mnm = run.max_abs_effort_mnm.max(out.effort_mnm.abs());
        last = out.effort_mnm;
        sim.advance(out.effort_mnm);
        run.pos_min_mm = run.pos_min_mm.min(sim.state.pos);
        run.pos_max_mm = run.pos_max_mm.max(sim.state.pos);
        run.status = out.status;
        if matches!(
            out.status,
            IdentifyStatus::Done | IdentifyStatus::Aborted(_)
        ) {
            run.machine_time_s = (k + 1) as f64 * FIRMWARE_PERIOD_S as f64;
            break;
        }
    }
    run.result = id.result().copied();
    run.final_speed_mm_s = sim.state.vel;
    run
}

pub fn run(axis: &PhysicalAxisConfig, seed: u64) -> Run {
    let mut sim = SimAxis::new(axis, 0.0, seed);
    run_with(&mut sim, &identify_config(axis), |_, _, _| {}, |_, _, _| {})
}

/// Relative errors of an identified model against the truth with its load folded into
/// the Coulomb terms; the Coulomb errors are relative to the true Coulomb magnitude
/// (the folded value may be near zero).
#[derive(Clone, Copy, Debug)]
pub struct Errors {
    pub inertia: f64,
    pub viscous: f64,
    pub coulomb_pos: f64,
    pub coulomb_neg: f64,
}

pub fn errors(m: &AxisModel, truth: &PhysicalAxisConfig) -> Errors {
    let t = AxisModel::from_physical_with_load(truth);
    let rel = |a: f32, b: f32, scale: f32| ((a - b) / scale) as f64;
    Errors {
        inertia: rel(m.inertia, t.inertia, t.inertia),
        viscous: rel(m.viscous, t.viscous, t.viscous),
        coulomb_pos: rel(
            m.coulomb_pos_mnm,
            t.coulomb_pos_mnm,
            truth.coulomb_pos_mnm.abs(),
        ),
        coulomb_neg: rel(
            m.coulomb_neg_mnm,
            t.coulomb_neg_mnm,
            truth.coulomb_neg_mnm.abs(),
        ),
    }
}

/// (min, median, max) of `v`.
pub fn spread(v: &[f64]) -> (f64, f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let med = if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    };
    (s[0], med, s[n - 1])
}
