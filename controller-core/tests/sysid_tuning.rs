//! Laws from identified models: every law builds from what identification finds, and its
//! model-dependent gains are within the identification's error of the true model's.

use crate::sysid_common;

use controller_core::law::adaptive_smc::AdaptiveSmc;
use controller_core::law::dob_smc::DobSmc;
use controller_core::law::Law as AxisLaw;
use controller_core::law::LawConfig;
use controller_core::plant::AxisModel;
use controller_core::presets::gantry::{tuning_for, GANTRY_AXES};
use controller_core::sysid::tuning;
use sysid_common::*;

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
