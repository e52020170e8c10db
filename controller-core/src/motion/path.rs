//! Path configuration: the serialisable description of a [`Trajectory`], validated into
//! one (lengths in the plant's units: mm on a machine, normalised units for the paper's
//! axis; angles in rad, times in s).

use super::trajectory::{Polyline, Trajectory, POLYLINE_MAX_VERTICES};
use crate::config::ConfigError;
use crate::Vec3;

/// A reference path. TOML: `path = { helix = { radius = 1.0, omega = 1.0, z_rate = 5.0 } }`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(rename_all = "snake_case", deny_unknown_fields)
)]
pub enum PathConfig {
    /// Every axis jumps from 0 to `target` at `t0_s`.
    Step {
        target: [f64; 3],
        #[cfg_attr(feature = "serde", serde(default))]
        t0_s: f64,
    },
    /// `pos_i = offset_i + amp_i sin(omega t + phase_i)`.
    Sine {
        amp: [f64; 3],
        omega: f64,
        #[cfg_attr(feature = "serde", serde(default))]
        phase: [f64; 3],
        #[cfg_attr(feature = "serde", serde(default))]
        offset: [f64; 3],
    },
    /// Constant-velocity line `start + vel t`.
    Line {
        #[cfg_attr(feature = "serde", serde(default))]
        start: [f64; 3],
        vel: [f64; 3],
    },
    /// `x = cx + r sin(ωt)`, `y = cy + r cos(ωt)`, `z = cz + z_rate t` (a circle for
    /// `z_rate = 0`; the paper's helix is r = 1, ω = 1, z_rate = 5).
    Helix {
        #[cfg_attr(feature = "serde", serde(default))]
        center: [f64; 3],
        radius: f64,
        omega: f64,
        #[cfg_attr(feature = "serde", serde(default))]
        z_rate: f64,
    },
    /// Axis-aligned square in the XY plane, counter-clockwise from `corner`, exact stop at
    /// every corner (trapezoidal speed profile `accel` up to `speed`), repeated.
    Square {
        #[cfg_attr(feature = "serde", serde(default))]
        corner: [f64; 3],
        side: f64,
        speed: f64,
        accel: f64,
    },
}

/// Where a path is placed when it starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum PathStart {
    /// In absolute machine coordinates, as written.
    #[default]
    Absolute,
    /// Translated so that its point at `t = 0` is where the machine is when it starts (no
    /// step in the reference).
    FromCurrentPosition,
}

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl PathConfig {
    /// The trajectory, or which parameter is invalid.
    pub fn build(&self) -> Result<Trajectory<f64>, ConfigError> {
        let v = Vec3::from_array;
        let tr = match *self {
            Self::Step { target, t0_s } => {
                if !all_finite(&[target[0], target[1], target[2], t0_s]) {
                    return Err(ConfigError::NotFinite("path.step"));
                }
                Trajectory::Step {
                    target: v(target),
                    t0: t0_s,
                }
            }
            Self::Sine {
                amp,
                omega,
                phase,
                offset,
            } => Trajectory::Sine {
                amp: v(amp),
                omega,
                phase: v(phase),
                offset: v(offset),
            },
            Self::Line { start, vel } => Trajectory::Line {
                start: v(start),
                vel: v(vel),
            },
            Self::Helix {
                center,
                radius,
                omega,
                z_rate,
            } => {
                if !(radius > 0.0) {
                    return Err(ConfigError::NotPositive("path.helix.radius"));
                }
                Trajectory::Helix {
                    center: v(center),
                    radius,
                    omega,
                    z_rate,
                }
            }
            Self::Square {
                corner,
                side,
                speed,
                accel,
            } => {
                if !all_finite(&corner) {
                    return Err(ConfigError::NotFinite("path.square.corner"));
                }
                if !(side > 0.0 && side.is_finite()) {
                    return Err(ConfigError::NotPositive("path.square.side"));
                }
                Trajectory::Polyline(
                    Polyline::square(v(corner), side, speed, accel)
                        .ok_or(ConfigError::NotPositive("path.square.speed/accel"))?,
                )
            }
        };
        // every parameter feeds the sample at t = 1: a cheap, complete finiteness check
        let s = tr.sample(1.0);
        if !(s.pos.is_finite() && s.vel.is_finite() && s.acc.is_finite()) {
            return Err(ConfigError::NotFinite("path"));
        }
        Ok(tr)
    }
}

const _: () = assert!(POLYLINE_MAX_VERTICES >= 4);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builds_and_rejects() {
        let h = PathConfig::Helix {
            center: [0.0; 3],
            radius: 1.0,
            omega: 1.0,
            z_rate: 5.0,
        };
        assert_eq!(h.build().unwrap(), Trajectory::paper_helix());
        let bad = PathConfig::Helix {
            center: [0.0; 3],
            radius: 0.0,
            omega: 1.0,
            z_rate: 5.0,
        };
        assert_eq!(
            bad.build(),
            Err(ConfigError::NotPositive("path.helix.radius"))
        );
        let nan = PathConfig::Line {
            start: [0.0; 3],
            vel: [f64::NAN, 0.0, 0.0],
        };
        assert_eq!(nan.build(), Err(ConfigError::NotFinite("path")));
    }
}
