//! Bring-up's first fix at a real power-on: a motor or an encoder wired the other way
//! round. On the simulated gantry with X's encoder (or motor) reversed, the machine faults
//! on the first move; with `axis.x.encoder.invert` (or `axis.x.motor.invert`) set it homes
//! and goes where it is told, the true axis with it (docs/bring-up.md).

use controller_core::axes::Axis;
use controller_core::machine::messages::MachineState;
use controller_core::sim::world::Injection;
use host_sim::cli::client::Client;
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self};

/// A machine whose X is wired the other way round (`wiring`), with `key` set to `true`
/// first when given.
fn machine(wiring: Injection, key: Option<&str>) -> Client<SimMachine> {
    let mut m = SimMachine::new(SimModels::Designed, 10).unwrap();
    m.inject(&wiring);
    let mut c = Client::connect_session(m, 5).unwrap();
    if let Some(k) = key {
        cli::set(&mut c, k, "true").unwrap();
        assert_eq!(cli::get(&mut c, k).unwrap(), "true");
    }
    c
}

/// Home, then move X to 20 mm: the machine's and the true position of X after it.
fn home_and_move(c: &mut Client<SimMachine>) -> anyhow::Result<(f32, f64)> {
    cli::ready(c, true)?;
    let s = cli::move_to(c, [20.0, 0.0, 0.0])?;
    let truth = c.transport.world().state()[0].pos;
    Ok((s.pos_mm[0], truth))
}

fn check_inverted_wiring_works(wiring: Injection, key: &str) {
    // as wired, the first motion faults (the loop pushes the wrong way)
    let mut c = machine(wiring, None);
    let e = home_and_move(&mut c).unwrap_err().to_string();
    let s = cli::wait_while(&mut c, |s| s.state == MachineState::Stopping).unwrap();
    assert_eq!(s.state, MachineState::Fault, "{e}: {s:?}");
    let fault = s.first_fault.as_deref().unwrap_or("");
    assert!(fault.ends_with("on x"), "{fault}");
    // with the setting, it homes and goes where it is told
    let mut c = machine(wiring, Some(key));
    let (pos_mm, true_mm) = home_and_move(&mut c).unwrap();
    assert!((pos_mm - 20.0).abs() < 0.01, "{key}: X at {pos_mm} mm");
    assert!(
        (true_mm - 20.0).abs() < 0.01,
        "{key}: the true X at {true_mm} mm"
    );
    let s = c.status().unwrap();
    assert_eq!(s.state, MachineState::Idle);
    assert!(s.first_fault.is_none(), "{:?}", s.first_fault);
}

#[test]
fn a_reversed_encoder_faults_and_encoder_invert_makes_it_right() {
    check_inverted_wiring_works(
        Injection::EncoderReversed { axis: Axis::X },
        "axis.x.encoder.invert",
    );
}

#[test]
fn a_reversed_motor_faults_and_motor_invert_makes_it_right() {
    check_inverted_wiring_works(
        Injection::MotorReversed { axis: Axis::X },
        "axis.x.motor.invert",
    );
}

#[test]
fn changing_a_direction_forgets_the_axis_home_and_is_refused_while_armed() {
    let mut c = machine(
        Injection::MotorReversed { axis: Axis::Y },
        Some("axis.y.motor.invert"),
    );
    cli::ready(&mut c, true).unwrap();
    assert_eq!(c.status().unwrap().homed, 0b111);
    // outputs on: refused, nothing changed
    let e = cli::set(&mut c, "axis.x.encoder.invert", "true").unwrap_err();
    assert!(format!("{e:#}").contains("outputs"), "{e:#}");
    assert_eq!(cli::get(&mut c, "axis.x.encoder.invert").unwrap(), "false");
    // outputs off: taken, and the position frame changed: every axis homes again
    expect_disarm(&mut c);
    cli::set(&mut c, "axis.x.encoder.invert", "true").unwrap();
    let s = c.status().unwrap();
    assert_eq!(s.homed, 0, "{s:?}");
    assert!(s.first_fault.is_none());
}

fn expect_disarm(c: &mut Client<SimMachine>) {
    host_sim::cli::client::expect_done(
        "disarm",
        c.exec(controller_core::machine::messages::Request::Disarm)
            .unwrap(),
    )
    .unwrap();
    cli::wait_while(c, |s| s.state != MachineState::Disabled).unwrap();
}
