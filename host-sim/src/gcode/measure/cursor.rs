//! The nearest programmed point to a moving point (the executed reference, the tool),
//! searched only near where the program is: within the program moves the current planner
//! segment covers plus [`NEIGHBOUR_MOVES`] on each side (a blend reaches one junction into
//! the next segment), and within that range only from the last nearest move forward as far
//! as the point can have travelled since the last sample (a segment may cover 10,000 tiny
//! moves: no scan over all of them per sample). A neighbouring pass of a zigzag that
//! happens to lie closer is never found: the distance is to the part of the program the
//! tool is on.

use super::distance::{self, Nearest};
use crate::gcode::{Move, MoveKind};
use controller_core::num::vec3::Vec3;
use std::ops::Range;

/// Program moves beyond the current segment's on each side that are always searched (a
/// blend reaches across one junction; two keep a junction between short moves in reach).
pub const NEIGHBOUR_MOVES: usize = 2;
/// Path length searched behind the last nearest point and beyond what the point can have
/// travelled, mm: the nearest programmed point jumps ahead of the point itself where a
/// blend crosses a corner's bisector (by up to the blend's length) and trails it where the
/// tool lags the reference.
pub const REACH_MARGIN_MM: f64 = 0.5;
/// A blend of tolerance ε reaches at most 6ε/|Δu| along each line (blend.rs: δ = |Δu|·d/6);
/// the margin adds this many tolerances (a 1/3-turn corner, |Δu| = 1.5, reaches 4ε).
pub const REACH_TOLERANCES: f64 = 8.0;

/// The programmed path: the moves, their lengths and bounding boxes.
pub struct ProgramPath<'a> {
    pub moves: &'a [Move],
    pub len_mm: Vec<f64>,
    /// Axis-aligned boxes of the arcs (`None` for other moves), to skip far ones cheaply.
    boxes: Vec<Option<[[f64; 2]; 3]>>,
}

impl<'a> ProgramPath<'a> {
    pub fn new(moves: &'a [Move]) -> Self {
        Self {
            moves,
            len_mm: moves.iter().map(distance::length).collect(),
            boxes: moves
                .iter()
                .map(|m| matches!(m.kind, MoveKind::Arc { .. }).then(|| m.extent_mm()))
                .collect(),
        }
    }

    /// Lower bound of the distance from `p` to move `k` (its box; 0 for lines).
    fn box_distance(&self, k: usize, p: [f64; 3]) -> f64 {
        match self.boxes.get(k).copied().flatten() {
            Some(b) => {
                let d = [0, 1, 2].map(|i| (b[i][0] - p[i]).max(p[i] - b[i][1]).max(0.0));
                Vec3::from_array(d).norm()
            }
            None => 0.0,
        }
    }
}

/// The nearest point found: on move `k`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Found {
    pub k: usize,
    pub near: Nearest,
}

/// The search state of one moving point.
#[derive(Clone, Debug, Default)]
pub struct PathCursor {
    /// Last nearest move and the fraction along it.
    at: Option<(usize, f64)>,
}

impl PathCursor {
    /// The nearest programmed point to `p` on the moves `covered` (the current segment's)
    /// ± [`NEIGHBOUR_MOVES`], searched from the last nearest point back by `margin_mm` and
    /// forward by `reach_mm` of path (∞: the whole range, for a first sample).
    pub fn nearest(
        &mut self,
        p: [f64; 3],
        path: &ProgramPath,
        covered: Range<usize>,
        reach_mm: f64,
        margin_mm: f64,
    ) -> Option<Found> {
        let n = path.moves.len();
        let lo = covered.start.saturating_sub(NEIGHBOUR_MOVES).min(n);
        let hi = covered.end.saturating_add(NEIGHBOUR_MOVES).min(n);
        if lo >= hi {
            return None;
        }
        // from the last nearest point, but not before the current segment (the tag says the
        // program has reached it)
        let (c, f) = match self.at {
            Some((k, f)) if (covered.start..hi).contains(&k) => (k, f),
            _ => (covered.start.clamp(lo, hi - 1), 0.0),
        };
        let len = |k: usize| path.len_mm.get(k).copied().unwrap_or(0.0);
        let mut best: Option<Found> = None;
        // `later`: on a tie the move further along wins (a move that doubles back over the
        // last one must take the cursor with it)
        let test = |k: usize, warm: Option<f64>, later: bool, best: &mut Option<Found>| {
            let bound = best.map_or(f64::INFINITY, |b| b.near.dist_mm);
            if path.box_distance(k, p) > bound || (!later && path.box_distance(k, p) == bound) {
                return;
            }
            if let Some(near) = path
                .moves
                .get(k)
                .and_then(|m| distance::nearest(p, m, warm))
            {
                if near.dist_mm < bound || (later && near.dist_mm <= bound) {
                    *best = Some(Found { k, near });
                }
            }
        };
        test(c, Some(f), true, &mut best);
        // forward: the rest of move c, then whole moves while within reach
        let mut walked = len(c) * (1.0 - f);
        for k in (c + 1)..hi {
            if walked >= reach_mm {
                break;
            }
            test(k, None, true, &mut best);
            walked += len(k);
        }
        // back: the part of move c behind, then whole moves within the margin
        let mut walked = len(c) * f;
        for k in (lo..c).rev() {
            if walked >= margin_mm {
                break;
            }
            test(k, None, false, &mut best);
            walked += len(k);
        }
        if let Some(b) = best {
            self.at = Some((b.k, b.near.at));
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_str;

    #[test]
    fn a_closer_neighbouring_pass_is_not_the_nearest_point() {
        // a zigzag of 10 mm passes 0.2 mm apart
        let mut text = String::from("G21 G90 G64 P0.01\nG1 X0 Y0 F600\n");
        for k in 1..=20 {
            let x = if k % 2 == 1 { 10.0 } else { 0.0 };
            text += &format!("G1 X{x}\nG1 Y{:.1}\n", 0.2 * k as f64);
        }
        let p = parse_str("z.nc", &text).unwrap();
        let path = ProgramPath::new(&p.moves);
        // pass 5 (line 11) at Y0.8, pass 6 (line 13) at Y1.0, two moves later
        let pass = p.moves.iter().position(|m| m.line == 11).unwrap();
        assert_eq!(p.moves[pass + 2].from[1], 1.0);
        // a point 0.15 mm beside pass 5 toward pass 6 (0.05 mm from it), on pass 5's
        // segment
        let q = [5.0, 0.95, 0.0];
        let mut cur = PathCursor::default();
        let f = cur.nearest(q, &path, pass..pass + 1, 0.1, 0.1).unwrap();
        // pass 6 is within the segment's neighbours but not within reach of the cursor
        assert_eq!(f.k, pass, "{f:?}");
        assert!((f.near.dist_mm - 0.15).abs() < 1e-12, "{f:?}");
    }

    #[test]
    fn a_segment_of_many_tiny_moves_is_walked_from_the_last_nearest_move() {
        // 20,000 chords of 0.005 mm along X, all in one "segment"
        let mut text = String::from("G21 G90 G64 P0.01\nG1 X0 Y0 F600\n");
        for k in 1..=20_000 {
            text += &format!("X{:.4}\n", 0.005 * k as f64);
        }
        let p = parse_str("c.nc", &text).unwrap();
        let path = ProgramPath::new(&p.moves);
        let all = 0..p.moves.len();
        let mut cur = PathCursor::default();
        let mut x = 0.0;
        while x < 99.0 {
            x += 0.025; // 250 mm/s for 0.1 ms
            let f = cur
                .nearest([x, 0.003, 0.0], &path, all.clone(), 0.03, 0.05)
                .unwrap();
            assert!((f.near.dist_mm - 0.003).abs() < 1e-12);
            let m = &p.moves[f.k];
            assert!(m.from[0] <= x + 1e-9 && m.to()[0] >= x - 1e-9, "{x}: {f:?}");
        }
    }
}
