//! The 3-axis shaper block: per-axis taps on a common delay, and the history they read.

use super::bound::DeviationBound;
use super::impulses::{Impulses, ParamNames, ShaperConfig, ShaperKind, MAX_IMPULSES};
use crate::axes::{Axis, AXES};
use crate::config::{positive, ConfigError};
use crate::motion::trajectory::RefSample;
use crate::Real;

/// Taps per axis at most: every impulse split over two samples.
pub const MAX_TAPS: usize = 2 * MAX_IMPULSES;

/// Highest mode frequency accepted, as a fraction of the control rate: at rate/20 the
/// linear split between samples changes an impulse's response by at most `(ωT)²/8`
/// = 1.2 % (T the period), so it adds at most about that much residual vibration.
pub const MAX_FREQ_OF_RATE: f32 = 0.05;

/// A fractional sample position this close to a whole period (in periods) is taken as
/// on it, one tap instead of two: the `f32` frequency's rounding leaves an impulse meant
/// to be on the grid up to ~1e-5 periods off it. The impulse moves by at most 10 ns at
/// 10 kHz, its axis' centroid by as much: 2.5 nm of skew at 250 mm/s.
const ON_GRID: f64 = 1e-4;

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

/// One tap: the sample `off` periods back, weighted `w`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Tap<R> {
    off: usize,
    w: R,
}

/// The validated shapers of the three axes (see the module docs): per axis up to
/// [`MAX_TAPS`] `(offset, weight)` pairs precomputed from the impulses, all axes centred
/// on one delay. `N` is the history's capacity in periods (a power of two).
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

/// The history the shaper reads: the last `N` reference samples per axis as
/// `[pos, vel, acc]`, newest at `head`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShaperState<R, const N: usize> {
    hist: [[[R; 3]; N]; AXES],
    head: usize,
    /// Periods since the input last changed (saturating).
    age: usize,
    window: usize,
}

impl<R: Real, const N: usize> InputShaper<R, N> {
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
        let mut imp: [Option<Impulses>; AXES] = [None; AXES];
        for (axis, slot) in Axis::ALL.iter().zip(imp.iter_mut()) {
            if let Some(c) = cfg.get(*axis) {
                let names = axis_names(*axis);
                *slot = Some(c.impulses_named(&names.params)?);
                if f64::from(c.freq_hz) * p > f64::from(MAX_FREQ_OF_RATE) {
                    return Err(ConfigError::OutOfRange(names.freq_high));
                }
            }
        }
        // The common delay D, rounded up to a whole period (an unshaped axis is then one
        // tap, an exact delay).
        let max_c = imp
            .iter()
            .flatten()
            .map(|s| s.centroid_s() / p)
            .fold(0.0, f64::max);
        let d = libm::ceil(max_c - ON_GRID);
        let mut sh = Self {
            taps: [[Tap::default(); MAX_TAPS]; AXES],
            n_taps: [0; AXES],
            window: 0,
            delay_periods: d as usize,
            period_s,
            bound: DeviationBound::default(),
        };
        for (i, (axis, s)) in Axis::ALL.iter().zip(imp.iter()).enumerate() {
            let (taps, n, m2) = axis_taps::<R>(s.as_ref(), d, p);
            let oldest = taps.iter().take(n).map(|t| t.off).max().unwrap_or(0);
            if oldest > N - 1 {
                let names = axis_names(*axis);
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
    /// bit for bit.
    #[inline]
    pub fn process(&self, st: &mut ShaperState<R, N>, input: &RefSample<R>) -> RefSample<R> {
        let mask = N - 1;
        let prev = st.head;
        let head = (prev + 1) & mask;
        st.head = head;
        let mut same = true;
        for (a, h) in st.hist.iter_mut().enumerate() {
            let x = [input.pos[a], input.vel[a], input.acc[a]];
            if let Some(p) = h.get(prev) {
                same &= *p == x;
            }
            if let Some(s) = h.get_mut(head) {
                *s = x;
            }
        }
        st.age = if same { st.age.saturating_add(1) } else { 0 };
        if st.age >= self.window {
            return *input;
        }
        let mut out = RefSample::default();
        for (a, (h, (taps, n))) in st
            .hist
            .iter()
            .zip(self.taps.iter().zip(self.n_taps))
            .enumerate()
        {
            let (mut p, mut v, mut acc) = (R::ZERO, R::ZERO, R::ZERO);
            for t in taps.iter().take(n) {
                if let Some(s) = h.get(head.wrapping_sub(t.off) & mask) {
                    p += t.w * s[0];
                    v += t.w * s[1];
                    acc += t.w * s[2];
                }
            }
            out.pos[a] = p;
            out.vel[a] = v;
            out.acc[a] = acc;
        }
        out
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
        hist: [[[R::ZERO; 3]; N]; AXES],
        head: 0,
        age: usize::MAX,
        window: 0,
    };

    /// Refill the history with `sample`: after a jump of the reference (homing re-bases
    /// the axes, a new mode starts) nothing is interpolated across the jump, and the
    /// shaped reference is `sample` at once.
    pub fn reset(&mut self, sample: &RefSample<R>) {
        for (a, h) in self.hist.iter_mut().enumerate() {
            let x = [sample.pos[a], sample.vel[a], sample.acc[a]];
            h.fill(x);
        }
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

/// The taps of one axis around the common delay `d` (periods; period `p` s), with their
/// second moment about `d` (s²). No shaper: one tap at `d`.
fn axis_taps<R: Real>(s: Option<&Impulses>, d: f64, p: f64) -> ([Tap<R>; MAX_TAPS], usize, f64) {
    let mut taps = [Tap::default(); MAX_TAPS];
    let mut w64 = [0.0f64; MAX_TAPS];
    let mut n = 0;
    let mut add = |off: usize, w: f64| {
        let i = taps.iter().take(n).position(|t| t.off == off).unwrap_or(n);
        if let (Some(t), Some(acc)) = (taps.get_mut(i), w64.get_mut(i)) {
            t.off = off;
            *acc += w;
            n = n.max(i + 1);
        }
    };
    match s {
        None => add(d as usize, 1.0),
        Some(s) => {
            let shift = d - s.centroid_s() / p;
            for (a, t) in s.iter() {
                let x = (t / p + shift).max(0.0);
                let k = libm::floor(x);
                let f = x - k;
                if f < ON_GRID {
                    add(k as usize, a);
                } else if f > 1.0 - ON_GRID {
                    add(k as usize + 1, a);
                } else {
                    add(k as usize, a * (1.0 - f));
                    add(k as usize + 1, a * f);
                }
            }
        }
    }
    let mut m2 = 0.0;
    for (t, w) in taps.iter_mut().zip(w64).take(n) {
        t.w = R::from_f64(w);
        let dt = (t.off as f64 - d) * p;
        m2 += w * dt * dt;
    }
    (taps, n, m2)
}

/// The names an axis' errors carry.
struct AxisNames {
    params: ParamNames,
    freq_high: &'static str,
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
            freq_high: concat!("shaper.", $a, ".freq_hz (<= 1/20 of the control rate)"),
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
