//! Frequency responses: the complex gain of a block at a frequency, as the margin check
//! multiplies them, and the little complex arithmetic that needs (in `f64`; nothing here
//! runs in the control period).

/// A block with a known frequency response: its complex gain `(re, im)` at `freq_hz`.
pub trait FrequencyResponse {
    fn response(&self, freq_hz: f32) -> (f32, f32);
}

/// A complex number in `f64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct C64 {
    pub re: f64,
    pub im: f64,
}

impl C64 {
    pub const ONE: Self = Self { re: 1.0, im: 0.0 };

    pub const fn new(re: f64, im: f64) -> Self {
        Self { re, im }
    }

    /// From an `(re, im)` pair of `f32`.
    pub fn from_pair(p: (f32, f32)) -> Self {
        Self::new(p.0 as f64, p.1 as f64)
    }

    /// `e^{jθ}`.
    pub fn unit(theta: f64) -> Self {
        let (s, c) = libm::sincos(theta);
        Self::new(c, s)
    }

    pub fn times(self, o: Self) -> Self {
        Self::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }

    /// `self / d`, or 0 when `|d|` is 0 (or its square underflows).
    pub fn over(self, d: Self) -> Self {
        let n2 = d.re * d.re + d.im * d.im;
        if n2 > 0.0 && n2.is_finite() {
            Self::new(
                (self.re * d.re + self.im * d.im) / n2,
                (self.im * d.re - self.re * d.im) / n2,
            )
        } else {
            Self::new(0.0, 0.0)
        }
    }

    pub fn scale(self, k: f64) -> Self {
        Self::new(self.re * k, self.im * k)
    }

    pub fn plus(self, o: Self) -> Self {
        Self::new(self.re + o.re, self.im + o.im)
    }

    pub fn abs(self) -> f64 {
        libm::hypot(self.re, self.im)
    }

    /// Argument in degrees, in (-180, 180].
    pub fn arg_deg(self) -> f64 {
        libm::atan2(self.im, self.re).to_degrees()
    }

    pub fn is_finite(self) -> bool {
        self.re.is_finite() && self.im.is_finite()
    }

    /// `(re, im)` in `f32`, each saturated to `±f32::MAX` (no infinity from a finite value).
    pub fn to_pair(self) -> (f32, f32) {
        let s = |v: f64| {
            if v.is_nan() {
                0.0
            } else {
                v.clamp(-(f32::MAX as f64), f32::MAX as f64) as f32
            }
        };
        (s(self.re), s(self.im))
    }
}

/// `20 log10 |h|` of an `(re, im)` pair (−∞ for 0).
pub fn gain_db(h: (f32, f32)) -> f64 {
    20.0 * libm::log10(C64::from_pair(h).abs())
}
