//! A/B swapped while the axis holds still (board configuration on the simulated gantry,
//! Z under gravity): the position loop turns into positive feedback, and an axis that any
//! load pushes runs away from where it holds until a check stops it. Measured: the
//! following-error limit at rest (0.1 mm) stops it after 470–750 periods with about
//! 0.21 mm of travel: issue 20's goal of 100 periods is not met (docs/safety.md,
//! "Swapped A/B at rest"). An axis nothing pushes (X, Y without load: the friction holds
//! them) does not move at all, and its swapped encoder shows nothing until it does.
//!
//! `cargo test --release -p controller-core --test reversed_at_rest -- --nocapture` prints
//! the table docs/safety.md quotes.

use controller_core::axes::Axis;
use controller_core::presets::board::servo_config;
use controller_core::presets::gantry::GANTRY_AXES;
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::{RunConfig, SimRun};
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, Injection, PlantConfig, SwitchConfig, WorldConfig,
};

/// Detection bound for a swapped A/B at rest on a loaded axis, periods: the following
/// error of 0.1 mm at rest reached on a runaway from rest (measured 468–743; the issue's
/// goal is 100).
const BOUND_PERIODS: u32 = 1_000;
/// Travel allowed from the swap to the outputs going off, mm (measured 0.205–0.211: the
/// 0.1 mm limit plus the runaway during the stop's period and the coast is not counted).
const BOUND_TRAVEL_MM: f64 = 0.25;

fn holding() -> SimRun<f32> {
    let cfg = RunConfig {
        servo: servo_config(10_000),
        world: WorldConfig {
            plants: GANTRY_AXES.map(PlantConfig::Physical),
            plant_substeps: 4,
            initial: [InitialState::default(); 3],
            switches: [SwitchConfig::NONE; 3],
            imperfections: ImperfectionConfig::default(),
        },
        truth: TruthSpec::default(),
        periods: u32::MAX,
        hold: true,
        inject: None,
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
