//! Property tests of the saturating fixed-point types: every operation on in-range
//! inputs gives the exact (truncated) result, out-of-range results saturate, nothing
//! panics or wraps (these tests run with overflow checks on, so an integer wrap inside
//! the implementation would panic), and the complete control step accepts any input.

use controller_core::controller::{Controller3, ControllerConfig, Measured};
use controller_core::law::LawConfig;
use controller_core::motion::trajectory::Trajectory;
use controller_core::num::fixed::{FxQ16, FxQ32};
use controller_core::presets::paper::{PAPER_DSMC, PAPER_LAMBDA, PAPER_PID, PAPER_SMC};
use controller_core::{Real, Vec3};
use proptest::prelude::*;

const Q16_MAX: f64 = 32768.0 - 1.0 / 65536.0;
const Q32_MAX: f64 = 2147483648.0 - 1.0 / 4294967296.0;

/// Exact value of a raw Q16.16 / Q32.32 number.
fn v16(x: FxQ16) -> f64 {
    x.to_bits() as f64 / 65536.0
}
fn v32(x: FxQ32) -> i128 {
    x.to_bits() as i128
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn q16_ops_exact_or_saturated(a in any::<i32>(), b in any::<i32>()) {
        let (x, y) = (FxQ16::from_bits(a), FxQ16::from_bits(b));
        let sat = |v: f64| v.clamp(-32768.0, Q16_MAX);
        // sums and differences are exact in f64 (33 bits)
        prop_assert_eq!(v16(x + y), sat(v16(x) + v16(y)));
        prop_assert_eq!(v16(x - y), sat(v16(x) - v16(y)));
        prop_assert_eq!(v16(-x), sat(-v16(x)));
        // product: floor to the LSB, then saturate (exact in i64)
        let p = (a as i64 * b as i64) >> 16;
        let expect = p.clamp(i32::MIN as i64, i32::MAX as i64);
        prop_assert_eq!((x * y).to_bits() as i64, expect);
        let mut acc = x;
        acc += y;
        prop_assert_eq!(acc, x + y);
        acc -= y;
        prop_assert_eq!(acc, (x + y) - y);
    }

    #[test]
    fn q32_ops_exact_or_saturated(a in any::<i64>(), b in any::<i64>()) {
        let (x, y) = (FxQ32::from_bits(a), FxQ32::from_bits(b));
        let sat = |v: i128| v.clamp(i64::MIN as i128, i64::MAX as i128);
        prop_assert_eq!(v32(x + y), sat(a as i128 + b as i128));
        prop_assert_eq!(v32(x - y), sat(a as i128 - b as i128));
        prop_assert_eq!(v32(-x), sat(-(a as i128)));
        prop_assert_eq!(v32(x * y), sat((a as i128 * b as i128) >> 32));
    }

    #[test]
    fn conversions_saturate_and_never_panic(v in any::<f64>()) {
        let x = FxQ32::from_f64(v);
        let y = FxQ16::from_f32(v as f32);
        if v.is_nan() {
            prop_assert_eq!(x, FxQ32::ZERO);
            prop_assert_eq!(y, FxQ16::ZERO);
        } else if v >= Q32_MAX {
            prop_assert_eq!(x, FxQ32::MAX);
        } else if v <= -2147483648.0 {
            prop_assert_eq!(x, FxQ32::MIN);
        } else {
            prop_assert!((x.to_f64() - v).abs() <= 1.0 / 4294967296.0);
        }
        if (v as f32) >= 32768.0 {
            prop_assert_eq!(y, FxQ16::MAX);
        } else if (v as f32) <= -32768.0 {
            prop_assert_eq!(y, FxQ16::MIN);
        }
    }

    #[test]
    fn total_functions_never_panic_on_any_bits(a in any::<i64>(), b in any::<i64>(), n in -7i16..8, d in prop::sample::select(vec![1i16, 3, 5, 9])) {
        let (x, y) = (FxQ32::from_bits(a), FxQ32::from_bits(b));
        let e = controller_core::Exponent { num: n, den: d };
        let _ = x.div_or(y, FxQ32::ONE);
        let _ = x.cbrt();
        let _ = x.sqrt_pos();
        let _ = x.sin_cos();
        let _ = x.pow_abs(e, y.abs());
        let (p, q) = (FxQ16::from_bits(a as i32), FxQ16::from_bits(b as i32));
        let _ = p.div_or(q, FxQ16::ONE);
        let _ = p.cbrt();
        let _ = p.sqrt_pos();
        let _ = p.sin_cos();
        let _ = p.pow_abs(e, q.abs());
    }

    /// The full 3-axis step for a real gantry in mm: any position within ±2000 mm, any
    /// velocity within ±1000 mm/s, any time in the first 3 hours, every law. Nothing
    /// panics, the outputs are bounded by the law's `u_max`, and in Q32.32 the output
    /// agrees in sign with the f64 law wherever the f64 output is clearly non-zero and
    /// unsaturated (no silent wrap anywhere in between).
    #[test]
    fn gantry_step_in_range_never_panics_or_wraps(
        pos in prop::array::uniform3(-2000.0f64..2000.0),
        vel in prop::array::uniform3(-1000.0f64..1000.0),
        t in 0.0f64..10_800.0,
        law in 0usize..3,
    ) {
        let mut lc = [PAPER_PID, PAPER_PID, PAPER_PID].map(LawConfig::Pid);
        let mut smc = [PAPER_SMC, PAPER_DSMC];
        for s in &mut smc {
            s.u_max = 1.0e6;
        }
        if law > 0 {
            lc = [LawConfig::Smc(smc[law - 1]); 3];
        } else {
            for l in &mut lc {
                if let LawConfig::Pid(p) = l {
                    p.u_max = 1.0e6;
                }
            }
        }
        let cfg = ControllerConfig { laws: lc, ..ControllerConfig::uniform(lc[0], PAPER_LAMBDA) };
        let traj = Trajectory::Helix {
            center: Vec3::zero(),
            radius: 100.0,
            omega: 1.0,
            z_rate: 50.0,
        };
        let mut fx = Controller3::<FxQ32>::new(&cfg).unwrap();
        let mut fr = Controller3::<f64>::new(&cfg).unwrap();
        let meas = |p: [f64; 3], v: [f64; 3]| Measured {
            pos: Vec3::from_array(p),
            vel: Vec3::from_array(v),
        };
        let tt = t.rem_euclid(1000.0); // keep the reference (z = 50 t) inside the travel
        let of = fx.step(&traj.cast().sample(FxQ32::from_f64(tt)), &meas(pos, vel).cast_meas(), FxQ32::from_f64(5e-5));
        let or = fr.step(&traj.sample(tt), &meas(pos, vel), 5e-5);
        for i in 0..3 {
            let (uf, ur) = (of.u[i].to_f64(), or.u[i]);
            prop_assert!(uf.abs() <= 1.0e6 + 1e-6);
            if ur.abs() > 1.0 && ur.abs() < 0.9e6 {
                prop_assert_eq!(uf.signum(), ur.signum(), "axis {} fixed {} f64 {}", i, uf, ur);
            }
        }
        // Q16.16 on the same inputs: saturates (range analysis), never panics
        let mut q = Controller3::<FxQ16>::new(&cfg).unwrap();
        let _ = q.step(&traj.cast().sample(FxQ16::from_f64(tt)), &meas(pos, vel).cast_meas(), FxQ16::from_f64(5e-5));
    }
}

trait CastMeas {
    fn cast_meas<S: Real>(&self) -> Measured<S>;
}
impl CastMeas for Measured<f64> {
    fn cast_meas<S: Real>(&self) -> Measured<S> {
        Measured {
            pos: self.pos.cast(),
            vel: self.vel.cast(),
        }
    }
}

#[test]
fn saturation_outside_the_range_is_sticky_and_symmetric() {
    let big = FxQ16::from_f32(1.0e9);
    assert_eq!(big, FxQ16::MAX);
    assert_eq!(big + FxQ16::ONE, FxQ16::MAX);
    assert_eq!(big * FxQ16::from_f32(-2.0), FxQ16::MIN);
    assert_eq!(FxQ16::MIN - FxQ16::ONE, FxQ16::MIN);
    assert_eq!(-FxQ16::MIN, FxQ16::MAX);
    assert_eq!(FxQ32::MAX * FxQ32::MAX, FxQ32::MAX);
    assert_eq!(FxQ32::MIN * FxQ32::MAX, FxQ32::MIN);
    // a power that overflows saturates instead of wrapping
    let e53 = controller_core::Exponent { num: 5, den: 3 };
    assert_eq!(
        FxQ16::from_f32(20_000.0).pow_abs(e53, FxQ16::ZERO),
        FxQ16::MAX
    );
    assert_eq!(FxQ32::from_f64(1.0e9).pow_abs(e53, FxQ32::ZERO), FxQ32::MAX);
}
