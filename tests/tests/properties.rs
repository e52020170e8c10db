//! Property tests of the core: contour-error geometry, and no NaN/inf from any law.

use controller_core::controller::{Controller3, ControllerConfig, Measured};
use controller_core::coupling::contour::{contour_error, cross_couple};
use controller_core::coupling::CouplingConfig;
use controller_core::law::pid::PidConfig;
use controller_core::law::smc::SurfaceConfig;
use controller_core::law::LawConfig;
use controller_core::motion::trajectory::RefSample;
use controller_core::presets::gantry::{adaptive_for, dob_smc_for, GANTRY_X, VARIABLE_GAIN_XY};
use controller_core::presets::paper::{PAPER_DSMC, PAPER_PID, PAPER_SMC};
use controller_core::Vec3;
use proptest::prelude::*;

fn v3(r: f64) -> impl Strategy<Value = Vec3<f64>> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    #[test]
    fn contour_vector_is_orthogonal_and_no_longer_than_e(e in v3(10.0), d in v3(10.0)) {
        prop_assume!(d.norm_sq() > 1e-9);
        let c = contour_error(e, d, Vec3::zero(), 1e-12);
        prop_assert!(c.dot(d).abs() <= 1e-9 * (1.0 + e.norm() * d.norm()));
        prop_assert!(c.norm() <= e.norm() * (1.0 + 1e-12) + 1e-15);
    }

    #[test]
    fn contour_is_zero_when_error_is_along_the_path(d in v3(10.0), k in -5.0f64..5.0) {
        prop_assume!(d.norm_sq() > 1e-6);
        let c = contour_error(d * k, d, Vec3::zero(), 1e-12);
        prop_assert!(c.norm() <= 1e-12 * (1.0 + d.norm() * k.abs()));
    }

    #[test]
    fn contour_is_finite_for_zero_or_tiny_direction(e in v3(1e6), tiny in -1e-30f32..1e-30) {
        let e32: Vec3<f32> = e.cast();
        let d = Vec3::new(tiny, 0.0, tiny);
        let c = contour_error(e32, d, Vec3::zero(), 0.0);
        prop_assert!(c.is_finite());
        let cc = cross_couple(e32, e32, d, Vec3::zero(), 0.01, 0.0);
        prop_assert!(cc.c.is_finite() && cc.c_dot.is_finite());
    }
}

fn extreme() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(0.0f32),
        Just(-0.0f32),
        Just(f32::MIN_POSITIVE),
        Just(-1e-30f32),
        Just(1e30f32),
        Just(-1e30f32),
        Just(f32::MAX),
        Just(f32::MIN),
        -1e3f32..1e3,
    ]
}

fn laws() -> Vec<LawConfig> {
    let mut nonsingular = PAPER_DSMC;
    nonsingular.surface = SurfaceConfig::Nonsingular {
        beta: 10.0,
        p: 5,
        q: 3,
    };
    let limited = PidConfig {
        u_max: 100.0,
        integral_limit: 1.0,
        kv_ff: 1.0,
        ka_ff: 1.0,
        ..PAPER_PID
    };
    vec![
        LawConfig::Pid(PAPER_PID),
        LawConfig::Pid(limited),
        LawConfig::Smc(PAPER_SMC),
        LawConfig::Smc(PAPER_DSMC),
        LawConfig::Smc(nonsingular),
        LawConfig::DobSmc(dob_smc_for(&GANTRY_X)),
        LawConfig::AdaptiveSmc(adaptive_for(&GANTRY_X)),
    ]
}

proptest! {
    #[test]
    fn no_law_emits_nan_or_inf(p in [extreme(), extreme(), extreme()], v in [extreme(), extreme(), extreme()],
                               r in [extreme(), extreme(), extreme()], rv in [extreme(), extreme(), extreme()]) {
        let couplings = [
            ControllerConfig::uniform(LawConfig::Pid(PAPER_PID), 0.01).coupling,
            CouplingConfig::None,
            CouplingConfig::VariableGain(VARIABLE_GAIN_XY),
        ];
        for law in laws() {
            for coupling in couplings {
                let mut g = Controller3::<f32>::new(&ControllerConfig { coupling, ..ControllerConfig::uniform(law, 0.01) }).unwrap();
                let reference = RefSample { pos: Vec3::from_array(r), vel: Vec3::from_array(rv), acc: Vec3::from_array(rv) };
                let meas = Measured { pos: Vec3::from_array(p), vel: Vec3::from_array(v) };
                for _ in 0..3 {
                    let out = g.step(&reference, &meas, 1e-4);
                    prop_assert!(out.u.is_finite(), "{:?} -> {:?}", law, out.u);
                    prop_assert!(out.s.is_finite());
                    prop_assert!(g.states().iter().all(|s| s.integral.is_finite()
                        && s.dob.v_hat.is_finite() && s.dob.d_hat.is_finite()
                        && s.adapt.j.is_finite() && s.adapt.b.is_finite()
                        && s.adapt.f_pos.is_finite() && s.adapt.f_neg.is_finite()));
                    prop_assert!(g.variable_gain_state().integral.is_finite());
                }
            }
        }
    }
}
