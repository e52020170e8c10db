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
    /// Piecewise-linear path through vertices with an exact stop at each (see [`Polyline`]).
    Polyline(Polyline<R>),
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
            Self::Polyline(p) => p.sample(t),
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
            Self::Polyline(p) => Trajectory::Polyline(p.cast()),
        }
    }
}

/// Most vertices a [`Polyline`] holds (fixed storage: no allocation in the core).
pub const POLYLINE_MAX_VERTICES: usize = 8;

/// A piecewise-linear path (e.g. a square with sharp corners), traversed segment by
/// segment with a trapezoidal speed profile (`accel` up to `speed`, cruise, `accel` down)
/// that **stops exactly at every vertex**.
///
/// Corner choice: a sharp geometric corner cannot be followed at constant speed by an axis
/// with finite torque (the velocity would jump, an infinite acceleration the analytic
/// `q_d''` cannot express). Exact stop (a CNC's G61 mode) keeps the corners perfectly
/// sharp and the reference velocity continuous; acceleration is piecewise constant
/// (it jumps at the profile's phase changes). At a vertex the velocity is zero, so
/// the tangent is undefined there and the contour models fall back as documented in
/// [`crate::coupling::contour`]. A closed polyline returns to its first vertex and repeats; an open
/// one holds its last vertex. Before `t = 0` it holds the first vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polyline<R> {
    vertices: [Vec3<R>; POLYLINE_MAX_VERTICES],
    count: usize,
    closed: bool,
    speed: R,
    accel: R,
}

impl<R: Real> Polyline<R> {
    /// `None` unless 2..=POLYLINE_MAX_VERTICES vertices and `speed`, `accel` > 0.
    pub fn new(vertices: &[Vec3<R>], closed: bool, speed: R, accel: R) -> Option<Self> {
        if vertices.len() < 2
            || vertices.len() > POLYLINE_MAX_VERTICES
            || !(speed > R::ZERO)
            || !(accel > R::ZERO)
        {
            return None;
        }
        let mut v = [Vec3::zero(); POLYLINE_MAX_VERTICES];
        v.iter_mut().zip(vertices).for_each(|(d, s)| *d = *s);
        Some(Self {
            vertices: v,
            count: vertices.len(),
            closed,
            speed,
            accel,
        })
    }

    /// Axis-aligned square in the XY plane, counter-clockwise from `corner`.
    pub fn square(corner: Vec3<R>, side: R, speed: R, accel: R) -> Option<Self> {
        let (x, y) = (
            Vec3::new(side, R::ZERO, R::ZERO),
            Vec3::new(R::ZERO, side, R::ZERO),
        );
        Self::new(
            &[corner, corner + x, corner + x + y, corner + y],
            true,
            speed,
            accel,
        )
    }

    /// Edges of the path: `count` for a closed one (the last returns to the first
    /// vertex), `count - 1` for an open one.
    pub fn edges(&self) -> usize {
        self.segments()
    }

    /// The end vertex of edge `i` (`None` past the last edge).
    pub fn edge_end(&self, i: usize) -> Option<Vec3<R>> {
        (i < self.segments()).then(|| self.segment(i).1)
    }

    /// The cruise speed along every edge.
    pub fn speed(&self) -> R {
        self.speed
    }

    /// Geometric distance from `p` to the path (the nearest point of any edge, however
    /// it is timed).
    pub fn distance(&self, p: Vec3<R>) -> R {
        let mut best: Option<R> = None;
        for i in 0..self.segments() {
            let (a, b) = self.segment(i);
            let ab = b - a;
            let s = (p - a)
                .dot(ab)
                .div_or(ab.dot(ab), R::ZERO)
                .max_of(R::ZERO)
                .min_of(R::ONE);
            let d = (a + ab * s - p).norm();
            best = Some(best.map_or(d, |b| b.min_of(d)));
        }
        // (a polyline has at least one edge)
        best.unwrap_or(R::ZERO)
    }

    fn segments(&self) -> usize {
        if self.closed {
            self.count
        } else {
            self.count - 1
        }
    }

    fn segment(&self, i: usize) -> (Vec3<R>, Vec3<R>) {
        let a = self.vertices.get(i).copied().unwrap_or_default();
        let j = if i + 1 >= self.count { 0 } else { i + 1 };
        let b = self.vertices.get(j).copied().unwrap_or_default();
        (a, b)
    }

    /// Peak speed and duration of a segment of length `len`.
    fn profile(&self, len: R) -> (R, R) {
        // trapezoid if the ramps fit, triangle (peak sqrt(L a)) otherwise
        let v = self.speed.min_of((len * self.accel).sqrt_pos());
        let t_ramp = v.div_or(self.accel, R::ZERO);
        let cruise = (len - v * t_ramp).max_of(R::ZERO).div_or(v, R::ZERO);
        (v, t_ramp + t_ramp + cruise)
    }

    /// Duration of one pass over all segments.
    pub fn duration(&self) -> R {
        let mut total = R::ZERO;
        for i in 0..self.segments() {
            let (a, b) = self.segment(i);
            total += self.profile((b - a).norm()).1;
        }
        total
    }

    pub fn sample(&self, t: R) -> RefSample<R> {
        let hold = |p: Vec3<R>| RefSample {
            pos: p,
            vel: Vec3::zero(),
            acc: Vec3::zero(),
        };
        if !(t > R::ZERO) {
            return hold(self.vertices.first().copied().unwrap_or_default());
        }
        let period = self.duration();
        let mut tau = t;
        if self.closed && period > R::ZERO {
            let laps = libm::floor(t.to_f64() / period.to_f64());
            tau = t - period * R::from_f64(laps);
        }
        let half = R::from_f32(0.5);
        for i in 0..self.segments() {
            let (a, b) = self.segment(i);
            let len = (b - a).norm();
            let (v, dur) = self.profile(len);
            if tau < dur {
                let dir = (b - a) * R::ONE.div_or(len, R::ZERO);
                let t_ramp = v.div_or(self.accel, R::ZERO);
                let (s, sd, sdd) = if tau < t_ramp {
                    (half * self.accel * tau * tau, self.accel * tau, self.accel)
                } else if tau < dur - t_ramp {
                    (half * v * t_ramp + v * (tau - t_ramp), v, R::ZERO)
                } else {
                    let r = dur - tau;
                    (len - half * self.accel * r * r, self.accel * r, -self.accel)
                };
                return RefSample {
                    pos: a + dir * s,
                    vel: dir * sd,
                    acc: dir * sdd,
                };
            }
            tau -= dur;
        }
        let last = if self.closed { 0 } else { self.count - 1 };
        hold(self.vertices.get(last).copied().unwrap_or_default())
    }

    pub fn cast<S: Real>(&self) -> Polyline<S> {
        Polyline {
            vertices: self.vertices.map(|v| v.cast()),
            count: self.count,
            closed: self.closed,
            speed: S::from_f64(self.speed.to_f64()),
            accel: S::from_f64(self.accel.to_f64()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polyline_distance_is_to_the_nearest_edge_and_edges_close_the_loop() {
        let sq = Polyline::<f64>::square(Vec3::zero(), 40.0, 50.0, 1000.0).unwrap();
        assert_eq!(sq.edges(), 4);
        assert_eq!(sq.edge_end(3), Some(Vec3::zero()));
        assert_eq!(sq.edge_end(4), None);
        // on an edge, inside near one, outside beyond a corner, above the plane
        assert_eq!(sq.distance(Vec3::new(20.0, 0.0, 0.0)), 0.0);
        assert!((sq.distance(Vec3::new(20.0, 3.0, 0.0)) - 3.0).abs() < 1e-12);
        assert!((sq.distance(Vec3::new(43.0, 44.0, 0.0)) - 5.0).abs() < 1e-12);
        assert!((sq.distance(Vec3::new(0.0, 20.0, 2.0)) - 2.0).abs() < 1e-12);
        let open =
            Polyline::<f64>::new(&[Vec3::zero(), Vec3::new(10.0, 0.0, 0.0)], false, 1.0, 1.0)
                .unwrap();
        assert_eq!(open.edges(), 1);
        assert!((open.distance(Vec3::new(-3.0, 4.0, 0.0)) - 5.0).abs() < 1e-12);
    }

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
    fn square_stops_at_corners_and_follows_the_sides() {
        // side 40 at 50 mm/s, 1000 mm/s²: ramps 0.05 s over 1.25 mm, cruise 0.75 s
        let sq = Polyline::<f64>::square(Vec3::zero(), 40.0, 50.0, 1000.0).unwrap();
        assert!((sq.duration() - 4.0 * 0.85).abs() < 1e-12);
        let tr = Trajectory::Polyline(sq);
        let corner = tr.sample(0.85);
        assert!((corner.pos - Vec3::new(40.0, 0.0, 0.0)).norm() < 1e-9);
        assert!(corner.vel.norm() < 1e-9);
        let mid = tr.sample(0.85 + 0.425);
        assert!((mid.pos - Vec3::new(40.0, 20.0, 0.0)).norm() < 1e-9);
        assert_eq!(mid.vel, Vec3::new(0.0, 50.0, 0.0));
        // closed: repeats
        assert!((tr.sample(3.4 + 0.1).pos - tr.sample(0.1).pos).norm() < 1e-9);
        // derivatives away from the phase changes
        for k in 1..300 {
            let t = 0.0113 * k as f64;
            let h = 1e-6;
            let (a, b, c) = (tr.sample(t - h), tr.sample(t), tr.sample(t + h));
            for i in 0..3 {
                let v = (c.pos[i] - a.pos[i]) / (2.0 * h);
                assert!((v - b.vel[i]).abs() < 1e-4, "vel axis {i} t {t}");
                let acc = (c.vel[i] - a.vel[i]) / (2.0 * h);
                // acceleration jumps at the phase changes: compare only where smooth
                if (c.acc[i] - a.acc[i]).abs() < 1e-9 {
                    assert!((acc - b.acc[i]).abs() < 1e-3, "acc axis {i} t {t}");
                }
            }
        }
        // short segment: triangular profile, peak sqrt(L a)
        let p = Polyline::<f64>::new(
            &[Vec3::zero(), Vec3::new(1.0, 0.0, 0.0)],
            false,
            50.0,
            1000.0,
        )
        .unwrap();
        assert!((p.duration() - 2.0 * libm::sqrt(1000.0) / 1000.0).abs() < 1e-12);
        assert_eq!(p.sample(10.0).pos, Vec3::new(1.0, 0.0, 0.0));
        assert!(Polyline::<f64>::new(&[Vec3::zero()], false, 1.0, 1.0).is_none());
    }

    #[test]
    fn paper_helix_values() {
        let s = Trajectory::<f64>::paper_helix().sample(0.0);
        assert_eq!(s.pos, Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(s.vel, Vec3::new(1.0, 0.0, 5.0));
    }
}
