//! The shipped default (presets::board, what `cargo fw` flashes) on the simulated physical
//! gantry, following its demo path (helix r = 10 mm, 15 s, then holding): fewer than 1 %
//! of periods with an amplifier at full scale, and no full-scale reversals after
//! start-up. (The configuration it replaced, the paper's normalised model applied in mm
//! with an effort limit of 50, saturated in 199,988 of 199,990 periods with 6,018
//! full-scale reversals in 20 s.)

use controller_core::presets::board::{servo_config, BOARD_RATE_HZ};
use controller_core::presets::gantry::GANTRY_AXES;
use controller_core::servo::ServoState;
use controller_core::sim::run::{RunConfig, SimRun};
use controller_core::sim::truth::TruthSpec;
use controller_core::sim::world::{
    ImperfectionConfig, InitialState, PlantConfig, SwitchConfig, WorldConfig,
};

#[test]
fn default_configuration_follows_the_demo_path_without_saturating() {
    let servo = servo_config(BOARD_RATE_HZ);
    let full = servo.amplifiers.map(|a| a.full_scale);
    let periods = 20 * BOARD_RATE_HZ;
    let mut run = SimRun::<f32>::new(&RunConfig {
        servo,
        world: WorldConfig {
            plants: GANTRY_AXES.map(PlantConfig::Physical),
            plant_substeps: 4,
            initial: [InitialState::default(); 3],
            switches: [SwitchConfig::NONE; 3],
            imperfections: ImperfectionConfig::default(),
            brakes: Default::default(),
        },
        truth: TruthSpec::default(),
        periods,
        hold: false,
        inject: None,
        program: false,
    })
    .unwrap();
    let startup = BOARD_RATE_HZ / 2; // the first 0.5 s
    let (mut saturated, mut reversals, mut max_err) = (0u32, 0u32, 0.0f32);
    let mut last_sign = [0i8; 3];
    while !run.done() {
        let s = *run.control();
        assert_eq!(s.state, ServoState::Run, "period {}", s.period);
        let mut sat = false;
        for i in 0..3 {
            let u = s.effort[i];
            sat |= u.abs() >= 0.999 * full[i];
            // a full-scale reversal: from one end of the range to the other
            let sign = if u >= 0.9 * full[i] {
                1
            } else if u <= -0.9 * full[i] {
                -1
            } else {
                last_sign[i]
            };
            if run.periods_run() > startup && sign != 0 && sign == -last_sign[i] {
                reversals += 1;
            }
            last_sign[i] = sign;
            max_err = max_err.max(s.tracking[i].abs());
        }
        saturated += u32::from(sat);
        run.finish_period();
    }
    let share = f64::from(saturated) / f64::from(periods);
    println!("saturated {saturated} of {periods} periods ({:.3} %), {reversals} full-scale reversals, max tracking error {max_err} mm", share * 100.0);
    assert!(share < 0.01, "{saturated} saturated periods");
    assert_eq!(reversals, 0);
    assert!(max_err < 0.05, "max tracking error {max_err} mm");
}
