//! Programmed path pieces: straight lines and helical arcs (circular arcs in any plane plus
//! a linear travel along the plane normal: G2/G3 in the XY, ZX or YZ plane, and arcs in
//! planes of any orientation from the path compressor), parametrised by path length σ (mm)
//! from the piece start.
//!
//! A piece can be evaluated outside `[0, len]` (the analytic continuation of the line or
//! helix): the junction blends of [`super::blend`] mix a piece with its neighbour's
//! continuation. Positions are only ever returned as *differences* [`Piece::delta`]
//! between two parameters, computed with half-angle identities, so that numbers stay
//! local (small) and f32 keeps sub-micrometre resolution anywhere in the ±150 mm travel.
//!
//! An arc whose start and end radii differ (within the validated tolerance) is a planar
//! spiral whose radius changes linearly with the angle, so that it ends exactly on the
//! programmed end point (LinuxCNC does the same). σ is then proportional to the angle and
//! equal to the arc length up to the relative radius mismatch.

use super::fmath::{self, F32Ext};
use crate::num::vec3::Vec3;

/// A point or direction of the planner (x, y, z in mm or per mm): the crate's vector in
/// the planner's `f32`.
pub(crate) type V3 = Vec3<f32>;

/// Length of `a` with the planner's own square root ([`fmath::sqrt`], not the
/// [`crate::Real`] one), so that every figure stays as the planner has always computed it.
#[inline]
pub(crate) fn norm(a: V3) -> f32 {
    fmath::sqrt(a.dot(a))
}

/// First, second and third derivative of a piece with respect to σ.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Derivs {
    pub d1: V3,
    pub d2: V3,
    pub d3: V3,
}

/// A helix about the normal `n` of the plane spanned by the orthonormal `e1`, `e2`
/// (`e1 × e2 = n`): in-plane radius `r0 + rho σ` at angle `psi0 + omega σ` (from `e1`
/// toward `e2`), normal travel `eta σ`. For G2/G3 the three are the plane's axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Helix {
    pub e1: V3,
    pub e2: V3,
    pub n: V3,
    /// Start angle in the plane (rad, from axis i1 toward i2).
    pub psi0: f32,
    /// Angle per mm of path (rad/mm); negative for clockwise.
    pub omega: f32,
    /// Radius at σ = 0 (mm).
    pub r0: f32,
    /// Radius change per mm of path (spiral; 0 for a circle).
    pub rho: f32,
    /// Normal travel per mm of path (helix pitch term).
    pub eta: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Shape {
    /// Unit direction.
    Line {
        u: V3,
    },
    Helix(Helix),
    /// A pause of zero length.
    Dwell,
}

/// One programmed piece with its exact (programmed) end points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Piece {
    pub start: V3,
    pub end: V3,
    pub len: f32,
    pub shape: Shape,
}

impl Helix {
    #[inline]
    fn radius(&self, s: f32) -> f32 {
        self.r0 + self.rho * s
    }
    #[inline]
    fn angle(&self, s: f32) -> f32 {
        self.psi0 + self.omega * s
    }
    fn axes(&self, a: f32, b: f32, nrm: f32) -> V3 {
        let (e1, e2, n) = (self.e1, self.e2, self.n);
        V3::new(
            a * e1[0] + b * e2[0] + nrm * n[0],
            a * e1[1] + b * e2[1] + nrm * n[1],
            a * e1[2] + b * e2[2] + nrm * n[2],
        )
    }
}

impl Piece {
    /// Position at `s1` minus position at `s0` (both may lie outside `[0, len]`).
    pub fn delta(&self, s0: f32, s1: f32) -> V3 {
        match self.shape {
            Shape::Line { u } => u.scale(s1 - s0),
            Shape::Dwell => V3::zero(),
            Shape::Helix(h) => {
                let ds = s1 - s0;
                let dpsi = h.omega * ds;
                let psim = h.angle(s0) + 0.5 * dpsi;
                let k = 2.0 * h.radius(s0) * fmath::sin_cos(0.5 * dpsi).0;
                let (sm, cm) = fmath::sin_cos(psim);
                let dr = h.rho * ds;
                let (sb, cb) = if dr != 0.0 {
                    fmath::sin_cos(h.angle(s1))
                } else {
                    (0.0, 0.0)
                };
                let a = -k * sm + dr * cb;
                let b = k * cm + dr * sb;
                h.axes(a, b, h.eta * ds)
            }
        }
    }

    /// Position at `s`, anchored at whichever programmed end point is nearer.
    pub fn position(&self, s: f32) -> V3 {
        if s <= 0.5 * self.len {
            self.start + self.delta(0.0, s)
        } else {
            self.end + self.delta(self.len, s)
        }
    }

    /// Derivatives with respect to σ at `s`.
    pub fn derivs(&self, s: f32) -> Derivs {
        match self.shape {
            Shape::Line { u } => Derivs {
                d1: u,
                ..Derivs::default()
            },
            Shape::Dwell => Derivs::default(),
            Shape::Helix(h) => {
                let psi = h.angle(s);
                let (sn, cs) = fmath::sin_cos(psi);
                let (r, w, rho) = (h.radius(s), h.omega, h.rho);
                let d1 = h.axes(rho * cs - r * w * sn, rho * sn + r * w * cs, h.eta);
                let d2 = h.axes(
                    -2.0 * rho * w * sn - r * w * w * cs,
                    2.0 * rho * w * cs - r * w * w * sn,
                    0.0,
                );
                let w2 = w * w;
                let d3 = h.axes(
                    -3.0 * rho * w2 * cs + r * w2 * w * sn,
                    -3.0 * rho * w2 * sn - r * w2 * w * cs,
                    0.0,
                );
                Derivs { d1, d2, d3 }
            }
        }
    }

    /// Upper bound of |third derivative| over the piece and one piece length beyond each
    /// end (where blends use its continuation).
    pub fn third_derivative_bound(&self) -> f32 {
        match self.shape {
            Shape::Line { .. } | Shape::Dwell => 0.0,
            Shape::Helix(h) => {
                let r_max = h.r0.abs().mx(h.radius(self.len).abs()) + (h.rho * self.len).abs();
                let w = h.omega.abs();
                3.0 * h.rho.abs() * w * w + r_max * w * w * w
            }
        }
    }

    pub fn is_curved(&self) -> bool {
        matches!(self.shape, Shape::Helix(_))
    }

    pub fn is_dwell(&self) -> bool {
        matches!(self.shape, Shape::Dwell)
    }

    /// Largest span length that keeps the septic fit of the exact curve accurate: half a
    /// radian of arc (fit error below 1e-9 of the radius), 64 mm of line (keeps the span
    /// parameter's f32 resolution below 4 nm).
    pub fn max_span_len(&self) -> f32 {
        match self.shape {
            Shape::Helix(h) if h.omega != 0.0 => (0.5 / h.omega.abs()).mn(MAX_LINE_SPAN_MM),
            _ => MAX_LINE_SPAN_MM,
        }
    }
}

/// Longest span on a straight line (mm).
pub(crate) const MAX_LINE_SPAN_MM: f32 = 64.0;

#[cfg(test)]
mod tests {
    use super::*;

    fn helix() -> Piece {
        // Quarter turn CCW in XY of radius 10 about (1, 2), rising 3 mm, start angle 0.3.
        let (r, sweep, h) = (10.0f32, core::f32::consts::FRAC_PI_2, 3.0f32);
        let len = fmath::sqrt((r * sweep) * (r * sweep) + h * h);
        let hx = Helix {
            e1: V3::unit_axis(0),
            e2: V3::unit_axis(1),
            n: V3::unit_axis(2),
            psi0: 0.3,
            omega: sweep / len,
            r0: r,
            rho: 0.0,
            eta: h / len,
        };
        let start = [1.0 + r * libm::cosf(0.3), 2.0 + r * libm::sinf(0.3), 5.0];
        let end = [
            1.0 + r * libm::cosf(0.3 + sweep),
            2.0 + r * libm::sinf(0.3 + sweep),
            8.0,
        ];
        Piece {
            start: V3::from_array(start),
            end: V3::from_array(end),
            len,
            shape: Shape::Helix(hx),
        }
    }

    #[test]
    fn helix_delta_reaches_end_and_derivatives_match_differences() {
        let p = helix();
        let e = p.start + p.delta(0.0, p.len);
        assert!(norm(e - p.end) < 2e-5, "{e:?} vs {:?}", p.end);
        // Unit speed and derivative consistency by central differences.
        for &s in &[-3.0f32, 0.0, 4.0, 9.5, p.len + 2.0] {
            let d = p.derivs(s);
            assert!((norm(d.d1) - 1.0).abs() < 1e-5);
            let h = 1e-2f32;
            let fd1 = p.delta(s - h, s + h).scale(0.5 / h);
            assert!(norm(fd1 - d.d1) < 1e-4, "d1 at {s}");
            let dm = p.derivs(s - h);
            let dp = p.derivs(s + h);
            let fd2 = (dp.d1 - dm.d1).scale(0.5 / h);
            assert!(norm(fd2 - d.d2) < 1e-4, "d2 at {s}");
            let fd3 = (dp.d2 - dm.d2).scale(0.5 / h);
            assert!(norm(fd3 - d.d3) < 1e-4, "d3 at {s}");
            // Curvature of a helix: r / (r² + c²) with c the rise per radian.
            let c = 3.0 / core::f32::consts::FRAC_PI_2;
            assert!((norm(d.d2) - 10.0 / (100.0 + c * c)).abs() < 1e-6);
        }
    }
}
