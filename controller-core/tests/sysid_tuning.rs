//! The tuning rules moved from `seed_params` to `sysid::tuning`: the presets' law
//! configurations must be bit-identical to what the old functions computed. The old
//! bodies are copied here verbatim (from commit 883df9f) as the reference.

mod sysid_common;

use controller_core::law::adaptive_smc::{AdaptiveSmc, AdaptiveSmcConfig, EstimateConfig};
use controller_core::law::dob_smc::{DobSmc, DobSmcConfig};
use controller_core::law::pid::PidConfig;
use controller_core::law::smc::{ReachingConfig, SmcConfig, SurfaceConfig};
use controller_core::law::Law as AxisLaw;
use controller_core::law::LawConfig;
use controller_core::model::PlantParams;
use controller_core::presets::gantry::{
    adaptive_for, dob_smc_for, dsmc_for, pid_for, tuning_for, ADAPTIVE_DEAD_ZONE_MM_S,
    ADAPT_GAIN_B, ADAPT_GAIN_F, ADAPT_GAIN_J, COUNT_MM, GANTRY_AXES, LOOP_OMEGA,
};
use controller_core::sim::physical::PhysicalAxisConfig;
use controller_core::sysid::{tuning, AxisModel};
use controller_core::Exponent;
use sysid_common::*;

const OLD_ADAPTIVE_DEAD_ZONE_MM_S: f32 = 0.05;
const OLD_ADAPT_GAIN_J: f32 = 6e-4 / 0.064;
const OLD_ADAPT_GAIN_B: f32 = 0.06 / 0.064;
const OLD_ADAPT_GAIN_F: f32 = 600.0 / 0.064;

fn old_pid_for(axis: &PhysicalAxisConfig) -> PidConfig {
    let j = axis.inertia;
    let w = LOOP_OMEGA;
    let ki = j * w * w * w;
    PidConfig {
        kp: 3.0 * j * w * w,
        ki,
        kd: 3.0 * j * w,
        kv_ff: 0.0,
        ka_ff: 0.0,
        integral_limit: axis.torque_max_mnm / ki,
        u_max: axis.torque_max_mnm,
    }
}

fn old_dsmc_for(axis: &PhysicalAxisConfig) -> SmcConfig {
    let j = axis.inertia;
    SmcConfig {
        plant: PlantParams {
            a: axis.viscous / j,
            b: 0.0,
            k: 1.0 / j,
        },
        surface: SurfaceConfig::Terminal {
            alpha: LOOP_OMEGA,
            beta: 10.0,
            p: 9,
            q: 5,
            singular_floor: COUNT_MM,
        },
        reaching: ReachingConfig::DoublePower {
            k1: 20.0,
            k2: 20.0,
            k3: 200.0,
            beta2: Exponent { num: 1, den: 3 },
            beta3: Exponent { num: 1, den: 3 },
        },
        k4: LOOP_OMEGA * LOOP_OMEGA * LOOP_OMEGA,
        integral_limit: axis.torque_max_mnm / j / (LOOP_OMEGA * LOOP_OMEGA * LOOP_OMEGA),
        u_max: axis.torque_max_mnm,
    }
}

fn old_dob_smc_for(axis: &PhysicalAxisConfig) -> DobSmcConfig {
    let j = axis.inertia;
    let wo = 250.0;
    DobSmcConfig {
        a: axis.viscous / j,
        b: 1.0 / j,
        c: LOOP_OMEGA,
        k: 100.0,
        eta: 200.0,
        boundary_layer: 5.0,
        k1: 2.0 * wo,
        k2: wo * wo,
        d_hat_limit: axis.torque_max_mnm / j,
        u_max: axis.torque_max_mnm,
    }
}

fn old_adaptive_for(axis: &PhysicalAxisConfig) -> AdaptiveSmcConfig {
    let j = axis.inertia;
    AdaptiveSmcConfig {
        lambda: LOOP_OMEGA,
        boundary_layer: 0.3,
        dead_zone: OLD_ADAPTIVE_DEAD_ZONE_MM_S,
        kd: 2.0 * j * LOOP_OMEGA,
        k: 10.0,
        inertia: EstimateConfig {
            initial: 0.75 * j,
            min: 0.3 * j,
            max: 3.0 * j,
            gamma: j * OLD_ADAPT_GAIN_J,
        },
        viscous: EstimateConfig {
            initial: 0.0,
            min: 0.0,
            max: 3.0 * axis.viscous,
            gamma: j * OLD_ADAPT_GAIN_B,
        },
        coulomb_pos: EstimateConfig {
            initial: 0.0,
            min: 0.0,
            max: 3.0 * axis.coulomb_pos_mnm,
            gamma: j * OLD_ADAPT_GAIN_F,
        },
        coulomb_neg: EstimateConfig {
            initial: 0.0,
            min: 3.0 * axis.coulomb_neg_mnm,
            max: 0.0,
            gamma: j * OLD_ADAPT_GAIN_F,
        },
        u_max: axis.torque_max_mnm,
    }
}

/// Bit-identical: `==` on the structs, and their Debug text, which prints every f32 as
/// its shortest round-trip decimal (so equal text means equal bits, -0.0 included).
fn assert_bit_identical<T: PartialEq + core::fmt::Debug>(new: &T, old: &T) {
    assert_eq!(new, old);
    assert_eq!(format!("{new:?}"), format!("{old:?}"));
}

#[test]
fn presets_are_bit_identical_to_the_old_rules() {
    assert_eq!(
        ADAPTIVE_DEAD_ZONE_MM_S.to_bits(),
        OLD_ADAPTIVE_DEAD_ZONE_MM_S.to_bits()
    );
    assert_eq!(ADAPT_GAIN_J.to_bits(), OLD_ADAPT_GAIN_J.to_bits());
    assert_eq!(ADAPT_GAIN_B.to_bits(), OLD_ADAPT_GAIN_B.to_bits());
    assert_eq!(ADAPT_GAIN_F.to_bits(), OLD_ADAPT_GAIN_F.to_bits());
    for axis in &GANTRY_AXES {
        assert_bit_identical(&pid_for(axis), &old_pid_for(axis));
        assert_bit_identical(&dsmc_for(axis), &old_dsmc_for(axis));
        assert_bit_identical(&dob_smc_for(axis), &old_dob_smc_for(axis));
        assert_bit_identical(&adaptive_for(axis), &old_adaptive_for(axis));
    }
    // and the same through the model-based entry points
    for axis in &GANTRY_AXES {
        let m = AxisModel::from_physical(axis);
        let t = tuning_for(axis);
        assert_bit_identical(&tuning::pid(&m, &t), &old_pid_for(axis));
        assert_bit_identical(&tuning::dsmc(&m, &t), &old_dsmc_for(axis));
        assert_bit_identical(&tuning::dob_smc(&m, &t), &old_dob_smc_for(axis));
    }
}

/// From identified models (the presets identified on the simulated axis): every law
/// builds, and the model-dependent gains are within the identification's error of the
/// gains from the true model.
#[test]
fn laws_from_identified_models() {
    for (i, axis) in GANTRY_AXES.iter().enumerate() {
        let r = run(axis, i as u64);
        let m = r.result.expect("identified").model;
        let t = tuning_for(axis);
        let truth = AxisModel::from_physical(axis);
        let pid = tuning::pid(&m, &t);
        assert!(AxisLaw::<f32>::new(&LawConfig::Pid(pid)).is_ok());
        let rel = |a: f32, b: f32| ((a - b) / b).abs();
        assert!(rel(pid.kp, tuning::pid(&truth, &t).kp) < 0.05);
        let dsmc = tuning::dsmc(&m, &t);
        assert!(AxisLaw::<f32>::new(&LawConfig::Smc(dsmc)).is_ok());
        assert!(rel(dsmc.plant.k, tuning::dsmc(&truth, &t).plant.k) < 0.05);
        assert!(DobSmc::<f32>::new(&tuning::dob_smc(&m, &t)).is_ok());
        let a = tuning::adaptive_smc(&m, &t);
        let law = AdaptiveSmc::<f32>::new(&a).expect("adaptive law builds");
        let s = law.initial_state();
        // the estimates start at the identified model (load folded into f±; the
        // adaptive law's f- is capped at 0)
        assert_eq!(
            (s.j, s.b, s.f_pos),
            (m.inertia, m.viscous, m.coulomb_pos_mnm)
        );
        assert_eq!(s.f_neg, m.coulomb_neg_mnm.min(0.0));
        // and the truth (plus load) lies inside the adaptation bounds
        let t_load = AxisModel::from_physical_with_load(axis);
        assert!(a.inertia.min <= t_load.inertia && t_load.inertia <= a.inertia.max);
        assert!(a.viscous.min <= t_load.viscous && t_load.viscous <= a.viscous.max);
        assert!(
            a.coulomb_pos.min <= t_load.coulomb_pos_mnm
                && t_load.coulomb_pos_mnm <= a.coulomb_pos.max
        );
    }
}
