//! Identification's safety behaviour: every abort path, what the effort does on it, and
//! bounded, finite output whatever the input.

use crate::sysid_common;

use controller_core::plant::physical::PhysicalAxisConfig;
use controller_core::presets::gantry::GANTRY_X;
use controller_core::sysid::identifier::SATURATION_LIMIT_S;
use controller_core::sysid::{
    AbortReason, AxisSample, Identifier, IdentifyConfig, IdentifyConfigError, IdentifyPhase,
    IdentifyStatus, IDENTIFY_DEFAULTS,
};
use proptest::prelude::*;
use sysid_common::*;

/// Period at which faults are injected: 2 s, in the friction passes.
const INJECT_AT: u32 = 20_000;

/// Run on GANTRY_X with `hook`; returns the run and every (period, output) from the
/// injection on.
fn run_injected(
    cfg: &IdentifyConfig,
    mut hook: impl FnMut(u32, &mut AxisSample, &mut SimAxis),
) -> (Run, Vec<(u32, controller_core::sysid::IdentifyOutput)>) {
    let mut sim = SimAxis::new(&GANTRY_X, 0.0, 3);
    let mut log = Vec::new();
    let r = run_with(&mut sim, cfg, &mut hook, |k, _, o| {
        if k >= INJECT_AT {
            log.push((k, *o));
        }
    });
    (r, log)
}

fn cfg() -> IdentifyConfig {
    identify_config(&GANTRY_X)
}

/// An immediate abort: the output of the injection period itself is zero and aborted.
fn assert_immediate(log: &[(u32, controller_core::sysid::IdentifyOutput)], reason: AbortReason) {
    let (k, o) = log[0];
    assert_eq!(k, INJECT_AT);
    assert_eq!(o.status, IdentifyStatus::Aborted(reason));
    assert_eq!(o.phase, IdentifyPhase::Aborted);
    assert_eq!(o.effort_mnm, 0.0);
}

#[test]
fn fault_flag_zeroes_the_effort_at_once() {
    let (r, log) = run_injected(&cfg(), |k, s, _| s.fault = k >= INJECT_AT);
    assert_immediate(&log, AbortReason::Fault);
    assert_eq!(r.status, IdentifyStatus::Aborted(AbortReason::Fault));
    assert!(r.result.is_none());
}

#[test]
fn non_finite_inputs_abort_with_zero_effort() {
    type Corrupt = fn(&mut AxisSample);
    let corrupt: [Corrupt; 3] = [
        |s| s.pos_mm = f32::NAN,
        |s| s.vel_mm_s = f32::INFINITY,
        |s| s.effort_applied_mnm = f32::NAN,
    ];
    for c in corrupt {
        let (_, log) = run_injected(&cfg(), |k, s, _| {
            if k == INJECT_AT {
                c(s)
            }
        });
        assert_immediate(&log, AbortReason::NonFiniteInput);
    }
}

#[test]
fn measured_position_outside_the_window_aborts_at_once() {
    let (_, log) = run_injected(&cfg(), |k, s, _| {
        if k == INJECT_AT {
            s.pos_mm = 50.001
        }
    });
    assert_immediate(&log, AbortReason::LeftWindow);
}

/// A push of 1.5× the cap (a crash, a falling load): the loop cannot hold the axis; the
/// velocity limit ends it with zero effort long before the window's end.
#[test]
fn runaway_trips_the_velocity_limit() {
    let c = cfg();
    let (r, log) = run_injected(&c, |k, _, sim| {
        if k == INJECT_AT {
            sim.external_mnm = -1.5 * c.torque_cap_mnm as f64;
        }
    });
    assert_eq!(
        r.status,
        IdentifyStatus::Aborted(AbortReason::VelocityLimit)
    );
    let last = log.last().unwrap().1;
    assert_eq!(last.effort_mnm, 0.0);
    // until the trip the loop pushed against the runaway with the whole cap (it
    // saturates ~8 ms after the push, the trip comes ~18 ms after it)
    let braking = &log[log.len().saturating_sub(50)..log.len() - 1];
    assert!(
        braking
            .iter()
            .all(|(_, o)| o.effort_mnm == -c.torque_cap_mnm),
        "{:?}",
        &braking[..3]
    );
    assert!(r.pos_max_mm < c.window_max_mm as f64 && r.pos_min_mm > c.window_min_mm as f64);
}

/// A blocked axis (friction above the cap) or an encoder that stopped counting: the
/// effort saturates, the watchdog zeroes it after [`SATURATION_LIMIT_S`].
#[test]
fn axis_that_does_not_follow_aborts_saturated() {
    let blocked = PhysicalAxisConfig {
        coulomb_pos_mnm: 600.0,
        coulomb_neg_mnm: -600.0,
        ..GANTRY_X
    };
    let mut sim = SimAxis::new(&blocked, 0.0, 1);
    let r = run_with(&mut sim, &cfg(), |_, _, _| {}, |_, _, _| {});
    assert_eq!(r.status, IdentifyStatus::Aborted(AbortReason::Saturated));
    assert!(r.machine_time_s < 2.0, "{}", r.machine_time_s);

    // encoder stuck at its reading of 2 s: the real axis would run away unseen; the loop
    // saturates once the setpoint leaves the frozen reading (the next ramp), the
    // watchdog trips SATURATION_LIMIT_S later
    let mut frozen = None;
    let (r, log) = run_injected(&cfg(), |k, s, _| {
        if k >= INJECT_AT {
            let f = *frozen.get_or_insert((s.pos_mm, s.vel_mm_s));
            s.pos_mm = f.0;
            s.vel_mm_s = f.1;
        }
    });
    assert_eq!(r.status, IdentifyStatus::Aborted(AbortReason::Saturated));
    let t_abort = (log.last().unwrap().0 - INJECT_AT) as f32 * 1e-4;
    assert!(
        (SATURATION_LIMIT_S..=SATURATION_LIMIT_S + 0.5).contains(&t_abort),
        "{t_abort}"
    );
}

#[test]
fn time_budget_brakes_to_rest_then_aborts() {
    let c = IdentifyConfig {
        time_budget_s: 2.0,
        ..cfg()
    };
    let mut states = Vec::new();
    let mut sim = SimAxis::new(&GANTRY_X, 0.0, 3);
    let r = run_with(
        &mut sim,
        &c,
        |_, _, _| {},
        |k, _, o| {
            if states.last().map(|(_, s)| *s) != Some(o.status) {
                states.push((k, o.status));
            }
        },
    );
    let statuses: Vec<_> = states.iter().map(|(_, s)| *s).collect();
    assert_eq!(
        statuses,
        [
            IdentifyStatus::Running,
            IdentifyStatus::Stopping(AbortReason::TimeBudget),
            IdentifyStatus::Aborted(AbortReason::TimeBudget)
        ]
    );
    assert!((states[1].0 as f32 * 1e-4 - 2.0).abs() < 1e-3);
    // braked to rest within a fraction of a second, inside the window
    assert!(r.machine_time_s < 2.5, "{}", r.machine_time_s);
    assert!(r.final_speed_mm_s.abs() < 2.0, "{}", r.final_speed_mm_s);
    assert!(r.pos_max_mm < 50.0 && r.pos_min_mm > -50.0);
}

/// Moving towards the end faster than the plan allows (here: a sample sequence as if
/// the axis had been pushed): the identifier brakes at once, then aborts at rest.
#[test]
fn predicted_window_exit_brakes_first() {
    let c = IDENTIFY_DEFAULTS;
    let mut id = Identifier::new(&c, 0.0).unwrap();
    let mut last = 0.0;
    let mut step = |id: &mut Identifier, pos: f32, vel: f32| {
        let o = id.step(&AxisSample {
            pos_mm: pos,
            vel_mm_s: vel,
            effort_applied_mnm: last,
            fault: false,
        });
        last = o.effort_mnm;
        o
    };
    for _ in 0..10 {
        assert_eq!(step(&mut id, 0.0, 0.0).status, IdentifyStatus::Running);
    }
    // 44 mm at 150 mm/s: the stopping point lies beyond 50 mm; brake with the cap
    let o = step(&mut id, 44.0, 150.0);
    assert_eq!(
        o.status,
        IdentifyStatus::Stopping(AbortReason::WouldLeaveWindow)
    );
    assert_eq!(o.phase, IdentifyPhase::Stopping);
    assert_eq!(o.effort_mnm, -c.torque_cap_mnm, "{o:?}");
    // decelerate to rest: braking effort all the way, then aborted with zero effort
    let mut v = 150.0;
    let mut pos = 44.0;
    let mut n = 0;
    loop {
        v = (v - 5.0_f32).max(0.0);
        pos += v * 1e-4;
        let o = step(&mut id, pos, v);
        n += 1;
        assert!(n < 2000, "never stopped");
        match o.status {
            IdentifyStatus::Stopping(AbortReason::WouldLeaveWindow) => {
                assert!(o.effort_mnm <= 0.0 || v == 0.0, "{o:?} at {v}")
            }
            IdentifyStatus::Aborted(AbortReason::WouldLeaveWindow) => {
                assert_eq!(o.effort_mnm, 0.0);
                break;
            }
            other => panic!("{other:?}"),
        }
    }
    // finished: zero from now on, whatever comes in
    for _ in 0..10 {
        let o = step(&mut id, 0.0, 0.0);
        assert_eq!(o.effort_mnm, 0.0);
        assert_eq!(
            o.status,
            IdentifyStatus::Aborted(AbortReason::WouldLeaveWindow)
        );
    }
}

/// The amplifier loses 70 % of its gain mid-pass (a failing drive): the reversal planned
/// with the old torque cannot stop in time, the window guard sees the stopping point
/// beyond the window, brakes with the whole (remaining) cap, and aborts at rest inside
/// the window.
#[test]
fn weakened_amplifier_is_stopped_inside_the_window() {
    // a random machine of the documented range (seed 5, index 3)
    let axis = PhysicalAxisConfig {
        inertia: 0.241_167_47,
        viscous: 0.198_980_78,
        coulomb_pos_mnm: 21.012_045,
        coulomb_neg_mnm: -40.7767,
        stiction_ratio: 1.057_432_3,
        v_stribeck_mm_s: 2.974_93,
        torque_max_mnm: 1360.1613,
        ..GANTRY_X
    };
    for at in [14_000, 15_000, 16_000] {
        let mut sim = SimAxis::new(&axis, 0.0, 3);
        let mut seq = Vec::new();
        let r = run_with(
            &mut sim,
            &identify_config(&axis),
            |k, _, sim| {
                if k == at {
                    sim.torque_scale = 0.3
                }
            },
            |_, _, o| {
                if seq.last() != Some(&o.status) {
                    seq.push(o.status)
                }
            },
        );
        assert_eq!(
            seq,
            [
                IdentifyStatus::Running,
                IdentifyStatus::Stopping(AbortReason::WouldLeaveWindow),
                IdentifyStatus::Aborted(AbortReason::WouldLeaveWindow)
            ],
            "at {at}"
        );
        assert!(
            r.pos_min_mm > -50.0 && r.pos_max_mm < 50.0,
            "{} {}",
            r.pos_min_mm,
            r.pos_max_mm
        );
        assert!(r.final_speed_mm_s.abs() < 2.0, "{}", r.final_speed_mm_s);
    }
}

/// Friction that leaves less than the planned torque fraction: the passes run (the
/// loop has the whole cap) but the inertia phase cannot accelerate; it says so.
#[test]
fn friction_near_the_cap_reports_no_torque_margin() {
    let heavy = PhysicalAxisConfig {
        coulomb_pos_mnm: 420.0,
        coulomb_neg_mnm: -420.0,
        stiction_ratio: 1.0,
        ..GANTRY_X
    };
    let mut sim = SimAxis::new(&heavy, 0.0, 1);
    let r = run_with(&mut sim, &cfg(), |_, _, _| {}, |_, _, _| {});
    assert_eq!(
        r.status,
        IdentifyStatus::Aborted(AbortReason::NoTorqueMargin)
    );
    assert!(r.final_speed_mm_s.abs() < 2.0);
    assert!(r.pos_max_mm < 50.0 && r.pos_min_mm > -50.0);
}

#[test]
fn start_outside_the_margins_is_rejected() {
    assert_eq!(
        Identifier::new(&IDENTIFY_DEFAULTS, -47.0).unwrap_err(),
        IdentifyConfigError::StartOutsideWindow {
            start_mm: -47.0,
            min_mm: -45.0,
            max_mm: 45.0
        }
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Whatever arrives (garbage positions, velocities, efforts, faults, non-finite
    /// values), the output is finite, within the cap, the progress within [0, 1], and
    /// once finished the effort stays zero.
    #[test]
    fn output_is_bounded_for_any_input(
        samples in prop::collection::vec(
            (
                prop_oneof![8 => -55.0f32..55.0, 1 => Just(f32::NAN)],
                prop_oneof![8 => -300.0f32..300.0, 1 => Just(f32::INFINITY)],
                -2000.0f32..2000.0,
                prop::bool::weighted(0.01),
            ),
            1..400,
        ),
        cap in 10.0f32..3000.0,
    ) {
        let c = IdentifyConfig { torque_cap_mnm: cap, ..IDENTIFY_DEFAULTS };
        let mut id = Identifier::new(&c, 0.0).unwrap();
        let mut finished = false;
        for (pos, vel, effort, fault) in samples {
            let o = id.step(&AxisSample { pos_mm: pos, vel_mm_s: vel, effort_applied_mnm: effort, fault });
            prop_assert!(o.effort_mnm.is_finite() && o.effort_mnm.abs() <= cap);
            prop_assert!((0.0..=1.0).contains(&o.progress));
            if finished {
                prop_assert_eq!(o.effort_mnm, 0.0);
            }
            finished |= matches!(o.status, IdentifyStatus::Done | IdentifyStatus::Aborted(_));
        }
    }

    /// The simulated axis with a fault injected at a random instant: effort zero from
    /// that period on, never NaN before.
    #[test]
    fn fault_at_any_time_zeroes_the_effort(at in 1u32..60_000) {
        let (r, log) = {
            let mut sim = SimAxis::new(&GANTRY_X, 0.0, 5);
            let mut log = Vec::new();
            let r = run_with(&mut sim, &cfg(), |k, s, _| s.fault = k >= at, |k, _, o| {
                if k >= at { log.push(o.effort_mnm) }
            });
            (r, log)
        };
        prop_assert!(r.all_finite);
        // a run that finished before `at` has no log
        prop_assert!(log.iter().all(|&u| u == 0.0));
        prop_assert!(matches!(r.status, IdentifyStatus::Aborted(AbortReason::Fault) | IdentifyStatus::Done));
    }
}
