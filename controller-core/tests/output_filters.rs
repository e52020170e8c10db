//! The output filters (controller-core `filter`) in the servo period, on the simulated
//! physical gantry in the board's configuration: configured in `ServoConfig::filters`,
//! they shape the effort the amplifiers get while the outputs are driven, and rest at 0
//! while they are off, so that arming never replays an effort from before a stop.

use controller_core::axes::Axis;
use controller_core::filter::{AxisFilterConfig, FilterConfig};
use controller_core::presets::board::servo_config;
use controller_core::presets::gantry::GANTRY_AXES;
use controller_core::servo::{Command, ServoConfig, ServoState};
use controller_core::sim::run::{RunConfig, SimRun};
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, Injection, PlantConfig, WorldConfig,
};

const RATE_HZ: u32 = 10_000;

fn run_with(servo: ServoConfig) -> SimRun<f32> {
    SimRun::new(&RunConfig { servo, ..base() }).expect("valid configuration")
}

/// The board's configuration with `stage` on X.
fn with_x(stage: FilterConfig) -> ServoConfig {
    let mut c = servo_config(RATE_HZ);
    c.filters[0] = AxisFilterConfig::new(&[stage]).unwrap();
    c
}

/// `n` periods with `cmds` in the first; X's effort in each.
fn step(r: &mut SimRun<f32>, cmds: &[Command], n: u32) -> Vec<f32> {
    (0..n)
        .map(|k| {
            let e = r.control_with(if k == 0 { cmds } else { &[] }).effort[0];
            r.finish_period();
            e
        })
        .collect()
}

/// X jogged at 100 mm/s for 0.3 s.
fn jog_x(r: &mut SimRun<f32>) -> Vec<f32> {
    step(r, &[Command::Arm], 1_000);
    let jog = Command::Jog {
        axis: Axis::X,
        vel_mm_s: 100.0,
    };
    (0..30).flat_map(|_| step(r, &[jog], 100)).collect()
}

/// The sum of the effort's changes from period to period (its chatter), mN·m.
fn variation(e: &[f32]) -> f32 {
    e.windows(2).map(|w| (w[1] - w[0]).abs()).sum()
}

#[test]
fn a_low_pass_takes_the_chatter_out_of_the_effort_and_keeps_its_mean() {
    let mut plain = run_with(servo_config(RATE_HZ));
    let mut lp = run_with(with_x(FilterConfig::low_pass(300.0)));
    let e0 = jog_x(&mut plain);
    let e1 = jog_x(&mut lp);
    // the cruise's last 0.1 s: the same friction to push against, less chatter
    let (c0, c1) = (&e0[2_000..], &e1[2_000..]);
    let mean = |e: &[f32]| e.iter().sum::<f32>() / e.len() as f32;
    let (v0, v1) = (variation(c0), variation(c1));
    assert!(v1 < 0.5 * v0, "chatter {v0:.1} -> {v1:.1} mN·m");
    let (m0, m1) = (mean(c0), mean(c1));
    assert!(
        (m1 - m0).abs() < 0.03 * m0.abs(),
        "mean {m0:.2} -> {m1:.2} mN·m"
    );
}

#[test]
fn a_notch_takes_its_frequency_out_of_the_effort() {
    // a 300 Hz notch 30 dB deep on X: the effort's content at 300 Hz (correlated over
    // the cruise) drops, the rest of the loop is unchanged enough to cruise the same
    let notch = FilterConfig::Notch {
        freq_hz: 300.0,
        width_hz: 60.0,
        depth_db: 30.0,
    };
    let at = |e: &[f32], f: f32| {
        let w = 2.0 * core::f32::consts::PI * f / RATE_HZ as f32;
        let (c, s) = e
            .iter()
            .enumerate()
            .fold((0.0f32, 0.0f32), |(c, s), (k, v)| {
                (c + v * (w * k as f32).cos(), s + v * (w * k as f32).sin())
            });
        c.hypot(s) / e.len() as f32
    };
    let mut plain = run_with(servo_config(RATE_HZ));
    let mut notched = run_with(with_x(notch));
    let e0 = jog_x(&mut plain);
    let e1 = jog_x(&mut notched);
    let (a0, a1) = (at(&e0[1_000..], 300.0), at(&e1[1_000..], 300.0));
    assert!(a1 < 0.3 * a0, "300 Hz content {a0:.4} -> {a1:.4} mN·m");
    let pos = |r: &SimRun<f32>| r.servo().snapshot().pos[0];
    assert!(
        (pos(&plain) - pos(&notched)).abs() < 0.05,
        "{} vs {}",
        pos(&plain),
        pos(&notched)
    );
}

#[test]
fn the_filters_rest_at_zero_while_the_outputs_are_off() {
    // X held in Idle against a push, the outputs switched off at once (a disarm from
    // Idle) while the low-pass holds the push's effort, the push gone, armed again: a
    // filter that kept its state would start from the old effort
    let mut r = run_with(with_x(FilterConfig::low_pass(300.0)));
    step(&mut r, &[Command::Arm], 1_000);
    r.world_mut().inject(&Injection::ExternalAccel {
        axis: Axis::X,
        accel_mm_s2: 2_000.0,
        for_s: 0.3,
    });
    let held = step(&mut r, &[], 2_990);
    let pushing = held.last().unwrap().abs();
    let off = step(&mut r, &[Command::Disarm], 2_000);
    assert_eq!(r.servo().state(), ServoState::Disabled);
    assert_eq!(off.last().copied(), Some(0.0));
    let again = step(&mut r, &[Command::Arm], 50);
    assert_eq!(r.servo().state(), ServoState::Idle);
    let worst = again.iter().fold(0.0f32, |m, e| m.max(e.abs()));
    assert!(pushing > 50.0, "holding effort {pushing:.1} mN·m");
    assert!(
        worst < 0.1 * pushing,
        "after arming again: {worst:.2} mN·m (held {pushing:.1})"
    );
}

#[test]
fn a_filter_the_control_rate_cannot_hold_is_refused_naming_its_field() {
    use controller_core::config::ConfigError;
    let e = SimRun::<f32>::new(&RunConfig {
        servo: with_x(FilterConfig::low_pass(4_600.0)),
        ..base()
    });
    assert_eq!(e.err(), Some(ConfigError::OutOfRange("low_pass.cutoff_hz")));
}

fn base() -> RunConfig {
    RunConfig {
        servo: servo_config(RATE_HZ),
        world: WorldConfig {
            plants: GANTRY_AXES.map(PlantConfig::Physical),
            plant_substeps: 4,
            initial: [InitialState {
                pos_mm: 0.0,
                vel_mm_s: 0.0,
            }; 3],
            switches: Default::default(),
            imperfections: ImperfectionConfig::default(),
            brakes: Default::default(),
        },
        truth: TruthSpec::default(),
        periods: u32::MAX,
        hold: true,
        inject: None,
        program: false,
    }
}
