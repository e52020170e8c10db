//! The holding brake on the gantry's vertical Z axis (docs/safety.md "Holding brakes"): the servo step of
//! the board's configuration (`presets::board`, Z brake fitted) against the simulated
//! gantry, whose Z brake holds 320 mN·m once it grips.
//!
//! The Z-drop table: Z holding at rest with an overload (a 150 mN·m load beyond its
//! 23 mN·m of gravity: a heavy spindle), then an e-stop of category 0 or 1, with and
//! without the brake; the drop is the largest fall of the true Z position within 0.5 s of
//! the e-stop. `cargo test --release -p controller-core --test core_tests holding_brake:: -- --nocapture`
//! prints it (docs/safety.md, "E-stop categories").
//!
//! And the order of events, in control periods (10 kHz: 300 periods = `engage_s`, 700 =
//! `release_s`): outputs off and brake gripping at boot; on arming the outputs come on
//! with the brake gripping, the brake is released a period later and motion waits for
//! `release_s`; a controlled stop engages the brake at rest and keeps the outputs on for
//! `engage_s`; an immediate stop engages it in the period the outputs go off.

use controller_core::axes::Axis;
use controller_core::presets::board::{servo_config, BOARD_RATE_HZ};
use controller_core::presets::gantry::{GANTRY_AXES, GANTRY_Z_BRAKE_HOLDING_MNM};
use controller_core::servo::brake::{BrakeConfig, DEFAULT_ENGAGE_S, DEFAULT_RELEASE_S};
use controller_core::servo::faults::FaultKind;
use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::{Command, Servo, ServoConfig, ServoState};
use controller_core::sim::world::{
    BrakePlantConfig, ImperfectionConfig, InitialState, PlantConfig, SwitchConfig, World,
    WorldConfig,
};

const Z: usize = 2;
/// The overload beyond gravity on Z, mN·m.
const OVERLOAD_MNM: f32 = 150.0;
/// Periods of `engage_s` and `release_s` at the board's 10 kHz.
const ENGAGE_PERIODS: u32 = 300;
const RELEASE_PERIODS: u32 = 700;
/// Armed and holding for 0.2 s (the brake open since 70 ms) before the e-stop.
const ESTOP_AT: u32 = 2_000;
/// The drop is measured over 0.5 s after the e-stop.
const AFTER: u32 = 5_000;

/// The board's configuration, e-stop category `category`, Z brake fitted or not.
fn servo_cfg(category: u8, brake: bool) -> ServoConfig {
    let mut c = servo_config(BOARD_RATE_HZ);
    c.safety.estop_category = category;
    c.brakes[Z] = if brake {
        BrakeConfig::FITTED
    } else {
        BrakeConfig::NONE
    };
    c
}

/// The simulated gantry with `load_mnm` beyond gravity on Z and its brake (or none).
fn world_cfg(load_mnm: f32, brake: bool) -> WorldConfig {
    let mut plants = GANTRY_AXES;
    plants[Z].load_const_mnm += load_mnm;
    let mut brakes = [BrakePlantConfig::NONE; 3];
    if brake {
        brakes[Z] = BrakePlantConfig {
            holding_mnm: GANTRY_Z_BRAKE_HOLDING_MNM,
            engage_s: DEFAULT_ENGAGE_S,
            release_s: DEFAULT_RELEASE_S,
        };
    }
    WorldConfig {
        plants: plants.map(PlantConfig::Physical),
        plant_substeps: 4,
        initial: [InitialState::default(); 3],
        switches: [SwitchConfig::NONE; 3],
        imperfections: ImperfectionConfig::default(),
        brakes,
    }
}

struct Rig {
    servo: Servo<f32>,
    world: World,
    /// Run periods so far (the servo's period counter is one ahead).
    k: u32,
}

impl Rig {
    fn new(category: u8, load_mnm: f32, brake: bool) -> Self {
        let cfg = servo_cfg(category, brake);
        let world = World::new(&world_cfg(load_mnm, brake), &cfg).unwrap();
        let servo = Servo::new(&cfg, world.counter_registers(), world.counts()).unwrap();
        Self { servo, world, k: 0 }
    }

    /// One period: the servo step, then the world over the period.
    fn step(&mut self, cmds: &[Command]) -> Snapshot {
        let s = *self.servo.period(&mut self.world, cmds);
        self.world.advance();
        self.k += 1;
        s
    }

    fn z_mm(&self) -> f64 {
        self.world.state()[Z].pos
    }
}

/// What one e-stop case gives.
#[derive(Debug)]
struct Case {
    drop_mm: f64,
    /// Periods from the e-stop to the Z brake command going to "engaged".
    brake_cmd_after: Option<u32>,
    /// Periods from the e-stop to the outputs going off.
    off_after: Option<u32>,
    /// The simulated brake gripped when the outputs went off.
    gripping_at_off: bool,
}

fn estop_case(category: u8, brake: bool) -> Case {
    let mut r = Rig::new(category, OVERLOAD_MNM, brake);
    let s = r.step(&[Command::Arm]);
    assert_eq!(s.state, ServoState::Idle);
    while r.k < ESTOP_AT {
        r.step(&[]);
    }
    assert_eq!(
        r.servo.brakes_released()[Z],
        brake,
        "brake open before the e-stop"
    );
    let z0 = r.z_mm();
    r.world.set_estop(true);
    let (mut z_min, mut brake_cmd_after, mut off_after, mut gripping_at_off) =
        (z0, None, None, false);
    for j in 0..AFTER {
        // the simulated brake over the coming period
        let gripping = r.world.brake_gripping()[Z];
        let s = r.step(&[]);
        if brake_cmd_after.is_none() && !s.brakes_released[Z] {
            brake_cmd_after = Some(j);
        }
        if off_after.is_none() && !s.outputs_on {
            off_after = Some(j);
            gripping_at_off = !brake || gripping;
        }
        z_min = z_min.min(r.z_mm());
    }
    assert_eq!(
        r.servo.faults().first().map(|f| f.fault.kind),
        Some(FaultKind::EStop)
    );
    Case {
        drop_mm: z0 - z_min,
        brake_cmd_after: if brake { brake_cmd_after } else { None },
        off_after,
        gripping_at_off,
    }
}

#[test]
fn z_drop_table_with_and_without_the_brake() {
    let mut rows = Vec::new();
    for category in [0u8, 1] {
        for brake in [false, true] {
            rows.push((category, brake, estop_case(category, brake)));
        }
    }
    println!("Z holding at rest, {OVERLOAD_MNM} mN·m beyond gravity, e-stop; Z drop within 0.5 s:");
    println!("| e-stop category | Z brake | Z drop | brake engaged after | outputs off after |");
    println!("| --- | --- | --- | --- | --- |");
    for (category, brake, c) in &rows {
        let cell = |p: Option<u32>| p.map_or("-".to_string(), |p| format!("{p} periods"));
        println!(
            "| {category} | {} | {:.3} mm | {} | {} |",
            if *brake { "yes (320 mN·m)" } else { "no" },
            c.drop_mm,
            cell(c.brake_cmd_after),
            cell(c.off_after),
        );
    }
    let get = |cat: u8, brake: bool| {
        &rows
            .iter()
            .find(|(c, b, _)| *c == cat && *b == brake)
            .unwrap()
            .2
    };
    // without the brake Z falls whatever the category: the overload is 5.8 times the
    // Coulomb friction that opposes the fall
    for cat in [0, 1] {
        let c = get(cat, false);
        assert!(c.drop_mm > 10.0, "cat {cat} without brake: {c:?}");
    }
    // category 0 with the brake: the outputs and the brake command go in the same
    // period, and Z falls freely for engage_s (1.6 mm at 3490 mm/s²) before the brake
    // stops it
    let c0 = get(0, true);
    assert_eq!(c0.brake_cmd_after, Some(0), "{c0:?}");
    assert_eq!(c0.off_after, Some(0), "{c0:?}");
    assert!(c0.drop_mm < 5.0 && c0.drop_mm > 0.5, "{c0:?}");
    // category 1 with the brake: Z is held at rest until the brake grips, then off
    let c1 = get(1, true);
    assert!(c1.drop_mm < 0.05, "{c1:?}");
    let (b, o) = (c1.brake_cmd_after.unwrap(), c1.off_after.unwrap());
    assert!(o >= b + ENGAGE_PERIODS, "{c1:?}");
    assert!(c1.gripping_at_off, "{c1:?}");
    // and within the category-1 bound (estop_stop_time_s = 0.3 s)
    assert!(o <= 3_000, "{c1:?}");
    // without the brake the category-1 stop does not wait for one
    let n1 = get(1, false);
    assert!(n1.off_after.unwrap() < o, "{n1:?} vs {c1:?}");
}

#[test]
fn boot_is_off_with_the_brake_gripping_and_arming_releases_it_a_period_later() {
    let mut r = Rig::new(0, 0.0, true);
    assert!(r.world.brake_gripping()[Z]);
    for _ in 0..10 {
        let s = r.step(&[]);
        assert!(!s.outputs_on);
        assert_eq!(s.brakes_released, [false; 3]);
        assert!(r.world.brake_gripping()[Z]);
    }
    // arming: the outputs come on holding, the brake still gripping
    let s = r.step(&[Command::Arm]);
    assert!(s.outputs_on);
    assert_eq!(s.brakes_released, [false; 3]);
    // the next period the Z brake (only Z has one) is released
    let released_in = r.k;
    let s = r.step(&[]);
    assert_eq!(s.brakes_released, [false, false, true]);
    // it still grips for release_s, then lets go: open over the period release_s later
    let mut opened = None;
    for _ in 0..RELEASE_PERIODS + 10 {
        if opened.is_none() && !r.world.brake_gripping()[Z] {
            opened = Some(r.k);
        }
        r.step(&[]);
    }
    assert_eq!(opened, Some(released_in + RELEASE_PERIODS));
}

#[test]
fn motion_commanded_at_arming_waits_for_release_s_and_is_not_refused() {
    for (name, cmd) in [
        (
            "jog",
            Command::Jog {
                axis: Axis::Z,
                vel_mm_s: 5.0,
            },
        ),
        ("path", Command::StartPath),
    ] {
        let mut r = Rig::new(0, 0.0, true);
        r.step(&[]);
        let s = r.step(&[Command::Arm, cmd]);
        assert_eq!(s.refused, None, "{name}");
        assert!(r.servo.motion_held(), "{name}");
        let armed_at = s.period;
        let start_ref = s.reference;
        let mut released_at = None;
        let mut moved_at = None;
        let mut started_at = None;
        for _ in 0..2 * RELEASE_PERIODS {
            let s = r.step(&[]);
            if started_at.is_none() && !r.servo.motion_held() {
                // the coming period is the first whose reference may move
                started_at = Some(s.period + 1);
            }
            assert_eq!(s.refused, None, "{name}");
            assert_ne!(s.state, ServoState::Idle, "{name}: the command was kept");
            if released_at.is_none() && s.brakes_released[Z] {
                released_at = Some(s.period);
            }
            if moved_at.is_none() && s.reference != start_ref {
                moved_at = Some(s.period);
            }
        }
        let (Some(rel), Some(mov), Some(start)) = (released_at, moved_at, started_at) else {
            panic!("{name}: released {released_at:?}, moved {moved_at:?}, started {started_at:?}");
        };
        println!(
            "{name}: armed in period {armed_at}, brake released in {rel}, motion starts in \
             {start}, reference position first moves in {mov}"
        );
        assert_eq!(rel, armed_at + 1, "{name}");
        // the motion starts in the period the brake is open: release_s after its release
        assert_eq!(start, rel + RELEASE_PERIODS, "{name}");
        // (a ramp or path at rest moves its position from its second sample on)
        assert!(mov >= start && mov <= start + 2, "{name}: {mov}");
        assert!(!r.servo.motion_held());
    }
}

#[test]
fn disarm_engages_the_brake_and_holds_for_engage_s_before_the_outputs_go_off() {
    let mut r = Rig::new(0, OVERLOAD_MNM, true);
    r.step(&[Command::Arm]);
    for _ in 0..2 * RELEASE_PERIODS {
        r.step(&[]);
    }
    let z0 = r.z_mm();
    let s = r.step(&[Command::Disarm]);
    assert_eq!(s.refused, None);
    assert!(s.outputs_on);
    let disarmed_at = s.period;
    let (mut engaged_at, mut off_at) = (None, None);
    if !s.brakes_released[Z] {
        engaged_at = Some(s.period);
    }
    for _ in 0..1_000 {
        let gripping = r.world.brake_gripping()[Z];
        let s = r.step(&[]);
        if engaged_at.is_none() && !s.brakes_released[Z] {
            engaged_at = Some(s.period);
        }
        if off_at.is_none() && !s.outputs_on {
            off_at = Some(s.period);
            assert!(gripping, "the brake grips when the outputs go off");
            assert_eq!(s.state, ServoState::Disabled);
        }
    }
    let (e, o) = (engaged_at.unwrap(), off_at.unwrap());
    println!("disarm at period {disarmed_at}: brake engaged at {e}, outputs off at {o}");
    assert!(e <= disarmed_at + 1);
    assert_eq!(o, e + ENGAGE_PERIODS);
    // the overloaded Z stays where it was held
    let drop = z0 - r.z_mm();
    assert!(drop.abs() < 0.05, "{drop} mm");
}
