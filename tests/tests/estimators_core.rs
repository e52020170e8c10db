//! Velocity estimators (controller-core `estimator`) against the numeric
//! requirements: zero steady-state velocity error on a ramp, bounded lag on a sine,
//! noise attenuation with ±1 count dither, no lost count at 16/32-bit counter wrap, and
//! rejection of unstable gain/period combinations. All signals are synthetic counts at
//! the paper simulation's timing (10 kHz, 1e-4 units per count), so units/s are
//! numerically counts per period.

use controller_core::config::ConfigError;
use controller_core::estimator::{
    CounterWidth, EstimatorConfig, EstimatorTiming, KalmanConfig, PllConfig, VelocityEstimator,
    WideCounter, PAPER_SIM_KALMAN, PAPER_SIM_PLL, PAPER_SIM_TIMING,
};
use controller_core::sim::rng::SplitMix64;

const TS: f64 = 1e-4;
const COUNT: f64 = 1e-4;

fn observers() -> [(&'static str, EstimatorConfig); 2] {
    [
        ("pll", EstimatorConfig::Pll(PAPER_SIM_PLL)),
        ("kalman", EstimatorConfig::Kalman(PAPER_SIM_KALMAN)),
    ]
}

/// Run `cfg` on counts `n(k)`, `k = 0..steps`; returns (k, estimated vel) pairs.
fn run(cfg: &EstimatorConfig, steps: usize, n: impl Fn(usize) -> i64) -> Vec<(usize, f64)> {
    let mut e = VelocityEstimator::<f64>::new(cfg, &PAPER_SIM_TIMING, n(0)).unwrap();
    (1..steps).map(|k| (k, e.update(n(k), 0.0).vel)).collect()
}

#[test]
fn ramp_has_zero_steady_state_velocity_error() {
    for (name, cfg) in observers() {
        // integer slope: 3 counts/period = 3 units/s, exact after settling
        let v = run(&cfg, 20_000, |k| 3 * k as i64 + 12_345);
        let worst = v[10_000..]
            .iter()
            .map(|&(_, x)| (x - 3.0).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{name}: integer ramp error {worst}");

        // fractional slope 0.37 counts/period: quantised, so the estimate fluctuates, but
        // its mean over the second second is the true velocity
        let v = run(&cfg, 20_000, |k| (0.37 * k as f64).floor() as i64);
        let tail = &v[10_000..];
        let mean = tail.iter().map(|&(_, x)| x).sum::<f64>() / tail.len() as f64;
        assert!((mean - 0.37).abs() < 1e-3, "{name}: mean {mean}");
    }
}

#[test]
fn sine_lag_is_bounded() {
    // 100-count (0.01 unit) amplitude at 5 Hz: velocity amplitude 0.314 units/s,
    // acceleration amplitude 9.87 units/s². Quantised to whole counts.
    let w = 2.0 * std::f64::consts::PI * 5.0;
    let amp_counts = 100.0;
    let pos = |k: usize| (amp_counts * (w * k as f64 * TS).sin()).round() as i64;
    let vel = |k: usize| amp_counts * COUNT * w * (w * k as f64 * TS).cos();
    let vel_amp = amp_counts * COUNT * w;
    // Bounds: PLL lag ≈ 2ζA/ω_pll = 2·9.87/500 = 0.039 (12 % of amplitude) plus
    // quantisation noise; the Kalman filter (three integrators, no acceleration input
    // here) lags far less.
    for (name, cfg, bound) in [
        ("pll", EstimatorConfig::Pll(PAPER_SIM_PLL), 0.15),
        ("kalman", EstimatorConfig::Kalman(PAPER_SIM_KALMAN), 0.05),
    ] {
        let v = run(&cfg, 20_000, pos);
        let worst = v[10_000..]
            .iter()
            .map(|&(k, x)| (x - vel(k)).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < bound * vel_amp,
            "{name}: worst {worst} vs amplitude {vel_amp}"
        );
    }
}

#[test]
fn commanded_acceleration_removes_kalman_lag() {
    // Same 5 Hz sine, now telling the Kalman filter the true acceleration: the error
    // left is quantisation noise only.
    let w = 2.0 * std::f64::consts::PI * 5.0;
    let a = 100.0 * COUNT;
    let mut e = VelocityEstimator::<f64>::new(
        &EstimatorConfig::Kalman(PAPER_SIM_KALMAN),
        &PAPER_SIM_TIMING,
        0,
    )
    .unwrap();
    let (mut worst_with, mut worst_without) = (0.0f64, 0.0f64);
    let mut e0 = e;
    for k in 1..20_000 {
        let t = k as f64 * TS;
        let n = (a / COUNT * (w * t).sin()).round() as i64;
        // mean acceleration over the period that just ended
        let acc = -a * w * w * (w * (t - TS / 2.0)).sin();
        let v_true = a * w * (w * t).cos();
        let with = e.update(n, acc).vel;
        let without = e0.update(n, 0.0).vel;
        if k >= 10_000 {
            worst_with = worst_with.max((with - v_true).abs());
            worst_without = worst_without.max((without - v_true).abs());
        }
    }
    assert!(worst_with < 0.03 * a * w, "{worst_with}");
    assert!(
        worst_with < 0.5 * worst_without,
        "{worst_with} vs {worst_without}"
    );
}

/// Deterministic ±1 count dither around 0: the first SplitMix64 draw seeded with the
/// sample index, mapped to {-1, 0, 1} with equal probability (independent samples).
fn dither(k: usize) -> i64 {
    let z = SplitMix64::new(k as u64).next_u64();
    (z % 3) as i64 - 1
}

#[test]
fn dither_on_a_stationary_axis_is_attenuated() {
    let rms = |v: &[(usize, f64)]| {
        (v[5_000..].iter().map(|&(_, x)| x * x).sum::<f64>() / (v.len() - 5_000) as f64).sqrt()
    };
    let bd = rms(&run(&EstimatorConfig::BackwardDifference, 20_000, dither));
    // difference of two independent uniform {-1,0,1}: RMS sqrt(4/3) counts/period
    assert!((bd - 1.155).abs() < 0.05, "{bd}");
    for (name, cfg, factor) in [
        ("pll", EstimatorConfig::Pll(PAPER_SIM_PLL), 0.05),
        ("kalman", EstimatorConfig::Kalman(PAPER_SIM_KALMAN), 0.02),
    ] {
        let r = rms(&run(&cfg, 20_000, dither));
        assert!(
            r < factor * bd,
            "{name}: rms {r} vs backward difference {bd}"
        );
    }
}

fn no_lost_count_across_wrap(width: CounterWidth, modulus: u64) {
    // 7 counts/period starting 300 counts below the wrap, through it and back down: the
    // wide counts must be the true counts, and every estimate must be bit-identical to
    // that of the same motion fed without any wrap.
    let start_raw = modulus - 300;
    for (name, cfg) in observers() {
        let mut wide = WideCounter::new(width, start_raw as u32, 0);
        let mut wrapped = VelocityEstimator::<f32>::new(&cfg, &PAPER_SIM_TIMING, 0).unwrap();
        let mut reference = wrapped;
        let mut true_count: i64 = 0;
        let mut crossings = 0;
        for k in 1..4_000 {
            let step = if k < 2_000 { 7 } else { -7 };
            let before = (start_raw as i64 + true_count) >= modulus as i64;
            true_count += step;
            let after = (start_raw as i64 + true_count) >= modulus as i64;
            crossings += (before != after) as u32;
            let raw = ((start_raw as i64 + true_count).rem_euclid(modulus as i64)) as u32;
            let n = wide.update(raw);
            assert_eq!(n, true_count, "{name}: count lost at k = {k}");
            assert_eq!(
                wrapped.update(n, 0.0),
                reference.update(true_count, 0.0),
                "{name}: k = {k}"
            );
        }
        assert_eq!(crossings, 2);
        assert_eq!(wide.count(), 7 * 1_999 - 7 * 2_000);
    }
}

#[test]
fn no_lost_count_across_16_bit_wrap() {
    no_lost_count_across_wrap(CounterWidth::Bits16, 1 << 16);
}

#[test]
fn no_lost_count_across_32_bit_wrap() {
    no_lost_count_across_wrap(CounterWidth::Bits32, 1 << 32);
}

#[test]
fn far_from_origin_f32_keeps_sub_count_precision() {
    // 10^9 counts from the origin (100 000 units): the estimators work relative to the
    // last count, so f32 still resolves the velocity of a 0.37 count/period ramp.
    let base = 1_000_000_000i64;
    let mut e = VelocityEstimator::<f32>::new(
        &EstimatorConfig::Kalman(PAPER_SIM_KALMAN),
        &PAPER_SIM_TIMING,
        base,
    )
    .unwrap();
    let mut sum = 0.0f64;
    for k in 1..20_000 {
        let v = e.update(base + (0.37 * k as f64).floor() as i64, 0.0).vel;
        if k >= 10_000 {
            sum += v as f64;
        }
    }
    let mean = sum / 10_000.0;
    assert!((mean - 0.37).abs() < 1e-3, "{mean}");
}

#[test]
fn unstable_combinations_are_rejected() {
    let t = PAPER_SIM_TIMING;
    // ζ = 1: stable iff ωTs < 2√2 - 2 = 0.828
    let pll = |w: f32, z: f32| {
        VelocityEstimator::<f32>::new(
            &EstimatorConfig::Pll(PllConfig {
                bandwidth_rad_s: w,
                damping: z,
            }),
            &t,
            0,
        )
    };
    assert!(pll(8_000.0, 1.0).is_ok());
    let unstable = Err(ConfigError::Unstable("pll bandwidth_rad_s * period_s"));
    assert_eq!(pll(8_500.0, 1.0), unstable);
    // heavy damping: α = 2ζωTs must stay below 2
    assert_eq!(pll(1_000.0, 10.0), unstable);
    // the same bandwidth is fine at 10x the rate
    let fast = EstimatorTiming {
        period_s: 1e-5,
        count_size: 1e-4,
    };
    assert!(VelocityEstimator::<f32>::new(
        &EstimatorConfig::Pll(PllConfig {
            bandwidth_rad_s: 8_500.0,
            damping: 1.0
        }),
        &fast,
        0
    )
    .is_ok());
    assert_eq!(
        pll(f32::NAN, 1.0),
        Err(ConfigError::NotFinite("bandwidth_rad_s"))
    );
    assert_eq!(
        pll(-5.0, 1.0),
        Err(ConfigError::NotPositive("bandwidth_rad_s"))
    );
    let kal = |s: f32, m: f32| {
        VelocityEstimator::<f32>::new(
            &EstimatorConfig::Kalman(KalmanConfig {
                accel_noise_units_s2: s,
                meas_noise_counts: m,
            }),
            &t,
            0,
        )
    };
    assert_eq!(
        kal(0.0, 0.3),
        Err(ConfigError::NotPositive("accel_noise_units_s2"))
    );
    assert_eq!(
        kal(0.05, -1.0),
        Err(ConfigError::NotPositive("meas_noise_counts"))
    );
    assert!(kal(f32::INFINITY, 0.3).is_err());
}

#[test]
fn stable_pll_settles_just_inside_the_boundary() {
    // ωTs = 0.8, just inside: the loop still settles on a step of 1000 counts
    let cfg = EstimatorConfig::Pll(PllConfig {
        bandwidth_rad_s: 8_000.0,
        damping: 1.0,
    });
    let v = run(&cfg, 5_000, |k| if k == 0 { 0 } else { 1_000 });
    let last = v.last().unwrap().1;
    assert!(last.abs() < 1e-9, "{last}");
}
