//! The 3-axis shaper block: per-axis taps on a common delay, and the history they read.

use super::bound::DeviationBound;
use super::impulses::{Impulses, ParamNames, ShaperConfig, ShaperKind, MAX_IMPULSES};
use crate::axes::{Axis, AXES};
use crate::config::{positive, ConfigError};
use crate::motion::trajectory::RefSample;
use crate::{Real, Vec3};

/// Taps per axis at most: one per impulse (the impulse times are rounded to whole
/// periods).
pub const MAX_TAPS: usize = MAX_IMPULSES;

/// Highest mode frequency accepted, as a fraction of the control rate (100 Hz at 10 kHz,
/// 200 Hz at 20 kHz). Rounding an impulse time to the nearest period moves it by at most
/// half a period `T`; the shortest spacing of any kind (MZV's 3/8 of the mode's period) is
/// then at least 37.5 periods, so the shaper is tuned to a frequency at most 1.3 % off,
/// inside every kind's band (ZV's, the narrowest, is ±3.7 %). The residual vibration the
/// rounding adds is at most `5.2·f·T`, 5.2 % at this limit (module docs, "Whole
/// periods").
pub const MAX_FREQ_OF_RATE: f32 = 0.01;

/// The shaper of each axis; `None` delays the axis by the common delay without shaping.
/// In TOML: `[shaper.y] kind = "zv"`, `freq_hz = 35.0` (missing axes are `None`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct AxisShapers {
    pub x: Option<ShaperConfig>,
    pub y: Option<ShaperConfig>,
    pub z: Option<ShaperConfig>,
}

impl AxisShapers {
    /// No shaping on any axis (the block is then a pass-through).
    pub const NONE: Self = Self {
        x: None,
        y: None,
        z: None,
    };

    pub fn get(&self, axis: Axis) -> Option<ShaperConfig> {
        match axis {
            Axis::X => self.x,
            Axis::Y => self.y,
            Axis::Z => self.z,
        }
    }
}

/// One tap: the sample `off` periods back, weighted `w`. An axis' first tap (its newest
/// sample) is the reference of the others: `process` reads its weight as `1 − Σ` theirs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Tap<R> {
    off: usize,
    w: R,
}

/// The validated shapers of the three axes (see the module docs): per axis up to
/// [`MAX_TAPS`] `(offset, weight)` pairs precomputed from the impulses, one per impulse
/// on a whole period, all axes centred on one delay. `N` is the history's capacity in
/// periods (a power of two).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputShaper<R, const N: usize> {
    taps: [[Tap<R>; MAX_TAPS]; AXES],
    n_taps: [usize; AXES],
    /// The oldest sample any tap reads (periods back).
    window: usize,
    delay_periods: usize,
    period_s: f32,
    bound: DeviationBound,
}

/// The history the shaper reads: the last `N` reference samples, newest at `head`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShaperState<R, const N: usize> {
    hist: [RefSample<R>; N],
    head: usize,
    /// Periods since the input last changed (saturating).
    age: usize,
    window: usize,
}

impl<R: Real, const N: usize> InputShaper<R, N> {
    /// No taps at all, for a static ([`super::ShaperStage::NONE`]); never processed.
    pub const ZERO: Self = Self {
        taps: [[Tap { off: 0, w: R::ZERO }; MAX_TAPS]; AXES],
        n_taps: [0; AXES],
        window: 0,
        delay_periods: 0,
        period_s: 0.0,
        bound: DeviationBound {
            second_moment_s2: [0.0; AXES],
        },
    };

    /// Validates the shapers for a control period `period_s` and a history of `N`
    /// periods. Refused: a bad shaper parameter (named with its axis), a mode above
    /// [`MAX_FREQ_OF_RATE`] of the rate, a set of shapers whose window (common delay
    /// plus the longest shifted impulse) does not fit `N − 1` periods (named with the
    /// axis and its kind: `shaper.y (zvd) longer than the history …`), `N` not a power of
    /// two.
    pub fn new(cfg: &AxisShapers, period_s: f32) -> Result<Self, ConfigError> {
        if !(N >= 2 && N.is_power_of_two()) {
            return Err(ConfigError::Unsupported(
                "shaper history capacity (a power of two >= 2)",
            ));
        }
        let p = f64::from(positive(period_s, "shaper period_s")?);
        let mut rounded: [Option<Rounded>; AXES] = [None; AXES];
        for (axis, slot) in Axis::ALL.iter().zip(rounded.iter_mut()) {
            if let Some(c) = cfg.get(*axis) {
                let names = axis_names(*axis);
                let imp = c.impulses_named(&names.params)?;
                if f64::from(c.freq_hz) * p > f64::from(MAX_FREQ_OF_RATE) {
                    return Err(ConfigError::OutOfRange(names.freq_high));
                }
                *slot = Some(Rounded::new(&imp, p));
            }
        }
        // The common delay D: the largest of the shaped axes' centroids, each rounded to a
        // whole period (an unshaped axis is then one tap, an exact delay).
        let d = rounded.iter().flatten().map(|r| r.delay).max().unwrap_or(0);
        let mut sh = Self {
            taps: [[Tap::default(); MAX_TAPS]; AXES],
            n_taps: [0; AXES],
            window: 0,
            delay_periods: d,
            period_s,
            bound: DeviationBound::default(),
        };
        for (i, (axis, r)) in Axis::ALL.iter().zip(rounded.iter()).enumerate() {
            let names = axis_names(*axis);
            let (taps, n, m2) = match r {
                None => {
                    let delay = Tap { off: d, w: R::ONE };
                    ([delay; MAX_TAPS], 1, 0.0)
                }
                Some(r) => r
                    .taps::<R>(d, p)
                    .ok_or(ConfigError::OutOfRange(names.too_damped))?,
            };
            let oldest = taps.iter().take(n).map(|t| t.off).max().unwrap_or(0);
            if oldest > N - 1 {
                let kind = cfg.get(*axis).map_or(0, |c| c.kind.index());
                return Err(ConfigError::OutOfRange(
                    names
                        .too_long
                        .get(kind)
                        .copied()
                        .unwrap_or(names.params.freq_hz),
                ));
            }
            sh.window = sh.window.max(oldest);
            if let (Some(t), Some(c), Some(b)) = (
                sh.taps.get_mut(i),
                sh.n_taps.get_mut(i),
                sh.bound.second_moment_s2.get_mut(i),
            ) {
                *t = taps;
                *c = n;
                *b = m2 as f32;
            }
        }
        Ok(sh)
    }

    /// A history filled with `start` (a machine at rest stays at rest: the shaped
    /// reference is `start` until the input moves).
    pub fn state(&self, start: &RefSample<R>) -> ShaperState<R, N> {
        let mut st = ShaperState::ZERO;
        self.restart(&mut st, start);
        st
    }

    /// Make `st` this shaper's history, filled with `sample` (in place: the board's
    /// history is a static of 18 KB). Changing the shapers restarts the history, which
    /// moves the shaped reference to `sample` at once: change them at rest.
    pub fn restart(&self, st: &mut ShaperState<R, N>, sample: &RefSample<R>) {
        st.window = self.window;
        st.reset(sample);
    }

    /// One control period: `input` (the unshaped reference of this period) enters the
    /// history and the shaped reference is returned. Once the input has been constant
    /// for the whole window ([`ShaperState::is_settled`]) the output is the input itself,
    /// bit for bit (every tap reads the same sample, so every difference from the
    /// reference tap is zero).
    #[inline]
    pub fn process(&self, st: &mut ShaperState<R, N>, input: &RefSample<R>) -> RefSample<R> {
        let mask = N - 1;
        let prev = st.head & mask;
        let head = (prev + 1) & mask;
        st.head = head;
        let same = st.hist.get(prev) == Some(input);
        if let Some(s) = st.hist.get_mut(head) {
            *s = *input;
        }
        st.age = if same { st.age.saturating_add(1) } else { 0 };
        let x = self.shape_axis(&st.hist, head, 0);
        let y = self.shape_axis(&st.hist, head, 1);
        let z = self.shape_axis(&st.hist, head, 2);
        RefSample {
            pos: Vec3::new(x[0], y[0], z[0]),
            vel: Vec3::new(x[1], y[1], z[1]),
            acc: Vec3::new(x[2], y[2], z[2]),
        }
    }

    /// Axis `a`'s shaped `[pos, vel, acc]` ([`shape_taps`]; `a` is a constant where
    /// `process` calls it, so the taps' and the samples' addresses are too).
    #[inline(always)]
    fn shape_axis(&self, hist: &[RefSample<R>; N], head: usize, a: usize) -> [R; 3] {
        let Some(taps) = self.taps.get(a) else {
            return [R::ZERO; 3];
        };
        let n = self.n_taps.get(a).copied().unwrap_or(0);
        shape_taps::<R, N>(hist, head, taps, n, a)
    }

    /// The common delay `D` of every axis (s): a whole number of periods.
    pub fn delay_s(&self) -> f32 {
        self.delay_periods as f32 * self.period_s
    }

    /// The common delay in periods.
    pub fn delay_periods(&self) -> usize {
        self.delay_periods
    }

    /// The oldest sample read (periods back): how long the shaped reference takes to
    /// settle after the input stops changing.
    pub fn window_periods(&self) -> usize {
        self.window
    }

    /// The number of taps (samples read per period) of `axis`.
    pub fn taps(&self, axis: Axis) -> usize {
        self.n_taps.get(axis.index()).copied().unwrap_or(0)
    }

    /// `(periods back, weight)` of `axis`' taps.
    pub fn tap_weights(&self, axis: Axis) -> impl Iterator<Item = (usize, R)> + '_ {
        let n = self.taps(axis);
        self.taps
            .get(axis.index())
            .into_iter()
            .flat_map(move |t| t.iter().take(n).map(|t| (t.off, t.w)))
    }

    /// The contour deviation bound's moments ([`DeviationBound`]).
    pub fn bound(&self) -> DeviationBound {
        self.bound
    }

    /// Distance (mm) within which the shaped point stays of the path, given a bound on
    /// the reference's acceleration (mm/s², every axis): `½ a √(Σᵢ Mᵢ²)`, see
    /// [`super::bound`].
    pub fn deviation_bound_mm(&self, acc_max_mm_s2: f32) -> f32 {
        self.bound.deviation_bound_mm(acc_max_mm_s2)
    }
}

impl<R: Real, const N: usize> ShaperState<R, N> {
    /// An empty history (zeros, no window) for a static; [`InputShaper::restart`] makes it
    /// a shaper's.
    pub const ZERO: Self = Self {
        hist: [RefSample {
            pos: Vec3::new(R::ZERO, R::ZERO, R::ZERO),
            vel: Vec3::new(R::ZERO, R::ZERO, R::ZERO),
            acc: Vec3::new(R::ZERO, R::ZERO, R::ZERO),
        }; N],
        head: 0,
        age: usize::MAX,
        window: 0,
    };

    /// Refill the history with `sample`: after a jump of the reference (homing re-bases
    /// the axes, a new mode starts) nothing is interpolated across the jump, and the
    /// shaped reference is `sample` at once.
    pub fn reset(&mut self, sample: &RefSample<R>) {
        self.hist.fill(*sample);
        self.age = usize::MAX;
    }

    /// The shaped reference has caught up with a constant input (it equals it exactly).
    pub fn is_settled(&self) -> bool {
        self.age >= self.window
    }

    /// Periods until the shaped reference equals the input, if the input stays as it is
    /// now (0 when settled): what a program's end or a stop waits for.
    pub fn pending_periods(&self) -> usize {
        self.window.saturating_sub(self.age)
    }
}

/// One axis' shaper on whole periods (module docs, "Whole periods"): the impulses at
/// `k` periods after the first, each time rounded to the nearest period, with their
/// amplitudes; `centroid` their centroid (periods) before the tilt, `delay` it rounded.
#[derive(Clone, Copy, Debug)]
struct Rounded {
    k: [usize; MAX_TAPS],
    amp: [f64; MAX_TAPS],
    n: usize,
    centroid: f64,
    delay: usize,
}

impl Rounded {
    fn new(s: &Impulses, p: f64) -> Self {
        let mut r = Self {
            k: [0; MAX_TAPS],
            amp: [0.0; MAX_TAPS],
            n: 0,
            centroid: 0.0,
            delay: 0,
        };
        for (a, t) in s.iter() {
            let k = libm::round((t / p).max(0.0)) as usize;
            // Two impulses on one period (only above the accepted frequencies) add up.
            let i = r.k.iter().take(r.n).position(|x| *x == k).unwrap_or(r.n);
            if let (Some(rk), Some(ra)) = (r.k.get_mut(i), r.amp.get_mut(i)) {
                *rk = k;
                *ra += a;
                r.n = r.n.max(i + 1);
            }
        }
        r.centroid = r.iter().map(|(k, a)| a * k).sum();
        r.delay = libm::round(r.centroid) as usize;
        r
    }

    /// `(periods after the first, amplitude)` of each impulse.
    fn iter(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.k
            .iter()
            .zip(self.amp)
            .take(self.n)
            .map(|(k, a)| (*k as f64, a))
    }

    /// The taps around the common delay `d` (periods; period `p` s) and their second
    /// moment about `d` (s²). The axis is shifted by `d − delay` whole periods; the
    /// amplitudes are tilted, `Aᵢ' = Aᵢ (1 + (kᵢ − c)(delay − c)/M)` (`c` the centroid, `M`
    /// the second moment about it, in periods): the smallest change (weighted by `1/Aᵢ`)
    /// that keeps their sum at 1 and moves the centroid onto `delay`, so onto `d` after
    /// the shift. `None` when a tilted amplitude is not positive (a tiny impulse of a
    /// heavily damped mode; module docs).
    fn taps<R: Real>(&self, d: usize, p: f64) -> Option<([Tap<R>; MAX_TAPS], usize, f64)> {
        let c = self.centroid;
        let m: f64 = self.iter().map(|(k, a)| a * (k - c) * (k - c)).sum();
        let tilt = if m > 0.0 {
            (self.delay as f64 - c) / m
        } else {
            0.0
        };
        let shift = d.checked_sub(self.delay)?;
        let mut taps = [Tap::default(); MAX_TAPS];
        let mut m2 = 0.0;
        for (t, (k, a)) in taps.iter_mut().zip(self.iter()) {
            let w = a * (1.0 + (k - c) * tilt);
            if !(w > 0.0) {
                return None;
            }
            *t = Tap {
                off: (k as usize).saturating_add(shift),
                w: R::from_f64(w),
            };
            let dt = (t.off as f64 - d as f64) * p;
            m2 += w * dt * dt;
        }
        Some((taps, self.n, m2))
    }
}

/// One axis' shaped `[pos, vel, acc]` from its `n` taps: the reference tap's sample `x₀`
/// plus `Σ wᵢ (xᵢ − x₀)` over the others. The same as `Σ wᵢ xᵢ` with the reference's
/// weight `1 − Σ` the others', but exact on a constant input (every difference is 0),
/// and the differences are small where the positions are large. One tap (an unshaped
/// axis) is a plain copy. The taps are nested tests, not a loop: straight-line code with
/// one compare per tap (a `match` on `n` costs a jump table and a loop the counter and
/// the branch back). The index is masked, so it is in range: the bound check folds away.
#[inline(always)]
fn shape_taps<R: Real, const N: usize>(
    hist: &[RefSample<R>; N],
    head: usize,
    taps: &[Tap<R>; MAX_TAPS],
    n: usize,
    a: usize,
) -> [R; 3] {
    let read = |off: usize| {
        hist.get(head.wrapping_sub(off) & (N - 1))
            .map_or([R::ZERO; 3], |s| [s.pos[a], s.vel[a], s.acc[a]])
    };
    // The `MAX_TAPS` (5) slots by name: this stops compiling if `MAX_TAPS` changes.
    let [t0, t1, t2, t3, t4] = taps;
    let x0 = read(t0.off);
    if n < 2 {
        return x0;
    }
    let term = |t: &Tap<R>| {
        let x = read(t.off);
        [
            t.w * (x[0] - x0[0]),
            t.w * (x[1] - x0[1]),
            t.w * (x[2] - x0[2]),
        ]
    };
    let mut s = term(t1);
    let mut add = |t: &Tap<R>| {
        for (s, d) in s.iter_mut().zip(term(t)) {
            *s += d;
        }
    };
    // Nested tests, not a loop: one compare per tap, nothing the compiler rolls back up.
    if n > 2 {
        add(t2);
        if n > 3 {
            add(t3);
            if n > 4 {
                add(t4);
            }
        }
    }
    [x0[0] + s[0], x0[1] + s[1], x0[2] + s[2]]
}

/// The names an axis' errors carry.
struct AxisNames {
    params: ParamNames,
    freq_high: &'static str,
    /// A tilted amplitude not positive (module docs, "Whole periods").
    too_damped: &'static str,
    /// Window too long for the history, per kind ([`ShaperKind::index`]).
    too_long: [&'static str; 6],
}

macro_rules! axis_names {
    ($a:literal) => {
        AxisNames {
            params: ParamNames {
                freq_hz: concat!("shaper.", $a, ".freq_hz"),
                damping_ratio: concat!("shaper.", $a, ".damping_ratio (0..=the kind's maximum)"),
                vibration_tolerance: concat!(
                    "shaper.",
                    $a,
                    ".vibration_tolerance (ei: 0..=0.2; hump ei: 0.05)"
                ),
            },
            freq_high: concat!("shaper.", $a, ".freq_hz (<= 1/100 of the control rate)"),
            too_damped: concat!(
                "shaper.",
                $a,
                ".damping_ratio (too high for impulses on whole periods at this freq_hz)"
            ),
            too_long: [
                concat!("shaper.", $a, " (zv) longer than the shaper history: raise freq_hz"),
                concat!("shaper.", $a, " (mzv) longer than the shaper history: raise freq_hz or use zv"),
                concat!("shaper.", $a, " (zvd) longer than the shaper history: raise freq_hz or use a shorter kind"),
                concat!("shaper.", $a, " (ei) longer than the shaper history: raise freq_hz or use a shorter kind"),
                concat!("shaper.", $a, " (2hump_ei) longer than the shaper history: raise freq_hz or use a shorter kind"),
                concat!("shaper.", $a, " (3hump_ei) longer than the shaper history: raise freq_hz or use a shorter kind"),
            ],
        }
    };
}

const X_NAMES: AxisNames = axis_names!("x");
const Y_NAMES: AxisNames = axis_names!("y");
const Z_NAMES: AxisNames = axis_names!("z");

fn axis_names(axis: Axis) -> &'static AxisNames {
    match axis {
        Axis::X => &X_NAMES,
        Axis::Y => &Y_NAMES,
        Axis::Z => &Z_NAMES,
    }
}

// The kinds' order in `too_long` is `ShaperKind::ALL`'s.
const _: () = assert!(ShaperKind::ThreeHumpEi.index() == 5 && ShaperKind::Zv.index() == 0);
