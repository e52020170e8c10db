//! The machine files host-sim reads (`host-sim/machines/*.toml`) describe exactly the
//! machines the core's presets name (the firmware builds its board default from the
//! presets): a change to one without the other fails here.

use controller_core::presets::gantry::{
    GANTRY_AMPLIFIERS, GANTRY_AXES, GANTRY_ENCODERS, GANTRY_SAFETY,
};
use controller_core::presets::paper::PAPER_PLANT;
use controller_core::sim::world::PlantConfig;
use gantry_tests::resolve_text;

fn machine(file: &str) -> gantry_scenario::Resolved {
    resolve_text(&format!(
        r#"
name = "machine_check"
horizon_s = 0.01
path = {{ step = {{ target = [0.0, 0.0, 0.0] }} }}
estimator = {{ axes.all = {{ pll = {{ bandwidth_rad_s = 1000.0 }} }} }}
controller = {{ coupling = "none", laws.all = {{ pid = {{ kp = 1.0, ki = 0.0, kd = 0.0 }} }} }}
machine = {{ file = "../machines/{file}" }}
"#
    ))
}

#[test]
fn gantry_machine_file_equals_the_core_presets() {
    let r = machine("gantry.toml");
    let s = &r.run.servo;
    assert_eq!(s.rate_hz, 10_000);
    assert_eq!(s.encoders, GANTRY_ENCODERS);
    assert_eq!(s.amplifiers, GANTRY_AMPLIFIERS);
    assert_eq!(s.safety.axes, GANTRY_SAFETY);
    for (i, p) in r.run.world.plants.iter().enumerate() {
        assert_eq!(*p, PlantConfig::Physical(GANTRY_AXES[i]), "axis {i}");
    }
}

#[test]
fn paper_machine_file_is_the_papers_axis() {
    let r = machine("paper_axis.toml");
    for p in r.run.world.plants {
        let PlantConfig::Paper(p) = p else {
            panic!("paper plant expected")
        };
        assert_eq!(
            (p.a, p.b, p.k),
            (PAPER_PLANT.a, PAPER_PLANT.b, PAPER_PLANT.k)
        );
        assert_eq!(p.disturbance_accel, 0.0);
    }
}
