//! Resonances and anti-resonances of a measured response ([`find_modes`]).
//!
//! 1. **Rigid body.** The lowest `rigid_points` points fit `1/H = J (jω)² + B jω` (linear
//!    least squares on the real and imaginary parts: `J`, `B`). On a two-mass axis this is
//!    the whole inertia, the line the response follows below its first mode.
//! 2. **Relative response.** `G = H (J (jω)² + B jω)`: the response over the rigid-body
//!    line, 1 (0 dB) where the axis moves as one body. A compliant mode seen from the
//!    motor is a zero pair (the anti-resonance, the tool side swinging on its spring
//!    while the motor stands) below a pole pair (the resonance, both sides swinging
//!    against each other): a dip then a peak of `|G|`.
//! 3. **Candidates.** A local maximum of `|G|` (dB) whose topographic prominence is at
//!    least `min_rise_db`, and at least `noise_sigmas` times the scatter of a difference
//!    of two points there, is a resonance candidate, a local minimum as deep an
//!    anti-resonance one (the prominence: the height over the higher of the two lowest
//!    points between it and the next higher point on either side, as on a map; the
//!    scatter: the median of `|db_k - (db_{k-1} + db_{k+1})/2|` over
//!    ±[`SCATTER_HALF_WIDTH`] points, as a standard deviation of one point: each
//!    frequency is its own window, so the points' errors are independent).
//! 4. **Delay.** A pure delay `τ` in the loop (the amplifier's, the period's) tilts the
//!    phase by `-ωτ`, which a second-order section would take for damping. Away from the
//!    candidates (outside an octave of each) `arg G ≈ -ωτ`; a weighted least-squares fit
//!    over those points (weighted by their scatter) gives `τ` ([`ModeReport::delay_s`])
//!    and `G e^{jωτ}` is fitted.
//! 5. **Local fit.** Around each candidate (the points within a factor `fit_band_ratio` of
//!    its frequency, at least `min_fit_points`), `G` is fitted with a second-order section
//!    `(b₂s² + b₁s + b₀)/(s² + a₁s + a₀)` (s normalised by the candidate's ω) by linear
//!    least squares on `G·D = N` (Levy), re-weighted by `1/|D|` of the previous solution
//!    (Sanathanan-Koerner, [`SK_ITERATIONS`]) so that the fit minimises the error of `G`
//!    itself. The poles give the resonance (`ω² = a₀`, `2ζω = a₁`), the zeros the
//!    anti-resonance (`ω² = b₀/b₂`, `2ζω = b₁/b₂`): frequency and damping between grid
//!    points, from the phase as well as the magnitude. `peak_db` is `20 log10 |G|` of the
//!    fitted section at that frequency: the height above the rigid-body line (negative
//!    for an anti-resonance), what a notch filter's depth is chosen from. A fit whose
//!    pair is not underdamped or not inside the band is dropped.
//!
//! Runs once after a measurement (not in the control period), in `f64`, with fixed-size
//! arrays; a mode needs more than `fit_band_ratio` of separation from the next one to
//! be fitted alone.

use super::config::MAX_POINTS;
use super::estimate::{FrequencyResponse, ResponsePoint};

/// Most resonances (and anti-resonances) reported.
pub const MAX_MODES: usize = 8;

/// Sanathanan-Koerner iterations of the local fit (the weights settle within 3-4 on
/// the gantry's modes; 8 leaves margin).
pub const SK_ITERATIONS: usize = 8;

/// How modes are found (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ModeConfig {
    /// Lowest points fitting the rigid-body line (they must lie below the first mode).
    pub rigid_points: u8,
    /// Smallest prominence of a peak (depth of a dip), dB.
    pub min_rise_db: f32,
    /// The local fit takes the points within this factor of the candidate's frequency.
    pub fit_band_ratio: f32,
    /// ... and at least this many points.
    pub min_fit_points: u8,
    /// A candidate's prominence must also exceed this many times the scatter of a
    /// difference of two points there.
    pub noise_sigmas: f32,
}

/// Defaults for the default grid (64 points over 5-300 Hz, 6.7 % apart): the five
/// lowest points (5-6.5 Hz) for the rigid line; 0.8 dB of prominence (measured through
/// the servo in the simulator with ±1 count of encoder noise, docs/precision.md §2: the
/// rigid gantry's largest wiggle is 0.53 dB, above 100 Hz where the counts are coarse
/// against the sine; the flexible gantry's weakest feature, Z's anti-resonance, 1.24 dB);
/// ±30 % (about nine points) for the local fit.
pub const MODE_DEFAULTS: ModeConfig = ModeConfig {
    rigid_points: 5,
    min_rise_db: 0.8,
    fit_band_ratio: 1.3,
    min_fit_points: 6,
    noise_sigmas: 3.0,
};

/// A resonance or anti-resonance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Mode {
    pub freq_hz: f32,
    pub damping_ratio: f32,
    /// Height of the response over the rigid-body line there, dB (negative: a dip).
    pub peak_db: f32,
}

/// The rigid-body line `1/(J s² + B s)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RigidBody {
    /// mN·m/(mm/s²).
    pub inertia: f32,
    /// mN·m/(mm/s).
    pub viscous: f32,
}

impl RigidBody {
    /// The line's response at `freq_hz`: `(re, im)`, mm/(mN·m).
    pub fn response(&self, freq_hz: f32) -> (f32, f32) {
        let w = 2.0 * core::f64::consts::PI * f64::from(freq_hz);
        let (dr, di) = (
            -f64::from(self.inertia) * w * w,
            f64::from(self.viscous) * w,
        );
        let d2 = dr * dr + di * di;
        if d2 > 0.0 {
            ((dr / d2) as f32, (-di / d2) as f32)
        } else {
            (0.0, 0.0)
        }
    }
}

/// What [`find_modes`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ModeReport {
    pub rigid: RigidBody,
    /// The loop's pure delay the phase shows, s (removed before the local fits).
    pub delay_s: f32,
    resonances: [Mode; MAX_MODES],
    n_res: usize,
    anti: [Mode; MAX_MODES],
    n_anti: usize,
}

impl ModeReport {
    /// Resonances, rising frequency.
    pub fn resonances(&self) -> &[Mode] {
        self.resonances.get(..self.n_res).unwrap_or(&[])
    }

    /// Anti-resonances, rising frequency.
    pub fn anti_resonances(&self) -> &[Mode] {
        self.anti.get(..self.n_anti).unwrap_or(&[])
    }
}

/// Why no modes could be looked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModeError {
    /// Fewer points than the rigid line and one fit need.
    TooFewPoints,
    /// The rigid-body line's inertia is not positive (the lowest points are not a mass).
    NoRigidBody,
}

/// A complex number (the fit's own, `f64`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct C {
    re: f64,
    im: f64,
}

impl C {
    fn mul(self, o: C) -> C {
        C {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }

    fn div(self, o: C) -> C {
        let d = o.re * o.re + o.im * o.im;
        C {
            re: (self.re * o.re + self.im * o.im) / d,
            im: (self.im * o.re - self.re * o.im) / d,
        }
    }

    fn abs(self) -> f64 {
        libm::sqrt(self.re * self.re + self.im * self.im)
    }
}

fn omega(p: &ResponsePoint) -> f64 {
    2.0 * core::f64::consts::PI * f64::from(p.freq_hz)
}

fn h_of(p: &ResponsePoint) -> C {
    C {
        re: f64::from(p.re),
        im: f64::from(p.im),
    }
}

/// The rigid-body line from the lowest `n` points.
fn rigid_line(pts: &[ResponsePoint], n: usize) -> Option<RigidBody> {
    let (mut jn, mut jd, mut bn, mut bd) = (0.0, 0.0, 0.0, 0.0);
    for p in pts.iter().take(n) {
        let w = omega(p);
        let inv = C { re: 1.0, im: 0.0 }.div(h_of(p));
        if !(inv.re.is_finite() && inv.im.is_finite()) {
            return None;
        }
        // 1/H = -J ω² + j B ω
        jn += -inv.re * w * w;
        jd += w * w * w * w;
        bn += inv.im * w;
        bd += w * w;
    }
    let (j, b) = (jn / jd, bn / bd);
    (j > 0.0 && j.is_finite() && b.is_finite()).then_some(RigidBody {
        inertia: j as f32,
        viscous: b as f32,
    })
}

/// Points on each side over which the scatter of the response is judged (21 in all: the
/// five or six points a resonance and its anti-resonance bend do not move the median;
/// with 11 they inflated it next to the gantry's Z mode).
pub const SCATTER_HALF_WIDTH: usize = 10;
/// Median absolute value to standard deviation, for normal errors.
const MAD_TO_SIGMA: f64 = 1.4826;
/// Smallest scatter a point is weighted with in the delay's fit, dB (one clean point
/// must not outweigh all others).
const SCATTER_FLOOR_DB: f64 = 0.01;

/// The scatter of one point's dB around `i` (see the module docs): the residual of a
/// point against the mean of its neighbours has `1.5` times a point's variance.
fn scatter_db(db: &[f64], i: usize) -> f64 {
    let n = db.len();
    if n < 3 {
        return 0.0;
    }
    let lo = i.saturating_sub(SCATTER_HALF_WIDTH).max(1);
    let hi = (i + SCATTER_HALF_WIDTH).min(n - 2);
    let mut r = [0.0f64; 2 * SCATTER_HALF_WIDTH + 1];
    let mut m = 0;
    for k in lo..=hi {
        let (Some(a), Some(b), Some(c)) = (db.get(k - 1), db.get(k), db.get(k + 1)) else {
            continue;
        };
        if let Some(slot) = r.get_mut(m) {
            *slot = libm::fabs(b - 0.5 * (a + c));
            m += 1;
        }
    }
    let r = r.get_mut(..m).unwrap_or(&mut []);
    r.sort_unstable_by(|a, b| a.total_cmp(b));
    let med = match (r.get(m / 2), r.get(m.saturating_sub(1) / 2)) {
        (Some(a), Some(b)) => 0.5 * (a + b),
        _ => 0.0,
    };
    med * MAD_TO_SIGMA / libm::sqrt(1.5)
}

/// `|G|` in dB at every point, and `G` itself.
fn relative(pts: &[ResponsePoint], rigid: &RigidBody) -> ([f64; MAX_POINTS], [C; MAX_POINTS]) {
    let mut db = [0.0; MAX_POINTS];
    let mut g = [C::default(); MAX_POINTS];
    let (j, b) = (f64::from(rigid.inertia), f64::from(rigid.viscous));
    for ((p, d), gi) in pts.iter().zip(db.iter_mut()).zip(g.iter_mut()) {
        let w = omega(p);
        *gi = h_of(p).mul(C {
            re: -j * w * w,
            im: b * w,
        });
        *d = 20.0 * libm::log10(gi.abs().max(1e-300));
    }
    (db, g)
}

/// The topographic prominence of the peak (`sign` 1) or dip (`sign` -1) at `i`: on each
/// side, the lowest point (highest, for a dip) before the curve passes `i`'s level
/// again (or ends); the higher of the two (lower, for a dip) is the base, and the
/// prominence is the height over it. A long slope into a neighbouring feature does not
/// count (a small wiggle next to a deep dip stays small).
fn prominence(db: &[f64], i: usize, sign: f64) -> f64 {
    let Some(&here) = db.get(i) else {
        return 0.0;
    };
    let side = |it: &mut dyn Iterator<Item = &f64>| {
        let mut base = here;
        for &x in it {
            if sign * (x - here) > 0.0 {
                break;
            }
            if sign * (x - base) < 0.0 {
                base = x;
            }
        }
        base
    };
    let left = side(&mut db.iter().take(i).rev());
    let right = side(&mut db.iter().skip(i + 1));
    let base = if sign > 0.0 {
        left.max(right)
    } else {
        left.min(right)
    };
    sign * (here - base)
}

/// [`prominence`] for the tests.
#[cfg(test)]
pub(crate) fn tests_prominence(db: &[f64], i: usize, sign: f64) -> f64 {
    prominence(db, i, sign)
}

/// The points of the local fit around `i`: those within the band ratio, at least
/// `min_points` (the nearest in log-frequency).
fn band(pts: &[ResponsePoint], i: usize, c: &ModeConfig) -> (usize, usize) {
    let n = pts.len();
    let f0 = pts.get(i).map_or(1.0, |p| p.freq_hz);
    let r = c.fit_band_ratio.max(1.0);
    let (mut lo, mut hi) = (i, i);
    while lo > 0 && pts.get(lo - 1).is_some_and(|p| p.freq_hz >= f0 / r) {
        lo -= 1;
    }
    while hi + 1 < n && pts.get(hi + 1).is_some_and(|p| p.freq_hz <= f0 * r) {
        hi += 1;
    }
    while hi + 1 - lo < usize::from(c.min_fit_points) && (lo > 0 || hi + 1 < n) {
        let ratio = |k: usize| libm::logf(pts.get(k).map_or(1.0, |p| p.freq_hz) / f0).abs();
        let below = (lo > 0).then(|| ratio(lo - 1));
        let above = (hi + 1 < n).then(|| ratio(hi + 1));
        match (below, above) {
            (Some(b), Some(a)) if b <= a => lo -= 1,
            (Some(_), None) => lo -= 1,
            _ => hi += 1,
        }
    }
    (lo, hi)
}

/// Solve the 5×5 system `a x = y` (Gaussian elimination, partial pivoting; the index
/// loops read like the textbook algorithm, every index is below 5).
#[allow(clippy::needless_range_loop)]
fn solve5(mut a: [[f64; 5]; 5], mut y: [f64; 5]) -> Option<[f64; 5]> {
    for col in 0..5 {
        let piv = (col..5).max_by(|&r, &s| {
            let (x, z) = (a[r][col].abs(), a[s][col].abs());
            x.partial_cmp(&z).unwrap_or(core::cmp::Ordering::Equal)
        })?;
        if !(a[piv][col].abs() > 1e-300) {
            return None;
        }
        a.swap(col, piv);
        y.swap(col, piv);
        for r in col + 1..5 {
            let f = a[r][col] / a[col][col];
            for k in col..5 {
                a[r][k] -= f * a[col][k];
            }
            y[r] -= f * y[col];
        }
    }
    let mut x = [0.0; 5];
    for r in (0..5).rev() {
        let mut s = y[r];
        for k in r + 1..5 {
            s -= a[r][k] * x[k];
        }
        x[r] = s / a[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The fitted section `[a1, a0, b2, b1, b0]` (s normalised by `w0`) of `g` over the
/// points `lo..=hi`.
fn fit_section(pts: &[ResponsePoint], g: &[C], lo: usize, hi: usize, w0: f64) -> Option<[f64; 5]> {
    let mut theta: Option<[f64; 5]> = None;
    for _ in 0..SK_ITERATIONS {
        let mut ata = [[0.0; 5]; 5];
        let mut aty = [0.0; 5];
        for k in lo..=hi {
            let (Some(p), Some(gk)) = (pts.get(k), g.get(k)) else {
                continue;
            };
            let w = omega(p) / w0;
            // weight 1/|D| of the previous solution (Levy's 1 at first)
            let wt = match theta {
                Some([a1, a0, ..]) => {
                    let d = C {
                        re: a0 - w * w,
                        im: a1 * w,
                    }
                    .abs();
                    if d > 0.0 {
                        1.0 / d
                    } else {
                        1.0
                    }
                }
                None => 1.0,
            };
            let rows = [
                ([-gk.im * w, gk.re, w * w, 0.0, -1.0], gk.re * w * w),
                ([gk.re * w, gk.im, 0.0, -w, 0.0], gk.im * w * w),
            ];
            for (x, yv) in rows {
                for r in 0..5 {
                    for s in 0..5 {
                        ata[r][s] += wt * wt * x[r] * x[s];
                    }
                    aty[r] += wt * wt * x[r] * yv;
                }
            }
        }
        theta = Some(solve5(ata, aty)?);
    }
    theta
}

/// A second-order pair `s² + p s + q` (normalised by `w0`) as (Hz, damping), when
/// underdamped.
fn pair(p: f64, q: f64, w0: f64) -> Option<(f64, f64)> {
    if !(q > 0.0 && p > 0.0) {
        return None;
    }
    let wn = libm::sqrt(q);
    let zeta = p / (2.0 * wn);
    (zeta < 1.0).then(|| (wn * w0 / (2.0 * core::f64::consts::PI), zeta))
}

/// `20 log10 |N/D|` of the section at the normalised frequency `w`.
fn section_db(t: &[f64; 5], w: f64) -> f64 {
    let [a1, a0, b2, b1, b0] = *t;
    let n = C {
        re: b0 - b2 * w * w,
        im: b1 * w,
    };
    let d = C {
        re: a0 - w * w,
        im: a1 * w,
    };
    20.0 * libm::log10(n.div(d).abs().max(1e-300))
}

/// The candidate at `i` fitted: its resonance (`resonance`) or anti-resonance.
fn fit_mode(
    pts: &[ResponsePoint],
    g: &[C],
    i: usize,
    resonance: bool,
    c: &ModeConfig,
) -> Option<Mode> {
    let (lo, hi) = band(pts, i, c);
    let w0 = omega(pts.get(i)?);
    let t = fit_section(pts, g, lo, hi, w0)?;
    let [a1, a0, b2, b1, b0] = t;
    let (f, zeta) = if resonance {
        pair(a1, a0, w0)?
    } else {
        if !(b2.abs() > 0.0) {
            return None;
        }
        pair(b1 / b2, b0 / b2, w0)?
    };
    let (f_lo, f_hi) = (
        f64::from(pts.get(lo)?.freq_hz),
        f64::from(pts.get(hi)?.freq_hz),
    );
    if !(f >= f_lo && f <= f_hi) {
        return None;
    }
    let peak = section_db(&t, f * 2.0 * core::f64::consts::PI / w0);
    Some(Mode {
        freq_hz: f as f32,
        damping_ratio: zeta as f32,
        peak_db: peak as f32,
    })
}

/// The candidate at `i` is prominent enough: over `min_rise_db` and over
/// `noise_sigmas` times the scatter of a difference of two points there.
fn significant(db: &[f64], i: usize, sign: f64, c: &ModeConfig) -> bool {
    let limit = f64::from(c.min_rise_db)
        .max(f64::from(c.noise_sigmas) * core::f64::consts::SQRT_2 * scatter_db(db, i));
    prominence(db, i, sign) >= limit
}

/// The delay `τ` from the phase of `g` at the points outside an octave of every
/// candidate (`arg G ≈ -ωτ` there), weighted by the inverse of their scatter squared; 0
/// without such points.
fn delay(pts: &[ResponsePoint], g: &[C], db: &[f64], candidates: &[usize]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (k, (p, gk)) in pts.iter().zip(g).enumerate() {
        let near = candidates.iter().any(|&c| {
            pts.get(c)
                .is_some_and(|q| p.freq_hz > 0.5 * q.freq_hz && p.freq_hz < 2.0 * q.freq_hz)
        });
        if near {
            continue;
        }
        let w = omega(p);
        let e = scatter_db(db, k).max(SCATTER_FLOOR_DB);
        let wt = 1.0 / (e * e);
        num += wt * libm::atan2(gk.im, gk.re) * w;
        den += wt * w * w;
    }
    let tau = if den > 0.0 { -num / den } else { 0.0 };
    if tau.is_finite() {
        tau
    } else {
        0.0
    }
}

/// Resonances and anti-resonances of `r` (see the module docs).
pub fn find_modes(r: &FrequencyResponse, c: &ModeConfig) -> Result<ModeReport, ModeError> {
    let pts = r.points();
    let n_rigid = usize::from(c.rigid_points).max(2);
    if pts.len() < n_rigid + 3 {
        return Err(ModeError::TooFewPoints);
    }
    let rigid = rigid_line(pts, n_rigid).ok_or(ModeError::NoRigidBody)?;
    let (db, mut g) = relative(pts, &rigid);
    let db = db.get(..pts.len()).unwrap_or(&[]);
    // candidates: (index, resonance)
    let mut cand = [(0usize, false); 2 * MAX_MODES];
    let mut n_cand = 0;
    for i in 1..pts.len().saturating_sub(1) {
        let (Some(&prev), Some(&here), Some(&next)) = (db.get(i - 1), db.get(i), db.get(i + 1))
        else {
            continue;
        };
        let kind = if here > prev && here >= next {
            Some(true)
        } else if here < prev && here <= next {
            Some(false)
        } else {
            None
        };
        if let Some(res) = kind {
            let sign = if res { 1.0 } else { -1.0 };
            if significant(db, i, sign, c) {
                if let Some(slot) = cand.get_mut(n_cand) {
                    *slot = (i, res);
                    n_cand += 1;
                }
            }
        }
    }
    let cand = cand.get(..n_cand).unwrap_or(&[]);
    let mut idx = [0usize; 2 * MAX_MODES];
    for (slot, (i, _)) in idx.iter_mut().zip(cand) {
        *slot = *i;
    }
    let tau = delay(pts, &g, db, idx.get(..n_cand).unwrap_or(&[]));
    for (gk, p) in g.iter_mut().zip(pts) {
        let ph = omega(p) * tau;
        *gk = gk.mul(C {
            re: libm::cos(ph),
            im: libm::sin(ph),
        });
    }
    let mut out = ModeReport {
        rigid,
        delay_s: tau as f32,
        ..ModeReport::default()
    };
    for &(i, res) in cand {
        let Some(m) = fit_mode(pts, &g, i, res, c) else {
            continue;
        };
        let (list, n) = if res {
            (&mut out.resonances, &mut out.n_res)
        } else {
            (&mut out.anti, &mut out.n_anti)
        };
        if let Some(slot) = list.get_mut(*n) {
            *slot = m;
            *n += 1;
        }
    }
    Ok(out)
}
