//! The loop measurement on an analytic loop: a mass with viscous friction, sampled
//! exactly under the hold, held by a discrete PID on the measurement's travelling
//! reference. Its loop `C(z)·P(z)` is known in closed form, and every measured point must
//! match it.

extern crate std;

use super::loop_measure::{LoopMeasurement, LOOP_DEFAULTS};
use super::{ResponseConfig, ResponseConfigError};
use crate::sysid::identifier::{AbortReason, AxisSample, IdentifyStatus};

const T: f64 = 1e-4;
/// The plant: inertia mN·m/(mm/s²), viscous mN·m/(mm/s).
const J: f64 = 0.1;
const B: f64 = 0.3;
/// The PID: crossover near 50 Hz, its integral a decade below.
const KP: f64 = 3300.0;
const KD: f64 = 31.4;
const KI: f64 = 33_000.0;

type C = (f64, f64);

fn mul(a: C, b: C) -> C {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

fn div(a: C, b: C) -> C {
    let d = b.0 * b.0 + b.1 * b.1;
    ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
}

/// `Φ = [[1, g], [0, e]]`, `Γ = [γ1, γ2]` of the mass and damper under the hold.
fn plant() -> (f64, f64, f64, f64) {
    let a = B / J;
    let e = libm::exp(-a * T);
    let g = (1.0 - e) / a;
    (e, g, (T - g) / B, (1.0 - e) / B)
}

/// `C(z)·P(z)` at `f` (measured: within 0.02 %).
fn exact_loop(f: f64) -> C {
    let (e, g, g1, g2) = plant();
    let w = 2.0 * core::f64::consts::PI * f * T;
    let z = (libm::cos(w), libm::sin(w));
    let zi = (libm::cos(w), -libm::sin(w));
    let zm1 = (z.0 - 1.0, z.1);
    let zme = (z.0 - e, z.1);
    // P = γ1/(z-1) + g γ2/((z-1)(z-e))
    let p = div((g1, 0.0), zm1);
    let p2 = div((g * g2, 0.0), mul(zm1, zme));
    let p = (p.0 + p2.0, p.1 + p2.1);
    let one_minus_zi = (1.0 - zi.0, -zi.1);
    let d = (KD / T * one_minus_zi.0, KD / T * one_minus_zi.1);
    let i = div((KI * T, 0.0), one_minus_zi);
    let c = (KP + d.0 + i.0, d.1 + i.1);
    mul(c, p)
}

fn config() -> ResponseConfig {
    ResponseConfig {
        period_s: T as f32,
        window_min_mm: -50.0,
        window_max_mm: 50.0,
        torque_cap_mnm: 500.0,
        velocity_limit_mm_s: 100.0,
        inertia_guess: 0.09,
        points: 24,
        ..LOOP_DEFAULTS
    }
}

/// Run `m` on the plant and PID until it finishes (at most `max_periods`), calling
/// `each` after every period; the furthest the reference went from 0, mm.
fn run(m: &mut LoopMeasurement, max_periods: u32, mut each: impl FnMut(&LoopMeasurement)) -> f32 {
    let (e, g, g1, g2) = plant();
    let (mut x, mut v) = (0.0f64, 0.0f64);
    let (mut integral, mut prev_err) = (0.0f64, 0.0f64);
    let mut furthest = 0.0f32;
    for _ in 0..max_periods {
        let r = m.reference();
        furthest = furthest.max(r.pos_mm.abs());
        let err = f64::from(r.pos_mm) - x;
        integral += KI * T * err;
        let u = KP * err + KD * (err - prev_err) / T + integral;
        prev_err = err;
        let sample = AxisSample {
            pos_mm: x as f32,
            vel_mm_s: v as f32,
            effort_applied_mnm: 0.0,
            fault: false,
        };
        let out = m.step(&sample, u as f32);
        let applied = f64::from(out.effort_mnm);
        (x, v) = (x + g * v + g1 * applied, e * v + g2 * applied);
        each(m);
        if matches!(
            out.status,
            IdentifyStatus::Done | IdentifyStatus::Aborted(_)
        ) {
            break;
        }
    }
    furthest
}

#[test]
fn the_loop_of_a_pid_on_a_mass_is_measured_within_0_2_percent() {
    let mut m = LoopMeasurement::new(&config(), 0.0).unwrap();
    // each point as it comes (from the top down) against the exact loop
    let mut seen = 0u8;
    let furthest = run(&mut m, 2_000_000, |m| {
        if m.measured() > seen {
            seen = m.measured();
            let (_, p) = m.last_point().unwrap();
            let l = exact_loop(f64::from(p.freq_hz));
            let err =
                libm::hypot(f64::from(p.re) - l.0, f64::from(p.im) - l.1) / libm::hypot(l.0, l.1);
            assert!(err < 0.002, "{p:?} against {l:?}: {err}");
        }
    });
    assert_eq!(m.status(), IdentifyStatus::Done);
    assert_eq!(seen, 24);
    // the reference stays between the turn points (window less the 5 mm edges)
    assert!(furthest <= 45.0, "{furthest}");
    // the inertia from the plant's response at the highest frequency
    assert!((f64::from(m.inertia_estimate()) / J - 1.0).abs() < 0.01);
}

#[test]
fn a_window_too_short_and_a_start_outside_it_are_refused() {
    let short = ResponseConfig {
        window_min_mm: -20.0,
        window_max_mm: 20.0,
        ..config()
    };
    assert!(matches!(
        LoopMeasurement::new(&short, 0.0),
        Err(ResponseConfigError::WindowTooShort { .. })
    ));
    assert_eq!(
        LoopMeasurement::new(&config(), 47.0).unwrap_err(),
        ResponseConfigError::StartOutsideWindow
    );
}

#[test]
fn a_fault_or_the_window_left_stops_the_effort_at_once() {
    let mut m = LoopMeasurement::new(&config(), 0.0).unwrap();
    let ok = AxisSample {
        pos_mm: 0.0,
        vel_mm_s: 0.0,
        effort_applied_mnm: 0.0,
        fault: false,
    };
    assert_eq!(m.step(&ok, 12.0).effort_mnm, 12.0);
    let out = m.step(&AxisSample { fault: true, ..ok }, 12.0);
    assert_eq!(out.effort_mnm, 0.0);
    assert_eq!(out.status, IdentifyStatus::Aborted(AbortReason::Fault));
    assert_eq!(m.step(&ok, 12.0).effort_mnm, 0.0);
    let mut m = LoopMeasurement::new(&config(), 0.0).unwrap();
    let out = m.step(&AxisSample { pos_mm: 50.5, ..ok }, 12.0);
    assert_eq!(out.effort_mnm, 0.0);
    assert_eq!(out.status, IdentifyStatus::Aborted(AbortReason::LeftWindow));
    // the laws' effort held at the cap for half a second: the axis does not follow
    let mut m = LoopMeasurement::new(&config(), 0.0).unwrap();
    let mut last = None;
    for _ in 0..5_001 {
        last = Some(m.step(&ok, 600.0));
    }
    assert_eq!(
        last.unwrap().status,
        IdentifyStatus::Aborted(AbortReason::Saturated)
    );
}
