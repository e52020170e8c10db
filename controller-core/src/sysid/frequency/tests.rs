//! The measurement and the mode finder on analytic systems: a mass-spring-damper through
//! the correlation alone, and a two-mass axis (the simulated world's frame model,
//! without friction) through the whole measurement.

extern crate std;

use super::estimate::Correlator;
use super::*;
use crate::sysid::identifier::{AxisSample, IdentifyStatus};

const T: f32 = 1e-4;
/// RK4 substeps per period of the test plants (10 µs: far below every mode's period).
const SUB: usize = 10;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Cx {
    re: f64,
    im: f64,
}

impl Cx {
    fn new(re: f64, im: f64) -> Self {
        Self { re, im }
    }
    fn add(self, o: Cx) -> Cx {
        Cx::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Cx) -> Cx {
        Cx::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Cx) -> Cx {
        Cx::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn div(self, o: Cx) -> Cx {
        let d = o.re * o.re + o.im * o.im;
        Cx::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
    fn abs(self) -> f64 {
        libm::sqrt(self.re * self.re + self.im * self.im)
    }
    fn poly(c: &[f64], s: Cx) -> Cx {
        c.iter()
            .fold(Cx::default(), |acc, k| acc.mul(s).add(Cx::new(*k, 0.0)))
    }
}

/// A second-order section `1/(m s² + c s + k)` through the correlation alone: every
/// frequency within 1 % (magnitude and, as a complex error, phase) of the exact response.
#[test]
fn a_mass_spring_damper_is_measured_within_one_percent() {
    let (m, c, k) = (0.05f64, 0.8f64, 3000.0f64);
    // natural frequency 39 Hz, damping 0.033: the peak and its phase swing are inside
    for f in [5.0f32, 20.0, 35.0, 39.0, 45.0, 80.0, 300.0] {
        // 1 s to settle (the transient decays by e^-8), then 0.5 s (whole cycles)
        let cycles = libm::ceilf(0.5 * f);
        let n = libm::roundf(cycles / (f * T)) as u32;
        let f = cycles / (n as f32 * T);
        let settle = 10_000u32;
        let (mut x, mut v) = (0.0f64, 0.0f64);
        let mut prev_x = 0.0;
        let mut corr = Correlator::new(n);
        let w = 2.0 * core::f32::consts::PI * f;
        for p in 0..settle + n {
            let ph = w * T * p as f32;
            let sc = (libm::sinf(ph), libm::cosf(ph));
            let u = 10.0 * f64::from(sc.0);
            if p >= settle {
                corr.add_step((x - prev_x) as f32, sc);
                corr.add_effort(u as f32, sc);
            }
            prev_x = x;
            let h = f64::from(T) / SUB as f64;
            let acc = |x: f64, v: f64| (u - c * v - k * x) / m;
            for _ in 0..SUB {
                let (k1x, k1v) = (v, acc(x, v));
                let (k2x, k2v) = (v + 0.5 * h * k1v, acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v));
                let (k3x, k3v) = (v + 0.5 * h * k2v, acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v));
                let (k4x, k4v) = (v + h * k3v, acc(x + h * k3x, v + h * k3v));
                x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
                v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            }
        }
        let pt = corr.response(f, T).unwrap();
        let s = Cx::new(0.0, f64::from(w));
        let exact = Cx::new(1.0, 0.0).div(Cx::poly(&[m, c, k], s));
        let got = Cx::new(f64::from(pt.re), f64::from(pt.im));
        let err = got.sub(exact).abs() / exact.abs();
        assert!(err < 0.01, "{f} Hz: {got:?} vs {exact:?} ({err})");
    }
}

/// The two-mass axis of the simulated world's frame (`crate::plant::frame`): motor and
/// tool on a spring and a damper, viscous friction on the motor side, no Coulomb.
struct TwoMass {
    jm: f64,
    jt: f64,
    k: f64,
    c: f64,
    b: f64,
    /// motor x, v; tool x, v
    s: [f64; 4],
}

impl TwoMass {
    /// `mode_hz` and `zeta` as the frame's config means them.
    fn new(j: f64, rho: f64, mode_hz: f64, zeta: f64, b: f64, x0: f64) -> Self {
        let (jm, jt) = ((1.0 - rho) * j, rho * j);
        let w = 2.0 * core::f64::consts::PI * mode_hz;
        let mu = jm * jt / j;
        Self {
            jm,
            jt,
            k: w * w * mu,
            c: 2.0 * zeta * w * mu,
            b,
            s: [x0, 0.0, x0, 0.0],
        }
    }

    fn deriv(&self, s: &[f64; 4], u: f64) -> [f64; 4] {
        let f = self.k * (s[0] - s[2]) + self.c * (s[1] - s[3]);
        [s[1], (u - self.b * s[1] - f) / self.jm, s[3], f / self.jt]
    }

    fn period(&mut self, u: f64) {
        let h = f64::from(T) / SUB as f64;
        for _ in 0..SUB {
            let s = self.s;
            let add =
                |a: &[f64; 4], d: &[f64; 4], f: f64| core::array::from_fn(|i| a[i] + f * d[i]);
            let k1 = self.deriv(&s, u);
            let k2 = self.deriv(&add(&s, &k1, 0.5 * h), u);
            let k3 = self.deriv(&add(&s, &k2, 0.5 * h), u);
            let k4 = self.deriv(&add(&s, &k3, h), u);
            self.s = core::array::from_fn(|i| {
                s[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            });
        }
    }

    /// Characteristic polynomial over s (the rigid pole at 0 removed), highest first.
    fn char_poly(&self) -> [f64; 4] {
        let (jm, jt, k, c, b) = (self.jm, self.jt, self.k, self.c, self.b);
        // (jm s² + (b+c) s + k)(jt s² + c s + k) - (c s + k)², divided by s
        [
            jm * jt,
            jm * c + jt * (b + c),
            jm * k + jt * k + b * c,
            b * k,
        ]
    }

    fn response(&self, f_hz: f64) -> Cx {
        let s = Cx::new(0.0, 2.0 * core::f64::consts::PI * f_hz);
        let num = Cx::poly(&[self.jt, self.c, self.k], s);
        num.div(Cx::poly(&self.char_poly(), s).mul(s))
    }

    /// The mode's pole (Newton from the undamped one): (Hz, damping).
    fn pole(&self, f_hz: f64) -> (f64, f64) {
        let p = self.char_poly();
        let dp = [3.0 * p[0], 2.0 * p[1], p[2]];
        let mut s = Cx::new(0.0, 2.0 * core::f64::consts::PI * f_hz);
        for _ in 0..50 {
            s = s.sub(Cx::poly(&p, s).div(Cx::poly(&dp, s)));
        }
        let wn = s.abs();
        (wn / (2.0 * core::f64::consts::PI), -s.re / wn)
    }
}

/// Run a measurement against `plant` (exact positions and velocities; the effort applied
/// one period late with `delayed`); the points and the largest travel from the start and
/// effort.
fn run(
    plant: &mut TwoMass,
    cfg: &ResponseConfig,
    delayed: bool,
) -> (FrequencyResponse, f64, f32, IdentifyStatus) {
    let x0 = plant.s[0];
    let mut m = ResponseMeasurement::new(cfg, x0 as f32, 0.0).unwrap();
    let mut frf = FrequencyResponse::new();
    let mut seen = None;
    let (mut travel, mut effort, mut applied) = (0.0f64, 0.0f32, 0.0f32);
    let mut late = 0.0f32;
    for _ in 0..2_000_000 {
        let out = m.step(&AxisSample {
            pos_mm: plant.s[0] as f32,
            vel_mm_s: plant.s[1] as f32,
            effort_applied_mnm: applied,
            fault: false,
        });
        if let Some((i, p)) = m.last_point() {
            if seen != Some(i) {
                seen = Some(i);
                frf.push(p);
            }
        }
        if !matches!(
            out.status,
            IdentifyStatus::Running | IdentifyStatus::Stopping(_)
        ) {
            return (frf, travel, effort, out.status);
        }
        applied = out.effort_mnm;
        effort = effort.max(applied.abs());
        let u = if delayed { late } else { applied };
        late = applied;
        plant.period(f64::from(u));
        travel = travel.max((plant.s[0] - x0).abs());
    }
    panic!("the measurement did not end");
}

/// A two-mass axis through the whole measurement: every point within 1 % of the exact
/// response; the resonance's frequency within 1 % and damping within 5 % of the exact
/// pole's, the anti-resonance's of the exact zero's; the window and the cap kept.
#[test]
fn a_two_mass_axis_is_measured_and_its_mode_found() {
    let mut plant = TwoMass::new(0.1, 0.1, 40.0, 0.04, 0.2, 10.0);
    let cfg = ResponseConfig {
        window_min_mm: -40.0,
        window_max_mm: 60.0,
        points: 40,
        freq_min_hz: 5.0,
        freq_max_hz: 200.0,
        ..RESPONSE_DEFAULTS
    };
    let (frf, travel, effort, status) = run(&mut plant, &cfg, false);
    assert_eq!(status, IdentifyStatus::Done);
    assert_eq!(frf.len(), 40);
    // the window -40..60 around the start at 10
    assert!(travel <= 50.0, "{travel}");
    assert!(effort <= 500.0, "{effort}");
    for p in frf.points() {
        let exact = plant.response(f64::from(p.freq_hz));
        let got = Cx::new(f64::from(p.re), f64::from(p.im));
        let err = got.sub(exact).abs() / exact.abs();
        assert!(err < 0.01, "{} Hz: {got:?} vs {exact:?} ({err})", p.freq_hz);
    }
    let modes = find_modes(&frf, &MODE_DEFAULTS).unwrap();
    assert!((modes.rigid.inertia / 0.1 - 1.0).abs() < 0.01, "{modes:?}");
    let [r] = modes.resonances() else {
        panic!("{modes:?}")
    };
    let (f, zeta) = plant.pole(40.0);
    assert!(
        (f64::from(r.freq_hz) / f - 1.0).abs() < 0.01,
        "{r:?} vs {f} Hz"
    );
    assert!(
        (f64::from(r.damping_ratio) / zeta - 1.0).abs() < 0.05,
        "{r:?} vs {zeta}"
    );
    assert!(r.peak_db > 3.0, "{r:?}");
    let [a] = modes.anti_resonances() else {
        panic!("{modes:?}")
    };
    // the zero: jt s² + c s + k
    let fa = libm::sqrt(plant.k / plant.jt) / (2.0 * core::f64::consts::PI);
    let za = plant.c / (2.0 * libm::sqrt(plant.k * plant.jt));
    assert!(
        (f64::from(a.freq_hz) / fa - 1.0).abs() < 0.01,
        "{a:?} vs {fa}"
    );
    assert!(
        (f64::from(a.damping_ratio) / za - 1.0).abs() < 0.05,
        "{a:?} vs {za}"
    );
    assert!(a.peak_db < -3.0, "{a:?}");
}

/// A rigid axis (no mode) shows none.
#[test]
fn a_rigid_axis_has_no_mode() {
    // a stiff frame far above the grid: rigid within it
    let mut plant = TwoMass::new(0.1, 0.1, 3000.0, 0.5, 0.2, 0.0);
    let cfg = ResponseConfig {
        points: 30,
        freq_max_hz: 200.0,
        ..RESPONSE_DEFAULTS
    };
    let (frf, _, _, status) = run(&mut plant, &cfg, false);
    assert_eq!(status, IdentifyStatus::Done);
    let modes = find_modes(&frf, &MODE_DEFAULTS).unwrap();
    assert!(modes.resonances().is_empty(), "{modes:?}");
    assert!(modes.anti_resonances().is_empty(), "{modes:?}");
}

/// One period of delay between the effort and the axis (an amplifier's, a period's):
/// the mode finder sees it in the phase, removes it, and finds the same mode.
#[test]
fn a_delay_is_found_and_does_not_pass_for_damping() {
    let mut plant = TwoMass::new(0.1, 0.1, 40.0, 0.04, 0.2, 10.0);
    let cfg = ResponseConfig {
        window_min_mm: -40.0,
        window_max_mm: 60.0,
        points: 40,
        freq_min_hz: 5.0,
        freq_max_hz: 300.0,
        ..RESPONSE_DEFAULTS
    };
    let (frf, _, _, status) = run(&mut plant, &cfg, true);
    assert_eq!(status, IdentifyStatus::Done);
    let modes = find_modes(&frf, &MODE_DEFAULTS).unwrap();
    assert!((modes.delay_s / T - 1.0).abs() < 0.05, "{modes:?}");
    let [r] = modes.resonances() else {
        panic!("{modes:?}")
    };
    let (f, zeta) = plant.pole(40.0);
    assert!(
        (f64::from(r.freq_hz) / f - 1.0).abs() < 0.01,
        "{r:?} vs {f} Hz"
    );
    assert!(
        (f64::from(r.damping_ratio) / zeta - 1.0).abs() < 0.05,
        "{r:?} vs {zeta}"
    );
    // the same data with the delay removed by hand (H e^{+jωT}): the finder sees none
    // and finds the same mode
    let mut no_comp = FrequencyResponse::new();
    for p in frf.points() {
        let ph = 2.0 * core::f32::consts::PI * p.freq_hz * T;
        let (c, s) = (libm::cosf(ph), libm::sinf(ph));
        no_comp.push(ResponsePoint {
            freq_hz: p.freq_hz,
            re: p.re * c - p.im * s,
            im: p.re * s + p.im * c,
        });
    }
    let m2 = find_modes(&no_comp, &MODE_DEFAULTS).unwrap();
    assert!(m2.delay_s.abs() < 0.05 * T, "{m2:?}");
    let [r2] = m2.resonances() else {
        panic!("{m2:?}")
    };
    assert!(
        (r2.damping_ratio / r.damping_ratio - 1.0).abs() < 0.02,
        "{r2:?} vs {r:?}"
    );
}

/// The prominence of a peak is its height over the higher of its two bases: a small
/// wiggle on the slope into a deep dip stays small, the mode's peak does not.
#[test]
fn prominence_is_measured_from_the_higher_base() {
    let cfg = ModeConfig {
        noise_sigmas: 0.0,
        ..MODE_DEFAULTS
    };
    // a flat response with a 0.4 dB wiggle beside a 6 dB dip and a 4 dB peak
    let mut frf = FrequencyResponse::new();
    let db = [
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1, 0.4, 0.1, -1.0, -3.0, -6.0, 4.0, 2.0, 1.0, 0.5, 0.5,
        0.5, 0.5, 0.5,
    ];
    for (i, d) in db.iter().enumerate() {
        let f = 5.0 * libm::powf(1.1, i as f32);
        let w = 2.0 * core::f32::consts::PI * f;
        // the rigid line 1/(J s²), J = 0.1, times the relative response (real)
        let mag = libm::powf(10.0, d / 20.0) / (0.1 * w * w);
        frf.push(ResponsePoint {
            freq_hz: f,
            re: -mag,
            im: 0.0,
        });
    }
    let m = find_modes(&frf, &cfg).unwrap();
    // the wiggle (index 7) is not a resonance; the peak (index 12) is a candidate (a
    // real section fits it or not: the fit may drop it, never the wiggle)
    assert!(
        m.resonances()
            .iter()
            .all(|r| r.freq_hz > 5.0 * libm::powf(1.1, 10.0)),
        "{m:?}"
    );
    // (the slope from the wiggle down into the dip does not count: 0.4, not 6.4)
    let db = db.map(f64::from);
    let prom = super::modes::tests_prominence;
    assert!((prom(&db, 7, 1.0) - 0.4).abs() < 1e-6);
    assert!((prom(&db, 12, 1.0) - 3.5).abs() < 1e-6);
    assert!((prom(&db, 11, -1.0) - 6.4).abs() < 1e-6);
}
