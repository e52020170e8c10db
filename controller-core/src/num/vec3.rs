//! Three-axis vectors (x, y, z) over any [`Real`].

use crate::Real;
use core::ops::{Add, Index, IndexMut, Mul, Neg, Sub};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3<R> {
    pub x: R,
    pub y: R,
    pub z: R,
}

impl<R: Real> Vec3<R> {
    pub const fn new(x: R, y: R, z: R) -> Self {
        Self { x, y, z }
    }

    pub fn zero() -> Self {
        Self::splat(R::ZERO)
    }

    pub fn splat(v: R) -> Self {
        Self { x: v, y: v, z: v }
    }

    pub fn from_array(a: [R; 3]) -> Self {
        Self::new(a[0], a[1], a[2])
    }

    pub fn to_array(self) -> [R; 3] {
        [self.x, self.y, self.z]
    }

    pub fn dot(self, o: Self) -> R {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// `self × o`.
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }

    /// Unit vector along axis `i` (0-2; any other index gives zero).
    pub fn unit_axis(i: usize) -> Self {
        match i {
            0 => Self::new(R::ONE, R::ZERO, R::ZERO),
            1 => Self::new(R::ZERO, R::ONE, R::ZERO),
            2 => Self::new(R::ZERO, R::ZERO, R::ONE),
            _ => Self::zero(),
        }
    }

    pub fn norm_sq(self) -> R {
        self.dot(self)
    }

    pub fn norm(self) -> R {
        self.norm_sq().sqrt_pos()
    }

    pub fn scale(self, k: R) -> Self {
        Self::new(self.x * k, self.y * k, self.z * k)
    }

    pub fn map(self, f: impl Fn(R) -> R) -> Self {
        Self::new(f(self.x), f(self.y), f(self.z))
    }

    /// Convert between number types (e.g. the f64 plant state to the f32 controller).
    pub fn cast<S: Real>(self) -> Vec3<S> {
        Vec3::new(
            S::from_f64(self.x.to_f64()),
            S::from_f64(self.y.to_f64()),
            S::from_f64(self.z.to_f64()),
        )
    }

    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
}

impl<R: Real> Add for Vec3<R> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl<R: Real> Sub for Vec3<R> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl<R: Real> Neg for Vec3<R> {
    type Output = Self;
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}

impl<R: Real> Mul<R> for Vec3<R> {
    type Output = Self;
    fn mul(self, k: R) -> Self {
        self.scale(k)
    }
}

impl<R> Index<usize> for Vec3<R> {
    type Output = R;
    /// Axis 0, 1, 2 = x, y, z; any larger index reads z (never panics).
    fn index(&self, i: usize) -> &R {
        match i {
            0 => &self.x,
            1 => &self.y,
            _ => &self.z,
        }
    }
}

impl<R> IndexMut<usize> for Vec3<R> {
    fn index_mut(&mut self, i: usize) -> &mut R {
        match i {
            0 => &mut self.x,
            1 => &mut self.y,
            _ => &mut self.z,
        }
    }
}

impl Vec3<f64> {
    /// `self / |self|` (each component divided by the norm), or zero for a vector of no
    /// positive length (the host's path geometry: a degenerate move has no direction).
    pub fn unit_or_zero(self) -> Self {
        let n = self.norm();
        if n > 0.0 {
            self.map(|x| x / n)
        } else {
            Self::zero()
        }
    }
}
