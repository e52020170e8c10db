//! The machine's supervisor (`machine::Machine`) on the simulated gantry: requests in
//! order, refusals with their reasons, a program through the planner, a bad segment
//! stopping the program, settings only with the outputs off, link loss.

use controller_core::machine::messages::{Outcome, Request};
use controller_core::machine::Machine;
use controller_core::motion::planner::Segment;
use controller_core::presets::gantry::GANTRY_AXES;
use controller_core::servo::ServoState;
use controller_core::settings::{Settings, FACTORY, PLACEHOLDER_MODELS};
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, PlantConfig, SwitchConfig, World, WorldConfig,
};

const RATE_HZ: u32 = 10_000;

/// The designed gantry with its models entered and homing off (the axes start referenced).
fn settings() -> Settings {
    let mut s = FACTORY;
    for (a, m) in s.axis.iter_mut().zip(PLACEHOLDER_MODELS) {
        a.model = Some(m);
        a.homing.enabled = false;
    }
    s
}

fn machine() -> (Machine, World) {
    let s = settings();
    let wcfg = WorldConfig {
        plants: GANTRY_AXES.map(PlantConfig::Physical),
        plant_substeps: 4,
        initial: [InitialState::default(); 3],
        switches: [SwitchConfig::NONE; 3],
        imperfections: ImperfectionConfig::default(),
    };
    let world = World::new(&wcfg, &s.servo_config(RATE_HZ).unwrap()).unwrap();
    let m = Machine::new(&s, RATE_HZ, world.counter_registers(), world.counts()).unwrap();
    (m, world)
}

fn periods(m: &mut Machine, w: &mut World, n: u32) {
    for _ in 0..n {
        m.period(w);
        w.advance();
    }
}

#[test]
fn a_program_runs_to_its_end_and_the_machine_returns_to_idle() {
    let (mut m, mut w) = machine();
    m.submit(Request::Arm);
    m.submit(Request::Run);
    for k in 1..=20u32 {
        let x = if k % 2 == 1 { 10.0 } else { 0.0 };
        m.submit(Request::Segment(Segment::line([x, 0.0, 0.0], 50.0, k)));
        periods(&mut m, &mut w, 2);
    }
    m.submit(Request::EndProgram);
    let mut k = 0;
    while !(m.status().program_done && m.servo().state() == ServoState::Idle) {
        periods(&mut m, &mut w, 100);
        k += 100;
        assert!(k < 200_000, "the program did not end");
    }
    let s = m.status();
    assert_eq!(s.executed, 23);
    assert_eq!(s.last, Outcome::Done);
    // it ends where the last segment ends, on the path
    assert!(s.pos_mm[0].abs() < 0.01, "{:?}", s.pos_mm);
    assert!(!m.servo().faults().any());
}

#[test]
fn a_bad_segment_is_refused_and_stops_the_program() {
    let (mut m, mut w) = machine();
    m.submit(Request::Arm);
    m.submit(Request::Run);
    periods(&mut m, &mut w, 3);
    m.submit(Request::Segment(Segment::line(
        [5.0, 0.0, 0.0],
        f32::NAN,
        1,
    )));
    // (the stop settles before Idle)
    periods(&mut m, &mut w, 1000);
    let s = m.status();
    let Outcome::Refused(why) = &s.last else {
        panic!("{:?}", s.last)
    };
    assert!(why.contains("program stopped"), "{why}");
    assert_eq!(m.servo().state(), ServoState::Idle);
    m.submit(Request::Segment(Segment::line([5.0, 0.0, 0.0], 10.0, 2)));
    periods(&mut m, &mut w, 1);
    assert!(matches!(m.status().last, Outcome::Refused(_)));
}

#[test]
fn settings_change_only_with_the_outputs_off_and_a_refusal_says_why() {
    let (mut m, mut w) = machine();
    let set = |k: &str, v: &str| Request::SettingSet {
        key: k.try_into().unwrap(),
        value: v.try_into().unwrap(),
    };
    m.submit(set("axis.x.law.bandwidth_rad_s", "300"));
    periods(&mut m, &mut w, 1);
    assert_eq!(m.status().last, Outcome::Done);
    assert_eq!(m.settings().axis[0].law.bandwidth_rad_s, 300.0);
    m.submit(Request::Arm);
    m.submit(set("axis.x.law.bandwidth_rad_s", "400"));
    periods(&mut m, &mut w, 3);
    let Outcome::Refused(why) = m.status().last else {
        panic!()
    };
    assert!(why.contains("outputs off"), "{why}");
    assert_eq!(m.settings().axis[0].law.bandwidth_rad_s, 300.0);
    m.submit(Request::Jog {
        axis: 7,
        vel_mm_s: 1.0,
    });
    periods(&mut m, &mut w, 1);
    assert!(matches!(m.status().last, Outcome::Refused(_)));
}

#[test]
fn link_loss_stops_a_running_program_with_a_link_lost_fault() {
    let (mut m, mut w) = machine();
    m.submit(Request::Arm);
    m.submit(Request::Run);
    m.submit(Request::Segment(Segment::line([100.0, 0.0, 0.0], 100.0, 1)));
    periods(&mut m, &mut w, 3000);
    assert!(m.status().vel_mm_s[0] > 50.0);
    m.link_lost();
    periods(&mut m, &mut w, 3000);
    assert_eq!(
        m.servo().faults().first().unwrap().fault.kind.name(),
        "link_lost"
    );
    assert!(m.status().vel_mm_s[0].abs() < 1.0);
    assert_eq!(m.servo().state(), ServoState::Fault);
}
