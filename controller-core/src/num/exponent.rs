//! [`Exponent`], the rational exponent of the laws' fractional powers, below both the
//! [`crate::Real`] trait that takes it and the fast powers that evaluate it.

/// A rational exponent `num/den`, `den` odd and positive, so that `sig(x)^(num/den)` is the
/// real odd root and is defined for negative `x`. Every exponent of the paper's laws
/// (5/9, -4/9, 1/3, 5/3) has this form, which lets fast implementations use cube roots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Exponent {
    pub num: i16,
    pub den: i16,
}

impl Exponent {
    /// `num/den`; `None` unless `den` is odd and positive.
    pub const fn new(num: i16, den: i16) -> Option<Self> {
        if den > 0 && den % 2 == 1 {
            Some(Self { num, den })
        } else {
            None
        }
    }

    pub fn as_f32(self) -> f32 {
        self.num as f32 / self.den as f32
    }

    pub fn as_f64(self) -> f64 {
        self.num as f64 / self.den as f64
    }

    /// `self - 1`, used for the derivative of `|e|^(q/p)`.
    pub const fn minus_one(self) -> Self {
        Self {
            num: self.num - self.den,
            den: self.den,
        }
    }

    /// `2 - self`, used by the nonsingular terminal surface.
    pub const fn two_minus(self) -> Self {
        Self {
            num: 2 * self.den - self.num,
            den: self.den,
        }
    }
}
