//! The frequency response at one frequency from the effort applied and the encoder's
//! position over a whole number of cycles (sin/cos correlation: one DFT bin each, no
//! storage of the samples), and the measured response of an axis
//! ([`FrequencyResponse`]: up to [`MAX_POINTS`] points in a fixed array).
//!
//! With `φ_k` the sine's phase in period `k`, `u_k` the effort applied over period `k`
//! (zero-order hold from `kT` to `(k+1)T`) and `x_k` the position read at `kT`:
//!
//! ```text
//! U  = Σ w_k u_k e^{-jφ_k}        D = Σ w_k (x_k - x_{k-1}) e^{-jφ_k}    (k = 0..N over the window)
//! H_zoh = D / (U (1 - e^{-jωT}))                 (the held, sampled response)
//! H(jω) = H_zoh e^{jθ} sin²θ / (θ² cos θ)  =  (D / U) e^{jωT} tan θ / (2j θ²),  θ = ωT/2
//! ```
//!
//! The position enters as its steps: the constant travel speed the axis moves at while it
//! is measured is a constant step, which has no component at `ω` over whole cycles
//! (the position itself, a ramp, would leak into every bin). Over whole cycles the steps'
//! bin is exactly `(1 - e^{-jωT})` times the position's periodic part's. The effort is held
//! over each period: the held, sampled response of a mass `1/(J s²)` is
//! `-T² cos θ e^{-jθ} / (4 J sin²θ)` (its zero-order-hold equivalent), and the last factor
//! turns exactly that into `1/(J (jω)²)`: `H` is the continuous effort-to-position
//! response of the axis (mm per mN·m), exact for a mass and within `θ⁴` (1e-4 at 300 Hz
//! and 10 kHz) for anything that rolls off as a mass does above its modes (the hold's
//! half-period delay and `sinc` alone, the usual correction, leave `θ²/3`).
//!
//! `w_k = (1 - cos(2πk/N))/2` is the (periodic) Hann window. Its transform has three
//! taps (bins 0 and ±1), so over `m ≥ 2` whole cycles the steady sine passes exactly (the
//! same factor `N/2` in `U` and `D`), a constant (the travel) not at all, and what is
//! not steady (the holding loop's slow drift after a reversal, a mode's ringing not quite
//! settled) leaks about `m²` times less than through the plain sums. Sums are
//! compensated (Neumaier): a window holds up to tens of thousands of samples.

pub use super::config::MAX_POINTS;
use crate::Real;

/// The inertia a stepped sine's first frequency measures is trusted within this factor
/// of the guess.
pub const INERTIA_RANGE: f32 = 25.0;

/// One measured frequency: `H(j 2π freq_hz)`, mm/(mN·m).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ResponsePoint {
    pub freq_hz: f32,
    pub re: f32,
    pub im: f32,
}

impl ResponsePoint {
    /// `|H|`, mm/(mN·m).
    pub fn magnitude(&self) -> f32 {
        libm::sqrtf(self.re * self.re + self.im * self.im)
    }

    /// `20 log10 |H|` (re 1 mm/(mN·m)), dB.
    pub fn magnitude_db(&self) -> f32 {
        20.0 * libm::log10f(self.magnitude().max(f32::MIN_POSITIVE))
    }

    /// The inertia of a mass with this response, `1/(ω² |H|)` (mN·m/(mm/s²)), trusted
    /// within [`INERTIA_RANGE`] of `guess` (the guess when it is not finite): above an
    /// axis' modes its response is its motor side's.
    pub fn mass_inertia(&self, guess: f32) -> f32 {
        let w = 2.0 * core::f32::consts::PI * self.freq_hz;
        let j = 1.0f32.div_or(w * w * self.magnitude(), guess);
        // max/min, not clamp: clamp panics on crossed or NaN bounds
        j.max(guess / INERTIA_RANGE).min(guess * INERTIA_RANGE)
    }

    /// `arg H`, degrees in (-180, 180].
    pub fn phase_deg(&self) -> f32 {
        libm::atan2f(self.im, self.re).to_degrees()
    }
}

/// The measured response of an axis: its points in rising frequency (whatever the order
/// they were measured in).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrequencyResponse {
    points: [ResponsePoint; MAX_POINTS],
    len: usize,
}

impl Default for FrequencyResponse {
    fn default() -> Self {
        Self::new()
    }
}

impl FrequencyResponse {
    pub const fn new() -> Self {
        Self {
            points: [ResponsePoint {
                freq_hz: 0.0,
                re: 0.0,
                im: 0.0,
            }; MAX_POINTS],
            len: 0,
        }
    }

    /// Add a point in its place by frequency (false when full or when the point is not
    /// finite).
    pub fn push(&mut self, p: ResponsePoint) -> bool {
        let ok = p.freq_hz.is_finite() && p.re.is_finite() && p.im.is_finite();
        if !ok || self.len >= MAX_POINTS {
            return false;
        }
        let at = self
            .points()
            .iter()
            .position(|q| q.freq_hz > p.freq_hz)
            .unwrap_or(self.len);
        if let Some(tail) = self.points.get_mut(at..=self.len) {
            tail.rotate_right(1);
            if let Some(slot) = tail.first_mut() {
                *slot = p;
            }
        }
        self.len += 1;
        true
    }

    pub fn points(&self) -> &[ResponsePoint] {
        self.points.get(..self.len).unwrap_or(&[])
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// A compensated sum (Neumaier).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sum {
    s: f32,
    c: f32,
}

impl Sum {
    fn add(&mut self, x: f32) {
        let t = self.s + x;
        if self.s.abs() >= x.abs() {
            self.c += (self.s - t) + x;
        } else {
            self.c += (x - t) + self.s;
        }
        self.s = t;
    }

    fn value(&self) -> f32 {
        self.s + self.c
    }
}

/// The correlation sums of one frequency's window.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Correlator {
    u_re: Sum,
    u_im: Sum,
    d_re: Sum,
    d_im: Sum,
    u_mean: Sum,
    n_u: u32,
    n_d: u32,
    /// Window length, periods.
    len: u32,
}

impl Correlator {
    /// A window of `len` periods.
    pub(crate) fn new(len: u32) -> Self {
        Self {
            len: len.max(1),
            ..Self::default()
        }
    }

    /// The Hann window's weight of the `k`-th sample.
    fn weight(&self, k: u32) -> f32 {
        let x = 2.0 * core::f32::consts::PI * k as f32 / self.len as f32;
        0.5 - 0.5 * <f32 as Real>::sin_cos(x).1
    }

    /// The effort of the next period of the window with the sine's `(sin, cos)` then.
    pub(crate) fn add_effort(&mut self, u: f32, sc: (f32, f32)) {
        let uw = u * self.weight(self.n_u);
        self.u_re.add(uw * sc.1);
        self.u_im.add(-uw * sc.0);
        self.u_mean.add(u);
        self.n_u = self.n_u.saturating_add(1);
    }

    /// The position step `x_k - x_{k-1}` of the next period of the window, with
    /// `(sin, cos)`.
    pub(crate) fn add_step(&mut self, dx: f32, sc: (f32, f32)) {
        let dw = dx * self.weight(self.n_d);
        self.d_re.add(dw * sc.1);
        self.d_im.add(-dw * sc.0);
        self.n_d = self.n_d.saturating_add(1);
    }

    /// Efforts and steps added.
    #[cfg(test)]
    pub(crate) fn counts(&self) -> (u32, u32) {
        (self.n_u, self.n_d)
    }

    /// The effort's bin `U` (the Hann-weighted sums: `N/4` times the amplitude's phasor).
    pub(crate) fn effort_bin(&self) -> (f32, f32) {
        (self.u_re.value(), self.u_im.value())
    }

    /// Mean effort over the window, mN·m.
    pub(crate) fn mean_effort(&self) -> f32 {
        self.u_mean.value() / self.n_u.max(1) as f32
    }

    /// Amplitude of the effort's component at the frequency, mN·m.
    #[cfg(test)]
    pub(crate) fn effort_amplitude(&self) -> f32 {
        let (re, im) = (self.u_re.value(), self.u_im.value());
        // the window's sum is N/2
        4.0 * libm::sqrtf(re * re + im * im) / self.n_u.max(1) as f32
    }

    /// `H(j 2π freq_hz)` (see the module docs); `None` without effort at the frequency.
    pub(crate) fn response(&self, freq_hz: f32, period_s: f32) -> Option<ResponsePoint> {
        let (ur, ui) = (self.u_re.value(), self.u_im.value());
        let (dr, di) = (self.d_re.value(), self.d_im.value());
        let uu = ur * ur + ui * ui;
        if !(uu > 0.0) {
            return None;
        }
        // D / U
        let (qr, qi) = ((dr * ur + di * ui) / uu, (di * ur - dr * ui) / uu);
        let theta = core::f32::consts::PI * freq_hz * period_s;
        let scale = libm::tanf(theta) / (2.0 * theta * theta);
        // · e^{j2θ} / j = · (sin 2θ - j cos 2θ)
        let (c2, s2) = (libm::cosf(2.0 * theta), libm::sinf(2.0 * theta));
        let (er, ei) = (s2, -c2);
        let p = ResponsePoint {
            freq_hz,
            re: scale * (qr * er - qi * ei),
            im: scale * (qr * ei + qi * er),
        };
        (p.re.is_finite() && p.im.is_finite()).then_some(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_response_keeps_finite_points_only_and_stops_when_full() {
        let mut r = FrequencyResponse::new();
        assert!(!r.push(ResponsePoint {
            freq_hz: 1.0,
            re: f32::NAN,
            ..ResponsePoint::default()
        }));
        // measured from the top down: kept in rising frequency
        for i in (0..MAX_POINTS).rev() {
            assert!(r.push(ResponsePoint {
                freq_hz: i as f32,
                re: 1.0,
                im: -1.0
            }));
        }
        assert!(!r.push(ResponsePoint::default()));
        assert_eq!(r.len(), MAX_POINTS);
        assert!(r.points().windows(2).all(|w| w[0].freq_hz < w[1].freq_hz));
        let p = r.points()[3];
        assert_eq!(p.freq_hz, 3.0);
        assert!((p.magnitude() - core::f32::consts::SQRT_2).abs() < 1e-6);
        assert!((p.phase_deg() + 45.0).abs() < 1e-4);
        assert!((p.magnitude_db() - 3.0103).abs() < 1e-3);
    }

    /// A mass under the hold (its exact discrete motion, on a constant travel speed and
    /// a constant effort) measures `-1/(J ω²)`.
    #[test]
    fn a_mass_measures_minus_one_over_j_omega_squared() {
        let (t, f, j) = (1e-4f32, 250.0f32, 0.05f32);
        let two_pi = 2.0 * core::f32::consts::PI;
        let dt = f64::from(t);
        let (mut x, mut v) = (3.0f64, 27.0f64);
        let mut prev_x = x;
        let mut c = Correlator::new(1600);
        // the window: 40 cycles in 1600 periods after 100 of run-in
        for k in 0..1700u32 {
            let ph = two_pi * f * t * k as f32;
            let sc = (libm::sinf(ph), libm::cosf(ph));
            if k >= 100 {
                c.add_step((x - prev_x) as f32, sc);
            }
            let u = sc.0;
            if k >= 100 {
                c.add_effort(u, sc);
            }
            // the period under the held effort
            let a = f64::from(u / j);
            prev_x = x;
            x += v * dt + 0.5 * a * dt * dt;
            v += a * dt;
        }
        assert_eq!(c.counts(), (1600, 1600));
        let p = c.response(f, t).unwrap();
        let w = two_pi * f;
        let exact = -1.0 / (j * w * w);
        assert!((p.re / exact - 1.0).abs() < 1e-3, "{p:?} {exact}");
        assert!((p.im / exact).abs() < 1e-3, "{p:?}");
        assert!((c.effort_amplitude() - 1.0).abs() < 1e-3);
        assert!(c.mean_effort().abs() < 1e-3);
    }
}
