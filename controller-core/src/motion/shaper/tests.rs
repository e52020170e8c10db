//! The block's construction and bookkeeping: the documented minimum frequencies, refusals
//! that name the axis, the common centroid of the taps, start-up, reset and settling.
//! (Residual vibration, limits, the deviation bound and fixed point: tests/shaper.rs.)

extern crate std;

use super::*;
use crate::axes::Axis;
use crate::config::ConfigError;
use crate::motion::trajectory::RefSample;
use crate::Vec3;

const PERIOD_S: f32 = 1.0e-4;

/// The board's set: MZV on X at 90 Hz, ZV on Y at 35 Hz, ZVD on Z at 55 Hz.
fn board_set() -> AxisShapers {
    AxisShapers {
        x: Some(ShaperConfig::new(ShaperKind::Mzv, 90.0)),
        y: Some(ShaperConfig::new(ShaperKind::Zv, 35.0)),
        z: Some(ShaperConfig::new(ShaperKind::Zvd, 55.0)),
    }
}

fn sample(p: [f64; 3], v: [f64; 3], a: [f64; 3]) -> RefSample<f64> {
    RefSample {
        pos: Vec3::new(p[0], p[1], p[2]),
        vel: Vec3::new(v[0], v[1], v[2]),
        acc: Vec3::new(a[0], a[1], a[2]),
    }
}

#[test]
fn the_boards_history_holds_the_documented_kinds() {
    // (module docs: the 512-period table times 2.004)
    let table = [19.71f32, 29.57, 39.42, 39.42, 58.39, 77.77];
    for (kind, want) in ShaperKind::ALL.into_iter().zip(table) {
        let f = min_freq_hz(kind, 0.1, PERIOD_S, BOARD_SHAPER_HISTORY).unwrap();
        assert!(f <= want && f > want - 0.02, "{kind:?}: {f} (docs {want})");
    }
}

#[test]
fn minimum_frequencies_are_the_documented_ones_and_hold() {
    let table = [9.84f32, 14.76, 19.67, 19.67, 29.14, 38.81];
    for (kind, want) in ShaperKind::ALL.into_iter().zip(table) {
        let f = min_freq_hz(kind, 0.1, PERIOD_S, 512).unwrap();
        // the table rounds up to 0.01 Hz: a frequency it names always fits
        assert!(f <= want && f > want - 0.01, "{kind:?}: {f} (docs {want})");
        let on_y = |freq_hz| AxisShapers {
            y: Some(ShaperConfig::new(kind, freq_hz)),
            ..AxisShapers::NONE
        };
        assert!(InputShaper::<f32, 512>::new(&on_y(f), PERIOD_S).is_ok());
        match InputShaper::<f32, 512>::new(&on_y(0.99 * f), PERIOD_S) {
            Err(ConfigError::OutOfRange(name)) => {
                assert!(name.starts_with("shaper.y ("), "{name}");
                assert!(name.contains(kind.name()), "{name}");
                assert!(name.contains("longer than the shaper history"), "{name}");
            }
            other => panic!("{kind:?} at 0.99 f_min: {other:?}"),
        }
    }
}

#[test]
fn bad_sets_are_refused_with_the_axis_named() {
    let mut s = board_set();
    s.z = Some(ShaperConfig::new(ShaperKind::Zvd, 10.0));
    assert_eq!(
        InputShaper::<f32, 512>::new(&s, PERIOD_S),
        Err(ConfigError::OutOfRange(
            "shaper.z (zvd) longer than the shaper history: raise freq_hz or use a shorter kind"
        ))
    );
    let mut s = board_set();
    s.x = Some(ShaperConfig::new(ShaperKind::Mzv, 0.0));
    assert_eq!(
        InputShaper::<f32, 512>::new(&s, PERIOD_S),
        Err(ConfigError::NotPositive("shaper.x.freq_hz"))
    );
    let mut s = board_set();
    s.y = Some(ShaperConfig::new(ShaperKind::Zv, 101.0));
    assert_eq!(
        InputShaper::<f32, 512>::new(&s, PERIOD_S),
        Err(ConfigError::OutOfRange(
            "shaper.y.freq_hz (<= 1/100 of the control rate)"
        ))
    );
    // ZV at ζ = 0.9, 100 Hz: the second impulse (0.15 %, 115 periods after the first)
    // puts the centroid 0.17 periods after the first; on whole periods it can only be
    // at 0 (the second impulse tilted to nothing) or 1 (its amplitude ×5.8): refused.
    let mut z = ShaperConfig::new(ShaperKind::Zv, 100.0);
    z.damping_ratio = 0.9;
    s.y = Some(z);
    assert_eq!(
        InputShaper::<f32, 512>::new(&s, PERIOD_S),
        Err(ConfigError::OutOfRange(
            "shaper.y.damping_ratio (too high for impulses on whole periods at this freq_hz)"
        ))
    );
    z.damping_ratio = 0.5;
    s.y = Some(z);
    assert!(InputShaper::<f32, 512>::new(&s, PERIOD_S).is_ok());
    assert!(matches!(
        InputShaper::<f32, 500>::new(&board_set(), PERIOD_S),
        Err(ConfigError::Unsupported(_))
    ));
    assert!(InputShaper::<f32, 512>::new(&board_set(), 0.0).is_err());
    // The board's set fits, a shorter history than its window does not.
    let sh = InputShaper::<f32, 512>::new(&board_set(), PERIOD_S).unwrap();
    assert!(sh.window_periods() < 256, "{}", sh.window_periods());
    assert!(InputShaper::<f32, 128>::new(&board_set(), PERIOD_S).is_err());
}

/// Every axis' taps: weights positive, summing to 1, centred on the common delay D (the
/// largest rounded centroid, ZVD at 55 Hz: impulses at 0, 91, 183 periods (91.37 and
/// 182.73 rounded), centroid 0.48774 · 91 + 0.17784 · 183 = 76.93, rounded to 77).
#[test]
fn every_axis_is_centred_on_the_common_delay() {
    let sh = InputShaper::<f64, 512>::new(&board_set(), PERIOD_S).unwrap();
    assert_eq!(sh.delay_periods(), 77);
    assert!((sh.delay_s() - 7.7e-3).abs() < 1e-7);
    for axis in Axis::ALL {
        let (mut sum, mut mean) = (0.0, 0.0);
        for (off, w) in sh.tap_weights(axis) {
            assert!(w > 0.0, "{axis:?}");
            sum += w;
            mean += w * off as f64;
        }
        assert!((sum - 1.0).abs() < 1e-12, "{axis:?}: {sum}");
        assert!((mean - 77.0).abs() < 1e-9, "{axis:?}: {mean}");
    }
    // one tap per impulse
    assert_eq!(sh.taps(Axis::X), 3);
    assert_eq!(sh.taps(Axis::Y), 2);
    assert_eq!(sh.taps(Axis::Z), 3);
    // An unshaped axis is one tap: an exact delay of D.
    let only_y = AxisShapers {
        y: board_set().y,
        ..AxisShapers::NONE
    };
    let sh = InputShaper::<f64, 512>::new(&only_y, PERIOD_S).unwrap();
    let mut x = sh.tap_weights(Axis::X);
    assert_eq!((x.next(), x.next()), (Some((61, 1.0)), None));
    assert_eq!(sh.bound().second_moment_s2[0], 0.0);
    // ZV's second moment A0·A1·(t_d/2)², 5.03e-5 s²; on whole periods A0'·A1'·(144 T)²:
    // the spacing 0.29 % longer (143.58 periods rounded to 144) and A1 tilted from
    // 0.42171 to 61/144 = 0.42361, which puts the centroid on period 61 (module docs,
    // "Whole periods"): 0.7 % more.
    let m = sh.bound().second_moment_s2[1] as f64;
    let zv = 0.5782862 * 0.4217138 * 0.01435768f64.powi(2);
    let w: std::vec::Vec<f64> = sh.tap_weights(Axis::Y).map(|(_, w)| w).collect();
    assert!((w[1] - 61.0 / 144.0).abs() < 1e-12, "{w:?}");
    assert!(
        (m / (w[0] * w[1] * 0.0144f64.powi(2)) - 1.0).abs() < 1e-6,
        "{m}"
    );
    assert!(m / zv > 1.006 && m / zv < 1.009, "{m} vs {zv}");
}

/// The taps are the impulses, each at its time rounded to the nearest period (shifted
/// by a whole number of periods), with the amplitudes changed by the tilt only: at most
/// `½ |kᵢ − c| / M` relative, `kᵢ` the rounded times, `c` their centroid and `M` their
/// second moment in periods (module docs); here at most 1.0 % (MZV's last impulse on X).
#[test]
fn taps_are_the_impulses_on_the_nearest_periods() {
    let sh = InputShaper::<f64, 512>::new(&board_set(), PERIOD_S).unwrap();
    let set = board_set();
    for axis in Axis::ALL {
        let s = set.get(axis).unwrap().impulses().unwrap();
        let taps: std::vec::Vec<(usize, f64)> = sh.tap_weights(axis).collect();
        assert_eq!(taps.len(), s.len, "{axis:?}");
        let first = taps[0].0 as f64;
        let k = |t: f64| (t / PERIOD_S as f64).round();
        let c: f64 = s.iter().map(|(a, t)| a * k(t)).sum();
        let m: f64 = s.iter().map(|(a, t)| a * (k(t) - c).powi(2)).sum();
        for ((off, w), (a, t)) in taps.iter().zip(s.iter()) {
            let periods = t / PERIOD_S as f64;
            assert_eq!(*off as f64 - first, k(t), "{axis:?}");
            assert!((*off as f64 - first - periods).abs() <= 0.5, "{axis:?}");
            let tilt = (w / a - 1.0).abs();
            assert!(
                tilt <= 0.5 * (k(t) - c).abs() / m + 1e-12,
                "{axis:?}: {w} vs {a}"
            );
            assert!(tilt < 0.0105, "{axis:?}: {w} vs {a}");
        }
    }
}

#[test]
fn no_shaper_is_a_pass_through() {
    let sh = InputShaper::<f64, 4>::new(&AxisShapers::NONE, PERIOD_S).unwrap();
    assert_eq!(sh.delay_periods(), 0);
    let mut st = sh.state(&sample([0.0; 3], [0.0; 3], [0.0; 3]));
    for k in 0..20 {
        let x = k as f64;
        let s = sample([x, 2.0 * x, -x], [1.0, 2.0, -1.0], [0.0; 3]);
        assert_eq!(sh.process(&mut st, &s), s);
    }
}

#[test]
fn rest_stays_rest_and_the_end_is_reached_exactly() {
    let sh = InputShaper::<f64, 512>::new(&board_set(), PERIOD_S).unwrap();
    let rest = sample([12.5, -3.25, 40.0], [0.0; 3], [0.0; 3]);
    let mut st = sh.state(&rest);
    assert!(st.is_settled());
    assert_eq!(st.pending_periods(), 0);
    for _ in 0..1000 {
        assert_eq!(sh.process(&mut st, &rest), rest);
    }
    // A step of the input: nothing moves before the first tap, the end is reached after
    // the window exactly, and pending_periods counts down to it.
    let moved = sample([13.5, -2.25, 41.0], [0.0; 3], [0.0; 3]);
    let w = sh.window_periods();
    let first = (0..3)
        .map(|a| {
            sh.tap_weights(Axis::ALL[a])
                .map(|(o, _)| o)
                .min()
                .unwrap_or(0)
        })
        .min()
        .unwrap();
    for k in 0..=w + 5 {
        let y = sh.process(&mut st, &moved);
        assert_eq!(st.pending_periods(), w.saturating_sub(k), "period {k}");
        if k < first {
            assert_eq!(y.pos, rest.pos, "period {k}");
        }
        if k >= w {
            assert!(st.is_settled());
            assert_eq!(y, moved, "period {k}");
        } else {
            assert!(!st.is_settled());
        }
    }
    // A jump after reset: the output is the new sample at once, no interpolation.
    let jumped = sample([-100.0, 0.0, 5.0], [0.0; 3], [0.0; 3]);
    st.reset(&jumped);
    assert!(st.is_settled());
    assert_eq!(sh.process(&mut st, &jumped), jumped);
}

/// Undamped shapers whose impulses and centroids fall on the 10 kHz grid (ZV at
/// 2500/71 Hz: impulses 142 periods apart, centroid 71; ZVD at 5000/91 Hz: 91 apart,
/// centroid 91; MZV at 3750/42 Hz: 42 apart, centroid 42) keep their times and their
/// amplitudes exactly (no tilt), though the `f32` frequencies put them ~1e-5 periods off.
#[test]
fn impulses_on_the_grid_keep_their_times_and_amplitudes() {
    let undamped = |kind, f| {
        let mut c = ShaperConfig::new(kind, f);
        c.damping_ratio = 0.0;
        Some(c)
    };
    let s = AxisShapers {
        x: undamped(ShaperKind::Mzv, 3750.0 / 42.0),
        y: undamped(ShaperKind::Zv, 2500.0 / 71.0),
        z: undamped(ShaperKind::Zvd, 5000.0 / 91.0),
    };
    let sh = InputShaper::<f64, 512>::new(&s, PERIOD_S).unwrap();
    assert_eq!(sh.delay_periods(), 91);
    let offsets = |a| {
        let mut v = [0usize; 3];
        for (d, (o, _)) in v.iter_mut().zip(sh.tap_weights(a)) {
            *d = o;
        }
        (sh.taps(a), v)
    };
    assert_eq!(offsets(Axis::X), (3, [49, 91, 133]));
    assert_eq!(offsets(Axis::Y), (2, [20, 162, 0]));
    assert_eq!(offsets(Axis::Z), (3, [0, 91, 182]));
    for axis in Axis::ALL {
        let s = s.get(axis).unwrap().impulses().unwrap();
        for ((_, w), (a, _)) in sh.tap_weights(axis).zip(s.iter()) {
            assert!((w - a).abs() < 1e-6, "{axis:?}: {w} vs {a}");
        }
    }
}
