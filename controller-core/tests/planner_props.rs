//! Property test over random segment chains: lines (long, short and tiny), reversals and
//! near-tangent (0.1°) joins, arcs in all three planes, both directions, helices and extra
//! turns, rapids, random feeds (5–400 mm/s) and blend tolerances (exact stop to 1 mm),
//! with a feed hold/resume and a feed override change at random times. On every sample, every axis stays within
//! (1 + 1e-3)× its velocity and acceleration limit and its jerk, taken as the finite
//! difference of the acceleration over one period, within (1 + 1e-3)× its limit. The
//! 1e-3 is f32 rounding headroom: the limits are enforced exactly in the construction
//! (Bernstein bounds of the executed polynomials, per-span path limits), the observed
//! ratios stay at 1 + 1e-5 or below. The path ends on the programmed end point, the
//! look-ahead never slips and the samples stay within the largest ε of the program.

use crate::planner_common;
use controller_core::motion::planner::{Blend, Feed, Motion, Plane, Segment};
use planner_common::*;
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Gen {
    Line {
        d: [f32; 3],
        tiny: bool,
    },
    /// Back along the previous direction (reversal) or a slight turn (near-tangent).
    Turn {
        back: bool,
        len: f32,
    },
    Arc {
        plane: u8,
        cw: bool,
        r: f32,
        a0: f32,
        sweep: f32,
        rise: f32,
        turns: u32,
    },
    /// An arc through a point in a plane of any orientation (`Segment::arc_through`).
    Through {
        r: f32,
        tilt: f32,
        yaw: f32,
        a0: f32,
        sweep: f32,
    },
}

fn gen_seg() -> impl Strategy<Value = (Gen, f32, u8, bool)> {
    let line = (
        prop::array::uniform3(-12.0f32..12.0),
        prop::bool::weighted(0.15),
    )
        .prop_map(|(d, tiny)| Gen::Line { d, tiny });
    let arc = (
        0u8..3,
        any::<bool>(),
        0.5f32..15.0,
        0.0f32..std::f32::consts::TAU,
        0.2f32..6.0,
        -4.0f32..4.0,
        prop::bool::weighted(0.1),
    )
        .prop_map(|(plane, cw, r, a0, sweep, rise, extra)| Gen::Arc {
            plane,
            cw,
            r,
            a0,
            sweep,
            rise,
            turns: extra as u32,
        });
    let turn = (any::<bool>(), 0.1f32..8.0).prop_map(|(back, len)| Gen::Turn { back, len });
    let through = (
        0.5f32..40.0,
        -3.0f32..3.0,
        -3.2f32..3.2,
        0.0f32..std::f32::consts::TAU,
        0.05f32..6.0,
    )
        .prop_map(|(r, tilt, yaw, a0, sweep)| Gen::Through {
            r,
            tilt,
            yaw,
            a0,
            sweep,
        });
    (
        prop_oneof![3 => line, 2 => arc, 1 => turn, 2 => through],
        5.0f32..400.0,
        0u8..7,
        prop::bool::weighted(0.1),
    )
}

fn build(chain: &[(Gen, f32, u8, bool)]) -> (Vec<Segment>, Vec<Prog>, f32) {
    let mut pos = [0.0f32; 3];
    let mut dir = [1.0f32, 0.0, 0.0];
    let mut segs = Vec::new();
    let mut prog = Vec::new();
    let mut eps_max = 0.0f32;
    for (k, (g, feed, blend, rapid)) in chain.iter().enumerate() {
        let tag = k as u32 + 1;
        let eps = [0.0f32, 0.002, 0.01, 0.01, 0.05, 0.2, 1.0][*blend as usize];
        eps_max = eps_max.max(eps);
        let blend = if *blend == 0 {
            Blend::ExactStop
        } else {
            Blend::Tolerance(eps)
        };
        match *g {
            Gen::Line { d, tiny } => {
                let k = if tiny { 0.01 } else { 1.0 };
                let end = [pos[0] + d[0] * k, pos[1] + d[1] * k, pos[2] + d[2] * k];
                let feed = if *rapid {
                    Feed::Rapid
                } else {
                    Feed::MmPerS(*feed)
                };
                segs.push(Segment {
                    motion: Motion::Line { end_mm: end, feed },
                    blend,
                    tag,
                });
                prog.push(Prog::Line { a: pos, b: end });
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if l > 1e-3 {
                    dir = [d[0] / l, d[1] / l, d[2] / l];
                }
                pos = end;
            }
            Gen::Turn { back, len } => {
                // Reversal, or 0.1° off the previous direction.
                let d = if back {
                    [-dir[0], -dir[1], -dir[2]]
                } else {
                    let (c, sn) = (0.1f32.to_radians().cos(), 0.1f32.to_radians().sin());
                    [dir[0] * c - dir[1] * sn, dir[0] * sn + dir[1] * c, dir[2]]
                };
                let end = [
                    pos[0] + d[0] * len,
                    pos[1] + d[1] * len,
                    pos[2] + d[2] * len,
                ];
                segs.push(Segment::line(end, *feed, tag).with_blend(blend));
                prog.push(Prog::Line { a: pos, b: end });
                dir = d;
                pos = end;
            }
            Gen::Arc {
                plane,
                cw,
                r,
                a0,
                sweep,
                rise,
                turns,
            } => {
                let plane = [Plane::XY, Plane::ZX, Plane::YZ][plane as usize];
                let (i1, i2, n) = match plane {
                    Plane::XY => (0, 1, 2),
                    Plane::ZX => (2, 0, 1),
                    Plane::YZ => (1, 2, 0),
                };
                let mut center = pos;
                center[i1] -= r * a0.cos();
                center[i2] -= r * a0.sin();
                let a1 = if cw { a0 - sweep } else { a0 + sweep };
                let mut end = center;
                end[i1] += r * a1.cos();
                end[i2] += r * a1.sin();
                end[n] = pos[n] + rise;
                segs.push(
                    Segment::arc(end, center, plane, cw, turns, *feed, tag).with_blend(blend),
                );
                prog.push(Prog::Arc {
                    start: pos,
                    end,
                    center,
                    plane,
                    cw,
                    turns,
                });
                pos = end;
            }
            Gen::Through {
                r,
                tilt,
                yaw,
                a0,
                sweep,
            } => {
                let n = [tilt.sin() * yaw.cos(), tilt.sin() * yaw.sin(), tilt.cos()];
                let h = if n[0].abs() < 0.9 {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                };
                let u = [
                    h[1] * n[2] - h[2] * n[1],
                    h[2] * n[0] - h[0] * n[2],
                    h[0] * n[1] - h[1] * n[0],
                ];
                let lu = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
                let u = u.map(|x| x / lu);
                let w = [
                    n[1] * u[2] - n[2] * u[1],
                    n[2] * u[0] - n[0] * u[2],
                    n[0] * u[1] - n[1] * u[0],
                ];
                let at = |ang: f32| {
                    let (c, s) = (ang.cos() - a0.cos(), ang.sin() - a0.sin());
                    [0, 1, 2].map(|i| pos[i] + r * (c * u[i] + s * w[i]))
                };
                let (via, end) = (at(a0 + 0.5 * sweep), at(a0 + sweep));
                segs.push(Segment::arc_through(via, end, *feed, tag).with_blend(blend));
                prog.push(Prog::Through {
                    start: pos,
                    via,
                    end,
                });
                pos = end;
            }
        }
    }
    (segs, prog, eps_max)
}

/// Cases per run: 96 by default (keeps `cargo test` quick); `PROPTEST_CASES=3000` (with
/// `--release`) is the soak run quoted in docs/planner.md.
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(96)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn random_chains_stay_within_the_limits(
        chain in prop::collection::vec(gen_seg(), 2..7),
        hold in prop::option::weighted(0.3, (0usize..20_000, 1usize..3000)),
        ovr in prop::option::weighted(0.3, (0usize..20_000, 0.05f32..2.0)),
    ) {
        let cfg = config();
        let (segs, prog, eps_max) = build(&chain);
        let mut mp = Mp::new(&cfg, [0.0; 3]).unwrap();
        let s = run_with(&mut mp, &segs, 3_000_000, |n, mp| {
            if let Some((at, dur)) = hold {
                if n == at {
                    mp.hold();
                }
                if n == at + dur {
                    mp.resume();
                }
            }
            if let Some((at, r)) = ovr {
                if n == at {
                    mp.set_feed_override(r).unwrap();
                }
            }
        });
        let (rv, ra, rj) = limit_ratios(&s, &cfg);
        prop_assert!(rv <= 1.0 + 1e-3, "velocity ratio {}", rv);
        prop_assert!(ra <= 1.0 + 1e-3, "acceleration ratio {}", ra);
        prop_assert!(rj <= 1.0 + 1e-3, "jerk ratio {}", rj);
        prop_assert_eq!(mp.planner_status().slips, 0);
        let end = mp.end_position_mm();
        let last = s.last().unwrap().pos_mm.to_array();
        for i in 0..3 {
            prop_assert!((last[i] - end[i]).abs() < 2e-4, "ended at {:?}, programmed {:?}", last, end);
        }
        prop_assert!(s.windows(2).all(|w| w[0].tag <= w[1].tag));
        // Deviation on every 25th sample (the distance to arcs is costly).
        let sub: Vec<_> = s.iter().step_by(25).copied().collect();
        let dev = max_deviation(&sub, &prog);
        prop_assert!(dev <= eps_max as f64 + 1e-4, "deviation {} > ε {}", dev, eps_max);
    }
}
