//! The servo's operating modes on the simulated physical gantry (the board's
//! configuration): homing on the limit switches, soft limits, jogging, identification,
//! and the refusals of commands that are not valid in the current state.

use controller_core::axes::Axis;
use controller_core::plant::AxisModel;
use controller_core::presets::board::{factory_config, servo_config};
use controller_core::presets::gantry::{GANTRY_AXES, GANTRY_HOMING};
use controller_core::servo::faults::FaultKind;
use controller_core::servo::{Command, CommandRefusal, ServoConfig, ServoState};
use controller_core::sim::run::{RunConfig, SimRun};
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, PlantConfig, SwitchConfig, WorldConfig,
};
use controller_core::sysid::IdentifyStatus;

const RATE_HZ: u32 = 10_000;
const COUNT_MM: f64 = 1.0 / 1600.0;

/// The switches of the simulated machine in its true coordinates (the machine powers up
/// somewhere in its travel: true 0 is wherever it was).
const SWITCH_X_MIN: f64 = -40.0;
const SWITCH_Y_MIN: f64 = -30.0;
const SWITCH_Z_MAX: f64 = 20.0;

fn world(start: [f64; 3]) -> WorldConfig {
    WorldConfig {
        plants: GANTRY_AXES.map(PlantConfig::Physical),
        plant_substeps: 4,
        initial: start.map(|p| InitialState {
            pos_mm: p,
            vel_mm_s: 0.0,
        }),
        switches: [
            SwitchConfig {
                min_mm: SWITCH_X_MIN,
                ..SwitchConfig::NONE
            },
            SwitchConfig {
                min_mm: SWITCH_Y_MIN,
                ..SwitchConfig::NONE
            },
            SwitchConfig {
                max_mm: SWITCH_Z_MAX,
                ..SwitchConfig::NONE
            },
        ],
        imperfections: ImperfectionConfig::default(),
        brakes: Default::default(),
    }
}

fn run_with(servo: ServoConfig, start: [f64; 3]) -> SimRun<f32> {
    SimRun::new(&RunConfig {
        servo,
        world: world(start),
        truth: TruthSpec::default(),
        periods: u32::MAX,
        hold: true,
        inject: None,
        program: false,
    })
    .expect("valid configuration")
}

fn run(start: [f64; 3]) -> SimRun<f32> {
    run_with(servo_config(RATE_HZ), start)
}

/// `n` periods with `cmds` in the first; the last snapshot's refusal, if any.
fn step(r: &mut SimRun<f32>, cmds: &[Command], n: u32) -> Option<CommandRefusal> {
    let mut refused = None;
    for k in 0..n {
        let s = r.control_with(if k == 0 { cmds } else { &[] });
        if k == 0 {
            refused = s.refused.map(|(_, why)| why);
        }
        r.finish_period();
    }
    refused
}

/// Periods until `done` holds (at most `max`).
fn until(r: &mut SimRun<f32>, max: u32, done: impl Fn(&SimRun<f32>) -> bool) -> u32 {
    for k in 0..max {
        if done(r) {
            return k;
        }
        r.control_with(&[]);
        r.finish_period();
    }
    panic!(
        "not done after {max} periods: state {:?}, faults {:?}",
        r.servo().state(),
        r.servo().faults().first()
    );
}

fn home(r: &mut SimRun<f32>) -> u32 {
    if r.servo().state() == ServoState::Disabled {
        assert_eq!(step(r, &[Command::Arm], 1), None);
    }
    assert_eq!(step(r, &[Command::Home], 1), None);
    assert_eq!(r.servo().state(), ServoState::Homing);
    until(r, 400_000, |r| r.servo().state() != ServoState::Homing)
}

#[test]
fn homing_finds_every_switch_and_repeats_to_a_count() {
    let mut r = run([0.0, 5.0, -3.0]);
    let periods = home(&mut r);
    assert_eq!(
        r.servo().state(),
        ServoState::Idle,
        "{:?}",
        r.servo().faults().first()
    );
    assert!(!r.servo().faults().any());
    let s = *r.servo().snapshot();
    assert_eq!(s.homed, 0b111);
    // every axis rests at its home point in machine coordinates...
    let home_mm = GANTRY_HOMING.axes.map(|a| a.home_mm());
    step(&mut r, &[], 2_000);
    let s = *r.servo().snapshot();
    for (i, (p, h)) in s.pos.iter().zip(home_mm).enumerate() {
        assert!((p - h).abs() < 0.005, "axis {i}: {p} vs {h}");
    }
    // ...which is `pulloff` from the switch in the true coordinates
    let t = r.world().state().map(|a| a.pos);
    assert!((t[0] - (SWITCH_X_MIN + 2.0)).abs() < 0.01, "{t:?}");
    assert!((t[1] - (SWITCH_Y_MIN + 2.0)).abs() < 0.01, "{t:?}");
    assert!((t[2] - (SWITCH_Z_MAX - 2.0)).abs() < 0.01, "{t:?}");
    // Z first, then X and Y: about 40 / 35 / 23 mm at 20 mm/s plus 4 mm slow each
    assert!(periods < 200_000, "{periods} periods");

    // home again from elsewhere: the origin repeats within a count or two
    let origin_before = [0, 1, 2].map(|i| s.counts[i] as f64 * COUNT_MM - t[i]);
    step(
        &mut r,
        &[Command::Jog {
            axis: Axis::X,
            vel_mm_s: 30.0,
        }],
        3_000,
    );
    until(&mut r, 50_000, |r| r.servo().state() == ServoState::Idle);
    home(&mut r);
    step(&mut r, &[], 2_000);
    let s = *r.servo().snapshot();
    let t = r.world().state().map(|a| a.pos);
    for i in 0..3 {
        let origin = s.counts[i] as f64 * COUNT_MM - t[i];
        assert!(
            (origin - origin_before[i]).abs() <= 2.0 * COUNT_MM,
            "axis {i}: origin moved {} mm",
            origin - origin_before[i]
        );
    }
}

#[test]
fn a_board_config_fault_is_never_reset_and_keeps_the_outputs_off() {
    // the firmware's boot self-check latches it (firmware/src/board/self_check.rs): the
    // board's registers are not what the table says, nothing a reset can change
    let mut r = run([0.0; 3]);
    r.machine_mut().latch_board_fault(FaultKind::BoardConfig);
    step(&mut r, &[], 10);
    assert_eq!(r.servo().state(), ServoState::Fault);
    for _ in 0..3 {
        step(&mut r, &[Command::Reset], 100);
        assert_eq!(r.servo().state(), ServoState::Fault);
        assert_eq!(
            step(&mut r, &[Command::Arm], 10),
            Some(CommandRefusal::FaultLatched)
        );
        assert!(!r.world().outputs_on());
    }
    let f = r.servo().faults().first().expect("latched");
    assert_eq!(
        (f.fault.kind, f.fault.kind.name()),
        (FaultKind::BoardConfig, "board_config")
    );
}

#[test]
fn a_forgotten_home_refuses_programs_until_homed_again() {
    // the firmware forgets Z's home after a stall its 16-bit counter cannot follow
    // (firmware/src/stall.rs): programs need Z homed again, the other axes keep theirs
    let mut r = run([0.0, 5.0, -3.0]);
    home(&mut r);
    assert_eq!(r.servo().snapshot().homed, 0b111);
    r.machine_mut().forget_home(Axis::Z);
    assert_eq!(r.servo().snapshot().homed, 0b011);
    assert_eq!(
        step(&mut r, &[Command::Run], 1),
        Some(CommandRefusal::NotHomed { axis: Axis::Z })
    );
    assert_eq!(r.servo().state(), ServoState::Idle);
    home(&mut r);
    assert_eq!(r.servo().snapshot().homed, 0b111);
    assert_ne!(
        step(&mut r, &[Command::Run], 1),
        Some(CommandRefusal::NotHomed { axis: Axis::Z })
    );
}

#[test]
fn jog_stops_at_the_soft_limit_once_homed() {
    let mut r = run([0.0; 3]);
    home(&mut r);
    // hold the jog key (a command every 0.1 s) toward X's min end for 6 s
    for _ in 0..60 {
        assert_eq!(
            step(
                &mut r,
                &[Command::Jog {
                    axis: Axis::X,
                    vel_mm_s: -50.0
                }],
                1_000
            ),
            None
        );
    }
    let s = *r.servo().snapshot();
    assert!(
        !r.servo().faults().any(),
        "{:?}",
        r.servo().faults().first()
    );
    assert!(s.reference[0] >= -150.0 - 1e-3, "{}", s.reference[0]);
    assert!(s.pos[0] >= -150.05 && s.pos[0] < -149.9, "{}", s.pos[0]);
    // the key released: the jog ends by itself and the machine holds
    until(&mut r, 10_000, |r| r.servo().state() == ServoState::Idle);
}

#[test]
fn jog_times_out_when_commands_stop() {
    let mut r = run([0.0; 3]);
    step(&mut r, &[Command::Arm], 10);
    step(
        &mut r,
        &[Command::Jog {
            axis: Axis::Y,
            vel_mm_s: 20.0,
        }],
        1,
    );
    // the jog starts once the Z brake is open (70 ms after arming: 690 periods after the
    // jog command), then 0.3 s timeout + 20 / 500 s of braking, then Idle
    let k = until(&mut r, 20_000, |r| r.servo().state() == ServoState::Idle);
    assert!((3_690..4_290).contains(&k), "{k}");
    let moved = r.servo().snapshot().pos[1];
    assert!((5.0..7.0).contains(&moved), "{moved}");
}

#[test]
fn unhomed_jog_into_a_switch_is_a_hard_limit_fault() {
    let mut r = run([0.0; 3]);
    step(&mut r, &[Command::Arm], 10);
    for _ in 0..30 {
        step(
            &mut r,
            &[Command::Jog {
                axis: Axis::Z,
                vel_mm_s: 50.0,
            }],
            1_000,
        );
        if r.servo().state() == ServoState::Fault {
            break;
        }
    }
    let f = r.servo().faults().first().expect("a fault");
    assert_eq!(f.fault.kind, FaultKind::LimitMax);
    assert_eq!(f.fault.axis, Some(Axis::Z));
    assert!(!r.world().outputs_on());
}

#[test]
fn refusals_name_the_reason_and_change_nothing() {
    let mut r = run([0.0; 3]);
    // not armed: no homing, no jog
    assert_eq!(
        step(&mut r, &[Command::Home], 1),
        Some(CommandRefusal::WrongState)
    );
    assert_eq!(
        step(
            &mut r,
            &[Command::Jog {
                axis: Axis::X,
                vel_mm_s: 1.0
            }],
            1
        ),
        Some(CommandRefusal::WrongState)
    );
    assert_eq!(r.servo().state(), ServoState::Disabled);
    step(&mut r, &[Command::Arm], 1);
    // programs need a homed machine
    assert_eq!(
        step(&mut r, &[Command::Run], 1),
        Some(CommandRefusal::NotHomed { axis: Axis::X })
    );
    assert_eq!(r.servo().state(), ServoState::Idle);
    // identification without homing needs a window that contains the axis
    assert_eq!(
        step(
            &mut r,
            &[Command::Identify {
                axis: Axis::X,
                window_mm: Some([5.0, 60.0])
            }],
            1
        ),
        Some(CommandRefusal::BadWindow { axis: Axis::X })
    );
    assert_eq!(r.servo().state(), ServoState::Idle);

    // factory settings: the models are unknown, the DSMC axes refuse to arm
    let mut f = run_with(factory_config(RATE_HZ), [0.0; 3]);
    assert_eq!(
        step(&mut f, &[Command::Arm], 1),
        Some(CommandRefusal::ModelMissing { axis: Axis::X })
    );
    assert_eq!(f.servo().state(), ServoState::Disabled);
    assert!(!f.world().outputs_on());
}

#[test]
fn identification_from_disabled_drives_one_axis_and_finds_its_model() {
    // factory settings: nothing armable, but an axis can be identified in a window
    let mut r = run_with(factory_config(RATE_HZ), [0.0; 3]);
    let cmd = Command::Identify {
        axis: Axis::X,
        window_mm: Some([-35.0, 60.0]),
    };
    assert_eq!(step(&mut r, &[cmd], 1), None);
    assert_eq!(r.servo().state(), ServoState::Identify);
    let mut max_other = 0.0f32;
    let mut lo = f64::MAX;
    let mut hi = f64::MIN;
    let k = {
        let mut k = 0;
        while r.servo().state() == ServoState::Identify {
            let s = *r.control_with(&[]);
            max_other = max_other.max(s.effort[1].abs()).max(s.effort[2].abs());
            r.finish_period();
            let x = r.world().state()[0].pos;
            lo = lo.min(x);
            hi = hi.max(x);
            k += 1;
            assert!(k < 200_000, "identification did not end");
        }
        k
    };
    assert_eq!(r.servo().state(), ServoState::Disabled);
    assert!(!r.world().outputs_on());
    assert_eq!(max_other, 0.0, "the other axes stay unpowered");
    assert!(lo >= -35.0 && hi <= 60.0, "left the window: {lo}..{hi}");
    let out = r.servo().identify_outcome().expect("an outcome");
    assert_eq!(out.status, IdentifyStatus::Done, "{:?}", out.status);
    let m = out.result.expect("a model").model;
    let t = AxisModel::from_physical_with_load(&GANTRY_AXES[0]);
    let rel = |a: f32, b: f32| ((a - b) / b).abs();
    assert!(rel(m.inertia, t.inertia) < 0.05, "{m:?} vs {t:?}");
    assert!(
        rel(m.coulomb_pos_mnm, t.coulomb_pos_mnm) < 0.10,
        "{m:?} vs {t:?}"
    );
    assert!(
        rel(m.coulomb_neg_mnm, t.coulomb_neg_mnm) < 0.10,
        "{m:?} vs {t:?}"
    );
    assert!(rel(m.viscous, t.viscous) < 0.25, "{m:?} vs {t:?}");
    // within 10 s of machine time
    assert!(k <= 100_000, "{k} periods");
}

#[test]
fn stop_ends_a_move_in_idle_and_disarm_during_identification_cuts_the_outputs() {
    let mut r = run([0.0; 3]);
    step(&mut r, &[Command::Arm, Command::StartPath], 5_000);
    assert_eq!(step(&mut r, &[Command::Stop], 1), None);
    assert_eq!(r.servo().state(), ServoState::Stopping);
    until(&mut r, 20_000, |r| r.servo().state() == ServoState::Idle);
    assert!(!r.servo().faults().any());
    assert!(r.world().outputs_on());

    let cmd = Command::Identify {
        axis: Axis::Y,
        window_mm: Some([-40.0, 40.0]),
    };
    let here = r.servo().snapshot().pos[1];
    assert_eq!(step(&mut r, &[cmd], 2_000), None, "from {here}");
    assert_eq!(r.servo().state(), ServoState::Identify);
    assert_eq!(step(&mut r, &[Command::Disarm], 1), None);
    assert_eq!(r.servo().state(), ServoState::Disabled);
    assert!(!r.world().outputs_on());
    assert!(matches!(
        r.servo().identify_outcome().map(|o| o.status),
        Some(IdentifyStatus::Aborted(_))
    ));
}

/// A frequency-response measurement from Idle runs in the identification's mode under
/// its rules: one axis driven by the measurement, the others holding where they are,
/// its points readable as they come; a stop ends it holding (Idle), its outcome kept
/// apart from the model identification's.
#[test]
fn a_frequency_response_from_idle_measures_one_axis_and_a_stop_ends_it() {
    let mut r = run([0.0; 3]);
    step(&mut r, &[Command::Arm], 2_000);
    assert_eq!(r.servo().state(), ServoState::Idle);
    // the window must contain the axis
    let bad = Command::MeasureResponse {
        axis: Axis::Y,
        window_mm: Some([5.0, 60.0]),
    };
    assert_eq!(
        step(&mut r, &[bad], 1),
        Some(CommandRefusal::BadWindow { axis: Axis::Y })
    );
    let held = r.world().state().map(|a| a.pos);
    let cmd = Command::MeasureResponse {
        axis: Axis::Y,
        window_mm: Some([-50.0, 50.0]),
    };
    assert_eq!(step(&mut r, &[cmd], 1), None);
    assert_eq!(r.servo().state(), ServoState::Identify);
    // 6 s: the start, then the highest frequencies, one after the other
    let mut seen = Vec::new();
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for _ in 0..60_000 {
        r.control_with(&[]);
        if let Some((i, p)) = r.servo().response_point() {
            if seen.last().map(|(j, _)| *j) != Some(i) {
                seen.push((i, p));
            }
        }
        r.finish_period();
        let y = r.world().state()[1].pos;
        lo = lo.min(y);
        hi = hi.max(y);
    }
    assert_eq!(r.servo().state(), ServoState::Identify);
    assert!(seen.len() >= 3, "{seen:?}");
    // from the top of the grid down, each a point of the rigid Y's response: 1/(J ω²)
    for (k, (i, p)) in seen.iter().enumerate() {
        assert_eq!(usize::from(*i), k);
        let w = 2.0 * core::f32::consts::PI * p.freq_hz;
        let rigid = 1.0 / (GANTRY_AXES[1].inertia * w * w);
        assert!((p.magnitude() / rigid - 1.0).abs() < 0.1, "{p:?}");
    }
    assert!(seen[0].1.freq_hz > 290.0 && seen[1].1.freq_hz < seen[0].1.freq_hz);
    assert!(lo >= -50.0 && hi <= 50.0, "{lo}..{hi}");
    // the others hold
    let now = r.world().state().map(|a| a.pos);
    for i in [0, 2] {
        assert!(
            (now[i] - held[i]).abs() < 0.01,
            "axis {i}: {} -> {}",
            held[i],
            now[i]
        );
    }
    assert_eq!(step(&mut r, &[Command::Stop], 1), None);
    assert_eq!(r.servo().state(), ServoState::Idle);
    assert!(r.world().outputs_on());
    let out = r.servo().response_outcome().expect("an outcome");
    assert_eq!(out.axis, Axis::Y);
    assert!(matches!(out.status, IdentifyStatus::Aborted(_)), "{out:?}");
    assert_eq!(usize::from(out.points), seen.len());
    assert!(r.servo().identify_outcome().is_none());
    assert!(r.servo().response_point().is_none());
}

/// The loop measurement runs only on the laws (from Idle, never from Disabled): the axis
/// follows the procedure's travelling reference within the window while the others hold,
/// the loop's points come from the top of the grid down, above the crossover and rolling
/// off, and a stop ends it holding.
#[test]
fn a_loop_measurement_runs_on_the_laws_from_idle_only() {
    let mut r = run([0.0; 3]);
    let cmd = Command::MeasureLoop {
        axis: Axis::Y,
        window_mm: Some([-50.0, 50.0]),
    };
    assert_eq!(step(&mut r, &[cmd], 1), Some(CommandRefusal::WrongState));
    step(&mut r, &[Command::Arm], 2_000);
    assert_eq!(r.servo().state(), ServoState::Idle);
    let held = r.world().state().map(|a| a.pos);
    assert_eq!(step(&mut r, &[cmd], 1), None);
    assert_eq!(r.servo().state(), ServoState::Identify);
    // 4 s: the start (0.6 s settling) and the highest frequencies
    let mut seen = Vec::new();
    let (mut lo, mut hi, mut top_speed) = (f64::MAX, f64::MIN, 0.0f64);
    for _ in 0..40_000 {
        r.control_with(&[]);
        if let Some((i, p)) = r.servo().response_point() {
            if seen.last().map(|(j, _)| *j) != Some(i) {
                seen.push((i, p));
            }
        }
        r.finish_period();
        let y = r.world().state()[1];
        lo = lo.min(y.pos);
        hi = hi.max(y.pos);
        top_speed = top_speed.max(y.vel.abs());
    }
    assert_eq!(r.servo().state(), ServoState::Identify);
    assert!(seen.len() >= 4, "{seen:?}");
    for (k, (i, p)) in seen.iter().enumerate() {
        assert_eq!(usize::from(*i), k);
        // above the crossover (the laws' ~50 Hz): |L| < 1, falling with the frequency
        assert!(p.magnitude() < 0.5, "{p:?}");
        if k > 0 {
            assert!(p.magnitude() > seen[k - 1].1.magnitude(), "{seen:?}");
        }
    }
    assert!(seen[0].1.freq_hz > 390.0);
    // travelling at 15 mm/s with the sine's few mm/s on it, inside the window
    assert!(lo >= -45.5 && hi <= 45.5, "{lo}..{hi}");
    assert!(
        hi - lo > 10.0 && top_speed < 25.0,
        "{lo}..{hi}, {top_speed}"
    );
    let now = r.world().state().map(|a| a.pos);
    for i in [0, 2] {
        assert!((now[i] - held[i]).abs() < 0.01, "axis {i}");
    }
    assert_eq!(step(&mut r, &[Command::Stop], 1), None);
    assert_eq!(r.servo().state(), ServoState::Idle);
    assert!(r.world().outputs_on());
    let out = r.servo().response_outcome().expect("an outcome");
    assert_eq!(out.axis, Axis::Y);
    assert_eq!(usize::from(out.points), seen.len());
}

#[test]
fn homing_on_the_index_latches_the_pulse_after_the_switch() {
    // X's switch closes at true -38.7 mm; its encoder gives an index every 5 mm (8000
    // counts) of true travel, so the next one toward the switch side is at true -40 mm
    let mut cfg = servo_config(RATE_HZ);
    cfg.homing.axes[0].use_index = true;
    let mut w = world([0.0; 3]);
    w.switches[0] = SwitchConfig {
        min_mm: -38.7,
        max_mm: f64::INFINITY,
        index_period_counts: 8000,
    };
    let mut r = SimRun::new(&RunConfig {
        servo: cfg,
        world: w,
        truth: TruthSpec::default(),
        periods: u32::MAX,
        hold: true,
        inject: None,
        program: false,
    })
    .unwrap();
    home(&mut r);
    assert_eq!(
        r.servo().state(),
        ServoState::Idle,
        "{:?}",
        r.servo().faults().first()
    );
    step(&mut r, &[], 2_000);
    let s = *r.servo().snapshot();
    let t = r.world().state()[0].pos;
    // the index (true -40) is at the switch's machine position plus the 1.3 mm from the
    // switch to the index: machine = true - 112.3 mm
    let offset = s.counts[0] as f64 * COUNT_MM - t;
    assert!((offset + 112.3).abs() <= 2.0 * COUNT_MM, "offset {offset}");
}

#[test]
fn reconfigure_only_with_outputs_off_and_keeps_homing_and_counts() {
    use controller_core::servo::ReconfigureError;
    let mut r = run([0.0; 3]);
    home(&mut r);
    let before = *r.servo().snapshot();
    let mut cfg = servo_config(RATE_HZ);
    cfg.safety.axes[0].ferror_mm *= 2.0;
    assert_eq!(
        r.machine_mut().reconfigure(&cfg),
        Err(ReconfigureError::OutputsOn)
    );
    // the outputs go off once the Z brake grips (engage_s = 300 periods)
    step(&mut r, &[Command::Disarm], 310);
    let mut bad = cfg;
    bad.rate_hz = 5;
    assert!(matches!(
        r.machine_mut().reconfigure(&bad),
        Err(ReconfigureError::Config(_))
    ));
    assert_eq!(r.machine_mut().reconfigure(&cfg), Ok(()));
    step(&mut r, &[Command::Arm], 100);
    let s = *r.servo().snapshot();
    assert_eq!(s.homed, 0b111);
    for i in 0..3 {
        assert!(
            (s.pos[i] - before.pos[i]).abs() < 0.01,
            "{:?} vs {:?}",
            s.pos,
            before.pos
        );
    }
    assert_eq!(r.servo().state(), ServoState::Idle);
}

#[test]
fn link_lost_is_a_controlled_stop_and_resets_only_after_the_link_is_back() {
    let mut r = run([0.0; 3]);
    step(&mut r, &[Command::Arm, Command::StartPath], 5_000);
    step(&mut r, &[Command::LinkLost], 1);
    assert_eq!(r.servo().state(), ServoState::Stopping);
    until(&mut r, 20_000, |r| r.servo().state() == ServoState::Fault);
    let f = r.servo().faults().first().unwrap();
    assert_eq!(f.fault.kind, FaultKind::LinkLost);
    assert_eq!(
        step(&mut r, &[Command::Reset], 1),
        Some(CommandRefusal::FaultLatched)
    );
    assert_eq!(r.servo().state(), ServoState::Fault);
    step(&mut r, &[Command::LinkUp, Command::Reset], 1);
    assert_eq!(r.servo().state(), ServoState::Disabled);
}
