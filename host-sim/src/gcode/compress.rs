//! Path compression: runs of short G1 chords turned into fewer, longer primitives (lines
//! and circular arcs in planes of any orientation) before the planner sees them, within
//! the program's own tolerance. CAM posts write curves as thousands of chords of a few
//! hundredths of a millimetre; sent one by one they fill the planner's look-ahead with
//! under a millimetre of path and cap the feed at "must be able to stop within the queue",
//! and the chord ends' rounding (4 decimals) puts curvature noise into the blends.
//!
//! # What is merged
//! Consecutive G1 moves at one feed under one G64 P Q (LinuxCNC's naive-CAM detector,
//! generalised from collinear runs to arcs): never rapids, programmed arcs, dwells, or
//! moves under G61/G61.1 (tolerance 0), and never across a change of feed or path mode.
//! Q = 0 turns it off (LinuxCNC); without Q it is P (the parser's job).
//!
//! # The bound
//! A primitive replaces the chords `P_i … P_j` and passes through `P_i` and `P_j` (their
//! f32 roundings, which the planner gets anyway). It is accepted only if its two-sided
//! distance to the polyline is at most the fit budget `b` (below): every point of the
//! primitive lies within `b` of a chord of the run and every point of the run's chords
//! within `b` of the primitive. The check, for distances `d_k` of the vertices from the
//! primitive and the vertices' positions along it increasing (no chord runs backwards):
//! * a line: the distance to a segment is convex along a chord, so a chord's points are
//!   within `max(d_k, d_k+1)`; the segment's points lie between two consecutive vertices'
//!   projections, within the same of the chord between them;
//! * an arc of radius R: a chord's points are within `max(d_k, d_k+1) + s` of the arc and
//!   the arc's within the same of the chord, with `s = R − √(R² − c²/4)` the sagitta of an
//!   arc chord of length `c ≤ |P_k P_k+1| + d_k + d_k+1` (the chord between the vertices'
//!   nearest arc points is within `max(d)` of the programmed chord, linearly; the arc
//!   within `s` of its chord).
//!
//! The budget: `b = min(Q, FIT_SHARE · P) − PLANNER_MARGIN_MM`, raised (up to
//! `MAX_FIT_SHARE · P`) to what the program's own rounding needs (`ROUNDING_STEPS` of
//! its coordinate step). The planner's blend at a
//! junction after a merged primitive gets `P − max(dev of the two primitives it joins)`,
//! where `dev` is the primitive's measured deviation (≤ b): the blend keeps the commanded
//! path within that of the primitives (`motion::planner::blend`), so the commanded path
//! stays within P of the programmed chords everywhere. `tests/gcode_compress.rs` checks
//! the bound by dense sampling on every program of the benchmark set.
//!
//! # Cost
//! Greedy, from each run start: the longest primitive found by doubling the span of
//! chords, then bisecting between the last fit and the first miss; each test is linear in
//! the chords it spans, so a run of n chords costs O(n log n) (a 170,000-line program
//! compresses in well under a second).

use super::{Blend, MoveKind, Program};
use controller_core::num::vec3::Vec3;
use std::ops::Range;

/// Share of a run's path tolerance P the compressor may use; the planner's blends at the
/// junctions get the rest (plus whatever the fit did not use). A tenth: a CAM post's
/// 4-decimal rounding (±0.05 µm) is far below it, curves still merge into long arcs, and
/// the commanded path stays close to the chords (`dense_contour.nc` on the simulated
/// gantry: contour RMS 1.2 µm with a tenth, 2.6 µm with a quarter, 4.2 µm with half).
pub const FIT_SHARE: f64 = 0.1;
/// The most of P the compressor takes where the program's own rounding needs more than
/// [`FIT_SHARE`] (a G20 program written with 4 decimals moves its points by up to
/// 1.27 µm: with the default 10 µm tolerance a tenth would merge nothing).
pub const MAX_FIT_SHARE: f64 = 0.5;
/// The budget a program's rounding needs, in steps of its coordinates: twice the largest
/// displacement of a point rounded on three axes (√3 · step / 2).
pub const ROUNDING_STEPS: f64 = 1.732_050_807_568_877_2;

/// Kept out of the fit budget for the planner's own numbers: its span fit (2e-5 mm), the
/// f32 arc through three points and f32 positions near 150 mm (≤ 1e-5 mm each).
pub const PLANNER_MARGIN_MM: f64 = 5.0e-5;
/// Largest arc radius the compressor emits (mm); the planner takes up to 10 m. Flatter
/// runs are lines within any tolerance worth merging at.
pub const MAX_ARC_RADIUS_MM: f64 = 5.0e3;
/// Largest arc sweep the compressor emits (rad): half a turn keeps the three points
/// well apart on the circle (a full circle of chords becomes two arcs).
pub const MAX_ARC_SWEEP_RAD: f64 = std::f64::consts::PI;
/// Smallest fit budget worth compressing for (mm): below it (a P of a few µm) the chords
/// go to the planner as they are.
pub const MIN_BUDGET_MM: f64 = 1.0e-4;

/// A merged primitive, in machine mm. `via` and `to` are the f32 values the planner gets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    Line {
        to: [f64; 3],
    },
    /// The arc from the start through `via` to `to` (less than half a turn).
    Arc {
        via: [f64; 3],
        to: [f64; 3],
    },
}

/// How one stretch of the program goes to the planner.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    /// The program moves it covers (indices into `Program::moves`).
    pub moves: Range<usize>,
    /// `Some`: the moves merged into one primitive at `feed_mm_s`; `None`: the single move
    /// as programmed.
    pub merged: Option<Primitive>,
    pub feed_mm_s: f64,
    /// Largest two-sided distance of the primitive from the moves' chords (bound above),
    /// mm; 0 for a move as programmed.
    pub dev_mm: f64,
}

/// Compression counts of a program (keys of the `cargo sim gcode` JSON's `compression`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Stats {
    /// Feed moves considered (G1 under G64 with a budget).
    pub chords: usize,
    /// Primitives they became.
    pub merged: usize,
    pub arcs: usize,
    pub lines: usize,
}

type V = [f64; 3];
/// The vector algebra's type (points stay arrays, as the program and the planner have them).
type V3 = Vec3<f64>;

/// The point as the planner gets it (f32 on the link).
fn f32r(p: V) -> V {
    p.map(|x| f64::from(x as f32))
}

/// The fit budget of a run under `blend` (the planner's configured tolerance for
/// `MachineDefault`) for a program written in steps of `resolution_mm`: 0 where nothing
/// may be merged.
pub fn budget_mm(blend: Blend, default_tol_mm: f64, resolution_mm: f64) -> f64 {
    let (p, q) = match blend {
        Blend::Tolerance { mm, naive_cam_mm } => (mm, naive_cam_mm),
        Blend::MachineDefault => (default_tol_mm, default_tol_mm),
        Blend::ExactPath | Blend::ExactStop => (0.0, 0.0),
    };
    let share = (FIT_SHARE * p)
        .max(ROUNDING_STEPS * resolution_mm)
        .min(MAX_FIT_SHARE * p);
    let b = q.min(share) - PLANNER_MARGIN_MM;
    if b >= MIN_BUDGET_MM {
        b
    } else {
        0.0
    }
}

/// Deviation of the line from `pts[0]` to `pts[last]` from the chords through `pts`, if
/// within `tol` and no chord runs backwards along it.
fn line_fit(pts: &[V], tol: f64) -> Option<f64> {
    let (&a, &b) = (pts.first()?, pts.last()?);
    let (a, b) = (V3::from_array(f32r(a)), V3::from_array(f32r(b)));
    let d = b - a;
    let len = d.norm();
    if !(len > 0.0) {
        return None;
    }
    let u = d.scale(1.0 / len);
    let mut dev = 0.0f64;
    let mut last_t = 0.0;
    for &p in pts {
        let p = V3::from_array(p);
        let q = p - a;
        let t = q.dot(u);
        if t < last_t - 1e-9 || t > len + tol {
            return None;
        }
        last_t = t.max(last_t);
        // distance to the segment (beyond its ends: to the end point)
        let off = if t < 0.0 {
            q.norm()
        } else if t > len {
            (p - b).norm()
        } else {
            (q - u.scale(t)).norm()
        };
        dev = dev.max(off);
        if dev > tol {
            return None;
        }
    }
    Some(dev)
}

/// The circle through three points (relative to the first): centre offset, radius and
/// unit normal (the points run counter-clockwise about it).
fn circle(a: V3, m: V3, b: V3) -> Option<(V3, f64, V3)> {
    let (u, w) = (m - a, b - a);
    let axb = u.cross(w);
    let n2 = axb.dot(axb);
    if !(n2 > (1e-12 * u.dot(u) * w.dot(w))) {
        return None;
    }
    let c = (w.scale(u.dot(u)) - u.scale(w.dot(w)))
        .cross(axb)
        .scale(0.5 / n2);
    Some((c, c.norm(), axb.scale(1.0 / n2.sqrt())))
}

/// The arc from `pts[0]` through the vertex nearest half the run's length to
/// `pts[last]`: its via point and deviation from the chords, if within `tol`.
fn arc_fit(pts: &[V], cum: &[f64], tol: f64) -> Option<(V, f64)> {
    let n = pts.len();
    if n < 3 {
        return None;
    }
    let half = 0.5 * cum.last()?;
    let m = cum
        .iter()
        .enumerate()
        .skip(1)
        .take(n - 2)
        .min_by(|x, y| (x.1 - half).abs().total_cmp(&(y.1 - half).abs()))?
        .0;
    let (a, via, b) = (f32r(pts[0]), f32r(pts[m]), f32r(pts[n - 1]));
    let (c, r, nrm) = circle(V3::from_array(a), V3::from_array(via), V3::from_array(b))?;
    if !(r <= MAX_ARC_RADIUS_MM) {
        return None;
    }
    let e1 = c.scale(-1.0 / r);
    let e2 = nrm.cross(e1);
    let angle = |p: V| {
        let q = V3::from_array(p) - V3::from_array(a) - c;
        q.dot(e2).atan2(q.dot(e1)).rem_euclid(std::f64::consts::TAU)
    };
    let sweep = angle(b);
    if !(sweep <= MAX_ARC_SWEEP_RAD) {
        return None;
    }
    let mut dev = 0.0f64;
    let mut last = (0.0f64, 0.0f64, pts[0]);
    for (k, &p) in pts.iter().enumerate() {
        let q = V3::from_array(p) - V3::from_array(a) - c;
        let h = q.dot(nrm);
        let inplane = q - nrm.scale(h);
        let rho = inplane.norm();
        let mut th = angle(p);
        // (the first and last vertex sit at 0 and `sweep` up to rounding; a rounding just
        // below 0 reads as almost 2π)
        if th > sweep + 0.5 * (std::f64::consts::TAU - sweep) {
            th -= std::f64::consts::TAU;
        }
        // (the ends may sit a rounding off the arc's ends: an angle of the tolerance)
        let slack = tol / r;
        if k > 0 && th < last.0 - 1e-12 {
            return None;
        }
        if th > sweep + slack || th < -slack {
            return None;
        }
        let d = (h * h + (rho - r) * (rho - r)).sqrt();
        if k > 0 {
            let chord = (V3::from_array(p) - V3::from_array(last.2)).norm() + d + last.1;
            let half_c = 0.5 * chord;
            if half_c >= r {
                return None;
            }
            let sag = r - (r * r - half_c * half_c).sqrt();
            dev = dev.max(d.max(last.1) + sag);
            if dev > tol {
                return None;
            }
        }
        last = (th, d, p);
    }
    Some((via, dev))
}

/// The best primitive over `pts` (line preferred), with its deviation.
fn fit(pts: &[V], cum: &[f64], tol: f64) -> Option<(Primitive, f64)> {
    let to = f32r(*pts.last()?);
    if let Some(dev) = line_fit(pts, tol) {
        return Some((Primitive::Line { to }, dev));
    }
    arc_fit(pts, cum, tol).map(|(via, dev)| (Primitive::Arc { via, to }, dev))
}

/// Greedy compression of one run of chords through `pts` (`pts[0]` the start): the
/// primitives as (index of their last point, primitive, deviation).
pub fn compress_run(pts: &[V], tol: f64) -> Vec<(usize, Primitive, f64)> {
    let mut cum = Vec::with_capacity(pts.len());
    let mut s = 0.0;
    for (k, p) in pts.iter().enumerate() {
        if k > 0 {
            s += (V3::from_array(*p) - V3::from_array(pts[k - 1])).norm();
        }
        cum.push(s);
    }
    let n = pts.len();
    let mut out = Vec::new();
    let mut i = 0;
    while i + 1 < n {
        let span = |j: usize| {
            let base = cum[i];
            let c: Vec<f64> = cum[i..=j].iter().map(|x| x - base).collect();
            fit(&pts[i..=j], &c, tol)
        };
        // one chord always fits (a line through its own ends)
        let mut best = (
            i + 1,
            Primitive::Line {
                to: f32r(pts[i + 1]),
            },
            0.0,
        );
        let mut step = 2;
        let mut miss = None;
        while best.0 < n - 1 {
            let j = (i + step).min(n - 1);
            match span(j) {
                Some((p, d)) => best = (j, p, d),
                None => {
                    miss = Some(j);
                    break;
                }
            }
            step *= 2;
        }
        if let Some(mut hi) = miss {
            let mut lo = best.0;
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                match span(mid) {
                    Some((p, d)) => {
                        best = (mid, p, d);
                        lo = mid;
                    }
                    None => hi = mid,
                }
            }
        }
        out.push(best);
        i = best.0;
    }
    out
}

/// How the program's moves go to the planner: runs of mergeable G1 moves compressed, every
/// other move on its own. `default_tol_mm` is the planner's tolerance of G64 without P.
pub fn groups(program: &Program, default_tol_mm: f64) -> (Vec<Group>, Stats) {
    let moves = &program.moves;
    let mut out = Vec::with_capacity(moves.len());
    let mut stats = Stats::default();
    let mut blend = Blend::MachineDefault;
    let mut k = 0;
    while k < moves.len() {
        let m = &moves[k];
        if let MoveKind::SetBlend(b) = m.kind {
            blend = b;
        }
        let budget = budget_mm(blend, default_tol_mm, program.coordinate_resolution_mm);
        let feed = match m.kind {
            MoveKind::Line { feed_mm_s, .. } if budget > 0.0 => Some(feed_mm_s),
            _ => None,
        };
        let Some(feed) = feed else {
            out.push(Group {
                moves: k..k + 1,
                merged: None,
                feed_mm_s: 0.0,
                dev_mm: 0.0,
            });
            k += 1;
            continue;
        };
        // the run: G1 moves at this feed, nothing else in between
        let mut end = k;
        let mut pts = vec![m.from];
        while let Some(MoveKind::Line { to, feed_mm_s }) = moves.get(end).map(|m| m.kind) {
            if feed_mm_s != feed {
                break;
            }
            pts.push(to);
            end += 1;
        }
        stats.chords += end - k;
        let mut first = 0;
        for (last, prim, dev) in compress_run(&pts, budget) {
            if last - first == 1 {
                // a single chord: the move as programmed
                out.push(Group {
                    moves: k + first..k + last,
                    merged: None,
                    feed_mm_s: 0.0,
                    dev_mm: 0.0,
                });
            } else {
                stats.merged += 1;
                match prim {
                    Primitive::Arc { .. } => stats.arcs += 1,
                    Primitive::Line { .. } => stats.lines += 1,
                }
                out.push(Group {
                    moves: k + first..k + last,
                    merged: Some(prim),
                    feed_mm_s: feed,
                    dev_mm: dev,
                });
            }
            first = last;
        }
        k = end;
    }
    (out, stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collinear_chords_become_one_line_and_a_circle_two_arcs() {
        let pts: Vec<V> = (0..=3000).map(|k| [0.0254 * k as f64, 0.0, 0.0]).collect();
        let r = compress_run(&pts, 0.005);
        assert_eq!(r.len(), 1);
        assert!(matches!(r[0].1, Primitive::Line { .. }));
        let rad = 25.4;
        let pts: Vec<V> = (0..=10_000)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 10_000.0;
                // rounded to 4 decimals as a CAM post writes them
                [
                    (rad * a.cos() * 1e4).round() / 1e4,
                    (rad * a.sin() * 1e4).round() / 1e4,
                    0.0,
                ]
            })
            .collect();
        let r = compress_run(&pts, 0.005);
        assert!(r.len() <= 3, "{} primitives", r.len());
        assert!(r
            .iter()
            .all(|x| matches!(x.1, Primitive::Arc { .. }) && x.2 <= 0.005));
    }

    #[test]
    fn a_corner_is_kept() {
        let pts = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
        ];
        let r = compress_run(&pts, 0.01);
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].0, 2);
    }

    #[test]
    fn a_run_that_turns_back_is_not_one_line() {
        // back and forth along X (within any tolerance of the line, but reversing)
        let pts = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
        ];
        let r = compress_run(&pts, 0.01);
        assert!(r.len() >= 2, "{r:?}");
    }
}
