//! A/B swapped on an axis, at rest and at arming (board configuration on the simulated
//! gantry, Z under gravity with its holding brake).
//!
//! At rest the position loop turns into positive feedback, and an axis that any load
//! pushes runs away from where it holds until the following-error limit at rest (0.1 mm)
//! stops it: 465–914 periods, about 0.21 mm of travel. An axis nothing pushes (X, Y: the
//! friction holds them) does not move at all and shows nothing until it does.
//!
//! The arm check (`safety.arm_encoder_check`) moves each axis' hold point 16 counts out
//! and back both ways at arming and faults a reading that goes the wrong way: X and Y
//! within 61 and 48 periods of motion (the goal: 100), Z 113 periods after its
//! brake opens (its load's runaway must outgrow a healthy Z's 6-count sag first), a few
//! µm of travel (docs/safety.md, "Swapped A/B at rest").
//!
//! `cargo test --release -p controller-core --test core_tests reversed_at_rest:: -- --nocapture` prints
//! the table docs/safety.md quotes.

use controller_core::axes::Axis;
use controller_core::presets::board::servo_config;
use controller_core::presets::gantry::{GANTRY_AXES, GANTRY_Z_BRAKE_HOLDING_MNM};
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::{RunConfig, SimRun};
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    BrakePlantConfig, ImperfectionConfig, InitialState, Injection, PlantConfig, SwitchConfig,
    WorldConfig,
};

/// Detection bound for a swapped A/B at rest on a loaded axis, periods: the following
/// error of 0.1 mm at rest reached on a runaway from rest (measured 465–914; the arm
/// check is what finds it within about 100).
const BOUND_PERIODS: u32 = 1_000;
/// Travel allowed from the swap to the outputs going off, mm (measured 0.205–0.214: the
/// 0.1 mm limit plus the runaway during the stop's period and the coast is not counted).
const BOUND_TRAVEL_MM: f64 = 0.25;

/// The simulated gantry with Z's holding brake (the board configuration has it).
fn gantry_world() -> WorldConfig {
    let mut brakes = [BrakePlantConfig::NONE; 3];
    brakes[Axis::Z.index()].holding_mnm = GANTRY_Z_BRAKE_HOLDING_MNM;
    WorldConfig {
        plants: GANTRY_AXES.map(PlantConfig::Physical),
        plant_substeps: 4,
        initial: [InitialState::default(); 3],
        switches: [SwitchConfig::NONE; 3],
        imperfections: ImperfectionConfig::default(),
        brakes,
    }
}

fn holding() -> SimRun<f32> {
    let cfg = RunConfig {
        servo: servo_config(10_000),
        world: gantry_world(),
        truth: TruthSpec::default(),
        periods: u32::MAX,
        hold: true,
        inject: None,
        program: false,
    };
    let mut r = SimRun::new(&cfg).expect("the board configuration validates");
    r.control_with(&[Command::Arm]);
    r.finish_period();
    for _ in 0..3_000 {
        r.control();
        r.finish_period();
    }
    assert_eq!(r.servo().state(), ServoState::Idle);
    r
}

/// Swap `axis`' A/B (after `load` as an outside acceleration, mm/s², 0.1 s earlier):
/// periods to the first fault and the travel until the outputs are off.
fn swap(axis: Axis, load_mm_s2: f32) -> (u32, f64, &'static str) {
    let mut r = holding();
    let i = axis.index();
    if load_mm_s2 != 0.0 {
        r.world_mut().inject(&Injection::ExternalAccel {
            axis,
            accel_mm_s2: load_mm_s2,
            for_s: f32::INFINITY,
        });
        for _ in 0..1_000 {
            r.control();
            r.finish_period();
        }
        assert!(
            !r.servo().faults().any(),
            "{:?}",
            r.servo().faults().first()
        );
    }
    let from = r.world().state()[i].pos;
    r.world_mut().inject(&Injection::EncoderReversed { axis });
    let mut periods = 0;
    while !r.servo().faults().any() {
        r.control();
        r.finish_period();
        periods += 1;
        if periods > 20_000 {
            let to = r.world().state()[i].pos;
            return (u32::MAX, (to - from).abs(), "none");
        }
    }
    let kind = r.servo().faults().first().unwrap().fault.kind.name();
    while r.world().outputs_on() {
        r.control();
        r.finish_period();
    }
    // coasting after the outputs went off is the plant's, not the detection's: counted
    // to the period they went off
    let to = r.world().state()[i].pos;
    (periods, (to - from).abs(), kind)
}

#[test]
fn a_swapped_encoder_at_rest_stops_within_the_following_error() {
    // X and Y with no load: nothing moves them, the swap changes nothing in 2 s
    for axis in [Axis::X, Axis::Y] {
        let (p, travel, _) = swap(axis, 0.0);
        assert_eq!(p, u32::MAX, "{axis:?}");
        assert!(travel < 1e-4, "{axis:?} moved {travel} mm");
    }
    let cases = [
        (Axis::Z, 0.0),
        (Axis::Z, 500.0),
        (Axis::Z, -500.0),
        (Axis::X, 300.0),
    ];
    println!(
        "| axis | outside load mm/s² | detected after periods | fault | travel to outputs off mm |"
    );
    println!("| --- | --- | --- | --- | --- |");
    let mut worst = 0;
    for (axis, load) in cases {
        let (p, travel, kind) = swap(axis, load);
        println!("| {axis:?} | {load} | {p} | {kind} | {travel:.4} |");
        assert!(
            p <= BOUND_PERIODS,
            "{axis:?} load {load}: {p} periods ({kind})"
        );
        assert!(
            travel <= BOUND_TRAVEL_MM,
            "{axis:?} load {load}: {travel} mm"
        );
        worst = worst.max(p);
    }
    println!("worst {worst} periods");
}

/// The board configuration with `safety.arm_encoder_check` on, disarmed for 0.1 s on the
/// simulated gantry (Z's brake gripping), with `swapped`'s A/B swapped while disarmed
/// (a wiring change made with the power off).
fn disarmed_with_arm_check(swapped: Option<Axis>) -> SimRun<f32> {
    let mut servo = servo_config(10_000);
    servo.safety.arm_encoder_check = true;
    let cfg = RunConfig {
        servo,
        world: gantry_world(),
        truth: TruthSpec::default(),
        periods: u32::MAX,
        hold: true,
        inject: None,
        program: false,
    };
    let mut r = SimRun::new(&cfg).expect("the board configuration validates");
    for _ in 0..1_000 {
        r.control_with(&[]);
        r.finish_period();
    }
    assert_eq!(r.servo().state(), ServoState::Disabled);
    if let Some(axis) = swapped {
        r.world_mut().inject(&Injection::EncoderReversed { axis });
    }
    r
}

/// Arm with the arm check on: (periods from arm to the end of the check, periods of it
/// with the axes free to move (every brake open), the state then, the first fault's name,
/// the largest travel of any axis from where it armed during the check, mm).
fn arm_checked(swapped: Option<Axis>) -> (u32, u32, ServoState, &'static str, f64) {
    let mut r = disarmed_with_arm_check(swapped);
    let from = r.world().state().map(|s| s.pos);
    r.control_with(&[Command::Arm]);
    r.finish_period();
    assert_eq!(
        r.servo().state(),
        ServoState::EncoderCheck,
        "{:?}",
        r.servo().faults().first()
    );
    let (mut periods, mut moving, mut travel) = (1u32, 0u32, 0.0f64);
    while r.servo().state() == ServoState::EncoderCheck {
        if !r.servo().motion_held() {
            moving += 1;
        }
        r.control_with(&[]);
        r.finish_period();
        periods += 1;
        let now = r.world().state().map(|s| s.pos);
        for i in 0..3 {
            travel = travel.max((now[i] - from[i]).abs());
        }
        assert!(periods < 20_000, "the arm check never ended");
    }
    let first = r.servo().faults().first();
    if let Some(f) = first {
        assert_eq!(f.fault.axis, swapped, "{f:?}");
    }
    let kind = first.map_or("none", |f| f.fault.kind.name());
    (periods, moving, r.servo().state(), kind, travel)
}

/// Periods the arm check may take on a healthy gantry: Z's brake opens (700 periods),
/// the 20 ms settle, the ramps out (16 counts at 5 mm/s: 20 periods) and back (40) with
/// the heaviest axis' (Y's) lag, and the 20 ms settle at the end (measured 1,792).
const ARM_CHECK_BOUND_PERIODS: u32 = 2_500;
/// Travel the arm check may make, mm: the 16 check counts (10 µm) and the laws'
/// overshoot (measured 0.0120).
const ARM_CHECK_TRAVEL_MM: f64 = 0.03;
/// The goal for a swapped A/B: found within 100 periods of motion (X and Y:
/// measured 61 and 48 periods after the check's reference starts moving).
const ARM_SWAP_BOUND_PERIODS: u32 = 100;
/// ... and on the braked Z, from its brake opening: the runaway its load starts must grow
/// past the sag a healthy Z shows (6 counts) before it tells (measured 113).
const ARM_SWAP_BRAKED_BOUND_PERIODS: u32 = 150;
/// Travel a swapped axis may make before its outputs go off, mm (measured 0.0013-0.0068:
/// a few counts).
const ARM_SWAP_TRAVEL_MM: f64 = 0.015;

#[test]
fn the_arm_check_finds_a_swapped_encoder_before_anything_moves() {
    // healthy: armed after the check, nothing latched, the axes back where they armed
    let (p, moving, state, kind, travel) = arm_checked(None);
    println!("| axis swapped | periods from arm | periods moving | state | fault | travel mm |");
    println!("| --- | --- | --- | --- | --- | --- |");
    println!("| none | {p} | {moving} | {state:?} | {kind} | {travel:.4} |");
    assert_eq!((state, kind), (ServoState::Idle, "none"));
    assert!(p <= ARM_CHECK_BOUND_PERIODS, "{p} periods");
    assert!(travel <= ARM_CHECK_TRAVEL_MM, "{travel} mm");
    for axis in [Axis::X, Axis::Y, Axis::Z] {
        let (p, moving, state, kind, travel) = arm_checked(Some(axis));
        println!("| {axis:?} | {p} | {moving} | {state:?} | {kind} | {travel:.4} |");
        assert_eq!(
            (state, kind),
            (ServoState::Fault, "encoder_jump"),
            "{axis:?}"
        );
        let bound = if axis == Axis::Z {
            ARM_SWAP_BRAKED_BOUND_PERIODS
        } else {
            ARM_SWAP_BOUND_PERIODS
        };
        assert!(moving <= bound, "{axis:?}: {moving} periods");
        assert!(travel <= ARM_SWAP_TRAVEL_MM, "{axis:?}: {travel} mm");
    }
}
