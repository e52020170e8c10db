//! A G-code program as the machine gets it: parsed in the machine's context (its work
//! offsets and tool table), checked against its travel, and mapped to the planner's
//! segments (with the path compressor's merges and the blend in force at each).

use crate::gcode::{self, check_travel, compress, MoveKind, ParseOptions, Program, Travel};
use anyhow::{anyhow, Result};
use controller_core::motion::planner::{Blend, Segment};
use controller_core::settings::{Settings, FACTORY, TOOL_COUNT};
use controller_core::sim::run::RunConfig;
use std::ops::Range;
use std::path::Path;

fn f32s(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// One planner segment and the program moves it covers.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanSegment {
    /// What the planner gets; its `tag` is the index of the first move it covers (so
    /// `program.moves[tag].line` is its G-code line).
    pub seg: Segment,
    /// Indices into `program.moves` of the moves the segment covers.
    pub moves: Range<usize>,
}

/// The planner segments of `program`: the one place that maps program moves to planner
/// segments. Today each covers exactly its one move (`i..i + 1`); blend changes (SetBlend)
/// are covered by none.
pub fn segments(program: &Program, default_tol_mm: f64) -> (Vec<PlanSegment>, compress::Stats) {
    let (groups, stats) = compress::groups(program, default_tol_mm);
    let mut blend = Blend::Default;
    // (the tolerance in force per segment, for the blends after merged ones)
    let mut out: Vec<(PlanSegment, f64, Option<f64>)> = Vec::with_capacity(groups.len());
    for g in &groups {
        let i = g.moves.start;
        let Some(m) = program.moves.get(i) else {
            continue;
        };
        let tag = u32::try_from(i).unwrap_or(u32::MAX);
        let seg = if let Some(prim) = g.merged {
            let feed = g.feed_mm_s as f32;
            match prim {
                compress::Primitive::Line { to } => Segment::line(f32s(to), feed, tag),
                compress::Primitive::Arc { via, to } => {
                    Segment::arc_through(f32s(via), f32s(to), feed, tag)
                }
            }
        } else {
            match m.kind {
                MoveKind::Rapid { to } => Segment::rapid(f32s(to), tag),
                MoveKind::Line { to, feed_mm_s } => Segment::line(f32s(to), feed_mm_s as f32, tag),
                MoveKind::Arc {
                    to,
                    center,
                    plane,
                    clockwise,
                    turns,
                    feed_mm_s,
                    ..
                } => Segment::arc(
                    f32s(to),
                    f32s(center),
                    plane,
                    clockwise,
                    turns.saturating_sub(1),
                    feed_mm_s as f32,
                    tag,
                ),
                MoveKind::Dwell { s } => Segment::dwell(s as f32, tag),
                // the simulated operator resumes at once: M0 is an exact stop
                MoveKind::Pause => Segment::dwell(0.0, tag),
                MoveKind::SetBlend(b) => {
                    blend = match b {
                        // G61.1: the machine comes to rest at the end of every move
                        gcode::Blend::ExactStop => Blend::ExactStop,
                        // G61: every programmed point exactly; with a tolerance of 0 the
                        // planner stops at corners and passes smooth junctions (collinear
                        // lines, a line tangent to an arc) without stopping, as LinuxCNC's
                        // exact path
                        gcode::Blend::ExactPath => Blend::Tolerance(0.0),
                        // (the naive-CAM tolerance Q is the path compressor's; the planner
                        // blends within P)
                        gcode::Blend::Tolerance { mm, .. } => Blend::Tolerance(mm as f32),
                        gcode::Blend::MachineDefault => Blend::Default,
                    };
                    continue;
                }
            }
        };
        let (seg, tol) = match seg.motion {
            controller_core::motion::planner::Motion::Dwell { .. } => (seg, None),
            _ => (
                seg.with_blend(blend),
                match blend {
                    Blend::Tolerance(e) => Some(f64::from(e)),
                    Blend::Default => Some(default_tol_mm),
                    Blend::ExactStop => None,
                },
            ),
        };
        out.push((
            PlanSegment {
                seg,
                moves: g.moves.clone(),
            },
            g.dev_mm,
            tol,
        ));
    }
    // The blend after a merged primitive (or before one) keeps the commanded path within P
    // of the programmed chords: it gets what the primitives' fit left of P
    // (gcode::compress, "The bound").
    for k in 0..out.len() {
        let dev_next = out.get(k + 1).map_or(0.0, |n| n.1);
        let (ps, dev, tol) = &mut out[k];
        let worst = dev.max(dev_next);
        if let (true, Some(p)) = (worst > 0.0, *tol) {
            ps.seg.blend = Blend::Tolerance(((p - worst).max(0.0)) as f32);
        }
    }
    (out.into_iter().map(|(ps, _, _)| ps).collect(), stats)
}

/// An `f32` setting as the decimal it was written as (0.01, not 0.009999999776).
pub fn decimal(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// The travel the program is checked against: the machine's soft limits (an unlimited
/// side is given a bound far beyond any program).
pub fn travel_of(cfg: &RunConfig) -> Result<Travel> {
    let big = gcode::MAX_WORD_MAGNITUDE;
    let t = cfg.servo.travel.axes.map(|a| {
        [
            if a.min_mm.is_finite() {
                f64::from(a.min_mm)
            } else {
                -big
            },
            if a.max_mm.is_finite() {
                f64::from(a.max_mm)
            } else {
                big
            },
        ]
    });
    Travel::new(t).map_err(|e| anyhow!("the machine's travel: {e}"))
}

/// The interpreter's machine context from a machine's `settings`: its work coordinate
/// systems and tool table (each value as the decimal it was written as), the program
/// starting at `start_mm`.
pub fn parse_options(settings: &Settings, start_mm: [f64; 3]) -> ParseOptions {
    ParseOptions {
        start_mm,
        work_offsets_mm: settings.work.to_array().map(|w| w.map(decimal)),
        tools: (1..=TOOL_COUNT)
            .filter_map(|n| settings.tool.get(n))
            .map(|t| gcode::Tool {
                length_mm: decimal(t.length_mm),
                diameter_mm: decimal(t.diameter_mm),
            })
            .collect(),
        ..ParseOptions::default()
    }
}

/// Parse and check `program` from `start_mm` with the factory settings' work offsets and
/// tool table (nothing runs).
pub fn load_program(
    path: &Path,
    start_mm: [f64; 3],
    travel: &Travel,
) -> Result<Program, gcode::Error> {
    load_program_with(path, &parse_options(&FACTORY, start_mm), travel)
}

/// Parse `program` in the machine context `options` and check it against the travel in
/// machine coordinates (work offsets and tool length applied; nothing runs).
pub fn load_program_with(
    path: &Path,
    options: &ParseOptions,
    travel: &Travel,
) -> Result<Program, gcode::Error> {
    let p = gcode::parse_file_with(path, options)?;
    check_travel(&p, travel)?;
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_cover_the_motion_moves_in_order_and_are_tagged_with_their_first() {
        let p = gcode::parse_str(
            "s.nc",
            "G21 G90 G61\nG0 X10\nG64 P0.02\nG1 X20 F600\nG4 P0.5\nG3 X20 Y0 I-5 J0\nM0\nG1 Y5\n",
        )
        .unwrap();
        let (segs, _) = segments(&p, 0.01);
        let mut covered = vec![0u32; p.moves.len()];
        let mut end = 0;
        for s in &segs {
            assert_eq!(s.seg.tag as usize, s.moves.start);
            assert!(s.moves.start >= end && s.moves.end > s.moves.start);
            end = s.moves.end;
            for k in s.moves.clone() {
                covered[k] += 1;
            }
        }
        for (m, n) in p.moves.iter().zip(&covered) {
            let want = u32::from(!matches!(m.kind, MoveKind::SetBlend(_)));
            assert_eq!(*n, want, "{m:?}");
        }
        // today one segment per move; the G1 under G64 P0.02 carries its tolerance
        assert_eq!(segs.len(), 6);
        assert!(segs.iter().all(|s| s.moves.len() == 1));
        assert_eq!(segs[1].seg.blend, Blend::Tolerance(0.02));
        assert_eq!(segs[0].seg.blend, Blend::Tolerance(0.0));
    }
}
