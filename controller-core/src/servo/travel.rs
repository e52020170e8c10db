//! Soft limits: the travel of each axis in machine coordinates, known once the axis is
//! homed. Jogs brake to stop at its ends, moves and programs that would leave it are
//! rejected before they start (the planner's and the G-code reader's checks), and the
//! servo step faults (`SoftLimit`, controlled stop) if a reference ever leaves it — the
//! last line of defence, which a correct planner never reaches.

use crate::axes::AXES;
use crate::config::ConfigError;

/// Travel of one axis, machine coordinates, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisTravel {
    pub min_mm: f32,
    pub max_mm: f32,
}

impl AxisTravel {
    /// No soft limit (simulation studies of the laws alone).
    pub const UNLIMITED: Self = Self {
        min_mm: f32::NEG_INFINITY,
        max_mm: f32::INFINITY,
    };

    /// `min < max`, neither NaN (either may be infinite: that end is unlimited).
    pub fn validate(&self, name: &'static str) -> Result<(), ConfigError> {
        if self.min_mm.is_nan() || self.max_mm.is_nan() {
            return Err(ConfigError::NotFinite(name));
        }
        if self.min_mm < self.max_mm {
            Ok(())
        } else {
            Err(ConfigError::OutOfRange(name))
        }
    }

    /// `pos_mm` lies within the travel (bounds included).
    pub fn contains(&self, pos_mm: f32) -> bool {
        pos_mm >= self.min_mm && pos_mm <= self.max_mm
    }

    /// Both ends finite.
    pub fn is_limited(&self) -> bool {
        self.min_mm.is_finite() && self.max_mm.is_finite()
    }
}

/// Travel of the three axes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct TravelConfig {
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub axes: [AxisTravel; AXES],
    /// A reference this far outside the travel faults the servo (`SoftLimit`), mm: room
    /// for the rounding of a reference that ends exactly on a bound.
    #[cfg_attr(feature = "serde", serde(default = "default_tolerance"))]
    pub tolerance_mm: f32,
}

#[cfg(feature = "serde")]
fn default_tolerance() -> f32 {
    TravelConfig::DEFAULT_TOLERANCE_MM
}

impl Default for TravelConfig {
    fn default() -> Self {
        Self::UNLIMITED
    }
}

impl TravelConfig {
    /// One micrometre: far above the `f32` rounding of a reference near 1 m (0.06 µm),
    /// far below anything a machine would notice.
    pub const DEFAULT_TOLERANCE_MM: f32 = 1e-3;

    pub const UNLIMITED: Self = Self {
        axes: [AxisTravel::UNLIMITED; AXES],
        tolerance_mm: Self::DEFAULT_TOLERANCE_MM,
    };

    pub fn validate(&self) -> Result<(), ConfigError> {
        const NAMES: [&str; AXES] = [
            "travel.x (min_mm < max_mm)",
            "travel.y (min_mm < max_mm)",
            "travel.z (min_mm < max_mm)",
        ];
        for (a, n) in self.axes.iter().zip(NAMES) {
            a.validate(n)?;
        }
        crate::config::non_negative(self.tolerance_mm, "travel.tolerance_mm")?;
        Ok(())
    }

    /// [`Self::violation`] of the axes in `mask` (bit i = axis i) of a reference.
    pub fn violation_of<R: crate::Real>(
        &self,
        pos: &crate::Vec3<R>,
        mask: u8,
    ) -> Option<(usize, f32)> {
        (0..AXES).find_map(|i| {
            if mask & (1 << i) == 0 {
                return None;
            }
            let t = self.axes[i];
            let p = pos[i].to_f32();
            let inside = p >= t.min_mm - self.tolerance_mm && p <= t.max_mm + self.tolerance_mm;
            (!inside).then_some((i, p))
        })
    }

    /// The first axis (and its position) outside the travel by more than the tolerance.
    pub fn violation(&self, pos_mm: &[f32; AXES]) -> Option<(usize, f32)> {
        (0..AXES).find_map(|i| {
            let t = self.axes[i];
            let p = pos_mm[i];
            let inside = p >= t.min_mm - self.tolerance_mm && p <= t.max_mm + self.tolerance_mm;
            (!inside).then_some((i, p))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn violation_names_the_axis_beyond_the_tolerance() {
        let mut t = TravelConfig::UNLIMITED;
        t.axes[1] = AxisTravel {
            min_mm: -150.0,
            max_mm: 150.0,
        };
        assert_eq!(t.violation(&[1e9, 150.0005, 0.0]), None);
        assert_eq!(t.violation(&[0.0, 150.002, 0.0]), Some((1, 150.002)));
        assert!(AxisTravel {
            min_mm: 1.0,
            max_mm: 1.0
        }
        .validate("t")
        .is_err());
    }
}
