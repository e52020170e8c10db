//! Jogging: each axis follows a commanded velocity with bounded acceleration
//! ([`super::ramp::Ramp`]), brakes to stop at the travel's ends once the axis is homed,
//! and stops by itself when the jog commands stop arriving (a host that dies mid-jog must
//! not leave the axis running into the end stop).

use super::ramp::Ramp;
use crate::axes::AXES;
use crate::config::{positive, ConfigError};

/// One axis' jog limits.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AxisJogConfig {
    /// Largest jog speed, mm/s (commands beyond it are clamped).
    pub speed_max_mm_s: f32,
    /// Acceleration and deceleration of a jog, mm/s².
    pub accel_mm_s2: f32,
}

/// Jog configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct JogConfig {
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub axes: [AxisJogConfig; AXES],
    /// Without a new jog command for this long the axis decelerates to rest, s. A host
    /// repeating its jog command at 10 Hz (a held key's auto-repeat) keeps moving.
    pub timeout_s: f32,
}

impl JogConfig {
    /// 50 mm/s at 500 mm/s² (a tenth of the gantry's rapid acceleration: a person at the
    /// keys reacts in 0.2 s, in which 50 mm/s covers 10 mm) and a 0.3 s timeout.
    pub const GANTRY: Self = Self {
        axes: [AxisJogConfig {
            speed_max_mm_s: 50.0,
            accel_mm_s2: 500.0,
        }; AXES],
        timeout_s: 0.3,
    };

    pub fn validate(&self) -> Result<(), ConfigError> {
        for a in &self.axes {
            positive(a.speed_max_mm_s, "jog.speed_max_mm_s")?;
            positive(a.accel_mm_s2, "jog.accel_mm_s2")?;
        }
        positive(self.timeout_s, "jog.timeout_s")?;
        Ok(())
    }
}

impl Default for JogConfig {
    fn default() -> Self {
        Self::GANTRY
    }
}

/// A jog in progress: one ramp per axis and the period each axis' last command expires.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jog {
    pub ramps: [Ramp; AXES],
    target_mm_s: [f32; AXES],
    /// Periods left until each axis' command expires.
    left: [u32; AXES],
}

impl Jog {
    /// Starting at rest at `pos_mm`.
    pub fn at(pos_mm: [f32; AXES]) -> Self {
        Self {
            ramps: pos_mm.map(Ramp::at),
            target_mm_s: [0.0; AXES],
            left: [0; AXES],
        }
    }

    /// A jog command: `vel_mm_s` (clamped to the axis' maximum; 0 stops) for the next
    /// `timeout_periods`.
    pub fn command(&mut self, axis: usize, vel_mm_s: f32, cfg: &JogConfig, timeout_periods: u32) {
        if let (Some(t), Some(l), Some(a)) = (
            self.target_mm_s.get_mut(axis),
            self.left.get_mut(axis),
            cfg.axes.get(axis),
        ) {
            let v = if vel_mm_s.is_finite() { vel_mm_s } else { 0.0 };
            // (max/min, not clamp: clamp panics on a bad bound)
            *t = v.max(-a.speed_max_mm_s).min(a.speed_max_mm_s);
            *l = timeout_periods;
        }
    }

    /// One period; `bounds` are each axis' travel (infinite when not homed).
    pub fn advance(&mut self, cfg: &JogConfig, bounds: &[(f32, f32); AXES], dt_s: f32) {
        let axes = self
            .ramps
            .iter_mut()
            .zip(self.target_mm_s.iter_mut())
            .zip(self.left.iter_mut())
            .zip(bounds.iter().zip(&cfg.axes));
        for (((ramp, target), left), ((lo, hi), a)) in axes {
            if *left == 0 {
                *target = 0.0;
            } else {
                *left -= 1;
            }
            ramp.step_velocity(*target, a.accel_mm_s2, *lo, *hi, dt_s);
        }
    }

    /// Every axis at rest with nothing commanded.
    pub fn finished(&self) -> bool {
        self.ramps.iter().all(Ramp::at_rest) && self.target_mm_s.iter().all(|v| *v == 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jog_stops_after_the_timeout_and_at_the_travel_end() {
        let cfg = JogConfig::GANTRY;
        let mut j = Jog::at([0.0; AXES]);
        let bounds = [
            (-10.0, 10.0),
            (f32::NEG_INFINITY, f32::INFINITY),
            (-1.0, 1.0),
        ];
        j.command(0, 40.0, &cfg, 5000);
        j.command(1, -1000.0, &cfg, 5000);
        // X: 0.08 s up to 40 mm/s, 6.8 mm at speed, 0.08 s braking: at 10 mm in 0.33 s
        for _ in 0..5000 {
            j.advance(&cfg, &bounds, 1e-4);
        }
        // X braked at its end, Y at the clamped speed
        assert!(
            (j.ramps[0].pos_mm - 10.0).abs() < 0.05,
            "{}",
            j.ramps[0].pos_mm
        );
        assert!((j.ramps[1].vel_mm_s + 50.0).abs() < 1e-3);
        // the command expired: Y stops within v/a = 0.1 s
        for _ in 0..1001 {
            j.advance(&cfg, &bounds, 1e-4);
        }
        assert!(j.finished(), "{:?}", j.ramps);
    }
}
