//! The simulated world with framed axes (controller-core plant/frame.rs, sim/frame_step.rs):
//! the encoder reads the motor side and the figures the tool side; a rigid machine is
//! unchanged by the frame's code path; the lead error and backlash show at the tool by
//! exactly their amounts; a kicked axis rings at its mode; a mode the plant step cannot
//! resolve is refused.

use controller_core::config::ConfigError;
use controller_core::plant::frame::{FrameConfig, PitchErrorConfig};
use controller_core::plant::physical::PhysicalAxisConfig;
use controller_core::presets::board::servo_config;
use controller_core::presets::gantry::{GANTRY_AXES, GANTRY_Y};
use controller_core::servo::io::ServoIo;
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, PlantConfig, SwitchConfig, World, WorldConfig,
};

const FRAME: FrameConfig = FrameConfig {
    mode_hz: 35.0,
    damping_ratio: 0.03,
    tool_inertia_ratio: 0.11,
    tool_friction_ratio: 0.3,
    backlash_mm: 0.02,
    pitch_error: PitchErrorConfig {
        cumulative_um_per_m: 20.0,
        periodic_um: 15.0,
        period_mm: 100.0,
    },
};

fn world(y: PhysicalAxisConfig, y_at_mm: f64) -> Result<World, ConfigError> {
    let mut plants = GANTRY_AXES.map(PlantConfig::Physical);
    plants[1] = PlantConfig::Physical(y);
    let mut initial = [InitialState::default(); 3];
    initial[1].pos_mm = y_at_mm;
    let cfg = WorldConfig {
        plants,
        plant_substeps: 4,
        initial,
        switches: [SwitchConfig::NONE; 3],
        imperfections: ImperfectionConfig::default(),
        brakes: Default::default(),
    };
    World::new(&cfg, &servo_config(10_000))
}

fn framed() -> PhysicalAxisConfig {
    PhysicalAxisConfig {
        frame: Some(FRAME),
        ..GANTRY_Y
    }
}

/// `n` periods with effort `u` on Y (X and Z at rest, outputs on).
fn drive(w: &mut World, u: f32, n: usize) {
    for _ in 0..n {
        w.write_outputs(&[0.0, u, 0.0]);
        w.advance();
    }
}

#[test]
fn the_lead_error_is_at_the_tool_not_at_the_encoder() {
    // 25 mm along Y: 20 µm/m · 25 mm + 15 µm · sin(2π · 25/100) = 15.5 µm
    let w = world(framed(), 25.0).unwrap();
    assert_eq!(w.state()[1].pos, 25.0);
    let e = w.tool_pos()[1] - 25.0;
    assert!((e - 15.5e-3).abs() < 1e-9, "{e} mm");
    // a rigid axis' tool is where its encoder is, bit for bit
    assert_eq!(w.tool_pos()[0], w.state()[0].pos);
    assert_eq!(w.framed(), [false, true, false]);
}

#[test]
fn a_rigid_machine_runs_bit_for_bit_as_before() {
    // Y framed or not leaves X and Z's integration untouched
    let mut a = world(GANTRY_Y, 0.0).unwrap();
    let mut b = world(framed(), 0.0).unwrap();
    for k in 0..2000 {
        let u = if k < 1000 { 300.0 } else { -300.0 };
        for w in [&mut a, &mut b] {
            w.write_outputs(&[u, 0.0, -u]);
            w.advance();
        }
    }
    for i in [0, 2] {
        assert_eq!(a.state()[i], b.state()[i]);
        assert_eq!(a.tool_pos()[i].to_bits(), b.tool_pos()[i].to_bits());
    }
}

#[test]
fn a_kicked_axis_rings_at_its_mode_and_backlash_is_lost_at_a_reversal() {
    // without backlash: a 20 ms push forward, then coast; the tool swings against the
    // screw at about the mode's frequency (the tool's relative velocity changes sign
    // twice a cycle), decaying
    let tight = PhysicalAxisConfig {
        frame: Some(FrameConfig {
            backlash_mm: 0.0,
            ..FRAME
        }),
        ..GANTRY_Y
    };
    let mut w = world(tight, 0.0).unwrap();
    drive(&mut w, 1500.0, 200);
    let rel = |w: &World| {
        let nut = w.state()[1].pos;
        w.tool_pos()[1] - (nut + lead(nut))
    };
    let (mut prev, mut last_dv) = (rel(&w), 0.0);
    let mut crossings = Vec::new();
    for k in 0..3000 {
        drive(&mut w, 0.0, 1);
        let r = rel(&w);
        let dv = r - prev;
        if k > 0 && dv * last_dv < 0.0 {
            crossings.push(k);
        }
        (prev, last_dv) = (r, dv);
    }
    assert!(crossings.len() >= 10, "{crossings:?}");
    // four half-cycles from the second crossing on
    let period_s = (crossings[9] - crossings[1]) as f64 / 4.0 * 1e-4;
    let f = 1.0 / period_s;
    // the mode: 35 Hz, or the tool's anti-resonance on a screw the friction holds
    // (35 · √0.89 = 33.0 Hz)
    assert!((32.5..35.5).contains(&f), "{f} Hz ({crossings:?})");

    // drive Y one way, stop, then the other way and stop: at rest the tool's guides hold
    // it against the nut's flank, so the lost motion is the backlash plus twice the
    // spring's share of the guides' friction at breakaway (what the tool presses the
    // flank with as it stops)
    let mut w = world(framed(), 0.0).unwrap();
    drive(&mut w, 150.0, 3000);
    drive(&mut w, 0.0, 5000);
    let fwd = rel(&w);
    drive(&mut w, -150.0, 3000);
    drive(&mut w, 0.0, 5000);
    let back = rel(&w);
    let lost = back - fwd;
    assert!(
        (0.02..0.02 + 0.006).contains(&lost),
        "lost motion {lost} mm"
    );
}

fn lead(x: f64) -> f64 {
    20e-6 * x + 15e-3 * (2.0 * std::f64::consts::PI * x / 100.0).sin()
}

#[test]
fn a_mode_the_plant_step_cannot_resolve_is_refused() {
    let fast = PhysicalAxisConfig {
        frame: Some(FrameConfig {
            mode_hz: 2000.0,
            ..FRAME
        }),
        ..GANTRY_Y
    };
    // 2π · 2000 Hz · 25 µs = 0.31: fine; at 1 kHz control with 1 substep, 12.6: refused
    assert!(world(fast, 0.0).is_ok());
    let mut plants = GANTRY_AXES.map(PlantConfig::Physical);
    plants[1] = PlantConfig::Physical(fast);
    let cfg = WorldConfig {
        plants,
        plant_substeps: 1,
        initial: [InitialState::default(); 3],
        switches: [SwitchConfig::NONE; 3],
        imperfections: ImperfectionConfig::default(),
        brakes: Default::default(),
    };
    let e = World::new(&cfg, &servo_config(1_000)).unwrap_err();
    assert!(
        matches!(e, ConfigError::OutOfRange(m) if m.contains("frame.mode_hz")),
        "{e:?}"
    );
}
