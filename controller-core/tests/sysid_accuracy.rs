//! Identification against simulated axes (issue 13 goals): inertia within 5 %, Coulomb
//! terms within 10 %, viscous within 25 %, the whole identification within 10 s of
//! machine time and inside the travel window, over random machines drawn from the range
//! documented in `sysid_common::random_machine` (docs/identification.md), the corners of
//! that range and the gantry presets. Each test prints its table (`--nocapture`).

mod sysid_common;

use controller_core::estimator::{EstimatorConfig, KalmanConfig};
use controller_core::presets::gantry::{GANTRY_AXES, GANTRY_X};
use controller_core::sim::physical::PhysicalAxisConfig;
use controller_core::sysid::{IdentifyConfig, IdentifyStatus};
use sysid_common::*;

/// Issue 13 goals.
const INERTIA_TOL: f64 = 0.05;
const COULOMB_TOL: f64 = 0.10;
const VISCOUS_TOL: f64 = 0.25;
const MACHINE_TIME_MAX_S: f64 = 10.0;
/// Validation figures every identified machine reached (measured over all sets: R² ≥
/// 0.985, NRMSE ≤ 0.036); a fit that no longer explains the validation move fails here.
const R2_MIN: f32 = 0.95;
const NRMSE_MAX: f32 = 0.05;

/// Number of random machines (issue: at least 20).
const RANDOM_MACHINES: usize = 24;
/// Seed of the random machines (any value; fixed so failures reproduce).
const MACHINE_SEED: u64 = 0x5151_D00D;

struct Row {
    name: String,
    err: Errors,
    time_s: f64,
    r2: f32,
    nrmse: f32,
}

/// Run `cfg` on `axis` from `start_mm`, assert every goal, return the figures.
fn check(name: &str, axis: &PhysicalAxisConfig, cfg: &IdentifyConfig, mut sim: SimAxis) -> Row {
    let r = run_with(&mut sim, cfg, |_, _, _| {}, |_, _, _| {});
    assert_eq!(r.status, IdentifyStatus::Done, "{name}: {axis:?}");
    let res = r.result.expect("result when done");
    let e = errors(&res.model, axis);
    let ctx = format!("{name}: {axis:?} -> {:?} errors {e:?}", res.model);
    assert!(e.inertia.abs() <= INERTIA_TOL, "inertia {ctx}");
    assert!(e.coulomb_pos.abs() <= COULOMB_TOL, "f+ {ctx}");
    assert!(e.coulomb_neg.abs() <= COULOMB_TOL, "f- {ctx}");
    assert!(e.viscous.abs() <= VISCOUS_TOL, "viscous {ctx}");
    assert!(
        r.machine_time_s <= MACHINE_TIME_MAX_S,
        "time {} {ctx}",
        r.machine_time_s
    );
    assert!(
        (res.machine_time_s as f64 - r.machine_time_s).abs() < 1e-3,
        "reported machine time {} vs {}",
        res.machine_time_s,
        r.machine_time_s
    );
    assert!(
        r.pos_min_mm >= cfg.window_min_mm as f64 && r.pos_max_mm <= cfg.window_max_mm as f64,
        "window [{}, {}] {ctx}",
        r.pos_min_mm,
        r.pos_max_mm
    );
    assert!(
        r.all_finite && r.max_abs_effort_mnm <= cfg.torque_cap_mnm,
        "{ctx}"
    );
    assert!(
        res.r2 >= R2_MIN && res.nrmse <= NRMSE_MAX,
        "validation {res:?}"
    );
    // diagnostics: every parameter excited by rows and samples, std errors finite
    for d in [
        res.fit.inertia,
        res.fit.viscous,
        res.fit.coulomb_pos,
        res.fit.coulomb_neg,
    ] {
        assert!(
            d.rows >= 2 && d.samples > 1000 && d.std_error.is_finite(),
            "{res:?}"
        );
    }
    assert!(res.validation_windows >= 50, "{res:?}");
    // ended at rest
    assert!(r.final_speed_mm_s.abs() < 5.0, "{ctx}");
    Row {
        name: name.to_string(),
        err: e,
        time_s: r.machine_time_s,
        r2: res.r2,
        nrmse: res.nrmse,
    }
}

fn report(title: &str, rows: &[Row]) {
    println!("\n{title}");
    println!(
        "{:<10} {:>8} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7}",
        "machine", "J %", "B %", "f+ %", "f- %", "time s", "R2", "NRMSE"
    );
    for r in rows {
        println!(
            "{:<10} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>7.2} {:>7.4} {:>7.4}",
            r.name,
            100.0 * r.err.inertia,
            100.0 * r.err.viscous,
            100.0 * r.err.coulomb_pos,
            100.0 * r.err.coulomb_neg,
            r.time_s,
            r.r2,
            r.nrmse
        );
    }
    let col = |f: &dyn Fn(&Row) -> f64| spread(&rows.iter().map(f).collect::<Vec<_>>());
    let line = |name: &str, (lo, med, hi): (f64, f64, f64), scale: f64| {
        println!(
            "{name:<14} min {:>7.2}  median {:>7.2}  max {:>7.2}",
            scale * lo,
            scale * med,
            scale * hi
        )
    };
    println!("|error| over {} machines:", rows.len());
    line("inertia %", col(&|r| r.err.inertia.abs()), 100.0);
    line("viscous %", col(&|r| r.err.viscous.abs()), 100.0);
    line("coulomb+ %", col(&|r| r.err.coulomb_pos.abs()), 100.0);
    line("coulomb- %", col(&|r| r.err.coulomb_neg.abs()), 100.0);
    line("time s", col(&|r| r.time_s), 1.0);
    line("R2", col(&|r| r.r2 as f64), 1.0);
}

#[test]
fn random_machines_meet_the_goals() {
    let mut rng = Rng::new(MACHINE_SEED);
    let rows: Vec<Row> = (0..RANDOM_MACHINES)
        .map(|i| {
            let axis = random_machine(&mut rng, i);
            let sim = SimAxis::new(&axis, 0.0, i as u64);
            check(&format!("rand{i}"), &axis, &identify_config(&axis), sim)
        })
        .collect();
    report(
        "random machines (PLL 100 Hz, start at the window's centre)",
        &rows,
    );
}

/// The 16 corners of the inertia × viscous × Coulomb × peak-torque range, with the
/// Stribeck peak and the load (none, +30, −30 mN·m) varied across them. The heavy,
/// damped, high-friction axis with the weakest motor is the slowest case (~8.7 s).
#[test]
fn corners_of_the_range_meet_the_goals() {
    let mut rows = Vec::new();
    let mut i = 0;
    for &j in &[0.02, 0.4] {
        for &b in &[0.05, 1.0] {
            for &f in &[10.0, 80.0] {
                for &tm in &[1000.0, 3000.0] {
                    let axis = PhysicalAxisConfig {
                        inertia: j,
                        viscous: b,
                        coulomb_pos_mnm: f,
                        coulomb_neg_mnm: -0.8 * f,
                        stiction_ratio: if i % 2 == 0 { 1.5 } else { 1.0 },
                        v_stribeck_mm_s: 3.0,
                        load_const_mnm: [0.0, 30.0, -30.0][i % 3],
                        torque_max_mnm: tm,
                        ..GANTRY_X
                    };
                    let sim = SimAxis::new(&axis, 0.0, i as u64);
                    rows.push(check(
                        &format!("corner{i}"),
                        &axis,
                        &identify_config(&axis),
                        sim,
                    ));
                    i += 1;
                }
            }
        }
    }
    report("corners of the range", &rows);
}

#[test]
fn gantry_presets_are_identified() {
    let rows: Vec<Row> = GANTRY_AXES
        .iter()
        .zip(["X", "Y", "Z"])
        .map(|(axis, name)| {
            let sim = SimAxis::new(axis, 0.0, 7);
            check(name, axis, &identify_config(axis), sim)
        })
        .collect();
    report("gantry presets (Z carries 23 mN·m of gravity)", &rows);
}

/// Starting next to either end of the window, and a window of ±30 mm instead of ±50.
#[test]
fn start_near_an_edge_and_a_short_window() {
    let mut rng = Rng::new(0x0077);
    let mut rows = Vec::new();
    for i in 0..8 {
        let axis = random_machine(&mut rng, i);
        for &(start, half) in &[(-44.0, 50.0), (44.0, 50.0), (0.0, 30.0)] {
            let cfg = IdentifyConfig {
                window_min_mm: -half,
                window_max_mm: half,
                ..identify_config(&axis)
            };
            let sim = SimAxis::new(&axis, start, i as u64);
            rows.push(check(&format!("m{i}@{start}/{half}"), &axis, &cfg, sim));
        }
    }
    report("start near an edge / ±30 mm window", &rows);
}

/// The identifier does not depend on the estimator: the board's Kalman filter (without
/// the acceleration input, which identification does not publish) works as well.
#[test]
fn kalman_estimator_works_too() {
    let mut rng = Rng::new(0x0099);
    let est = EstimatorConfig::Kalman(KalmanConfig {
        accel_noise_units_s2: 30.0,
        meas_noise_counts: 0.6,
    });
    let rows: Vec<Row> = (0..8)
        .map(|i| {
            let axis = random_machine(&mut rng, i);
            let sim = SimAxis::with_estimator(&axis, 0.0, i as u64, &est);
            check(&format!("kal{i}"), &axis, &identify_config(&axis), sim)
        })
        .collect();
    report("Kalman estimator", &rows);
}

/// A larger sweep for the documentation's figures (docs/identification.md):
/// `cargo test -p controller-core --release --test sysid_accuracy -- --ignored --nocapture`.
#[test]
#[ignore = "200 machines: run in release for the documentation's table"]
fn sweep_200_random_machines() {
    let mut rng = Rng::new(0xABCD_0001);
    let rows: Vec<Row> = (0..200)
        .map(|i| {
            let axis = random_machine(&mut rng, i);
            let sim = SimAxis::new(&axis, 0.0, i as u64);
            check(&format!("s{i}"), &axis, &identify_config(&axis), sim)
        })
        .collect();
    let col = |f: &dyn Fn(&Row) -> f64| spread(&rows.iter().map(f).collect::<Vec<_>>());
    println!("\n200 random machines:");
    for (name, v, scale) in [
        ("inertia %", col(&|r| r.err.inertia.abs()), 100.0),
        ("viscous %", col(&|r| r.err.viscous.abs()), 100.0),
        ("coulomb+ %", col(&|r| r.err.coulomb_pos.abs()), 100.0),
        ("coulomb- %", col(&|r| r.err.coulomb_neg.abs()), 100.0),
        ("time s", col(&|r| r.time_s), 1.0),
        ("R2", col(&|r| r.r2 as f64), 1.0),
        ("NRMSE", col(&|r| r.nrmse as f64), 1.0),
    ] {
        println!(
            "{name:<12} min {:>7.3} median {:>7.3} max {:>7.3}",
            scale * v.0,
            scale * v.1,
            scale * v.2
        );
    }
    println!(
        "signed inertia error % median {:.3}",
        100.0 * col(&|r| r.err.inertia).1
    );
}
