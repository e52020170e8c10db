//! Exact distance from a point to the programmed path of one move, and the path's unit
//! tangent at the nearest point.
//!
//! * Lines: projection on the segment, clamped to its ends.
//! * Arcs and helices (radius and normal coordinate linear in the swept angle, as the
//!   planner interpolates them, see [`Helix`]): a 1-D minimisation of the squared
//!   distance `D(u)` over the swept angle `u` that cannot miss the nearest turn.
//!
//! **Why the arc search is exact.** With `ρ`, `φ` the point's planar radius and angle about
//! the centre, `θ(u) = ψ(u) − φ` and `r(u)`, `h(u)` the arc's radius and normal coordinate,
//! `D(u) = r² + ρ² − 2rρ·cos θ + (h − p_n)²`. Its third derivative
//! `D''' = 2ρ(3ṙ·cos θ − s·r·sin θ)` (ṙ = dr/du, s = ±1 the direction) vanishes only at
//! `θ ≡ β` and `θ ≡ β + π` (`tan β = 3sṙ/r`, |β| < 0.01 rad), so on each *window* between
//! consecutive angles `θ ≡ β + π` the curvature `D''` rises to its maximum at `θ ≡ β` and
//! falls again: `D'' > 0` on one interval (the window's core) and nowhere else. A local
//! minimum needs `D'' ≥ 0`, and `D'` increases on the core, so every window has at most one
//! interior local minimum, the root of `D'` in its core. The window's minimum is that root
//! or one of the window's ends; the path's minimum is the least over the windows. The core
//! ends (roots of the monotone `D''`) and the root of `D'` are found by Newton steps kept
//! inside a bracket (bisection where Newton would leave it), started from the guess of the
//! point's planar angle and the guess of its normal coordinate; a warm start from the last
//! sample's nearest point is accepted when Newton converges on it with `D'' > 0` (it is then
//! that unique minimum). Windows whose lower bound (the normal and the radial offsets alone)
//! cannot beat the best distance found are skipped. The final distance is computed from the
//! point difference, not from `D`'s cosine form, so it keeps full precision near 0.
//! Tested against dense brute-force sampling to 1e-9 mm on random steep and flat helices.

use crate::gcode::{Move, MoveKind};
use controller_core::num::vec3::Vec3;

/// Newton iterations at most in a bracketed root search (each bracket at least halves per
/// bisection, so 200 iterations cover any f64 interval).
const MAX_ROOT_ITERATIONS: usize = 200;
/// Newton iterations tried from a warm start before the full window search.
const WARM_ITERATIONS: usize = 6;
/// Relative step (rad) below which a root search has converged (a few f64 ulps).
const ROOT_TOL_REL: f64 = 1e-15;

/// The nearest point of one move's path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Distance from the point, mm.
    pub dist_mm: f64,
    /// Where along the move (0 start, 1 end; for arcs, the fraction of the sweep).
    pub at: f64,
    /// Unit tangent of the programmed path there, in the direction of travel.
    pub tangent: [f64; 3],
}

/// A programmed arc or helix: in its plane `(i1, i2)` the point at swept angle `u`
/// (0..=sweep) is `centre + r(u)·(cos ψ, sin ψ)`, `ψ = ψ₀ + s·u`, `r = r₀ + ṙ·u`, and its
/// normal coordinate is `h₀ + k·u`: radius and normal coordinate linear in the angle, as the
/// planner interpolates them (an arc's start and end radius may differ by the arc
/// tolerance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Helix {
    /// Plane axes `[first, second, normal]`.
    pub axes: [usize; 3],
    pub center: [f64; 2],
    pub psi0_rad: f64,
    /// +1 counter-clockwise (G3), −1 clockwise (G2), seen from the positive normal.
    pub dir: f64,
    pub sweep_rad: f64,
    pub r0_mm: f64,
    /// Radius change per radian swept, mm/rad.
    pub dr_mm_rad: f64,
    pub h0_mm: f64,
    /// Normal-coordinate change per radian swept (lead / 2π), mm/rad.
    pub k_mm_rad: f64,
}

impl Helix {
    /// The helix of an arc move (`None` for other moves or a degenerate sweep).
    pub fn of(m: &Move) -> Option<Self> {
        let MoveKind::Arc {
            to,
            center,
            plane,
            clockwise,
            sweep_rad,
            ..
        } = m.kind
        else {
            return None;
        };
        if !(sweep_rad > 0.0) {
            return None;
        }
        let [i1, i2, n] = plane.axes();
        let (a0, b0) = (m.from[i1] - center[i1], m.from[i2] - center[i2]);
        let (a1, b1) = (to[i1] - center[i1], to[i2] - center[i2]);
        let (r0, r1) = (a0.hypot(b0), a1.hypot(b1));
        Some(Self {
            axes: [i1, i2, n],
            center: [center[i1], center[i2]],
            psi0_rad: b0.atan2(a0),
            dir: if clockwise { -1.0 } else { 1.0 },
            sweep_rad,
            r0_mm: r0,
            dr_mm_rad: (r1 - r0) / sweep_rad,
            h0_mm: m.from[n],
            k_mm_rad: (to[n] - m.from[n]) / sweep_rad,
        })
    }

    pub fn radius_mm(&self, u: f64) -> f64 {
        self.r0_mm + self.dr_mm_rad * u
    }

    /// The point at swept angle `u`.
    pub fn point(&self, u: f64) -> [f64; 3] {
        let [i1, i2, n] = self.axes;
        let psi = self.psi0_rad + self.dir * u;
        let r = self.radius_mm(u);
        let mut q = [0.0; 3];
        q[i1] = self.center[0] + r * psi.cos();
        q[i2] = self.center[1] + r * psi.sin();
        q[n] = self.h0_mm + self.k_mm_rad * u;
        q
    }

    /// Unit tangent at `u`, in the direction of travel.
    pub fn tangent(&self, u: f64) -> [f64; 3] {
        let [i1, i2, n] = self.axes;
        let psi = self.psi0_rad + self.dir * u;
        let (s, c) = psi.sin_cos();
        let r = self.radius_mm(u);
        let mut t = [0.0; 3];
        t[i1] = self.dr_mm_rad * c - self.dir * r * s;
        t[i2] = self.dr_mm_rad * s + self.dir * r * c;
        t[n] = self.k_mm_rad;
        Vec3::from_array(t).unit_or_zero().to_array()
    }

    /// Length of the path, mm (exact for a constant radius; with the radius changing by
    /// the arc tolerance at most, the mean radius).
    pub fn length_mm(&self) -> f64 {
        let r_mean = self.r0_mm + 0.5 * self.dr_mm_rad * self.sweep_rad;
        (r_mean * self.sweep_rad).hypot(self.k_mm_rad * self.sweep_rad)
    }

    /// The nearest point to `p`: `(u, distance)`. `warm_u`: the swept angle of a nearby
    /// earlier answer (only a starting point; the result does not depend on it).
    pub fn nearest(&self, p: [f64; 3], warm_u: Option<f64>) -> (f64, f64) {
        let q = Query::new(self, p);
        let tau = std::f64::consts::TAU;
        let sweep = self.sweep_rad;
        // window boundaries: θ(u) ≡ β + π, i.e. u ≡ s·(β + π − θ₀) (mod 2π)
        let beta = (3.0 * self.dir * self.dr_mm_rad / self.r0_mm.max(f64::MIN_POSITIVE)).atan();
        let u0 = (self.dir * (beta + std::f64::consts::PI - q.theta0)).rem_euclid(tau);
        let windows = ((sweep - u0).max(0.0) / tau).floor() as usize + 2;
        let window = |j: usize| -> Option<(f64, f64, f64)> {
            // window j: [u0 + 2π(j − 1), u0 + 2πj] clipped to the sweep; centre (θ ≡ β)
            // half-way
            let a = u0 + tau * (j as f64 - 1.0);
            let b = u0 + tau * j as f64;
            let (ua, ub) = (a.max(0.0), b.min(sweep));
            (ub > ua).then_some((ua, ub, a + 0.5 * tau))
        };
        let mut best = Best::new();
        best.consider(&q, 0.0);
        best.consider(&q, sweep);
        // the window of the warm start (or of the smallest lower bound) first, so that the
        // others are mostly skipped by their bound
        let first = match warm_u {
            Some(w) if (0.0..=sweep).contains(&w) => ((w - u0) / tau).floor().max(-1.0) as i64 + 1,
            _ => (0..windows)
                .filter_map(|j| window(j).map(|(a, b, _)| (j, q.lower_bound(a, b))))
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .map_or(0, |(j, _)| j as i64),
        };
        let first = first.clamp(0, windows as i64 - 1) as usize;
        if let Some((a, b, c)) = window(first) {
            q.window_min(a, b, c, warm_u, &mut best);
        }
        for j in (0..windows).filter(|&j| j != first) {
            if let Some((a, b, c)) = window(j) {
                if q.lower_bound(a, b) < best.d2 {
                    q.window_min(a, b, c, None, &mut best);
                }
            }
        }
        (best.u, best.d2.sqrt())
    }
}

/// The best point found so far (squared distance from the point difference).
struct Best {
    u: f64,
    d2: f64,
}

impl Best {
    fn new() -> Self {
        Self {
            u: 0.0,
            d2: f64::INFINITY,
        }
    }

    fn consider(&mut self, q: &Query, u: f64) {
        let d = Vec3::from_array(q.helix.point(u)) - Vec3::from_array(q.p);
        let d2 = d.dot(d);
        if d2 < self.d2 {
            self.d2 = d2;
            self.u = u;
        }
    }
}

/// One point against one helix: `D(u)` and its derivatives.
struct Query<'a> {
    helix: &'a Helix,
    p: [f64; 3],
    rho: f64,
    theta0: f64,
    pn: f64,
}

impl<'a> Query<'a> {
    fn new(helix: &'a Helix, p: [f64; 3]) -> Self {
        let [i1, i2, n] = helix.axes;
        let (pa, pb) = (p[i1] - helix.center[0], p[i2] - helix.center[1]);
        Self {
            helix,
            p,
            rho: pa.hypot(pb),
            theta0: helix.psi0_rad - pb.atan2(pa),
            pn: p[n],
        }
    }

    /// `(D'(u), D''(u), D'''(u))`.
    fn derivs(&self, u: f64) -> (f64, f64, f64) {
        let h = self.helix;
        let (dr, k, s, rho) = (h.dr_mm_rad, h.k_mm_rad, h.dir, self.rho);
        let r = h.radius_mm(u);
        let (sn, cs) = (self.theta0 + s * u).sin_cos();
        let dn = h.h0_mm + k * u - self.pn;
        let d1 = 2.0 * dr * (r - rho * cs) + 2.0 * r * rho * s * sn + 2.0 * k * dn;
        let d2 = 2.0 * dr * dr + 4.0 * dr * rho * s * sn + 2.0 * r * rho * cs + 2.0 * k * k;
        let d3 = 2.0 * rho * (3.0 * dr * cs - s * r * sn);
        (d1, d2, d3)
    }

    /// A lower bound of `D` over `[a, b]`: the normal offset and the radial offset alone
    /// (both linear in `u`).
    fn lower_bound(&self, a: f64, b: f64) -> f64 {
        let h = self.helix;
        let lin_min = |f0: f64, slope: f64| {
            let (x, y) = (f0 + slope * a, f0 + slope * b);
            if x * y <= 0.0 {
                0.0
            } else {
                x.abs().min(y.abs())
            }
        };
        let dn = lin_min(h.h0_mm - self.pn, h.k_mm_rad);
        let dr = lin_min(h.r0_mm - self.rho, h.dr_mm_rad);
        dn * dn + dr * dr
    }

    /// The least `D` over the window `[a, b]` (centre `c`, where `D''` peaks) into `best`.
    fn window_min(&self, a: f64, b: f64, c: f64, warm: Option<f64>, best: &mut Best) {
        best.consider(self, a);
        best.consider(self, b);
        if let Some(w) = warm.filter(|w| (a..=b).contains(w)) {
            // Newton on D' from the warm start: a root with D'' > 0 inside the window is
            // its unique interior minimum
            let mut x = w;
            for _ in 0..WARM_ITERATIONS {
                let (d1, d2, _) = self.derivs(x);
                if !(d2 > 0.0) {
                    break;
                }
                let step = d1 / d2;
                x -= step;
                if !(a..=b).contains(&x) {
                    break;
                }
                if step.abs() <= ROOT_TOL_REL * (1.0 + x.abs()) {
                    if self.derivs(x).1 > 0.0 {
                        best.consider(self, x);
                        return;
                    }
                    break;
                }
            }
        }
        let uc = c.clamp(a, b);
        if !(self.derivs(uc).1 > 0.0) {
            // D'' ≤ 0 on the whole window: its minimum is at an end
            return;
        }
        let c1 = if self.derivs(a).1 > 0.0 {
            a
        } else {
            root_increasing(
                |x| {
                    let (_, d2, d3) = self.derivs(x);
                    (d2, d3)
                },
                a,
                uc,
                uc,
            )
        };
        let c2 = if self.derivs(b).1 > 0.0 {
            b
        } else {
            root_increasing(
                |x| {
                    let (_, d2, d3) = self.derivs(x);
                    (-d2, -d3)
                },
                uc,
                b,
                uc,
            )
        };
        let (g1, g2) = (self.derivs(c1).0, self.derivs(c2).0);
        if g1 >= 0.0 {
            // D increasing on the core (and, concave, before it): the minimum is at a
            best.consider(self, c1);
            return;
        }
        if g2 <= 0.0 {
            best.consider(self, c2);
            return;
        }
        // start from the better of the planar-angle guess (the core's centre) and the
        // normal-coordinate guess
        let h = self.helix;
        let mut x0 = uc.clamp(c1, c2);
        if h.k_mm_rad != 0.0 {
            let un = ((self.pn - h.h0_mm) / h.k_mm_rad).clamp(c1, c2);
            if self.derivs(un).0.abs() < self.derivs(x0).0.abs() {
                x0 = un;
            }
        }
        let u = root_increasing(
            |x| {
                let (d1, d2, _) = self.derivs(x);
                (d1, d2)
            },
            c1,
            c2,
            x0,
        );
        best.consider(self, u);
    }
}

/// The root of `f` (value, derivative), increasing on `[lo, hi]` with `f(lo) ≤ 0 ≤ f(hi)`:
/// Newton steps from `x0`, bisection where a step would leave the bracket.
fn root_increasing(f: impl Fn(f64) -> (f64, f64), lo: f64, hi: f64, x0: f64) -> f64 {
    let (mut lo, mut hi) = (lo, hi);
    let mut x = x0.clamp(lo, hi);
    for _ in 0..MAX_ROOT_ITERATIONS {
        let (v, dv) = f(x);
        if v == 0.0 {
            return x;
        }
        if v < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let newton = x - v / dv;
        let next = if dv > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        let tol = ROOT_TOL_REL * (1.0 + x.abs());
        if (next - x).abs() <= tol || hi - lo <= tol {
            return next;
        }
        x = next;
    }
    x
}

/// The nearest point of the path of move `m` to `p` (`None` for moves that do not move:
/// dwells, pauses, blend changes). `warm_at`: the fraction of an earlier nearby answer on
/// the same move (arcs start their search there).
pub fn nearest(p: [f64; 3], m: &Move, warm_at: Option<f64>) -> Option<Nearest> {
    match m.kind {
        MoveKind::Rapid { to } | MoveKind::Line { to, .. } => {
            let from = Vec3::from_array(m.from);
            let ab = Vec3::from_array(to) - from;
            let ap = Vec3::from_array(p) - from;
            let l2 = ab.dot(ab);
            let t = if l2 > 0.0 {
                (ap.dot(ab) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            Some(Nearest {
                dist_mm: (ap - ab.scale(t)).norm(),
                at: t,
                tangent: ab.unit_or_zero().to_array(),
            })
        }
        MoveKind::Arc { .. } => {
            let h = Helix::of(m)?;
            let (u, d) = h.nearest(p, warm_at.map(|f| f * h.sweep_rad));
            Some(Nearest {
                dist_mm: d,
                at: u / h.sweep_rad,
                tangent: h.tangent(u),
            })
        }
        MoveKind::Dwell { .. } | MoveKind::Pause | MoveKind::SetBlend(_) => None,
    }
}

/// Length of the path of move `m`, mm (0 for moves that do not move).
pub fn length(m: &Move) -> f64 {
    match m.kind {
        MoveKind::Rapid { to } | MoveKind::Line { to, .. } => {
            (Vec3::from_array(to) - Vec3::from_array(m.from)).norm()
        }
        MoveKind::Arc { .. } => Helix::of(m).map_or(0.0, |h| h.length_mm()),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::Plane;
    use controller_core::sim::rng::SplitMix64;

    /// Brute force: the least distance over a dense grid of the sweep, refined by golden
    /// section around the best grid point.
    fn brute(h: &Helix, p: [f64; 3]) -> f64 {
        let n = 200_000;
        let d = |u: f64| (Vec3::from_array(h.point(u)) - Vec3::from_array(p)).norm();
        let du = h.sweep_rad / n as f64;
        let mut best = (0usize, f64::INFINITY);
        for i in 0..=n {
            let v = d(i as f64 * du);
            if v < best.1 {
                best = (i, v);
            }
        }
        let (mut a, mut b) = (
            (best.0 as f64 - 1.0).max(0.0) * du,
            ((best.0 + 1) as f64 * du).min(h.sweep_rad),
        );
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..200 {
            let x1 = b - g * (b - a);
            let x2 = a + g * (b - a);
            if d(x1) < d(x2) {
                b = x2;
            } else {
                a = x1;
            }
        }
        d(0.5 * (a + b)).min(best.1)
    }

    fn arc_move(
        from: [f64; 3],
        to: [f64; 3],
        center: [f64; 3],
        plane: Plane,
        cw: bool,
        sweep: f64,
    ) -> Move {
        Move {
            line: 1,
            from,
            kind: MoveKind::Arc {
                to,
                center,
                plane,
                clockwise: cw,
                turns: 1,
                sweep_rad: sweep,
                feed_mm_s: 10.0,
            },
        }
    }

    /// A random helix: radius 0.3-40 mm, lead 0-100 mm per turn, up to 4 turns, a radius
    /// change within the arc tolerance, any plane and direction.
    fn random_helix(rng: &mut SplitMix64, steep: bool) -> Helix {
        let plane = [Plane::XY, Plane::ZX, Plane::YZ][(rng.next_u64() % 3) as usize];
        let [i1, i2, n] = plane.axes();
        let r0: f64 = rng.uniform(0.3, 40.0);
        let dr_total: f64 = rng.uniform(-0.005, 0.005);
        let sweep: f64 = rng.uniform(0.05, 4.0 * std::f64::consts::TAU);
        let lead: f64 = if steep {
            rng.uniform(20.0, 100.0)
        } else {
            rng.uniform(0.0, 2.0)
        };
        let rise =
            lead * sweep / std::f64::consts::TAU * if rng.next_u64() & 1 == 1 { 1.0 } else { -1.0 };
        let cw: bool = rng.next_u64() & 1 == 1;
        let psi0: f64 = rng.uniform(-3.1, 3.1);
        let mut center = [0.0; 3];
        for c in center.iter_mut() {
            *c = rng.uniform(-100.0, 100.0);
        }
        let mut from = center;
        from[i1] += r0 * psi0.cos();
        from[i2] += r0 * psi0.sin();
        let psi1 = psi0 + if cw { -sweep } else { sweep };
        let mut to = center;
        to[i1] += (r0 + dr_total) * psi1.cos();
        to[i2] += (r0 + dr_total) * psi1.sin();
        to[n] = from[n] + rise;
        center[n] = from[n];
        Helix::of(&arc_move(from, to, center, plane, cw, sweep)).unwrap()
    }

    #[test]
    fn helix_distances_match_brute_force_on_random_steep_and_flat_helices() {
        let mut rng = SplitMix64::new(11);
        let mut worst = 0.0f64;
        for case in 0..400 {
            let steep = case % 2 == 0;
            let h = random_helix(&mut rng, steep);
            // a point near the path (a random point of it moved 0.01-3 mm), or anywhere
            // around the helix's axis
            let p = if case % 3 != 0 {
                let u = rng.uniform(0.0, h.sweep_rad);
                let mut p = h.point(u);
                let off: f64 = rng.uniform(0.01, 3.0);
                let dir = Vec3::new(
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(-1.0, 1.0),
                )
                .unit_or_zero();
                for i in 0..3 {
                    p[i] += off * dir[i];
                }
                p
            } else {
                let mut p = h.point(rng.uniform(0.0, h.sweep_rad));
                for x in p.iter_mut() {
                    *x += rng.uniform(-30.0, 30.0);
                }
                p
            };
            let want = brute(&h, p);
            let warm = (rng.next_u64() & 1 == 1).then(|| rng.uniform(0.0, h.sweep_rad));
            let (u, got) = h.nearest(p, warm);
            worst = worst.max((got - want).abs());
            assert!(
                (got - want).abs() < 1e-9,
                "case {case}: {got} vs brute force {want} ({h:?}, p {p:?}, u {u})"
            );
            // the reported angle is where that distance is
            assert!(
                ((Vec3::from_array(h.point(u)) - Vec3::from_array(p)).norm() - got).abs() < 1e-12
            );
        }
        assert!(worst < 1e-9, "{worst}");
    }

    #[test]
    fn a_point_on_a_steep_helix_is_at_distance_zero_not_at_its_planar_angle() {
        // 0.86 mm radius, 85 mm lead: the planar-angle guess of a point beside the path is
        // far from its nearest point
        let r = 0.86;
        let lead = 85.0;
        let m = arc_move(
            [r, 0.0, 42.0],
            [r, 0.0, 42.0 - lead],
            [0.0, 0.0, 42.0],
            Plane::XY,
            false,
            std::f64::consts::TAU,
        );
        let h = Helix::of(&m).unwrap();
        for k in 1..50 {
            let u = k as f64 * 0.12;
            let on = h.point(u);
            let (_, d) = h.nearest(on, None);
            assert!(d < 1e-9, "{u}: {d}");
            // 0.05 mm off the path along its normal plane: exactly 0.05
            let t = Vec3::from_array(h.tangent(u));
            let radial = Vec3::new(on[0], on[1], 0.0).unit_or_zero();
            let off = (radial - t.scale(radial.dot(t))).unit_or_zero();
            let p = [
                on[0] + 0.05 * off[0],
                on[1] + 0.05 * off[1],
                on[2] + 0.05 * off[2],
            ];
            let n = nearest(p, &m, None).unwrap();
            assert!((n.dist_mm - 0.05).abs() < 1e-9, "{u}: {}", n.dist_mm);
            assert!((n.at * h.sweep_rad - u).abs() < 1e-6, "{u}: {}", n.at);
        }
    }

    #[test]
    fn line_distances_are_exact_and_clamped_to_the_ends() {
        let m = Move {
            line: 1,
            from: [0.0, 0.0, 0.0],
            kind: MoveKind::Line {
                to: [10.0, 0.0, 0.0],
                feed_mm_s: 10.0,
            },
        };
        let n = nearest([4.0, 3.0, 4.0], &m, None).unwrap();
        assert!((n.dist_mm - 5.0).abs() < 1e-15 && (n.at - 0.4).abs() < 1e-15);
        assert_eq!(n.tangent, [1.0, 0.0, 0.0]);
        let n = nearest([13.0, 4.0, 0.0], &m, None).unwrap();
        assert!((n.dist_mm - 5.0).abs() < 1e-15 && n.at == 1.0);
        let n = nearest([-3.0, 0.0, -4.0], &m, None).unwrap();
        assert!((n.dist_mm - 5.0).abs() < 1e-15 && n.at == 0.0);
    }

    #[test]
    fn length_of_a_helix_turn() {
        let m = arc_move(
            [10.0, 0.0, 0.0],
            [10.0, 0.0, -1.0],
            [0.0, 0.0, 0.0],
            Plane::XY,
            false,
            std::f64::consts::TAU,
        );
        let want = (std::f64::consts::TAU * 10.0).hypot(1.0);
        assert!((length(&m) - want).abs() < 1e-12);
    }
}
