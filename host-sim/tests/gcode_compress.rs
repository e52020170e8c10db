//! The path compressor's bound, measured: on every program of the set, every merged
//! primitive (as the planner gets it: f32 start, via and end) lies within its fit budget of
//! the chords it replaces and every chord within it of the primitive, by dense sampling in
//! both directions (the sampling step is added to what is measured, so a pass is a proof
//! up to the step).

use host_sim::gcode::compress::{budget_mm, groups, Primitive, MAX_FIT_SHARE};
use host_sim::gcode::{parse_str, Blend, MoveKind, Program};

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: V) -> f64 {
    dot(a, a).sqrt()
}
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn lerp(a: V, b: V, t: f64) -> V {
    [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * t)
}
fn f32r(p: V) -> V {
    p.map(|x| f64::from(x as f32))
}

fn seg_dist(p: V, a: V, b: V) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(ab, ab);
    let t = if l2 > 0.0 {
        (dot(sub(p, a), ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm(sub(p, lerp(a, b, t)))
}

/// A primitive as points along it: `at(u)` for u in [0, 1], and its length.
struct Curve {
    start: V,
    kind: Primitive,
    // arc: centre, radius, frame, sweep
    c: V,
    r: f64,
    e1: V,
    e2: V,
    sweep: f64,
}

impl Curve {
    fn new(start: V, kind: Primitive) -> Self {
        let mut k = Curve {
            start,
            kind,
            c: [0.0; 3],
            r: 0.0,
            e1: [0.0; 3],
            e2: [0.0; 3],
            sweep: 0.0,
        };
        if let Primitive::Arc { via, to } = kind {
            let (u, w) = (sub(via, start), sub(to, start));
            let axb = cross(u, w);
            let n2 = dot(axb, axb);
            let m = sub(w.map(|x| x * dot(u, u)), u.map(|x| x * dot(w, w)));
            let c = cross(m, axb).map(|x| x * 0.5 / n2);
            let r = norm(c);
            let n = axb.map(|x| x / n2.sqrt());
            k.e1 = c.map(|x| -x / r);
            k.e2 = cross(n, k.e1);
            let pe = sub(w, c);
            k.sweep = dot(pe, k.e2)
                .atan2(dot(pe, k.e1))
                .rem_euclid(std::f64::consts::TAU);
            k.c = c;
            k.r = r;
        }
        k
    }
    fn len(&self) -> f64 {
        match self.kind {
            Primitive::Line { to } => norm(sub(to, self.start)),
            Primitive::Arc { .. } => self.r * self.sweep,
        }
    }
    fn at(&self, u: f64) -> V {
        match self.kind {
            Primitive::Line { to } => lerp(self.start, to, u),
            Primitive::Arc { .. } => {
                let a = self.sweep * u;
                [0, 1, 2].map(|i| {
                    self.start[i]
                        + self.c[i]
                        + self.r * (a.cos() * self.e1[i] + a.sin() * self.e2[i])
                })
            }
        }
    }
}

/// Distance from `p` to the primitive (exact: the nearest point of the segment, or of the
/// full circle where it lies on the arc, else the nearer end).
fn dist_to(curve: &Curve, p: V) -> f64 {
    match curve.kind {
        Primitive::Line { to } => seg_dist(p, curve.start, to),
        Primitive::Arc { .. } => {
            let n = cross(curve.e1, curve.e2);
            let q = sub(sub(p, curve.start), curve.c);
            let h = dot(q, n);
            let (x, y) = (dot(q, curve.e1), dot(q, curve.e2));
            let ang = y.atan2(x).rem_euclid(std::f64::consts::TAU);
            if ang <= curve.sweep {
                let rho = x.hypot(y);
                (h * h + (rho - curve.r) * (rho - curve.r)).sqrt()
            } else {
                norm(sub(p, curve.at(0.0))).min(norm(sub(p, curve.at(1.0))))
            }
        }
    }
}

/// The two-sided distance between a merged primitive and the chords through `pts`,
/// sampled with step `h` (a lower bound of the true one, within `h` of it): the
/// primitive's points to the chords (a window of chords following the walk), the chords'
/// points to the primitive (exact).
fn two_sided(curve: &Curve, pts: &[V], h: f64) -> f64 {
    let n = ((curve.len() / h).ceil() as usize).max(8);
    let mut worst = 0.0f64;
    let mut j = 0usize;
    for k in 0..=n {
        let p = curve.at(k as f64 / n as f64);
        let lo = j.saturating_sub(2);
        let hi = (j + 24).min(pts.len() - 1);
        let (mut best, mut at) = (f64::INFINITY, j);
        for i in lo..hi {
            let d = seg_dist(p, pts[i], pts[i + 1]);
            if d < best {
                best = d;
                at = i;
            }
        }
        j = at;
        worst = worst.max(best);
    }
    for w in pts.windows(2) {
        let m = ((norm(sub(w[1], w[0])) / h).ceil() as usize).max(1);
        for k in 0..=m {
            worst = worst.max(dist_to(curve, lerp(w[0], w[1], k as f64 / m as f64)));
        }
    }
    worst
}

/// Checks every merged group of `program`; returns (chords, primitives).
fn check(name: &str, program: &Program, default_tol: f64) -> (usize, usize) {
    let (gs, stats) = groups(program, default_tol);
    let mut blend = Blend::MachineDefault;
    let mut merged = 0;
    for g in &gs {
        let first = &program.moves[g.moves.start];
        if let MoveKind::SetBlend(b) = first.kind {
            blend = b;
        }
        let Some(prim) = g.merged else { continue };
        merged += 1;
        let budget = budget_mm(blend, default_tol, program.coordinate_resolution_mm);
        let p_tol = match blend {
            Blend::Tolerance { mm, .. } => mm,
            _ => default_tol,
        };
        assert!(budget > 0.0 && budget <= MAX_FIT_SHARE * p_tol, "{name}");
        assert!(g.dev_mm <= budget, "{name}: dev {} > {budget}", g.dev_mm);
        let mut pts = vec![first.from];
        pts.extend(program.moves[g.moves.clone()].iter().map(|m| m.to()));
        let curve = Curve::new(f32r(first.from), prim);
        // sampled, the deviation never exceeds the bound the compressor claims (the true one
        // lies within a sampling step of the samples; the claim is proven in compress.rs)
        let d = two_sided(&curve, &pts, (0.25 * budget).max(1e-6));
        assert!(
            d <= g.dev_mm + 1e-9,
            "{name}: moves {:?}: sampled two-sided {d} mm > claimed {} mm",
            g.moves,
            g.dev_mm
        );
    }
    assert_eq!(merged, stats.merged);
    (stats.chords, merged)
}

fn circle_of_chords(n: usize, r: f64, decimals: i32, mode: &str) -> String {
    let k = 10f64.powi(decimals);
    let mut s = format!("G21 G90 {mode}\nG0 X{r:.4} Y0\n");
    for i in 1..=n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        s += &format!(
            "G1 X{:.4} Y{:.4} F100000\n",
            (r * a.cos() * k).round() / k,
            (r * a.sin() * k).round() / k
        );
    }
    s + "M2\n"
}

fn surface_raster() -> String {
    // a smooth 3-D surface in 0.3 mm chords, rows 1 mm apart, G64 P0.0254 (0.001 in)
    let mut s = String::from("G21 G90 G64 P0.0254\nG0 X-30 Y-20 Z5\n");
    for row in 0..40 {
        let y = -20.0 + row as f64;
        let xs: Vec<f64> = (0..=200).map(|k| -30.0 + 0.3 * k as f64).collect();
        let xs: Vec<f64> = if row % 2 == 0 {
            xs
        } else {
            xs.into_iter().rev().collect()
        };
        for x in xs {
            let z = 2.0 * (x / 12.0).sin() * (y / 17.0).cos() - 1.0;
            s += &format!("G1 X{x:.4} Y{y:.4} Z{z:.4} F3000\n");
        }
    }
    s + "M2\n"
}

#[test]
fn merged_primitives_stay_within_their_budget_of_the_chords() {
    let programs = [
        ("circle", circle_of_chords(10_000, 25.4, 4, "G64")),
        // 0.44 mm chords: their sagitta (0.95 µm) needs a budget above it
        ("circle_coarse", circle_of_chords(360, 25.4, 4, "G64 P0.05")),
        (
            "collinear",
            (1..=3000).fold(String::from("G21 G90 G64\n"), |s, k| {
                s + &format!("G1 X{:.4} F6000\n", 0.0254 * k as f64)
            }),
        ),
        ("surface", surface_raster()),
        (
            "dense_contour",
            std::fs::read_to_string(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/programs/dense_contour.nc"
            ))
            .unwrap(),
        ),
    ];
    for (name, text) in programs {
        let p = parse_str(name, &text).unwrap();
        let (chords, merged) = check(name, &p, 0.01);
        println!("{name}: {chords} chords into {merged} primitives");
        assert!(
            merged > 0 && merged * 3 < chords,
            "{name}: {merged} of {chords}"
        );
    }
}

#[test]
fn what_may_not_be_merged_is_not() {
    // G61 and G61.1, Q0, rapids, a feed change, programmed arcs: all kept as they are
    for text in [
        "G21 G90 G61\nG1 X1 F600\nX2\nX3\nX4\n",
        "G21 G90 G61.1\nG1 X1 F600\nX2\nX3\nX4\n",
        "G21 G90 G64 P0.1 Q0\nG1 X1 F600\nX2\nX3\nX4\n",
        "G21 G90 G64 P0.1\nG0 X1\nX2\nX3\nX4\n",
        "G21 G90 G64 P0.1\nG1 X1 F600\nX2 F700\nX3 F800\nX4 F900\n",
    ] {
        let p = parse_str("k.nc", text).unwrap();
        let (gs, stats) = groups(&p, 0.01);
        assert_eq!(stats.merged, 0, "{text}");
        assert!(gs.iter().all(|g| g.moves.len() == 1 && g.merged.is_none()));
    }
    // the same collinear moves under G64 P0.1 merge into one line
    let p = parse_str("m.nc", "G21 G90 G64 P0.1\nG1 X1 F600\nX2\nX3\nX4\n").unwrap();
    let (gs, stats) = groups(&p, 0.01);
    assert_eq!(stats.merged, 1);
    assert!(gs.iter().any(|g| g.moves.len() == 4));
}
