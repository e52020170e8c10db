//! Reference trajectories with analytic first and second derivatives.
//!
//! The analytic velocity is also the path tangent that the contour-error model falls back
//! to, and the analytic acceleration is the feed-forward `q_d''` of the sliding-mode laws
//! (accelerations are never measured on the machine).

use crate::{Real, Vec3};

/// Reference position, velocity and acceleration at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefSample<R> {
    pub pos: Vec3<R>,
    pub vel: Vec3<R>,
    pub acc: Vec3<R>,
}

/// A reference path, evaluated at absolute time `t` (s). Lengths are in the plant's
/// units: normalised units for the paper plant, millimetres for physical axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Trajectory<R> {
    /// Every axis jumps from 0 to `target` at `t0` (velocity and acceleration zero).
    Step { target: Vec3<R>, t0: R },
    /// `pos_i = offset_i + amp_i sin(omega t + phase_i)`.
    Sine {
        amp: Vec3<R>,
        omega: R,
        phase: Vec3<R>,
        offset: Vec3<R>,
    },
    /// Constant-velocity line `start + vel t`.
    Line { start: Vec3<R>, vel: Vec3<R> },
    /// `x = cx + r sin(ωt)`, `y = cy + r cos(ωt)`, `z = cz + z_rate t`: the paper's helix
    /// (eq. 25) is r = 1, ω = 1, z_rate = 5; a circle is z_rate = 0.
    Helix {
        center: Vec3<R>,
        radius: R,
        omega: R,
        z_rate: R,
    },
}

impl<R: Real> Trajectory<R> {
    /// The paper's helix: x = sin t, y = cos t, z = 5t.
    pub fn paper_helix() -> Self {
        Self::Helix {
            center: Vec3::zero(),
            radius: R::ONE,
            omega: R::ONE,
            z_rate: R::from_f32(5.0),
        }
    }

    /// Circle in the XY plane, starting at (cx, cy + r).
    pub fn circle(center: Vec3<R>, radius: R, omega: R) -> Self {
        Self::Helix {
            center,
            radius,
            omega,
            z_rate: R::ZERO,
        }
    }

    pub fn sample(&self, t: R) -> RefSample<R> {
        match *self {
            Self::Step { target, t0 } => RefSample {
                pos: if t >= t0 { target } else { Vec3::zero() },
                vel: Vec3::zero(),
                acc: Vec3::zero(),
            },
            Self::Sine {
                amp,
                omega,
                phase,
                offset,
            } => {
                let mut s = RefSample::default();
                for i in 0..3 {
                    let (sn, cs) = (omega * t + phase[i]).sin_cos();
                    s.pos[i] = offset[i] + amp[i] * sn;
                    s.vel[i] = amp[i] * omega * cs;
                    s.acc[i] = -amp[i] * omega * omega * sn;
                }
                s
            }
            Self::Line { start, vel } => RefSample {
                pos: start + vel * t,
                vel,
                acc: Vec3::zero(),
            },
            Self::Helix {
                center,
                radius,
                omega,
                z_rate,
            } => {
                let (sn, cs) = (omega * t).sin_cos();
                let rw = radius * omega;
                let rww = rw * omega;
                RefSample {
                    pos: Vec3::new(
                        center.x + radius * sn,
                        center.y + radius * cs,
                        center.z + z_rate * t,
                    ),
                    vel: Vec3::new(rw * cs, -rw * sn, z_rate),
                    acc: Vec3::new(-rww * sn, -rww * cs, R::ZERO),
                }
            }
        }
    }

    /// Convert the parameters to another number type.
    pub fn cast<S: Real>(&self) -> Trajectory<S> {
        let c = |v: R| S::from_f64(v.to_f64());
        match *self {
            Self::Step { target, t0 } => Trajectory::Step {
                target: target.cast(),
                t0: c(t0),
            },
            Self::Sine {
                amp,
                omega,
                phase,
                offset,
            } => Trajectory::Sine {
                amp: amp.cast(),
                omega: c(omega),
                phase: phase.cast(),
                offset: offset.cast(),
            },
            Self::Line { start, vel } => Trajectory::Line {
                start: start.cast(),
                vel: vel.cast(),
            },
            Self::Helix {
                center,
                radius,
                omega,
                z_rate,
            } => Trajectory::Helix {
                center: center.cast(),
                radius: c(radius),
                omega: c(omega),
                z_rate: c(z_rate),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_derivatives(tr: Trajectory<f64>) {
        let h = 1e-5;
        for k in 0..50 {
            let t = 0.37 * k as f64;
            let (a, b, c) = (tr.sample(t - h), tr.sample(t), tr.sample(t + h));
            for i in 0..3 {
                let v = (c.pos[i] - a.pos[i]) / (2.0 * h);
                let acc = (c.vel[i] - a.vel[i]) / (2.0 * h);
                assert!((v - b.vel[i]).abs() < 1e-6, "vel axis {i} t {t}");
                assert!((acc - b.acc[i]).abs() < 1e-6, "acc axis {i} t {t}");
            }
        }
    }

    #[test]
    fn analytic_derivatives_match_finite_differences() {
        check_derivatives(Trajectory::paper_helix());
        check_derivatives(Trajectory::circle(Vec3::new(1.0, 2.0, 3.0), 5.0, 2.0));
        check_derivatives(Trajectory::Line {
            start: Vec3::new(1.0, 2.0, 3.0),
            vel: Vec3::new(0.5, -1.0, 2.0),
        });
        check_derivatives(Trajectory::Sine {
            amp: Vec3::new(1.0, 2.0, 0.0),
            omega: 3.0,
            phase: Vec3::new(0.0, 1.0, 0.0),
            offset: Vec3::zero(),
        });
    }

    #[test]
    fn paper_helix_values() {
        let s = Trajectory::<f64>::paper_helix().sample(0.0);
        assert_eq!(s.pos, Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(s.vel, Vec3::new(1.0, 0.0, 5.0));
    }
}
