//! The servo step's safety state machine on the simulated physical gantry (board
//! configuration, controller-core presets): states, commands, stops and reset rules. The fault classes'
//! detection bounds are the fault matrix's (`host-sim faults`, tests/tests/faults.rs).

use controller_core::axes::Axis;
use controller_core::presets::board::servo_config;
use controller_core::presets::gantry::GANTRY_AXES;
use controller_core::servo::faults::FaultKind;
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::{RunConfig, SimRun, TimedInjection};
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, Injection, PlantConfig, SwitchConfig, WorldConfig,
};

fn run(inject: Option<TimedInjection>) -> SimRun<f32> {
    let cfg = RunConfig {
        servo: servo_config(10_000),
        world: WorldConfig {
            plants: GANTRY_AXES.map(PlantConfig::Physical),
            plant_substeps: 4,
            initial: [InitialState::default(); 3],
            switches: [SwitchConfig::NONE; 3],
            imperfections: ImperfectionConfig::default(),
            brakes: Default::default(),
        },
        truth: TruthSpec::default(),
        periods: 1_000_000,
        hold: true,
        inject,
        program: false,
    };
    SimRun::new(&cfg).expect("the board configuration validates")
}

/// Run `n` periods with `cmds` in the first.
fn step(r: &mut SimRun<f32>, cmds: &[Command], n: u32) {
    for k in 0..n {
        r.control_with(if k == 0 { cmds } else { &[] });
        r.finish_period();
    }
}

fn true_pos(r: &SimRun<f32>) -> [f64; 3] {
    r.world().state().map(|s| s.pos)
}

#[test]
fn boots_disabled_and_arming_holds_position() {
    let mut r = run(None);
    step(&mut r, &[], 10);
    assert_eq!(r.servo().state(), ServoState::Disabled);
    assert!(!r.world().outputs_on());
    step(&mut r, &[Command::Arm], 5_000);
    assert_eq!(r.servo().state(), ServoState::Idle);
    assert!(r.world().outputs_on());
    // half a second armed: no motion beyond the holding dither (a few counts)
    for p in true_pos(&r) {
        assert!(p.abs() < 0.01, "moved {p} mm while holding");
    }
    // the path moves only when started
    step(&mut r, &[Command::StartPath], 5_000);
    assert_eq!(r.servo().state(), ServoState::Run);
    assert!(true_pos(&r)[0].abs() > 1.0, "{:?}", true_pos(&r));
}

#[test]
fn disarm_while_moving_is_a_controlled_stop_not_a_fault() {
    let mut r = run(None);
    step(&mut r, &[Command::Arm, Command::StartPath], 5_000);
    step(&mut r, &[Command::Disarm], 1);
    assert_eq!(r.servo().state(), ServoState::Stopping);
    step(&mut r, &[], 3_000);
    assert_eq!(r.servo().state(), ServoState::Disabled);
    assert!(!r.servo().faults().any());
    assert!(!r.world().outputs_on());
}

#[test]
fn estop_reset_waits_for_release_and_never_re_enables() {
    let mut r = run(None);
    step(&mut r, &[Command::Arm], 100);
    r.world_mut().set_estop(true);
    step(&mut r, &[], 1);
    assert_eq!(r.servo().state(), ServoState::Fault);
    assert!(!r.world().outputs_on());
    // reset and arm refused while pressed
    step(&mut r, &[Command::Reset], 10);
    step(&mut r, &[Command::Arm], 10);
    assert_eq!(r.servo().state(), ServoState::Fault);
    r.world_mut().set_estop(false);
    // released: still latched until reset; arming a latched fault is refused
    step(&mut r, &[Command::Arm], 10);
    assert_eq!(r.servo().state(), ServoState::Fault);
    step(&mut r, &[Command::Reset], 10);
    assert_eq!(r.servo().state(), ServoState::Disabled);
    assert!(!r.world().outputs_on());
    step(&mut r, &[Command::Arm], 10);
    assert_eq!(r.servo().state(), ServoState::Idle);
}

#[test]
fn a_healthy_encoder_passes_the_check_after_a_jump_and_a_stuck_one_does_not() {
    // a one-off count jump (noise): the encoder is fine afterwards
    let mut r = run(Some(TimedInjection {
        at_s: 0.05,
        fault: Injection::EncoderJump {
            axis: Axis::Y,
            counts: 900,
        },
    }));
    step(&mut r, &[Command::Arm], 1_000);
    assert_eq!(r.servo().state(), ServoState::Fault);
    let f = r.servo().faults().first().expect("latched");
    assert_eq!(f.fault.kind, FaultKind::EncoderJump);
    step(&mut r, &[Command::Reset], 1);
    assert_eq!(r.servo().state(), ServoState::EncoderCheck);
    step(&mut r, &[], 1_000);
    assert_eq!(r.servo().state(), ServoState::Disabled, "the check passes");
    assert!(!r.servo().faults().any());
    // a stuck one: the reset is refused, after a bounded drift (stuck while the path
    // moves: it starts once the Z brake is open, 70 ms after arming)
    let mut r = run(Some(TimedInjection {
        at_s: 0.12,
        fault: Injection::EncoderStuck { axis: Axis::Y },
    }));
    step(&mut r, &[Command::Arm, Command::StartPath], 1_500);
    assert_eq!(r.servo().state(), ServoState::Fault);
    step(&mut r, &[], 3_000); // coast to rest
    let before = true_pos(&r)[1];
    step(&mut r, &[Command::Reset], 1_000);
    assert_eq!(r.servo().state(), ServoState::Fault, "reset refused");
    let drift = (true_pos(&r)[1] - before).abs();
    assert!(drift < 0.5, "moved {drift} mm during the check");
}

#[test]
fn arming_with_a_limit_switch_active_is_refused() {
    let mut r = run(None);
    r.world_mut().inputs.limits[2][0] = true;
    step(&mut r, &[Command::Arm], 10);
    assert_eq!(r.servo().state(), ServoState::Disabled);
    r.world_mut().inputs.limits[2][0] = false;
    step(&mut r, &[Command::Arm], 10);
    assert_eq!(r.servo().state(), ServoState::Idle);
}

#[test]
fn fault_history_keeps_the_first_and_the_period() {
    let mut r = run(None);
    step(&mut r, &[Command::Arm], 100);
    r.world_mut().inputs.amp_fault[1] = true;
    step(&mut r, &[], 1);
    r.world_mut().set_estop(true);
    step(&mut r, &[], 1);
    let log = r.servo().faults();
    let first = log.first().unwrap();
    assert_eq!(first.fault.kind, FaultKind::AmplifierFault);
    assert_eq!(first.fault.axis, Some(Axis::Y));
    assert_eq!(first.period, 101);
    assert!(log.is_latched(FaultKind::EStop, None));
    assert_eq!(log.history().count(), 2);
    // the amplifier fault input still active: reset refused
    r.world_mut().set_estop(false);
    step(&mut r, &[Command::Reset], 10);
    assert_eq!(r.servo().state(), ServoState::Fault);
    r.world_mut().inputs.amp_fault[1] = false;
    step(&mut r, &[Command::Reset], 10);
    assert_eq!(r.servo().state(), ServoState::Disabled);
}
