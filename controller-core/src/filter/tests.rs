//! The filters' figures: attenuation and widths, the low-pass' cutoff, fixed point
//! against `f32` against `f64`, the empty chain's bit-exact passthrough, placement, and
//! margins against closed forms.

use super::chain::{FilterChain, OutputFilters};
use super::design::{AxisFilterConfig, FilterConfig, MAX_STAGES};
use super::margins::{
    accept, loop_margins, pid_response, Rejection, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG,
};
use super::placement::{place, Resonance};
use super::response::{gain_db, FrequencyResponse, C64};
use crate::num::fixed::FxQ32;
use crate::{Real, Vec3};
use core::f64::consts::PI;

const T: f32 = 1.0e-4;

fn notch(freq_hz: f32, width_hz: f32, depth_db: f32) -> FilterConfig {
    FilterConfig::Notch {
        freq_hz,
        width_hz,
        depth_db,
    }
}

fn chain<R: Real>(stages: &[FilterConfig]) -> FilterChain<R, MAX_STAGES> {
    FilterChain::new(&AxisFilterConfig::new(stages).unwrap(), T).unwrap()
}

/// xorshift64*: a reproducible uniform sequence in [-1, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (v >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// The frequency between `lo` and `hi` where the chain's gain (dB) crosses `level`
/// (bisection; the gain is monotonic there).
fn crossing(c: &FilterChain<f64, MAX_STAGES>, mut lo: f64, mut hi: f64, level: f64) -> f64 {
    let above_at_lo = gain_db(c.response(lo as f32)) > level;
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if (gain_db(c.response(mid as f32)) > level) == above_at_lo {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn notch_depth_and_shoulders() {
    for (f, w, d) in [
        (35.0, 5.0, 20.0),
        (250.0, 25.0, 30.0),
        (1200.0, 150.0, 12.0),
    ] {
        for gains in [
            [0.5, 1.0, 2.0].map(|k| gain_db(chain::<f32>(&[notch(f, w, d)]).response(k * f))),
            [0.5, 1.0, 2.0].map(|k| gain_db(chain::<FxQ32>(&[notch(f, w, d)]).response(k * f))),
        ] {
            let [below, centre, above] = gains;
            assert!(centre <= -(d as f64) + 0.5, "{f} Hz: centre {centre} dB");
            assert!(centre >= -(d as f64) - 0.5, "{f} Hz: centre {centre} dB");
            assert!(
                below.abs() < 1.0 && above.abs() < 1.0,
                "{f} Hz: {below} / {above} dB"
            );
        }
        // the width is the distance between the half-depth frequencies (exact, digital)
        let c = chain::<f64>(&[notch(f, w, d)]);
        let half = -(d as f64) / 2.0;
        let lo = crossing(&c, 0.2 * f as f64, f as f64, half);
        let hi = crossing(&c, f as f64, 3.0 * f as f64, half);
        assert!(
            ((hi - lo) / w as f64 - 1.0).abs() < 1e-3,
            "{f} Hz: {lo}..{hi}"
        );
    }
}

#[test]
fn low_pass_is_3_db_down_at_cutoff() {
    for fc in [20.0, 100.0, 400.0, 2000.0, 4000.0] {
        let lp = [FilterConfig::low_pass(fc)];
        for g in [
            gain_db(chain::<f32>(&lp).response(fc)),
            gain_db(chain::<f64>(&lp).response(fc)),
            gain_db(chain::<FxQ32>(&lp).response(fc)),
        ] {
            assert!((g + 3.0103).abs() < 0.2, "{fc} Hz: {g} dB");
        }
        let pass = gain_db(chain::<f32>(&lp).response(0.1 * fc));
        assert!(pass.abs() < 0.01, "{fc} Hz: {pass} dB a decade below");
    }
}

/// The kernel's filter set of one axis (notch + low-pass): 10 s of uniform random input
/// at 10 kHz through f64, f32 and Q32.32.
#[test]
fn f32_and_q32_follow_f64() {
    let stages = [notch(52.0, 15.0, 18.0), FilterConfig::low_pass(400.0)];
    let (mut c64, mut c32, mut cfx) = (
        chain::<f64>(&stages),
        chain::<f32>(&stages),
        chain::<FxQ32>(&stages),
    );
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let amp = 300.0;
    let (mut e32, mut efx, mut efx32, mut sum2, mut peak) = (0.0f64, 0.0f64, 0.0f64, 0.0, 0.0f64);
    let mut e32_max = 0.0f64;
    let mut efx32_max = 0.0f64;
    let n = 100_000;
    for _ in 0..n {
        let x = amp * rng.next();
        let y = c64.process(x);
        let y32 = c32.process(x as f32) as f64;
        let yfx = cfx.process(FxQ32::from_f64(x));
        assert!(yfx < FxQ32::MAX && yfx > FxQ32::MIN, "saturated");
        let yfx = yfx.to_f64();
        e32 += (y32 - y) * (y32 - y);
        efx += (yfx - y) * (yfx - y);
        efx32 += (yfx - y32) * (yfx - y32);
        e32_max = e32_max.max((y32 - y).abs());
        efx32_max = efx32_max.max((yfx - y32).abs());
        sum2 += y * y;
        peak = peak.max(y.abs());
    }
    let rms = libm::sqrt(sum2 / n as f64);
    let rel = |e: f64| libm::sqrt(e / n as f64) / rms;
    assert!(rel(e32) < 1e-4, "f32 vs f64: {}", rel(e32));
    assert!(rel(efx) < 1e-6, "Q32.32 vs f64: {}", rel(efx));
    assert!(rel(efx32) < 1e-4, "Q32.32 vs f32 (rms): {}", rel(efx32));
    extern crate std;
    std::println!(
        "rms relative: f32 {:.2e}, Q32.32 {:.2e}; peak relative Q32.32 vs f32 {:.2e}",
        rel(e32),
        rel(efx),
        efx32_max / peak
    );
    // the figure: Q32.32 within 1e-4 of f32, relative to the output's peak
    assert!(
        efx32_max / peak < 1e-4,
        "Q32.32 vs f32: {}",
        efx32_max / peak
    );
    assert!(e32_max / peak > 1e-9, "f32 must differ from f64 somewhere");
}

/// Random bit patterns, including the signed zeros, subnormals and non-finite values.
#[test]
fn empty_filters_are_bit_exact_passthrough() {
    let mut none = OutputFilters::<f32>::none();
    let mut built = OutputFilters::<f32>::new(&[AxisFilterConfig::NONE; 3], T).unwrap();
    assert!(none.is_empty() && built.is_empty());
    let mut rng = Rng(7);
    let specials = [0.0, -0.0, 1e-45, -1e-40, f32::MAX, f32::INFINITY, f32::NAN];
    for i in 0..20_000 {
        let bits = |r: &mut Rng| (r.next().to_bits() >> 17) as u32;
        let u = if let Some(&s) = specials.get(i) {
            Vec3::new(s, -s, s)
        } else {
            Vec3::new(
                f32::from_bits(bits(&mut rng)),
                f32::from_bits(bits(&mut rng)),
                f32::from_bits(bits(&mut rng)),
            )
        };
        for f in [&mut none, &mut built] {
            let y = f.process(u);
            assert_eq!(
                [y.x.to_bits(), y.y.to_bits(), y.z.to_bits()],
                [u.x.to_bits(), u.y.to_bits(), u.z.to_bits()]
            );
        }
    }
    // an axis with filters does change its output, the others stay bit-exact
    let y_only = [
        AxisFilterConfig::NONE,
        AxisFilterConfig::new(&[notch(35.0, 14.0, 15.0)]).unwrap(),
        AxisFilterConfig::NONE,
    ];
    let mut f = OutputFilters::<f32>::new(&y_only, T).unwrap();
    let y = f.process(Vec3::new(0.3, 0.3, -0.7));
    assert_eq!((y.x, y.z), (0.3, -0.7));
    assert!(y.y != 0.3);
}

#[test]
fn reset_holds_a_constant_output_and_nan_does_not_latch() {
    let cfg = [
        AxisFilterConfig::new(&[notch(90.0, 20.0, 15.0)]).unwrap(),
        AxisFilterConfig::new(&[notch(35.0, 14.0, 15.0)]).unwrap(),
        AxisFilterConfig::new(&[notch(52.0, 15.0, 18.0), FilterConfig::low_pass(400.0)]).unwrap(),
    ];
    let mut f = OutputFilters::<f32>::new(&cfg, T).unwrap();
    let u = Vec3::new(12.5, -3.0, 250.0);
    f.reset(u);
    for _ in 0..2000 {
        let y = f.process(u);
        for (a, b) in y.to_array().iter().zip(u.to_array()) {
            assert!((a - b).abs() <= 2e-4 * b.abs(), "{a} vs {b}");
        }
    }
    // a NaN clears the chain instead of latching
    let z = f.process(Vec3::new(f32::NAN, 1.0, 1.0));
    assert_eq!(z.x, 0.0);
    let next = f.process(Vec3::new(1.0, 1.0, 1.0));
    assert!(next.x.is_finite() && (next.x - 1.0).abs() < 0.1, "{next:?}");
    // a chain shorter than the configuration refuses it
    let two =
        AxisFilterConfig::new(&[notch(52.0, 15.0, 18.0), FilterConfig::low_pass(400.0)]).unwrap();
    assert_eq!(
        FilterChain::<f32, 1>::new(&two, T),
        Err(crate::config::ConfigError::OutOfRange("filters"))
    );
    assert_eq!(FilterChain::<f32, 2>::new(&two, T).map(|c| c.len()), Ok(2));
    // bad configurations name their field
    let mut bad = cfg;
    bad[2] =
        AxisFilterConfig::new(&[notch(52.0, 15.0, 18.0), FilterConfig::low_pass(4800.0)]).unwrap();
    assert_eq!(
        OutputFilters::<f32>::new(&bad, T),
        Err(crate::config::ConfigError::OutOfRange("low_pass.cutoff_hz"))
    );
}

#[test]
fn places_a_notch_on_the_35_hz_mode() {
    let mode = Resonance {
        freq_hz: 35.0,
        damping_ratio: 0.11,
        peak_db: 20.0 * libm::log10f(1.0 / (2.0 * 0.11)),
    };
    let p = place(&[mode], 10.0, T, false).unwrap();
    let stages = p.filters.stages();
    assert_eq!(stages.len(), 1);
    let FilterConfig::Notch {
        freq_hz,
        width_hz,
        depth_db,
    } = stages[0]
    else {
        panic!("{stages:?}")
    };
    assert_eq!(freq_hz, 35.0);
    assert!(depth_db >= mode.peak_db, "{depth_db}");
    assert!(
        width_hz > 2.0 * 0.11 * 35.0 && width_hz < 35.0,
        "{width_hz}"
    );
    // the notched mode ends on the rigid-body line: |notch · mode| peaks at 1.25 dB (a
    // mode of damping 0.5)
    let c = chain::<f32>(stages);
    let w_r = 2.0 * PI * 35.0;
    let mut worst = f64::NEG_INFINITY;
    for i in 0..400 {
        let f = 5.0 * libm::pow(40.0, i as f64 / 399.0);
        let s = C64::new(0.0, 2.0 * PI * f);
        let m = C64::new(w_r * w_r, 0.0).over(
            s.times(s)
                .plus(s.scale(2.0 * 0.11 * w_r))
                .plus(C64::new(w_r * w_r, 0.0)),
        );
        worst = worst.max(20.0 * libm::log10(m.times(C64::from_pair(c.response(f as f32))).abs()));
    }
    assert!(worst < 1.5, "filtered mode peaks at {worst} dB");
    // the phase it costs at the bandwidth and at 1.5x (the rule's documented figures)
    let lag = |f: f32| -C64::from_pair(c.response(f)).arg_deg();
    assert!((lag(10.0) - 13.4).abs() < 1.0, "{}", lag(10.0));
    let near = place(
        &[Resonance {
            freq_hz: 15.0,
            ..mode
        }],
        10.0,
        T,
        false,
    )
    .unwrap();
    let c15 = chain::<f32>(near.filters.stages());
    let lag15 = -C64::from_pair(c15.response(10.0)).arg_deg();
    assert!((lag15 - 35.4).abs() < 1.5, "{lag15}");
}

#[test]
fn placement_rules() {
    let m = |freq_hz, peak_db| Resonance {
        freq_hz,
        damping_ratio: 0.05,
        peak_db,
    };
    // 12 Hz is too close to a 10 Hz bandwidth, 2 dB too small, 6000 Hz out of range;
    // five notchable peaks for three stages (one left for the low-pass): the 3 highest
    let modes = [
        m(12.0, 10.0),
        m(80.0, 2.0),
        m(6000.0, 20.0),
        m(40.0, 8.0),
        m(300.0, 15.0),
        m(150.0, 6.0),
        m(900.0, 12.0),
        m(500.0, 9.0),
    ];
    let p = place(&modes, 10.0, T, true).unwrap();
    assert_eq!((p.near_bandwidth, p.out_of_range, p.no_room), (1, 1, 2));
    let freqs: heapless::Vec<f32, 4> = p
        .filters
        .stages()
        .iter()
        .map(|s| match *s {
            FilterConfig::Notch { freq_hz, .. } => freq_hz,
            FilterConfig::LowPass { cutoff_hz, .. } => -cutoff_hz,
        })
        .collect();
    assert_eq!(freqs.as_slice(), &[300.0, 500.0, 900.0, -60.0]);
    p.filters.validate(T).unwrap();
    assert!(place(&[m(f32::NAN, 3.0)], 10.0, T, false).is_err());
    assert!(place(&modes, 0.0, T, false).is_err());
    assert!(place(
        &[Resonance {
            damping_ratio: 1.5,
            ..m(50.0, 10.0)
        }],
        10.0,
        T,
        false
    )
    .is_err());
}

/// Log-spaced frequencies, `per_decade` per decade from `f0` over `decades`.
fn grid<const N: usize>(f0: f64, decades: f64) -> [f32; N] {
    core::array::from_fn(|i| (f0 * libm::pow(10.0, decades * i as f64 / (N - 1) as f64)) as f32)
}

/// `k / (s (s + a))` with a delay `e^{-s τ}` (the computation delay) at `f`.
fn plant_k_s_sa(k: f64, a: f64, tau: f64, f: f64) -> (f32, f32) {
    let s = C64::new(0.0, 2.0 * PI * f);
    C64::new(k, 0.0)
        .over(s.times(s.plus(C64::new(a, 0.0))))
        .times(C64::unit(-2.0 * PI * f * tau))
        .to_pair()
}

/// `k/(s(s+a))` under the PD `kd (s + a)` (its zero on the plant's pole) and a delay τ is
/// `k kd e^{-sτ}/s`: crossover at `ω_c = k kd`, phase margin `90° - ω_c τ`, phase
/// crossover at `ω τ = π/2`, gain margin `π/(2 τ k kd)`.
#[test]
fn margins_of_a_known_loop() {
    let (k, a, tau) = (400.0, 30.0, 2.0e-3);
    let kd = 2.0 * PI * 20.0 / k; // crossover at 20 Hz
    let kp = kd * a;
    let freq: [f32; 301] = grid(1.0, 3.0);
    let plant = freq.map(|f| plant_k_s_sa(k, a, tau, f as f64));
    let pd = freq.map(|f| pid_response(kp as f32, 0.0, kd as f32, f));
    let m = loop_margins(&freq, &plant, &pd, &FilterChain::<f32, 4>::none()).unwrap();
    let wc = k * kd;
    let pm = 90.0 - (wc * tau).to_degrees();
    let gm = 20.0 * libm::log10(PI / (2.0 * tau * wc));
    assert!(m.stable);
    assert!(
        (m.phase_margin_deg as f64 - pm).abs() < 1.0,
        "{m:?} vs {pm}"
    );
    assert!((m.gain_margin_db as f64 - gm).abs() < 0.5, "{m:?} vs {gm}");
    assert!((m.gain_crossover_hz.unwrap() as f64 - 20.0).abs() < 0.2);
    assert!((m.phase_crossover_hz.unwrap() as f64 - 1.0 / (4.0 * tau)).abs() < 1.5);
    assert_eq!(m.gain_crossovers, 1);
    assert_eq!(accept(&m, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG), Ok(()));

    // a low-pass far too low (8 Hz under a 20 Hz crossover) destabilises it: rejected
    let low = chain::<f32>(&[FilterConfig::low_pass(8.0)]);
    let m_low = loop_margins(&freq, &plant, &pd, &low).unwrap();
    assert!(!m_low.stable, "{m_low:?}");
    assert_eq!(
        accept(&m_low, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG),
        Err(Rejection::Unstable)
    );
    // one at 30 Hz keeps it stable but eats the phase margin; one at 300 Hz is accepted
    let mid = loop_margins(
        &freq,
        &plant,
        &pd,
        &chain::<f32>(&[FilterConfig::low_pass(30.0)]),
    )
    .unwrap();
    assert!(
        mid.stable && mid.phase_margin_deg < MIN_PHASE_MARGIN_DEG,
        "{mid:?}"
    );
    let ok = loop_margins(
        &freq,
        &plant,
        &pd,
        &chain::<f32>(&[FilterConfig::low_pass(300.0)]),
    )
    .unwrap();
    assert_eq!(
        accept(&ok, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG),
        Ok(()),
        "{ok:?}"
    );
}

/// The pole-placement PID `(s + ω)³` on `J s²` scaled by `g` is stable iff `g > 1/9`
/// (Routh on `s³ + 3gω s² + 3gω² s + gω³`): conditionally stable, its phase starts at
/// -270°; the Nyquist count must agree with Routh on both sides.
#[test]
fn stability_of_a_conditionally_stable_pid_agrees_with_routh() {
    let (j, w) = (2.0e-3, 2.0 * PI * 15.0);
    let freq: [f32; 401] = grid(0.1, 4.0);
    let plant = freq.map(|f| {
        let s = C64::new(0.0, 2.0 * PI * f as f64);
        C64::ONE.over(s.times(s).scale(j)).to_pair()
    });
    for (g, stable) in [
        (0.05, false),
        (0.1, false),
        (0.13, true),
        (1.0, true),
        (5.0, true),
    ] {
        let (kp, ki, kd) = (3.0 * j * w * w * g, j * w * w * w * g, 3.0 * j * w * g);
        let c = freq.map(|f| pid_response(kp as f32, ki as f32, kd as f32, f));
        let m = loop_margins(&freq, &plant, &c, &FilterChain::<f32, 4>::none()).unwrap();
        assert_eq!(m.stable, stable, "g = {g}: {m:?}");
        if stable {
            // the lower gain margin is how far g may fall: 20 log(9 g)
            let lgm = 20.0 * libm::log10(9.0 * g);
            assert!(
                (m.lower_gain_margin_db as f64 - lgm).abs() < 0.5,
                "{g}: {m:?} vs {lgm}"
            );
        }
    }
}

/// The whole flow on an axis with a 35 Hz mode (ζ 0.11) seen by the encoder, a PD for
/// 10 Hz: the bare loop is rejected, the placed notch makes it acceptable.
#[test]
fn placed_notch_passes_the_margin_check() {
    let (j, wc, wr, zeta) = (1.0, 2.0 * PI * 10.0, 2.0 * PI * 35.0, 0.11);
    // PD with 60° of phase at 10 Hz on J s²
    let kd = j * wc / (1.0f64 + 1.0 / 3.0).sqrt();
    let kp = kd * wc / 3.0f64.sqrt();
    let freq: [f32; 601] = grid(1.0, 3.0);
    let plant = freq.map(|f| {
        let s = C64::new(0.0, 2.0 * PI * f as f64);
        let mode = C64::new(wr * wr, 0.0).over(
            s.times(s)
                .plus(s.scale(2.0 * zeta * wr))
                .plus(C64::new(wr * wr, 0.0)),
        );
        mode.over(s.times(s).scale(j))
            .times(C64::unit(-2.0 * PI * f as f64 * 1.5e-4))
            .to_pair()
    });
    let c = freq.map(|f| pid_response(kp as f32, 0.0, kd as f32, f));
    let bare = loop_margins(&freq, &plant, &c, &FilterChain::<f32, 4>::none()).unwrap();
    assert!(
        accept(&bare, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG).is_err(),
        "{bare:?}"
    );
    let mode = Resonance {
        freq_hz: 35.0,
        damping_ratio: zeta as f32,
        peak_db: 20.0 * libm::log10f(1.0 / (2.0 * zeta as f32)),
    };
    let p = place(&[mode], 10.0, T, false).unwrap();
    let filtered = loop_margins(&freq, &plant, &c, &chain::<f32>(p.filters.stages())).unwrap();
    assert_eq!(
        accept(&filtered, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG),
        Ok(()),
        "{filtered:?}"
    );
    assert!(
        filtered.gain_margin_db > 10.0 && filtered.phase_margin_deg > 40.0,
        "{filtered:?}"
    );
    // the optional low-pass (6x the bandwidth) costs 14° more: too much for this PD
    let with_lp = place(&[mode], 10.0, T, true).unwrap();
    let lp = loop_margins(&freq, &plant, &c, &chain::<f32>(with_lp.filters.stages())).unwrap();
    assert_eq!(
        accept(&lp, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG),
        Err(Rejection::PhaseMargin)
    );
    assert!((filtered.phase_margin_deg - lp.phase_margin_deg - 14.0).abs() < 1.0);
}
