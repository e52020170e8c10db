//! Glitches and the index pulse on the simulated physical gantry (board configuration,
//! its encoders giving an index every 8000 counts): a glitch too small for the jump check
//! is corrected at the next index pass (the count back to the truth, the
//! correction in the snapshot); glitches adding up to more than
//! `index_max_correction_counts` within a revolution are the `encoder_index` fault;
//! without the index the same glitch stays as a silent offset (what the check is for).
//!
//! `cargo test --release -p controller-core --test core_tests index_glitch:: -- --nocapture` prints
//! the figures docs/safety.md quotes.

use controller_core::axes::Axis;
use controller_core::presets::board::servo_config;
use controller_core::presets::gantry::{GANTRY_AXES, GANTRY_INDEX_PERIOD_COUNTS};
use controller_core::servo::faults::FaultKind;
use controller_core::servo::{Command, ServoConfig, ServoState};
use controller_core::sim::run::{RunConfig, SimRun};
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, Injection, PlantConfig, SwitchConfig, WorldConfig,
};

const RATE_HZ: u32 = 10_000;

fn run(servo: ServoConfig, index_counts: u32, noise_counts: u8) -> SimRun<f32> {
    let sw = SwitchConfig {
        index_period_counts: index_counts,
        ..SwitchConfig::NONE
    };
    let cfg = RunConfig {
        servo,
        world: WorldConfig {
            plants: GANTRY_AXES.map(PlantConfig::Physical),
            plant_substeps: 4,
            initial: [InitialState::default(); 3],
            switches: [sw; 3],
            imperfections: ImperfectionConfig {
                noise_counts,
                seed: 5,
                ..ImperfectionConfig::default()
            },
            // (X carries the index check under test; Z's brake plays no part)
            brakes: Default::default(),
        },
        truth: TruthSpec::default(),
        periods: u32::MAX,
        hold: true,
        inject: None,
        program: false,
    };
    SimRun::new(&cfg).expect("the board configuration validates")
}

/// Run `n` periods with `cmds` in the first; returns the servo's count of X less the true
/// count it read it at, in the last period (constant while the encoder is healthy).
fn step(r: &mut SimRun<f32>, cmds: &[Command], n: u32) -> i64 {
    let mut off = 0;
    for k in 0..n {
        r.control_with(if k == 0 { cmds } else { &[] });
        off = r.servo().snapshot().counts[0] - r.world().counts()[0];
        r.finish_period();
    }
    off
}

/// Armed, on the demo helix (X sweeps ±10 mm at 10 mm/s from 0: an index at every 5 mm),
/// 0.7 s in: X has passed its first index (at 5 mm), the check's reference.
fn moving(servo: ServoConfig, index_counts: u32, noise_counts: u8) -> SimRun<f32> {
    let mut r = run(servo, index_counts, noise_counts);
    step(&mut r, &[Command::Arm], 1_000);
    step(&mut r, &[Command::StartPath], 7_000);
    assert_eq!(r.servo().state(), ServoState::Run);
    r
}

/// Inject a `counts` glitch on X now; run until the servo's count is back where the truth
/// puts it or a fault latched (at most 3 s). Returns the periods taken and X's travel.
fn until_corrected_or_faulted(r: &mut SimRun<f32>, counts: i32) -> (u32, f64) {
    let before = step(r, &[], 1);
    r.world_mut().inject(&Injection::EncoderJump {
        axis: Axis::X,
        counts,
    });
    let mut periods = 0u32;
    let mut travel_mm = 0.0f64;
    let mut last = r.world().state()[0].pos;
    let mut off = before + i64::from(counts);
    while off != before && !r.servo().faults().any() {
        off = step(r, &[], 1);
        periods += 1;
        let p = r.world().state()[0].pos;
        travel_mm += (p - last).abs();
        last = p;
        assert!(periods < 30_000, "neither corrected nor faulted in 3 s");
        if off != before && !r.servo().faults().any() {
            assert_eq!(off, before + i64::from(counts));
        }
    }
    (periods, travel_mm)
}

#[test]
fn a_two_count_glitch_is_corrected_at_the_next_index_pass() {
    // 2 counts: the jump check never sees it (2 + 1 of quantisation < 3.5 on X)
    let mut r = moving(servo_config(RATE_HZ), GANTRY_INDEX_PERIOD_COUNTS, 0);
    let before = step(&mut r, &[], 1);
    let at_mm = r.world().state()[0].pos;
    let (periods, travel_mm) = until_corrected_or_faulted(&mut r, 2);
    let after = step(&mut r, &[], 10_000);
    let s = *r.servo().snapshot();
    assert_eq!(
        r.servo().state(),
        ServoState::Run,
        "{:?}",
        r.servo().faults().first()
    );
    assert_eq!(s.index_corrected_counts, [2, 0, 0]);
    assert_eq!(after, before);
    // corrected within one revolution of travel (5 mm) of the glitch
    assert!(travel_mm <= 5.0 + 0.01, "{travel_mm} mm");
    println!(
        "2-count glitch on X at {at_mm:.3} mm: corrected after {periods} periods, \
         {travel_mm:.3} mm of travel"
    );
}

#[test]
fn a_three_count_glitch_is_faulted_at_once_or_corrected_never_silent() {
    // injected at 24 moments of the helix (every 0.1 s): the encoder checks see it where
    // the motion's own count step adds to it, the index pass corrects it elsewhere
    let (mut jumped, mut corrected, mut worst_travel, mut worst_detect) = (0, 0, 0.0f64, 0);
    for k in 0..24 {
        let mut r = moving(servo_config(RATE_HZ), GANTRY_INDEX_PERIOD_COUNTS, 0);
        let before = step(&mut r, &[], 1 + 1_000 * k);
        let (periods, travel_mm) = until_corrected_or_faulted(&mut r, 3);
        match r.servo().faults().first() {
            Some(f) => {
                // the jump check, or, near X's reversal, the counts-due check seeing a
                // count against the motion
                assert!(
                    matches!(
                        f.fault.kind,
                        FaultKind::EncoderJump | FaultKind::EncoderStuck
                    ),
                    "{f:?}"
                );
                assert!(periods <= 5, "seen within 5 periods: {f:?}");
                worst_detect = worst_detect.max(periods);
                jumped += 1;
            }
            None => {
                assert_eq!(step(&mut r, &[], 1), before);
                assert!(travel_mm <= 5.0 + 0.01, "{travel_mm} mm");
                worst_travel = worst_travel.max(travel_mm);
                corrected += 1;
            }
        }
    }
    assert_eq!(jumped + corrected, 24);
    assert!(
        corrected > 0 && jumped > 0,
        "{jumped} jumped, {corrected} corrected"
    );
    println!(
        "3-count glitch on X at 24 moments: {jumped} encoder faults (within {worst_detect} periods), {corrected} \
         corrected at the next index pass (within {worst_travel:.3} mm of travel), 0 silent"
    );
}

#[test]
fn without_the_index_the_same_glitch_stays_a_silent_offset() {
    let mut cfg = servo_config(RATE_HZ);
    for e in &mut cfg.encoders {
        e.index_period_counts = 0;
    }
    let mut r = moving(cfg, 0, 0);
    let before = step(&mut r, &[], 1);
    r.world_mut().inject(&Injection::EncoderJump {
        axis: Axis::X,
        counts: 2,
    });
    let after = step(&mut r, &[], 20_000);
    assert_eq!(r.servo().state(), ServoState::Run);
    assert!(!r.servo().faults().any());
    assert_eq!(after, before + 2);
}

#[test]
fn glitches_beyond_the_correction_limit_are_the_encoder_index_fault() {
    let mut r = moving(servo_config(RATE_HZ), GANTRY_INDEX_PERIOD_COUNTS, 0);
    // nine 2-count glitches 10 periods apart: 18 counts, each below the jump threshold
    for _ in 0..9 {
        r.world_mut().inject(&Injection::EncoderJump {
            axis: Axis::X,
            counts: 2,
        });
        step(&mut r, &[], 10);
        assert!(
            !r.servo().faults().any(),
            "{:?}",
            r.servo().faults().first()
        );
    }
    let mut periods = 0u32;
    while !r.servo().faults().any() {
        step(&mut r, &[], 1);
        periods += 1;
        assert!(periods < 30_000, "no fault in 3 s");
    }
    let f = r.servo().faults().first().unwrap();
    assert_eq!(f.fault.kind, FaultKind::EncoderIndex);
    assert_eq!(f.fault.axis, Some(Axis::X));
    assert_eq!(f.value, 18.0);
    // an immediate stop: the outputs are off from the period of detection
    step(&mut r, &[], 1);
    assert!(!r.world().outputs_on());
    assert_eq!(r.servo().snapshot().index_corrected_counts, [0; 3]);
    println!("18 counts of glitches on X: encoder_index after {periods} periods");
}

#[test]
fn edge_noise_at_every_index_pass_is_no_correction_and_no_fault() {
    let mut cfg = servo_config(RATE_HZ);
    cfg.safety.encoder_noise_counts = 2.0;
    let mut r = moving(cfg, GANTRY_INDEX_PERIOD_COUNTS, 2);
    let before = step(&mut r, &[], 1);
    // 20 s of the helix: X passes an index about 40 times, Y as often
    let after = step(&mut r, &[], 200_000);
    assert_eq!(
        r.servo().state(),
        ServoState::Run,
        "{:?}",
        r.servo().faults().first()
    );
    assert_eq!(r.servo().snapshot().index_corrected_counts, [0; 3]);
    // the count stays within the noise of the truth
    assert!((after - before).abs() <= 2, "{}", after - before);
}
