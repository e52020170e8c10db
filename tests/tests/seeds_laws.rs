//! Closed-loop behaviour of the seed methods (issue 5) on the physical gantry axes:
//! disturbance observer, DOB-SMC load rejection, variable-gain cross-coupling, adaptive
//! friction identification. The fixture runs the firmware's arrangement: controller in
//! f32 at 10 kHz with zero-order hold, positions quantised to 0.625 µm counts, velocities
//! from the project's PLL estimator, plant in f64 with 4 RK4 steps per period.

use controller_core::dob_smc::{DobSmc, DobState};
use controller_core::estimator::{EstimatorConfig, EstimatorTiming, PllConfig, VelocityEstimator};
use controller_core::gantry::Measured;
use controller_core::law::AxisSignals;
use controller_core::metrics::{distance_to_path, MaxRms};
use controller_core::physical_plant::{PhysicalAxis, PhysicalAxisConfig};
use controller_core::plant::{rk4_step, AxisState};
use controller_core::seed_gantry::{SeedController, SeedControllerConfig};
use controller_core::seed_params::{
    adaptive_for, SeedMethod, COUNT_MM, CUTTING_LOAD_MNM, DOB_SMC_X, FIRMWARE_PERIOD_S,
    GANTRY_AXES, GANTRY_X,
};
use controller_core::trajectory::{Polyline, RefSample, Trajectory};
use controller_core::Vec3;
use host_sim::seeds::{self, SeedsReport};
use std::sync::OnceLock;

const TS: f64 = FIRMWARE_PERIOD_S as f64;
const SUBSTEPS: usize = 4;
/// Velocity PLL, critically damped, 2000 rad/s: the PLL has no acceleration
/// feed-forward, so its lag 2A/ω must stay small at the contouring accelerations.
const PLL: EstimatorConfig = pll(2000.0);

const fn pll(bandwidth_rad_s: f32) -> EstimatorConfig {
    EstimatorConfig::Pll(PllConfig {
        bandwidth_rad_s,
        damping: 1.0,
    })
}
const TIMING: EstimatorTiming = EstimatorTiming {
    period_s: FIRMWARE_PERIOD_S,
    count_size: COUNT_MM,
};

fn counts(pos_mm: f64) -> i64 {
    (pos_mm / COUNT_MM as f64).round() as i64
}

struct Run {
    contour: MaxRms<f64>,
    max_err: [f64; 3],
    ctl: SeedController<f32>,
}

/// Runs a 3-axis controller on the gantry, starting on the reference.
fn simulate(
    cfg: &SeedControllerConfig,
    axes: &[PhysicalAxisConfig; 3],
    traj: &Trajectory<f64>,
    horizon_s: f64,
) -> Run {
    simulate_with(PLL, cfg, axes, traj, horizon_s)
}

fn simulate_with(
    pll: EstimatorConfig,
    cfg: &SeedControllerConfig,
    axes: &[PhysicalAxisConfig; 3],
    traj: &Trajectory<f64>,
    horizon_s: f64,
) -> Run {
    let ctl = SeedController::<f32>::new(cfg).unwrap();
    let plants = axes.map(|c| PhysicalAxis::<f64>::new(&c).unwrap());
    let r0 = traj.sample(0.0);
    let mut st = [0, 1, 2].map(|i| AxisState {
        pos: r0.pos[i],
        vel: r0.vel[i],
    });
    let mut est =
        [0, 1, 2].map(|i| VelocityEstimator::<f32>::new(&pll, &TIMING, counts(st[i].pos)).unwrap());
    let mut run = Run {
        contour: MaxRms::default(),
        max_err: [0.0; 3],
        ctl,
    };
    let n = (horizon_s / TS).round() as usize;
    for k in 0..n {
        let t = k as f64 * TS;
        let r = traj.sample(t);
        let mut m = Measured::<f32>::default();
        for i in 0..3 {
            let e = est[i].update(counts(st[i].pos), r.acc[i] as f32);
            m.pos[i] = e.pos;
            m.vel[i] = e.vel;
        }
        let rf = RefSample {
            pos: r.pos.cast::<f32>(),
            vel: r.vel.cast(),
            acc: r.acc.cast(),
        };
        let u = run.ctl.step(&rf, &m, TS as f32).u.cast::<f64>();
        let p = Vec3::new(st[0].pos, st[1].pos, st[2].pos);
        if k % 10 == 0 {
            run.contour.add(distance_to_path(traj, p, t, 0.1));
        }
        for i in 0..3 {
            run.max_err[i] = run.max_err[i].max((r.pos[i] - p[i]).abs());
        }
        for j in 0..SUBSTEPS {
            let h = TS / SUBSTEPS as f64;
            rk4_step(&plants, &mut st, t + j as f64 * h, h, |_, _| u.to_array());
        }
    }
    run
}

fn loaded_axes(t_load_s: f32) -> [PhysicalAxisConfig; 3] {
    let mut a = GANTRY_AXES;
    a[0].load_step_mnm = CUTTING_LOAD_MNM;
    a[0].load_step_t_s = t_load_s;
    a
}

#[test]
fn observer_estimate_converges_to_a_constant_load_within_200_ms() {
    // X axis held at 0 by DOB-SMC; 150 mN·m load from 0.1 s. At rest the friction is 0,
    // so once the axis is back at rest the disturbance is -T/J = -2344 mm/s² (while it
    // moves, friction adds to it). The estimate is within 2 % of it 200 ms after the step.
    let law = DobSmc::<f32>::new(&DOB_SMC_X).unwrap();
    let mut axis_cfg = GANTRY_X;
    axis_cfg.load_step_mnm = CUTTING_LOAD_MNM;
    axis_cfg.load_step_t_s = 0.1;
    let plant = [PhysicalAxis::<f64>::new(&axis_cfg).unwrap()];
    let mut st = [AxisState::default()];
    let mut est = VelocityEstimator::<f32>::new(&PLL, &TIMING, 0).unwrap();
    let mut obs = DobState::default();
    let truth = -(CUTTING_LOAD_MNM / GANTRY_X.inertia) as f64;
    for k in 0..((0.3 / TS) as usize) {
        let t = k as f64 * TS;
        let e = est.update(counts(st[0].pos), 0.0);
        let sig = AxisSignals {
            e: -e.pos,
            e_dot: -e.vel,
            q: e.pos,
            q_dot: e.vel,
            ..Default::default()
        };
        let u = law.step(&mut obs, &sig, TS as f32).u as f64;
        rk4_step(&plant, &mut st, t, TS, |_, _| [u]);
    }
    let d_hat = obs.d_hat as f64;
    assert!(
        (d_hat - truth).abs() < 0.02 * truth.abs(),
        "d̂ = {d_hat}, truth {truth}"
    );
}

/// Peak |e| of the X axis after a load step at 0.1 s, holding position, with or without
/// the observer (without: the same sliding-mode law with d̂ = 0).
fn load_step_peak(with_observer: bool) -> f64 {
    let law = DobSmc::<f32>::new(&DOB_SMC_X).unwrap();
    let mut axis_cfg = GANTRY_X;
    axis_cfg.load_step_mnm = CUTTING_LOAD_MNM;
    axis_cfg.load_step_t_s = 0.1;
    let plant = [PhysicalAxis::<f64>::new(&axis_cfg).unwrap()];
    let mut st = [AxisState::default()];
    let mut est = VelocityEstimator::<f32>::new(&PLL, &TIMING, 0).unwrap();
    let mut obs = DobState::default();
    let mut peak = 0.0f64;
    for k in 0..((0.5 / TS) as usize) {
        let t = k as f64 * TS;
        let e = est.update(counts(st[0].pos), 0.0);
        let sig = AxisSignals {
            e: -e.pos,
            e_dot: -e.vel,
            q: e.pos,
            q_dot: e.vel,
            ..Default::default()
        };
        let u = if with_observer {
            law.step(&mut obs, &sig, TS as f32).u
        } else {
            law.evaluate(&DobState::default(), &sig).u
        } as f64;
        rk4_step(&plant, &mut st, t, TS, |_, _| [u]);
        peak = peak.max(st[0].pos.abs());
    }
    peak
}

#[test]
fn dob_smc_rejects_a_load_step_better_than_smc_without_observer() {
    let (dob, smc) = (load_step_peak(true), load_step_peak(false));
    // without the observer the boundary-layer SMC settles at an offset of
    // T / (J (c k + ...)) ≈ 60 µm; the observer cuts the peak by more than half
    assert!(dob < 0.5 * smc, "DOB-SMC {dob} mm, SMC {smc} mm");
    assert!(dob < 0.05, "DOB-SMC peak {dob} mm");
}

fn circle() -> Trajectory<f64> {
    Trajectory::circle(Vec3::new(0.0, -20.0, 0.0), 20.0, 2.5)
}

fn square() -> Trajectory<f64> {
    Trajectory::Polyline(Polyline::square(Vec3::zero(), 40.0, 50.0, 1000.0).unwrap())
}

#[test]
fn cross_coupling_lowers_contour_error_on_circle_and_square_for_every_law() {
    for (name, traj, horizon) in [("circle", circle(), 3.0), ("square", square(), 3.4)] {
        for m in [SeedMethod::Pid, SeedMethod::Dsmc, SeedMethod::DobSmc] {
            let axes = loaded_axes(1.5);
            let plain = simulate(&m.controller(false), &axes, &traj, horizon);
            let ccc = simulate(&m.controller(true), &axes, &traj, horizon);
            let (a, b) = (plain.contour, ccc.contour);
            assert!(
                b.max < 0.9 * a.max && b.rms() < 0.9 * a.rms(),
                "{name} {}: contour max {} -> {}, rms {} -> {} mm",
                m.name(),
                a.max,
                b.max,
                a.rms(),
                b.rms()
            );
            // and the coupled runs stay accurate in absolute terms (< 40 µm)
            assert!(b.max < 0.04, "{name} {} contour max {} mm", m.name(), b.max);
        }
    }
}

/// The friction study exactly as `host-sim seeds` runs it (seeds_friction.toml: 5 mm at
/// 2 Hz on X and Y, 8 s, Kalman velocity with the reference acceleration, 12-bit PWM),
/// run once and shared by the tests below.
fn friction_report() -> &'static SeedsReport {
    static REP: OnceLock<SeedsReport> = OnceLock::new();
    REP.get_or_init(|| {
        let mut rep = SeedsReport::default();
        seeds::run_file(
            &seeds::builtin_file("seeds_friction.toml").unwrap(),
            &mut rep,
        )
        .unwrap();
        rep
    })
}

#[test]
fn adaptive_estimates_end_within_10_percent_of_the_truth_on_x_and_y() {
    // issue 5: J, B, f+, f- within 10 % on a persistently exciting trajectory, on every
    // moving axis (measured: all within 4 %)
    let rep = friction_report();
    for axis in ["x", "y"] {
        let m = &rep.adaptation[axis];
        for k in ["J", "B", "f_pos", "f_neg"] {
            let e = &m[k];
            assert!(
                (e.estimate - e.truth).abs() < 0.1 * e.truth.abs(),
                "{axis} {k}: estimate {}, truth {}",
                e.estimate,
                e.truth
            );
        }
    }
    // the recorded history ends on the reported values' run and starts at the guesses
    let first = rep.estimates.first().unwrap();
    assert_eq!(first.t, 0.0);
    assert_eq!(first.axes[0][1], 0.0, "B̂ starts unknown");
    assert!(rep.estimates.last().unwrap().t > 7.9);
}

#[test]
fn adaptive_law_tracks_velocity_reversals_better_than_the_fixed_smc() {
    // largest |e| within ±20 ms of every velocity reversal over t in [6 s, 8 s], after
    // adaptation has converged; both laws start from the same poor guesses (J 25 % low,
    // B = f± = 0), the fixed SMC keeps them. Measured: adaptive 0.6 / 0.2 µm, fixed
    // 13.6 / 9.5 µm on X / Y.
    let rep = friction_report();
    let laws = &rep.scenarios["friction_sine"];
    let (adaptive, fixed) = (&laws["ASMC"], &laws["SMC"]);
    for i in 0..2 {
        let (a, f) = (adaptive.reversal_max_error[i], fixed.reversal_max_error[i]);
        assert!(f > 0.0 && a > 0.0, "axis {i}: reversals measured");
        assert!(a < 0.2 * f, "axis {i}: adaptive {a} mm vs fixed {f} mm");
        assert!(a < 0.002, "axis {i}: adaptive reversal error {a} mm");
    }
}

#[test]
fn adaptive_estimates_stay_within_bounds_without_excitation() {
    // Holding still against an unmodelled 100 mN·m load (above the switching gain k):
    // the error never vanishes, s_Δ stays nonzero and the friction estimate is driven
    // into its bound; the projection must hold every estimate inside its bounds.
    let mut axes = GANTRY_AXES;
    axes[0].load_const_mnm = 100.0;
    let hold = Trajectory::Step {
        target: Vec3::zero(),
        t0: 0.0,
    };
    let r = simulate(&SeedMethod::Adaptive.controller(false), &axes, &hold, 2.0);
    let c = adaptive_for(&GANTRY_X);
    let a = r.ctl.states()[0].adapt;
    let within =
        |v: f32, e: &controller_core::adaptive_smc::EstimateConfig| v >= e.min && v <= e.max;
    assert!(within(a.j, &c.inertia), "{a:?}");
    assert!(within(a.b, &c.viscous), "{a:?}");
    assert!(within(a.f_pos, &c.coulomb_pos), "{a:?}");
    assert!(within(a.f_neg, &c.coulomb_neg), "{a:?}");
    // the test exercises the projection: some estimate sits on a bound
    let on_bound = a.f_pos == c.coulomb_pos.max
        || a.f_neg == c.coulomb_neg.min
        || a.f_neg == c.coulomb_neg.max
        || a.j == c.inertia.max
        || a.j == c.inertia.min;
    assert!(on_bound, "{a:?}");
}

#[test]
fn seeds_json_keeps_the_issue_shape() {
    // public interface: "adaptation": {"J"|"B"|"f_pos"|"f_neg": {"estimate", "truth"}} (X axis),
    // every adapted axis under "adaptation_axes"
    let v = friction_report().to_json();
    for k in ["J", "B", "f_pos", "f_neg"] {
        let e = &v["adaptation"][k];
        assert!(
            e["estimate"].as_f64().unwrap().is_finite(),
            "adaptation.{k}"
        );
        assert_eq!(e["truth"], v["adaptation_axes"]["x"][k]["truth"]);
    }
    let friction = v["friction_sine"].as_object().unwrap();
    for (law, fig) in friction {
        for k in ["contour_max", "contour_rms"] {
            assert!(fig[k].as_f64().unwrap() >= 0.0, "{law}.{k}");
        }
        for k in ["itse", "peak_torque"] {
            assert_eq!(fig[k].as_array().unwrap().len(), 3, "{law}.{k}");
        }
    }
}
