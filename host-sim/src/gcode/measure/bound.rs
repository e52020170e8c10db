//! A lower bound on a program's machine time: no planner that keeps every axis within
//! `limits.vel/acc/jerk` (the planner's own limits) and the path within the tolerances in
//! force can run the program faster (at 100 % feed override). f64 throughout.
//!
//! **Stretches.** The program is split where every such planner must stop: the program's
//! start and end, dwells and pauses (M0), and junctions without tolerance (G61, G64 P0)
//! where the tangent jumps (a velocity direction cannot jump at speed). Every other
//! junction may be passed at speed (the planner blends every junction with a tolerance,
//! rapid-feed transitions included: controller-core `motion/planner/blend.rs`), so the
//! bound does not stop there. Splitting at fewer stops than a planner makes only lowers the
//! bound (two rest-to-rest motions in a row are one feasible motion). Dwells add their time.
//!
//! **Per stretch** `T ≥ max(T_rr, T_caps)`:
//!
//! * `T_rr`: the exact time-optimal rest-to-rest time of a 1-D motion over the stretch's
//!   length with the largest path velocity, acceleration and jerk the stretch allows
//!   ([`rest_to_rest_s`]). Along a straight stretch these are the projected limits
//!   `min_i lim_i/|t_i|` ([`directions::projected`]). A stretch that turns gets the largest
//!   speed cap on it, the largest *support* `Σ acc_i·|t_i|` over its directions (on a curve
//!   the tangential acceleration is `a·t`, which the centripetal part can push past the
//!   projected limit but never past the support), and no jerk limit (the path jerk on a
//!   curve is `j·t + v³κ²`, not bounded by the axes' jerk alone).
//! * `T_caps`: the fastest 1-D motion from rest to rest with acceleration ≤ that same `A`
//!   and a speed cap `v_cap(σ)` along the path ([`capped_time_s`]), by the forward/backward
//!   pass `v² ≤ v_prev² + 2AΔσ` over cells of constant cap (exact for piecewise-constant
//!   caps). The cap is the least of:
//!   - the programmed feed (feed moves; rapids have none);
//!   - the projected velocity limit of the path direction; near a blended corner, where the
//!     path's direction sweeps from one line's to the next, the largest projected limit
//!     over those directions ([`directions::max_projected_between`]), within the largest
//!     fillet's tangent length of the corner;
//!   - on programmed arcs, the curvature bound `v² ≤ a_n·(R + ε)`: `R` the helix's radius
//!     of curvature, ε the tolerance (a path within ε of the arc may run on a circle ε
//!     wider), `a_n = Σ acc_i·|n_i|` the largest acceleration the axes give along the
//!     principal normal `n` (the centripetal `v²κ = a·n`; at most `√Σ acc_i²`);
//!   - at a blended corner of turning angle θ and tolerance ε, `v² ≤ a_n·R` with
//!     `R = 2ε/(1 − cos(θ/2))`, the largest fillet that stays within ε of both lines allowed
//!     to bulge ε outward, `n` along the turn;
//!   - at every vertex of a run of lines (the short chords a CAM post writes), the circle
//!     through the points [`CHORD_WINDOWS_MM`] before and after along the polyline: with
//!     sagitta `h > 4ε`, any path within ε of the three points bends at least as a circle
//!     of sagitta `h − 2ε` on a chord 2ε longer, so `v ≤ √(a_n/κ)` with the largest such
//!     κ. This reads the window's bend as spread over it (a path that bends less at the
//!     vertex bends more elsewhere in the window); unlike the other caps it is not a strict
//!     pointwise bound.
//!
//!   A blend also shortens the path: at a corner within ε of the tolerance tube, by at most
//!   `min(2ε·tan(θ/2), 4ε)` (the inner side of the tube), taken off the cells at the corner,
//!   where the cap is lowest, so the bound stays below any such path.
//!
//! The programs in `host-sim/programs/` run 1.02-1.46 times this bound
//! (`time_ratio_to_bound`, docs/planner.md §3); a bound above a real run would be a bug.

use super::directions::{self, projected, support};
use super::distance::Helix;
use super::tolerance::Tolerances;
use crate::gcode::report::LimitsJson;
use crate::gcode::{Move, MoveKind, Program};
use controller_core::num::vec3::Vec3;

/// Tangent jumps at or below this are smooth: the planner neither blends nor stops
/// (controller-core `motion/planner/blend.rs`, `SMOOTH_TANGENT`).
pub const SMOOTH_TANGENT: f64 = 1.0e-6;
/// Half-lengths of the chord windows at polyline vertices, mm (a few chord lengths of a CAM
/// contour up to a few mm: short windows see tight bends, long ones shallow bends whose
/// sagitta over a short window would drown in the tolerance).
pub const CHORD_WINDOWS_MM: [f64; 3] = [0.5, 2.0, 8.0];
/// A chord window counts only when its sagitta exceeds this many tolerances (a path within
/// ε of three points can flatten the sagitta by 2ε; beyond 4ε at least half of it is left).
pub const CHORD_SAGITTA_TOLERANCES: f64 = 4.0;
/// Cells per radian of arc sweep at most: 1° cells, each capped by its largest cap.
/// A chord window counts only where the chords turn evenly (a curve, not a corner): no
/// vertex in it turns by more than this (rad)...
pub const CHORD_WINDOW_MAX_TURN_RAD: f64 = 0.35;
/// ... nor by more than this many times the window's mean turn (plus the rounding of a
/// straight run): a window's curvature holds somewhere in it, and applied at its middle it
/// must not be a nearby corner's (a corner has its own cap).
pub const CHORD_WINDOW_EVEN_TURN: f64 = 3.0;
const CHORD_WINDOW_TURN_NOISE_RAD: f64 = 1.0e-3;
pub const ARC_CELL_RAD: f64 = std::f64::consts::PI / 180.0;

/// The exact time-optimal rest-to-rest time of a 1-D motion over `len_mm` with velocity,
/// acceleration and jerk at most `v`, `a`, `j` (`j` = ∞: no jerk limit): the symmetric
/// jerk-limited S-curve (accelerate to the peak speed, cruise, mirror), s.
pub fn rest_to_rest_s(len_mm: f64, v: f64, a: f64, j: f64) -> f64 {
    if !(len_mm > 0.0) {
        return 0.0;
    }
    // time and distance to reach speed w from rest and come back to zero acceleration
    let accel = |w: f64| -> (f64, f64) {
        if j.is_finite() && w < a * a / j {
            let t = 2.0 * (w / j).sqrt();
            (t, 0.5 * w * t)
        } else {
            let t = w / a + if j.is_finite() { a / j } else { 0.0 };
            (t, 0.5 * w * t)
        }
    };
    let (t_acc, d_acc) = accel(v);
    if len_mm >= 2.0 * d_acc {
        return 2.0 * t_acc + (len_mm - 2.0 * d_acc) / v;
    }
    // the speed is not reached: the peak w with 2·d_acc(w) = len
    if !j.is_finite() {
        return 2.0 * (len_mm / a).sqrt();
    }
    if len_mm >= 2.0 * a * a * a / (j * j) {
        // acceleration a reached: len = w²/a + w·a/j
        let q = a * a / j;
        let w = 0.5 * (-q + (q * q + 4.0 * a * len_mm).sqrt());
        2.0 * (w / a + a / j)
    } else {
        // jerk phases only: len = 2w·√(w/j)
        4.0 * (0.5 * len_mm / j).cbrt()
    }
}

/// One cell of constant speed cap along the path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    pub len_mm: f64,
    pub cap_mm_s: f64,
}

/// Speed caps along a stretch: `cells`, and `points[k]` the cap at the boundary before
/// cell `k` (`points.len() == cells.len() + 1`; the first and last are 0: at rest).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Caps {
    pub cells: Vec<Cell>,
    pub points: Vec<f64>,
}

impl Caps {
    fn point(&mut self, cap: f64) {
        if self.points.len() > self.cells.len() {
            if let Some(p) = self.points.last_mut() {
                *p = p.min(cap);
            }
        } else {
            self.points.push(cap);
        }
    }

    fn cell(&mut self, len_mm: f64, cap_mm_s: f64) {
        if !(len_mm > 0.0) {
            return;
        }
        if self.points.len() == self.cells.len() {
            self.points.push(f64::INFINITY);
        }
        self.cells.push(Cell { len_mm, cap_mm_s });
    }

    fn len_mm(&self) -> f64 {
        self.cells.iter().map(|c| c.len_mm).sum()
    }

    fn max_cap(&self) -> f64 {
        self.cells.iter().map(|c| c.cap_mm_s).fold(0.0, f64::max)
    }
}

/// The fastest motion from rest to rest through `caps` with acceleration at most `a`
/// (forward and backward pass on `v²`, then each cell's accelerate-cruise-decelerate time
/// in closed form), s.
pub fn capped_time_s(caps: &Caps, a: f64) -> f64 {
    let n = caps.cells.len();
    if n == 0 || !(a > 0.0) {
        return 0.0;
    }
    let mut v2: Vec<f64> = (0..=n)
        .map(|k| {
            let mut c = caps.points.get(k).copied().unwrap_or(0.0);
            if k > 0 {
                c = c.min(caps.cells[k - 1].cap_mm_s);
            }
            if k < n {
                c = c.min(caps.cells[k].cap_mm_s);
            }
            c * c
        })
        .collect();
    v2[0] = 0.0;
    v2[n] = 0.0;
    for k in 0..n {
        v2[k + 1] = v2[k + 1].min(v2[k] + 2.0 * a * caps.cells[k].len_mm);
    }
    for k in (0..n).rev() {
        v2[k] = v2[k].min(v2[k + 1] + 2.0 * a * caps.cells[k].len_mm);
    }
    caps.cells
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let (vi2, vo2) = (v2[k], v2[k + 1]);
            let vp2 = (c.cap_mm_s * c.cap_mm_s).min(0.5 * (vi2 + vo2) + a * c.len_mm);
            let (vi, vo, vp) = (vi2.sqrt(), vo2.sqrt(), vp2.sqrt());
            let cruise = c.len_mm - (2.0 * vp2 - vi2 - vo2) / (2.0 * a);
            let t = (2.0 * vp - vi - vo) / a;
            if cruise > 0.0 && vp > 0.0 {
                t + cruise / vp
            } else {
                t
            }
        })
        .sum()
}

/// The geometry of one motion move.
#[derive(Clone, Copy, Debug)]
enum Geo {
    Line { u: [f64; 3], len: f64 },
    Arc(Helix),
}

/// How far the direction turns from the end of `before` to the start of `after`: the
/// length of the difference of the unit tangents.
fn tangent_jump(before: &Geo, after: &Geo) -> f64 {
    (Vec3::from_array(after.start_tangent()) - Vec3::from_array(before.end_tangent())).norm()
}

impl Geo {
    fn of(m: &Move) -> Option<Self> {
        match m.kind {
            MoveKind::Rapid { to } | MoveKind::Line { to, .. } => {
                let d = Vec3::from_array(to) - Vec3::from_array(m.from);
                let len = d.norm();
                (len > 0.0).then(|| Geo::Line {
                    u: d.unit_or_zero().to_array(),
                    len,
                })
            }
            MoveKind::Arc { .. } => Helix::of(m).map(Geo::Arc),
            _ => None,
        }
    }
    fn start_tangent(&self) -> [f64; 3] {
        match self {
            Geo::Line { u, .. } => *u,
            Geo::Arc(h) => h.tangent(0.0),
        }
    }
    fn end_tangent(&self) -> [f64; 3] {
        match self {
            Geo::Line { u, .. } => *u,
            Geo::Arc(h) => h.tangent(h.sweep_rad),
        }
    }
}

/// One motion move of a stretch.
struct Part {
    k: usize,
    geo: Geo,
    /// Programmed feed, mm/s (∞ for rapids).
    feed: f64,
}

/// A blended junction's effect on the caps.
#[derive(Clone, Copy, Debug, Default)]
struct Corner {
    /// Cap at the corner point, mm/s.
    cap: f64,
    /// Largest projected velocity limit of the directions between both tangents.
    vel_between: f64,
    /// How far from the corner the path's direction may differ from the lines', mm.
    zone_mm: f64,
    /// How much shorter a path within the tolerance may be, mm.
    shortcut_mm: f64,
}

const NO_CORNER: Corner = Corner {
    cap: f64::INFINITY,
    vel_between: 0.0,
    zone_mm: 0.0,
    shortcut_mm: 0.0,
};

/// The lower bound of `program`'s machine time, s.
pub fn time_bound_s(program: &Program, tol: &Tolerances, limits: &LimitsJson) -> f64 {
    let mut total = 0.0;
    let mut stretch: Vec<Part> = Vec::new();
    for (k, m) in program.moves.iter().enumerate() {
        match m.kind {
            MoveKind::Dwell { s } => {
                total += stretch_time_s(&stretch, program, tol, limits);
                stretch.clear();
                total += s.max(0.0);
            }
            MoveKind::Pause => {
                total += stretch_time_s(&stretch, program, tol, limits);
                stretch.clear();
            }
            MoveKind::SetBlend(_) => {}
            MoveKind::Rapid { .. } | MoveKind::Line { .. } | MoveKind::Arc { .. } => {
                let Some(geo) = Geo::of(m) else { continue };
                if let Some(prev) = stretch.last() {
                    let jump = tangent_jump(&prev.geo, &geo);
                    let eps = tol.after_mm.get(prev.k).copied().unwrap_or(0.0);
                    if jump > SMOOTH_TANGENT && !(eps > 0.0) {
                        total += stretch_time_s(&stretch, program, tol, limits);
                        stretch.clear();
                    }
                }
                let feed = match m.kind {
                    MoveKind::Line { feed_mm_s, .. } | MoveKind::Arc { feed_mm_s, .. } => feed_mm_s,
                    _ => f64::INFINITY,
                };
                stretch.push(Part { k, geo, feed });
            }
        }
    }
    total + stretch_time_s(&stretch, program, tol, limits)
}

/// `T ≥ max(T_rr, T_caps)` of one stretch from rest to rest.
fn stretch_time_s(parts: &[Part], program: &Program, tol: &Tolerances, lim: &LimitsJson) -> f64 {
    if parts.is_empty() {
        return 0.0;
    }
    let caps = stretch_caps(parts, program, tol, lim);
    let len = caps.len_mm();
    let straight = parts.iter().all(|p| matches!(p.geo, Geo::Line { .. }))
        && parts
            .windows(2)
            .all(|w| tangent_jump(&w[0].geo, &w[1].geo) <= SMOOTH_TANGENT);
    let (v, a, j) = if straight {
        let u = parts[0].geo.start_tangent();
        (
            projected(lim.vel, u).min(caps.max_cap()),
            projected(lim.acc, u),
            projected(lim.jerk, u),
        )
    } else {
        (caps.max_cap(), max_support(parts, lim.acc), f64::INFINITY)
    };
    if !(v > 0.0 && a > 0.0) {
        return 0.0;
    }
    rest_to_rest_s(len, v, a, j).max(capped_time_s(&caps, a))
}

/// The largest tangential acceleration `a·t` the axes give anywhere on the stretch.
fn max_support(parts: &[Part], acc: [f64; 3]) -> f64 {
    let mut best = 0.0f64;
    for (i, p) in parts.iter().enumerate() {
        best = best.max(match p.geo {
            Geo::Line { u, .. } => support(acc, u),
            Geo::Arc(h) => {
                let [i1, i2, n] = h.axes;
                let m = h.r0_mm.max(h.radius_mm(h.sweep_rad)).hypot(h.dr_mm_rad);
                let nn = m.hypot(h.k_mm_rad);
                // in-plane part along any in-plane angle, plus the normal part
                (m / nn) * acc[i1].hypot(acc[i2]) + acc[n] * h.k_mm_rad.abs() / nn
            }
        });
        if let Some(q) = parts.get(i + 1) {
            best = best.max(directions::max_support_between(
                acc,
                p.geo.end_tangent(),
                q.geo.start_tangent(),
            ));
        }
    }
    best
}

/// The corner between `a` and `b` (tolerance `eps` > 0).
fn corner(a: &Part, b: &Part, eps: f64, lim: &LimitsJson) -> Corner {
    let (ta, tb) = (a.geo.end_tangent(), b.geo.start_tangent());
    let jump = Vec3::from_array(tb) - Vec3::from_array(ta);
    if !(jump.norm() > SMOOTH_TANGENT) || !(eps > 0.0) {
        return NO_CORNER;
    }
    let theta = Vec3::from_array(ta)
        .dot(Vec3::from_array(tb))
        .clamp(-1.0, 1.0)
        .acos();
    let half = 0.5 * theta;
    let r = 2.0 * eps / (1.0 - half.cos());
    let a_n = support(lim.acc, jump.unit_or_zero().to_array());
    let vel_between = directions::max_projected_between(lim.vel, ta, tb);
    let feed = a.feed.max(b.feed);
    let zone_mm = if half.cos() > 0.0 {
        r * half.tan()
    } else {
        f64::INFINITY
    };
    // The fillet argument holds where the fillet fits on the two lines: a tiny chord's
    // corner (a CAM post's rounding makes them by the thousand) may be smoothed over its
    // neighbours instead, within the tolerance; then only the chord windows bound it.
    let fits = match (a.geo, b.geo) {
        (Geo::Line { len: la, .. }, Geo::Line { len: lb, .. }) => zone_mm <= la.min(lb),
        _ => true,
    };
    let bend = if fits {
        (a_n * r).sqrt()
    } else {
        f64::INFINITY
    };
    Corner {
        cap: bend.min(vel_between).min(feed),
        vel_between,
        zone_mm,
        shortcut_mm: (2.0 * eps * half.tan()).min(4.0 * eps),
    }
}

/// The speed caps along a stretch.
fn stretch_caps(parts: &[Part], program: &Program, tol: &Tolerances, lim: &LimitsJson) -> Caps {
    let corners: Vec<Corner> = parts
        .windows(2)
        .map(|w| {
            let eps = tol.after_mm.get(w[0].k).copied().unwrap_or(0.0);
            corner(&w[0], &w[1], eps, lim)
        })
        .collect();
    let chord = chord_caps(parts, program, tol, lim);
    let mut caps = Caps::default();
    caps.point(0.0);
    for (i, p) in parts.iter().enumerate() {
        let c_in = if i > 0 { corners[i - 1] } else { NO_CORNER };
        let c_out = corners.get(i).copied().unwrap_or(NO_CORNER);
        match p.geo {
            Geo::Line { u, len } => {
                let v_line = projected(lim.vel, u).min(p.feed);
                let z_in = c_in.zone_mm.min(0.5 * len);
                let z_out = c_out.zone_mm.min(0.5 * len);
                let v_in = v_line.max(c_in.vel_between.min(p.feed));
                let v_out = v_line.max(c_out.vel_between.min(p.feed));
                caps.cell(z_in - (0.5 * c_in.shortcut_mm).min(z_in), v_in);
                caps.cell(len - z_in - z_out, v_line);
                caps.cell(z_out - (0.5 * c_out.shortcut_mm).min(z_out), v_out);
            }
            Geo::Arc(h) => {
                let eps = tol
                    .allowed_mm
                    .get(p.k)
                    .copied()
                    .unwrap_or(0.0)
                    .max(tol.in_force_mm.get(p.k).copied().unwrap_or(0.0));
                arc_cells(&mut caps, &h, p.feed, eps, lim);
            }
        }
        if i + 1 < parts.len() {
            caps.point(
                c_out
                    .cap
                    .min(chord.get(i).copied().unwrap_or(f64::INFINITY)),
            );
        }
    }
    caps.point(0.0);
    caps
}

/// The cells of one arc: per [`ARC_CELL_RAD`] of sweep, the least of the feed, the largest
/// projected velocity limit and the largest curvature bound over the cell.
fn arc_cells(caps: &mut Caps, h: &Helix, feed: f64, eps: f64, lim: &LimitsJson) {
    let [i1, i2, n] = h.axes;
    let cells = (h.sweep_rad / ARC_CELL_RAD).ceil().max(1.0) as usize;
    let len = h.length_mm();
    let du = h.sweep_rad / cells as f64;
    let k = h.k_mm_rad;
    // the in-plane tangent is the radius vector turned by atan2(s·r, ṙ)
    let turn = (h.dir * h.r0_mm).atan2(h.dr_mm_rad);
    for c in 0..cells {
        let (ua, ub) = (c as f64 * du, (c + 1) as f64 * du);
        let (ra, rb) = (h.radius_mm(ua), h.radius_mm(ub));
        let (r_lo, r_hi) = (ra.min(rb), ra.max(rb));
        let (pa, pb) = (h.psi0_rad + h.dir * ua, h.psi0_rad + h.dir * ub);
        let (psi_lo, psi_hi) = (pa.min(pb), pa.max(pb));
        // projected velocity: (N/m)·(in-plane projected) and the normal axis' N/|k|
        let m_lo = r_lo.hypot(h.dr_mm_rad);
        let m_hi = r_hi.hypot(h.dr_mm_rad);
        let in_plane = m_lo.hypot(k) / m_lo
            * directions::max_planar_projected(
                lim.vel[i1],
                lim.vel[i2],
                psi_lo + turn,
                psi_hi + turn,
            );
        let normal = if k != 0.0 {
            lim.vel[n] * m_hi.hypot(k) / k.abs()
        } else {
            f64::INFINITY
        };
        // curvature: radius of curvature (r² + k²)/r, largest at an end of [r_lo, r_hi]
        let rc = |r: f64| (r * r + k * k) / r;
        let radius = rc(r_lo).max(rc(r_hi)) + eps;
        let a_n = directions::max_planar_support(lim.acc[i1], lim.acc[i2], psi_lo, psi_hi);
        let curve = (a_n * radius).sqrt();
        caps.cell(
            len * (ub - ua) / h.sweep_rad,
            feed.min(in_plane).min(normal).min(curve),
        );
    }
}

/// The chord-window cap at the end of each part that joins a line to a line (∞ elsewhere).
fn chord_caps(parts: &[Part], program: &Program, tol: &Tolerances, lim: &LimitsJson) -> Vec<f64> {
    let mut out = vec![f64::INFINITY; parts.len()];
    let mut i = 0;
    while i < parts.len() {
        // a run of consecutive lines
        let start = i;
        while i < parts.len() && matches!(parts[i].geo, Geo::Line { .. }) {
            i += 1;
        }
        if i - start >= 2 {
            run_caps(&parts[start..i], program, tol, lim, &mut out[start..i]);
        }
        i = i.max(start + 1);
    }
    out
}

/// Chord-window caps along one run of lines: `out[j]` at the vertex after line `j`.
fn run_caps(run: &[Part], program: &Program, tol: &Tolerances, lim: &LimitsJson, out: &mut [f64]) {
    let moves = &program.moves;
    // vertices and their arc length along the run
    let mut pts = Vec::with_capacity(run.len() + 1);
    let mut cum = Vec::with_capacity(run.len() + 1);
    pts.push(moves[run[0].k].from);
    cum.push(0.0);
    for p in run {
        if let Geo::Line { len, .. } = p.geo {
            pts.push(moves[p.k].to());
            cum.push(cum.last().copied().unwrap_or(0.0) + len);
        }
    }
    let total = cum.last().copied().unwrap_or(0.0);
    // how much the chords turn at each vertex
    let turn: Vec<f64> = (0..pts.len())
        .map(|v| {
            if v == 0 || v + 1 >= pts.len() {
                return 0.0;
            }
            let [before, here, after] = [pts[v - 1], pts[v], pts[v + 1]].map(Vec3::from_array);
            let (a, b) = (here - before, after - here);
            let (na, nb) = (a.norm(), b.norm());
            if na > 0.0 && nb > 0.0 {
                (a.dot(b) / (na * nb)).clamp(-1.0, 1.0).acos()
            } else {
                0.0
            }
        })
        .collect();
    let even = |lo: f64, hi: f64| {
        let (a, b) = (
            cum.partition_point(|&c| c < lo),
            cum.partition_point(|&c| c <= hi),
        );
        let w = turn.get(a..b).unwrap_or_default();
        if w.is_empty() {
            return false;
        }
        let max = w.iter().fold(0.0f64, |m, &x| m.max(x));
        let mean = w.iter().sum::<f64>() / w.len() as f64;
        max <= CHORD_WINDOW_MAX_TURN_RAD
            && max <= CHORD_WINDOW_EVEN_TURN * mean + CHORD_WINDOW_TURN_NOISE_RAD
    };
    let eps = run
        .iter()
        .map(|p| tol.after_mm.get(p.k).copied().unwrap_or(0.0))
        .fold(0.0, f64::max);
    let at = |s: f64| -> [f64; 3] {
        let j = cum.partition_point(|&c| c <= s).clamp(1, cum.len() - 1);
        let (s0, s1) = (cum[j - 1], cum[j]);
        let f = if s1 > s0 { (s - s0) / (s1 - s0) } else { 0.0 };
        let (a, b) = (pts[j - 1], pts[j]);
        [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * f)
    };
    for v in 1..pts.len() - 1 {
        let sv = cum[v];
        let vx = Vec3::from_array(pts[v]);
        let mut cap = f64::INFINITY;
        for l in CHORD_WINDOWS_MM {
            if sv - l < 0.0 || sv + l > total || !even(sv - l, sv + l) {
                continue;
            }
            let (pm, pp) = (Vec3::from_array(at(sv - l)), Vec3::from_array(at(sv + l)));
            let chord = pp - pm;
            let c = chord.norm();
            if !(c > 0.0) {
                continue;
            }
            let e = chord.map(|x| x / c);
            let w = vx - pm;
            let foot = pm + e.scale(w.dot(e));
            let toward = foot - vx;
            let h = toward.norm();
            if !(h > CHORD_SAGITTA_TOLERANCES * eps) {
                continue;
            }
            let (h2, c2) = (h - 2.0 * eps, c + 2.0 * eps);
            let radius = (0.25 * c2 * c2 + h2 * h2) / (2.0 * h2);
            let a_n = support(lim.acc, toward.map(|x| x / h).to_array());
            cap = cap.min((a_n * radius).sqrt());
        }
        out[v - 1] = cap;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_str;

    const LIMITS: LimitsJson = LimitsJson {
        vel: [250.0; 3],
        acc: [2000.0; 3],
        jerk: [1.0e5; 3],
    };

    fn bound(text: &str) -> f64 {
        let p = parse_str("b.nc", text).unwrap();
        let t = Tolerances::of(&p, 0.01);
        time_bound_s(&p, &t, &LIMITS)
    }

    #[test]
    fn rest_to_rest_of_the_factory_limits_in_closed_form() {
        // 100 mm: cruise at 250 mm/s after 0.145 s of S-curve (18.125 mm) each way
        assert!((rest_to_rest_s(100.0, 250.0, 2000.0, 1e5) - 0.545).abs() < 1e-12);
        // 10 mm: peak w = (−40 + √(1600 + 80000))/2 mm/s, acceleration 2000 reached
        let w = 0.5 * (-40.0 + (1600.0f64 + 80_000.0).sqrt());
        let t10 = 2.0 * (w / 2000.0 + 0.02);
        assert!((rest_to_rest_s(10.0, 250.0, 2000.0, 1e5) - t10).abs() < 1e-12);
        assert!((t10 - 0.162_829).abs() < 1e-6, "{t10}");
        // 1 mm (< 2a³/j² = 1.6 mm): jerk phases only, 4·(L/2j)^(1/3)
        let t1 = rest_to_rest_s(1.0, 250.0, 2000.0, 1e5);
        assert!((t1 - 4.0 * (5.0e-6f64).cbrt()).abs() < 1e-12);
        assert!((t1 - 0.068_399).abs() < 1e-6, "{t1}");
        // no jerk limit: bang-bang
        assert!(
            (rest_to_rest_s(1.0, 250.0, 2000.0, f64::INFINITY) - 2.0 * (1.0f64 / 2000.0).sqrt())
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn a_g61_line_along_x_and_at_45_degrees_is_its_rest_to_rest_time() {
        for len in [1.0, 10.0, 100.0] {
            let t = bound(&format!("G21 G90 G61\nG1 X{len} F15000\n"));
            let want = rest_to_rest_s(len, 250.0, 2000.0, 1e5);
            assert!((t - want).abs() < 1e-9, "{len}: {t} vs {want}");
            // along 45° in XY the projected limits are √2 larger (a feed above them)
            let d = len / 2f64.sqrt();
            let t = bound(&format!("G21 G90 G61\nG1 X{d:.12} Y{d:.12} F60000\n"));
            let s = 2f64.sqrt();
            let want = rest_to_rest_s(len, 250.0 * s, 2000.0 * s, 1e5 * s);
            assert!((t - want).abs() < 1e-9, "45° {len}: {t} vs {want}");
        }
        assert!((bound("G21 G90 G61\nG1 X100 F15000\n") - 0.545).abs() < 1e-9);
    }

    #[test]
    fn g61_corners_stop_and_dwells_add_their_time() {
        let one = rest_to_rest_s(10.0, 250.0, 2000.0, 1e5);
        let t = bound("G21 G90 G61\nG1 X10 F15000\nG1 Y10\nG4 P0.5\nG1 X0\n");
        assert!((t - (3.0 * one + 0.5)).abs() < 1e-9, "{t}");
        // blended (G64), the corner is passed at speed: less than stopping, more than one
        // straight 20 mm line
        let t = bound("G21 G90 G64 P0.01\nG1 X10 F15000\nG1 Y10\n");
        assert!(
            t < 2.0 * one && t > rest_to_rest_s(20.0, 250.0, 2000.0, 1e5) * 0.9,
            "{t}"
        );
    }

    #[test]
    fn a_circle_of_10000_chords_cruises_at_its_curvature_cap() {
        let r = 25.4;
        let n = 10_000;
        let mut text = format!("G21 G90 G61\nG0 X{r} Y0\nG64\nF30000\n");
        for k in 1..=n {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            text += &format!("G1 X{:.6} Y{:.6}\n", r * a.cos(), r * a.sin());
        }
        let p = parse_str("c.nc", &text).unwrap();
        let tol = Tolerances::of(&p, 0.01);
        let len = std::f64::consts::TAU * r;
        // the rapid alone (a G61 corner after it)
        let rapid = rest_to_rest_s(r, 250.0, 2000.0, 1e5);
        let circle = time_bound_s(&p, &tol, &LIMITS) - rapid;
        // the cap at a vertex whose bend is along an axis: √(2000·R') with R' the 8 mm
        // window's reduced circle, ≈ √(2000·25.4) = 225 mm/s
        let parts: Vec<Part> = p
            .moves
            .iter()
            .enumerate()
            .filter_map(|(k, m)| {
                let geo = Geo::of(m)?;
                matches!(m.kind, MoveKind::Line { .. }).then_some(Part {
                    k,
                    geo,
                    feed: 500.0,
                })
            })
            .collect();
        let caps = chord_caps(&parts, &p, &tol, &LIMITS);
        let at_y_axis = caps[n / 4 - 1];
        assert!(
            (at_y_axis - (2000.0f64 * r).sqrt()).abs() < 0.01 * 225.4,
            "{at_y_axis}"
        );
        // between all caps at 225 (bend along an axis) and all at √(2828·R) (at 45°):
        // the circle takes at least L/cap plus the acceleration from and to rest
        let slow = (2000.0f64 * 25.9).sqrt();
        let fast = (2000.0f64 * 2f64.sqrt() * 25.9).sqrt();
        assert!(
            circle > len / fast && circle < len / slow + 2.0 * slow / 2000.0,
            "{circle}"
        );
    }

    #[test]
    fn capped_time_of_one_cell_is_accelerate_cruise_decelerate() {
        let caps = Caps {
            cells: vec![Cell {
                len_mm: 100.0,
                cap_mm_s: 250.0,
            }],
            points: vec![0.0, 0.0],
        };
        // 2·(250/2000) s to accelerate and brake over 2·15.625 mm, the rest at 250
        let want = 0.25 + (100.0 - 31.25) / 250.0;
        assert!((capped_time_s(&caps, 2000.0) - want).abs() < 1e-12);
        // too short to reach the cap: 2·√(L/a)
        let caps = Caps {
            cells: vec![Cell {
                len_mm: 1.0,
                cap_mm_s: 250.0,
            }],
            points: vec![0.0, 0.0],
        };
        assert!((capped_time_s(&caps, 2000.0) - 2.0 * (1.0f64 / 2000.0).sqrt()).abs() < 1e-12);
    }
}
