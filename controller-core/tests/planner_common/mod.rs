//! Shared helpers of the planner integration tests: running a program through the
//! planner + executor, checking per-axis limits on the samples, and measuring the distance
//! of the samples from the programmed path.
#![allow(dead_code)]

use controller_core::motion::planner::{
    MotionPlanner, PathSample, Plane, PlannerConfig, PlannerState, Segment, GANTRY_PLANNER,
};

pub type Mp = MotionPlanner<64, 256, 128, 32>;

pub fn config() -> PlannerConfig {
    GANTRY_PLANNER
}

/// A programmed piece for distance measurements.
#[derive(Clone, Copy, Debug)]
pub enum Prog {
    Line {
        a: [f32; 3],
        b: [f32; 3],
    },
    Arc {
        start: [f32; 3],
        end: [f32; 3],
        center: [f32; 3],
        plane: Plane,
        cw: bool,
        turns: u32,
    },
    /// The circular arc from `start` through `via` to `end` (`Segment::arc_through`).
    Through {
        start: [f32; 3],
        via: [f32; 3],
        end: [f32; 3],
    },
}

fn d3(a: [f32; 3]) -> [f64; 3] {
    a.map(f64::from)
}
fn sub64(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot64(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross64(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Distance from `p` to the arc from `start` through `via` to `end` (f64, exact: the
/// nearest point of the full circle, or an end point where that lies off the arc).
pub fn through_distance(p: [f32; 3], start: [f32; 3], via: [f32; 3], end: [f32; 3]) -> f64 {
    let s0 = d3(start);
    let a = sub64(d3(via), s0);
    let b = sub64(d3(end), s0);
    let axb = cross64(a, b);
    let n2 = dot64(axb, axb);
    let m = sub64(b.map(|x| x * dot64(a, a)), a.map(|x| x * dot64(b, b)));
    let c = cross64(m, axb).map(|x| x * 0.5 / n2);
    let r = dot64(c, c).sqrt();
    let n = axb.map(|x| x / n2.sqrt());
    let e1 = c.map(|x| -x / r);
    let e2 = cross64(n, e1);
    let ang = |q: [f64; 3]| {
        let v = sub64(q, c);
        dot64(v, e2)
            .atan2(dot64(v, e1))
            .rem_euclid(std::f64::consts::TAU)
    };
    let sweep = ang(b);
    let q = sub64(d3(p), s0);
    let h = dot64(sub64(q, c), n);
    let inplane = sub64(sub64(q, c), n.map(|x| x * h));
    let rho = dot64(inplane, inplane).sqrt();
    let on_arc = ang(q) <= sweep;
    let to_end = |e: [f64; 3]| norm(sub64(q, e));
    if on_arc && rho > 0.0 {
        (h * h + (rho - r) * (rho - r)).sqrt()
    } else {
        to_end([0.0; 3]).min(to_end(b))
    }
}

/// Runs `segs` from `start` (streaming them in as slots free up) until the machine is
/// idle; calls `each` before every period with the period index. Returns the samples.
pub fn run_with(
    mp: &mut Mp,
    segs: &[Segment],
    max_periods: usize,
    mut each: impl FnMut(usize, &mut Mp),
) -> Vec<PathSample> {
    let mut out = Vec::new();
    let mut next = 0;
    let mut quiet = 0;
    for n in 0..max_periods {
        while next < segs.len() && mp.push(&segs[next]).is_ok() {
            next += 1;
        }
        each(n, mp);
        out.push(mp.tick());
        if next == segs.len() && mp.is_idle() && mp.planner_status().state == PlannerState::Idle {
            quiet += 1;
            if quiet > 50 {
                break;
            }
        } else {
            quiet = 0;
        }
    }
    out
}

pub fn run(mp: &mut Mp, segs: &[Segment], max_periods: usize) -> Vec<PathSample> {
    run_with(mp, segs, max_periods, |_, _| {})
}

/// Largest ratios |v_i|/vmax_i, |a_i|/amax_i, |Δa_i/T|/jmax_i over all samples.
pub fn limit_ratios(samples: &[PathSample], cfg: &PlannerConfig) -> (f32, f32, f32) {
    let (mut rv, mut ra, mut rj) = (0.0f32, 0.0f32, 0.0f32);
    for (k, s) in samples.iter().enumerate() {
        let v = s.vel_mm_s.to_array();
        let a = s.acc_mm_s2.to_array();
        for i in 0..3 {
            rv = rv.max(v[i].abs() / cfg.vel_max_mm_s[i]);
            ra = ra.max(a[i].abs() / cfg.acc_max_mm_s2[i]);
        }
        if k > 0 {
            let a0 = samples[k - 1].acc_mm_s2.to_array();
            for i in 0..3 {
                let j = (a[i] - a0[i]) / cfg.period_s;
                rj = rj.max(j.abs() / cfg.jerk_max_mm_s3[i]);
            }
        }
    }
    (rv, ra, rj)
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f64; 3] {
    [
        a[0] as f64 - b[0] as f64,
        a[1] as f64 - b[1] as f64,
        a[2] as f64 - b[2] as f64,
    ]
}
fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn plane_axes(p: Plane) -> (usize, usize, usize) {
    match p {
        Plane::XY => (0, 1, 2),
        Plane::ZX => (2, 0, 1),
        Plane::YZ => (1, 2, 0),
    }
}

/// Distance from `p` to a programmed piece (f64).
pub fn distance(p: [f32; 3], g: &Prog) -> f64 {
    match *g {
        Prog::Through { start, via, end } => through_distance(p, start, via, end),
        Prog::Line { a, b } => {
            let ab = sub(b, a);
            let ap = sub(p, a);
            let l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
            let t = if l2 > 0.0 {
                ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            norm([ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]])
        }
        Prog::Arc {
            start,
            end,
            center,
            plane,
            cw,
            turns,
        } => {
            // Sample the helix finely and refine around the nearest sample.
            let (i1, i2, n) = plane_axes(plane);
            let c = [center[0] as f64, center[1] as f64, center[2] as f64];
            let a0 = start[i1] as f64 - c[i1];
            let b0 = start[i2] as f64 - c[i2];
            let a1 = end[i1] as f64 - c[i1];
            let b1 = end[i2] as f64 - c[i2];
            let (r0, r1) = (a0.hypot(b0), a1.hypot(b1));
            let psi0 = b0.atan2(a0);
            let mut d = b1.atan2(a1) - psi0;
            let tau = std::f64::consts::TAU;
            while d > std::f64::consts::PI {
                d -= tau;
            }
            while d <= -std::f64::consts::PI {
                d += tau;
            }
            let full = (a1 - a0).hypot(b1 - b0) < 1e-3;
            let sweep = if cw {
                (if full || d >= 0.0 { d - tau } else { d }) - tau * turns as f64
            } else {
                (if full || d <= 0.0 { d + tau } else { d }) + tau * turns as f64
            };
            let rise = end[n] as f64 - start[n] as f64;
            let at = |f: f64| {
                let psi = psi0 + sweep * f;
                let r = r0 + (r1 - r0) * f;
                let mut q = c;
                q[i1] += r * psi.cos();
                q[i2] += r * psi.sin();
                q[n] = start[n] as f64 + rise * f;
                q
            };
            let pd = [p[0] as f64, p[1] as f64, p[2] as f64];
            let dist = |f: f64| {
                let q = at(f);
                norm([pd[0] - q[0], pd[1] - q[1], pd[2] - q[2]])
            };
            // Coarse samples (≤ 0.05 rad apart), then a ternary search around every
            // coarse local minimum (a point near the start of a turn can be closest to the
            // end of the previous one).
            let m = ((sweep.abs() / 0.05).ceil() as usize).max(16);
            let coarse: Vec<f64> = (0..=m).map(|k| dist(k as f64 / m as f64)).collect();
            let mut best = f64::INFINITY;
            for k in 0..=m {
                let left = if k > 0 { coarse[k - 1] } else { f64::INFINITY };
                let right = if k < m { coarse[k + 1] } else { f64::INFINITY };
                if coarse[k] > left || coarse[k] > right {
                    continue;
                }
                let (mut lo, mut hi) = (
                    (k as f64 - 1.0).max(0.0) / m as f64,
                    (k as f64 + 1.0).min(m as f64) / m as f64,
                );
                for _ in 0..60 {
                    let m1 = lo + (hi - lo) / 3.0;
                    let m2 = hi - (hi - lo) / 3.0;
                    if dist(m1) < dist(m2) {
                        hi = m2;
                    } else {
                        lo = m1;
                    }
                }
                best = best.min(dist(0.5 * (lo + hi))).min(coarse[k]);
            }
            best
        }
    }
}

/// Largest distance of the samples from the programmed path.
pub fn max_deviation(samples: &[PathSample], prog: &[Prog]) -> f64 {
    let mut worst = 0.0f64;
    for s in samples {
        let p = s.pos_mm.to_array();
        let d = prog
            .iter()
            .map(|g| distance(p, g))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    worst
}

/// Lines through `pts` as segments and programmed pieces.
pub fn polyline(pts: &[[f32; 3]], feed: f32) -> (Vec<Segment>, Vec<Prog>) {
    let mut segs = Vec::new();
    let mut prog = Vec::new();
    for (k, w) in pts.windows(2).enumerate() {
        segs.push(Segment::line(w[1], feed, k as u32 + 1));
        prog.push(Prog::Line { a: w[0], b: w[1] });
    }
    (segs, prog)
}
