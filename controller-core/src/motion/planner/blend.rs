//! Junction blends: how the commanded path leaves the programmed one near a junction, and
//! by how much at most.
//!
//! The programmed path `p₀(σ)` is followed everywhere except within `±d` of a junction at
//! `σ_k`, where a correction is added (`x = σ − σ_k`, A = incoming piece and B = outgoing
//! piece, both continued analytically through the junction point C, as offsets from C):
//!
//! ```text
//! p(σ) = p₀(σ) + Δu·E(x) + F(x)·S₅(x)
//! Δu   = B'(0) − A'(0)                      tangent jump
//! F(x) = B(x) − A(x) − Δu·x                 what is left after the tangent jump (arcs)
//! E(x) = ∫₋d^x (G(ξ) − step(ξ)) dξ = d r³/6,  r = (d − |x|)/d,  G' = hat of width 2d
//! S₅   = G₅ − step, G₅ the quintic smoothstep over [−d, d]
//! ```
//!
//! * The tangent term mixes the two directions with a hat-shaped weight (a quadratic
//!   smoothstep G): p' = (1 − G) u_A + G u_B is continuous, p'' = Δu G' (the curvature)
//!   is continuous and piecewise linear, p''' is bounded. For the chords of a smooth curve
//!   (the thousands-of-short-segments case) transitions of width 2d = twice the chord
//!   length overlap so that their hats add up to a constant: the commanded curvature is
//!   then the curve's own, not a bump per chord (see docs/planner.md for the numbers).
//! * The F term mixes the positions of two curved pieces (position blending with a C²
//!   weight); with F(0) = F'(0) = 0 it removes the curvature jump of a tangent line–arc
//!   or arc–arc join and leaves the path C².
//! * Outside ±d both terms vanish exactly (E(±d) = 0, F·S₅ = 0), so blends are local and
//!   the planner can fix the path up to a junction before the next segment is known.
//!
//! **Deviation bound.** At any σ the commanded point differs from the programmed point at
//! the same path length by at most
//! `δ(d) = |Δu|·d/6 + |Δc|/2·m₂·d² + (|A'''| + |B'''|)/6·m₃·d³`,
//! with `|E| ≤ E(0) = d/6`, `|F(x)| ≤ |Δc| x²/2 + (|A'''| + |B'''|)|x|³/6` (Taylor, Δc the
//! curvature-vector jump), `m₂ = max x²|S₅|/d² = 0.02666`, `m₃ = max |x|³|S₅|/d³ = 0.01316`.
//! Its distance to the programmed path is therefore at most δ as well; the planner picks the
//! largest `d` with `δ(d) ≤ ε` (shared with an overlapping neighbour, see
//! [`plan_junction`]). A reversal (Δu = −2u) gets `d = 3ε`: the path reverses `d/3 ≤ ε`
//! before the corner, with speed going smoothly through zero.

use super::fmath::F32Ext;
use super::geometry::{norm, Piece, V3};

/// Tangent and curvature jumps below these are treated as smooth (no blend, no stop):
/// a 1e-6 direction change is a 1e-4 mm/s velocity step at 100 mm/s, a 1e-6 /mm curvature
/// step a 0.06 mm/s² acceleration step at 250 mm/s.
const SMOOTH_TANGENT: f32 = 1.0e-6;
const SMOOTH_CURVATURE_PER_MM: f32 = 1.0e-6;

/// `max x²|S₅(x)|` over `|x| ≤ d`, in units of d² (computed numerically, rounded up).
const M2: f32 = 0.026_66;
/// `max |x|³|S₅(x)|` in units of d³.
const M3: f32 = 0.013_16;

/// Value and three derivatives (with respect to σ) of a path offset.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Jet {
    pub p: V3,
    pub d1: V3,
    pub d2: V3,
    pub d3: V3,
}

impl Jet {
    pub fn add(&mut self, o: &Jet) {
        for i in 0..3 {
            self.p[i] += o.p[i];
            self.d1[i] += o.d1[i];
            self.d2[i] += o.d2[i];
            self.d3[i] += o.d3[i];
        }
    }
}

/// The transition at one junction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Junction {
    /// Half-width (mm of programmed path on each side); 0 = no transition.
    pub d: f32,
    /// Tangent jump u_B − u_A.
    pub du: V3,
    /// Whether a curved piece takes part (F term needed).
    pub mixed: bool,
    /// The machine stops at the junction (G61, dwell, no tolerance, or blend too small).
    pub stop: bool,
    /// Deviation bound δ(d) of this transition (mm).
    pub dev: f32,
}

impl Junction {
    /// No junction yet (path start or end): nothing to blend, nothing to stop for here.
    pub const NONE: Junction = Junction {
        d: 0.0,
        du: V3::new(0.0, 0.0, 0.0),
        mixed: false,
        stop: false,
        dev: 0.0,
    };

    /// The machine comes to rest at the junction, whatever its geometry.
    pub const STOP: Junction = Junction {
        stop: true,
        ..Junction::NONE
    };

    /// Correction jet at `x = σ − σ_k` (clamped to `[−d, d]`) for the incoming piece `a`
    /// and outgoing piece `b`. Whether the transition is active at a span end is the
    /// caller's decision (one-sided at breakpoints); `right` selects the side at `x = 0`,
    /// where the third derivative jumps.
    pub fn correction(&self, a: &Piece, b: &Piece, x: f32, right: bool) -> Jet {
        let d = self.d;
        if !(d > 0.0) {
            return Jet::default();
        }
        let x = x.clampf(-d, d);
        let on_right = x > 0.0 || (x == 0.0 && right);
        let r = ((d - x.abs()) / d).clampf(0.0, 1.0);
        let inv_d = 1.0 / d;
        // Hat kernel (tangent term).
        let e = d * r * r * r * (1.0 / 6.0);
        let s = if on_right { -0.5 * r * r } else { 0.5 * r * r };
        let g1 = r * inv_d;
        let g2 = if on_right {
            -inv_d * inv_d
        } else {
            inv_d * inv_d
        };
        let mut j = Jet::default();
        for i in 0..3 {
            let du = self.du[i];
            j.p[i] = du * e;
            j.d1[i] = du * s;
            j.d2[i] = du * g1;
            j.d3[i] = du * g2;
        }
        if self.mixed {
            let sq = (x + d) * 0.5 * inv_d;
            let sq2 = sq * sq;
            let g5 = sq2 * sq * (10.0 + sq * (-15.0 + 6.0 * sq));
            let h = 0.5 * inv_d;
            let q1 = 30.0 * sq2 * (1.0 - sq) * (1.0 - sq) * h;
            let q2 = 60.0 * sq * (1.0 - sq) * (1.0 - 2.0 * sq) * h * h;
            let q3 = (360.0 * sq2 - 360.0 * sq + 60.0) * h * h * h;
            let s5 = if on_right { g5 - 1.0 } else { g5 };
            let ea = a.len + x;
            let fa = a.delta(a.len, ea);
            let fb = b.delta(0.0, x);
            let da = a.derivs(ea);
            let db = b.derivs(x);
            for i in 0..3 {
                let f0 = fb[i] - fa[i] - self.du[i] * x;
                let f1 = db.d1[i] - da.d1[i] - self.du[i];
                let f2 = db.d2[i] - da.d2[i];
                let f3 = db.d3[i] - da.d3[i];
                j.p[i] += f0 * s5;
                j.d1[i] += f1 * s5 + f0 * q1;
                j.d2[i] += f2 * s5 + 2.0 * f1 * q1 + f0 * q2;
                j.d3[i] += f3 * s5 + 3.0 * f2 * q1 + 3.0 * f1 * q2 + f0 * q3;
            }
        }
        j
    }
}

/// Deviation bound δ(d) of a transition (see the module docs).
#[derive(Clone, Copy, Debug)]
struct DevModel {
    k1: f32,
    k2: f32,
    k3: f32,
}

impl DevModel {
    fn dev(&self, d: f32) -> f32 {
        d * (self.k1 + d * (self.k2 + d * self.k3))
    }
    /// Largest `d ≤ cap` with `dev(d) ≤ budget` (bisection; dev is increasing).
    fn inverse(&self, budget: f32, cap: f32) -> f32 {
        if !(budget > 0.0) || !(cap > 0.0) {
            return 0.0;
        }
        if self.dev(cap) <= budget {
            return cap;
        }
        let (mut lo, mut hi) = (0.0f32, cap);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if self.dev(mid) <= budget {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }
}

/// Chooses the transition at the junction between `a` and `b`.
///
/// * `tol`: the blend tolerance ε of `a`'s segment (`None` = exact stop); the budget for
///   the transition itself is ε minus the span fit tolerance `fit_tol`.
/// * `prev`: the transition at `a`'s start (already fixed).
/// * `a_free`: how much of `a` (measured back from its end) is not yet handed to the
///   executor; the transition must not reach into the fixed part.
///
/// Width rule (causal: a junction only sees the past and the next piece):
/// 1. `d ≤ min(len_a, len_b, a_free)` and `δ(d) ≤ budget`: a transition reaches at most the
///    neighbouring junctions, so at most two transitions overlap anywhere.
/// 2. Beyond half of `b` only if `δ(d) ≤ budget/2`: the next junction keeps at least half
///    of `b` for itself, or half the budget to overlap with this one.
/// 3. Overlapping `prev` only if `δ(d) + δ_prev ≤ budget`; otherwise stop where `prev`
///    ends (rule 2 applied to `prev` guarantees that leaves half of `a` or half the budget).
///
/// A transition narrower than `min_half_width` (the shortest span) becomes an exact stop.
pub(crate) fn plan_junction(
    a: &Piece,
    b: &Piece,
    tol: Option<f32>,
    prev: &Junction,
    a_free: f32,
    fit_tol: f32,
    min_half_width: f32,
) -> Junction {
    if a.is_dwell() || b.is_dwell() {
        return stop();
    }
    let da = a.derivs(a.len);
    let db = b.derivs(0.0);
    let du = db.d1 - da.d1;
    let dc = db.d2 - da.d2;
    let (ndu, ndc) = (norm(du), norm(dc));
    if ndu <= SMOOTH_TANGENT && ndc <= SMOOTH_CURVATURE_PER_MM {
        return Junction::NONE;
    }
    let Some(eps) = tol else {
        return stop();
    };
    let budget = if eps > 2.0 * fit_tol {
        eps - fit_tol
    } else {
        0.5 * eps
    };
    let mixed = a.is_curved() || b.is_curved();
    let model = DevModel {
        k1: ndu * (1.0 / 6.0),
        k2: if mixed { 0.5 * ndc * M2 } else { 0.0 },
        k3: if mixed {
            (a.third_derivative_bound() + b.third_derivative_bound()) * (1.0 / 6.0) * M3
        } else {
            0.0
        },
    };
    let cap = a.len.mn(b.len).mn(a_free.mx(0.0));
    let mut d = model.inverse(budget, cap);
    // Rule 2.
    if d > 0.5 * b.len {
        d = (0.5 * b.len).mx(model.inverse(0.5 * budget, d));
    }
    // Rule 3.
    if d + prev.d > a.len && model.dev(d) + prev.dev > budget {
        let apart = (a.len - prev.d).mx(0.0).mn(d);
        d = apart.mx(model.inverse(budget - prev.dev, d));
    }
    if d < min_half_width {
        return stop();
    }
    Junction {
        d,
        du,
        mixed,
        stop: false,
        dev: model.dev(d),
    }
}

fn stop() -> Junction {
    Junction::STOP
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::geometry::Shape;
    use super::*;

    /// The line piece from `start` to `end` (also for `corner`'s tests).
    pub(crate) fn line(start: [f32; 3], end: [f32; 3]) -> Piece {
        let (start, end) = (V3::from_array(start), V3::from_array(end));
        let d = end - start;
        let len = norm(d);
        Piece {
            start,
            end,
            len,
            shape: Shape::Line {
                u: d.scale(1.0 / len),
            },
        }
    }

    /// Commanded point near a line-line corner: programmed point + correction.
    fn commanded(j: &Junction, a: &Piece, b: &Piece, x: f32) -> V3 {
        let prog = if x < 0.0 {
            a.end + a.delta(a.len, a.len + x)
        } else {
            b.start + b.delta(0.0, x)
        };
        if x.abs() < j.d {
            prog + j.correction(a, b, x, true).p
        } else {
            prog
        }
    }

    #[test]
    fn corner_deviation_within_bound_and_path_continuous() {
        // Direction changes: near-tangent (179.9° corner), 170°, 135°, 90° corners,
        // a sharp 10° corner and a reversal.
        for turn in [0.1f32, 10.0, 45.0, 90.0, 170.0, 180.0] {
            let t = turn.to_radians();
            let a = line([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]);
            let b = line(
                [10.0, 0.0, 0.0],
                [10.0 + 10.0 * t.cos(), 10.0 * t.sin(), 0.0],
            );
            let j = plan_junction(&a, &b, Some(0.01), &Junction::NONE, 10.0, 0.0, 5e-4);
            assert!(!j.stop && j.d > 0.0, "{turn}: {j:?}");
            assert!(j.dev <= 0.01 * (1.0 + 1e-5));
            let n = 2000;
            let mut last = commanded(&j, &a, &b, -j.d * 1.01);
            for k in 0..=n {
                let x = -j.d * 1.01 + 2.02 * j.d * k as f32 / n as f32;
                let p = commanded(&j, &a, &b, x);
                // Distance to the programmed point at the same σ (the proved quantity).
                let prog = if x < 0.0 {
                    a.end + a.delta(a.len, a.len + x)
                } else {
                    b.start + b.delta(0.0, x)
                };
                assert!(norm(p - prog) <= j.dev * (1.0 + 1e-3) + 1e-6);
                assert!(norm(p - last) < 2.02 * j.d / n as f32 * 1.5 + 1e-6);
                last = p;
            }
        }
    }

    #[test]
    fn derivatives_of_the_correction_match_finite_differences() {
        let a = line([0.0, 0.0, 0.0], [5.0, 0.0, 0.0]);
        let b = line([5.0, 0.0, 0.0], [5.0, 5.0, 1.0]);
        let j = plan_junction(&a, &b, Some(0.5), &Junction::NONE, 5.0, 0.0, 5e-4);
        let h = 1e-3f32;
        for &x in &[-0.9f32, -0.4, -0.1, 0.2, 0.6] {
            let x = x * j.d;
            let c = j.correction(&a, &b, x, true);
            let cp = j.correction(&a, &b, x + h, true);
            let cm = j.correction(&a, &b, x - h, true);
            for i in 0..3 {
                let fd1 = (cp.p[i] - cm.p[i]) / (2.0 * h);
                let fd2 = (cp.d1[i] - cm.d1[i]) / (2.0 * h);
                let fd3 = (cp.d2[i] - cm.d2[i]) / (2.0 * h);
                assert!((fd1 - c.d1[i]).abs() < 1e-3, "d1 {x} {i}");
                assert!((fd2 - c.d2[i]).abs() < 1e-2, "d2 {x} {i}");
                assert!(
                    (fd3 - c.d3[i]).abs() < 2e-1 * (1.0 + c.d3[i].abs()),
                    "d3 {x} {i}"
                );
            }
        }
    }
}
