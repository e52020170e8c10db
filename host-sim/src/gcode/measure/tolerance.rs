//! The path tolerance in force at every program move, from the program's blend modes
//! (G61/G64), as the planner applies them: the blend mode in force at a move governs the
//! junction after it ([`Segment::blend`](controller_core::motion::planner::Segment)), a
//! dwell or pause stops (no blend next to it), and the program starts and ends at rest.

use crate::gcode::{self, MoveKind, Program};

/// The planner's span fit: every span's polynomial stays within this of the exact curve, mm
/// (controller-core `motion::planner::span::FIT_TOL_MM`).
pub const PLANNER_FIT_MM: f64 = controller_core::motion::planner::span::FIT_TOL_MM as f64;
/// f32 rounding of the executed reference across the path, mm. Positions are f32: half an
/// ulp is 3.8e-6 mm at 64-128 mm and 7.6e-6 mm at 128-256 mm from the origin, and the span
/// fit mostly stays well inside its bound; G61 lines, arcs and a three-turn helix up to
/// 140 mm from the origin deviate by at most 1.94e-5 mm in all (measured with `cargo sim
/// gcode`), inside the fit plus this.
pub const F32_POSITION_ROUNDING_MM: f64 = 5.0e-6;
/// Numerical slack on top of the tolerance in force before a deviation counts as a
/// violation near the origin, mm: the span fit plus the f32 rounding (2.5e-5 mm); farther
/// out it grows with the f32 resolution ([`slack_mm`]).
pub const TOLERANCE_SLACK_MM: f64 = PLANNER_FIT_MM + F32_POSITION_ROUNDING_MM;

/// f32 units in the last place the executed reference may be off by at a position (the
/// span polynomial's Horner sum and the arc geometry in f32): measured up to 2.1 at
/// 61 mm from the origin (a 36 mm-radius G61 circle deviates by 3.27e-5 mm).
pub const F32_POSITION_ULPS: f64 = 4.0;

/// The slack at position `p` (mm): [`TOLERANCE_SLACK_MM`], or the span fit plus
/// [`F32_POSITION_ULPS`] of the f32 resolution at the largest coordinate, whichever is
/// more (3.5e-5 mm at 32-64 mm, 5.1e-5 mm at 64-128 mm, 8.1e-5 mm at 128-256 mm).
pub fn slack_mm(p: [f64; 3]) -> f64 {
    let m = p.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let ulp = if m >= f64::from(f32::MIN_POSITIVE) {
        (m.log2().floor() - 23.0).exp2()
    } else {
        0.0
    };
    TOLERANCE_SLACK_MM.max(PLANNER_FIT_MM + F32_POSITION_ULPS * ulp)
}

/// The tolerance a blend mode allows, mm: G64 P ε → ε, G64 → the configured default,
/// G61 and G61.1 → 0 (no blend: corners are passed exactly, stopping where the tangent
/// jumps; G61.1 stops at every move).
pub fn blend_tolerance_mm(blend: gcode::Blend, default_mm: f64) -> f64 {
    match blend {
        gcode::Blend::ExactStop | gcode::Blend::ExactPath => 0.0,
        gcode::Blend::Tolerance { mm, .. } => mm,
        gcode::Blend::MachineDefault => default_mm,
    }
}

/// Whether a move has a path (the moves distances are measured to).
pub fn moves_the_tool(kind: &MoveKind) -> bool {
    matches!(
        kind,
        MoveKind::Rapid { .. } | MoveKind::Line { .. } | MoveKind::Arc { .. }
    )
}

/// Whether a move is a feed move (G1/G2/G3).
pub fn is_feed(kind: &MoveKind) -> bool {
    matches!(kind, MoveKind::Line { .. } | MoveKind::Arc { .. })
}

/// The tolerances of one program, per move (indices into `program.moves`).
#[derive(Clone, Debug, PartialEq)]
pub struct Tolerances {
    /// The tolerance of the blend mode in force at the move, mm.
    pub in_force_mm: Vec<f64>,
    /// The tolerance at the junction after the move, mm: its mode's, but 0 after the last
    /// motion, next to a dwell or pause, and after moves that do not move.
    pub after_mm: Vec<f64>,
    /// How far the executed path may be from the programmed one where its nearest
    /// programmed point is on the move: the larger tolerance of the junctions at both of
    /// its ends, mm (without [`TOLERANCE_SLACK_MM`]).
    pub allowed_mm: Vec<f64>,
    /// The configured default (G64 without P, and before any G61/G64), mm.
    pub default_mm: f64,
}

impl Tolerances {
    pub fn of(program: &Program, default_mm: f64) -> Self {
        let moves = &program.moves;
        let n = moves.len();
        let mut in_force_mm = Vec::with_capacity(n);
        // the planner's segments start in the configured default (segments())
        let mut blend = gcode::Blend::MachineDefault;
        for m in moves {
            if let MoveKind::SetBlend(b) = m.kind {
                blend = b;
            }
            in_force_mm.push(blend_tolerance_mm(blend, default_mm));
        }
        // the junction after move k joins it to the next move that moves or stops
        let mut after_mm = vec![0.0; n];
        let mut next_stops = true; // after the last motion: the program's end
        for k in (0..n).rev() {
            let kind = &moves[k].kind;
            match kind {
                MoveKind::SetBlend(_) => continue,
                MoveKind::Dwell { .. } | MoveKind::Pause => {
                    next_stops = true;
                    continue;
                }
                _ => {}
            }
            after_mm[k] = if next_stops { 0.0 } else { in_force_mm[k] };
            next_stops = false;
        }
        let mut allowed_mm = vec![0.0; n];
        let mut before = 0.0; // the program's start
        for k in 0..n {
            match moves[k].kind {
                MoveKind::SetBlend(_) => continue,
                MoveKind::Dwell { .. } | MoveKind::Pause => {
                    before = 0.0;
                    continue;
                }
                _ => {}
            }
            allowed_mm[k] = f64::max(before, after_mm[k]);
            before = after_mm[k];
        }
        Self {
            in_force_mm,
            after_mm,
            allowed_mm,
            default_mm,
        }
    }

    /// The program's own tolerance: the smallest in force on any feed move (on any motion
    /// when there is no feed move; the default for a program that does not move), mm.
    pub fn program_mm(&self, program: &Program) -> f64 {
        let pick = |f: &dyn Fn(&MoveKind) -> bool| {
            program
                .moves
                .iter()
                .zip(&self.in_force_mm)
                .filter(|(m, _)| f(&m.kind))
                .map(|(_, t)| *t)
                .fold(None, |a: Option<f64>, t| Some(a.map_or(t, |a| a.min(t))))
        };
        pick(&is_feed)
            .or_else(|| pick(&moves_the_tool))
            .unwrap_or(self.default_mm)
    }

    /// The distinct tolerances in force on the moves that move the tool, ascending, mm.
    pub fn distinct_mm(&self, program: &Program) -> Vec<f64> {
        let mut v: Vec<f64> = program
            .moves
            .iter()
            .zip(&self.in_force_mm)
            .filter(|(m, _)| moves_the_tool(&m.kind))
            .map(|(_, t)| *t)
            .collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_str;

    #[test]
    fn each_move_gets_the_tolerance_of_the_junctions_at_its_ends() {
        let p = parse_str(
            "t.nc",
            "G21 G90 G61\nG1 X10 F600\nG64 P0.05\nG1 Y10\nG1 X0\nG4 P1\nG1 Y0\nG64\nG1 X5\nG1 X6 Y1\n",
        )
        .unwrap();
        let t = Tolerances::of(&p, 0.01);
        let line_of = |l: u32| {
            p.moves
                .iter()
                .position(|m| m.line == l && moves_the_tool(&m.kind))
                .unwrap()
        };
        // G61 line: its end junction is exact, its start is the program's start
        assert_eq!(t.allowed_mm[line_of(2)], 0.0);
        // G64 P0.05, after a G61 junction: its own end blends
        assert_eq!(t.after_mm[line_of(2)], 0.0);
        assert_eq!(t.allowed_mm[line_of(4)], 0.05);
        // before the dwell: stops
        assert_eq!(t.after_mm[line_of(5)], 0.0);
        assert_eq!(t.allowed_mm[line_of(5)], 0.05);
        // after the dwell: starts at rest, ends in P0.05
        assert_eq!(t.allowed_mm[line_of(7)], 0.05);
        // G64: the default; the last move ends the program
        assert_eq!(t.allowed_mm[line_of(9)], 0.05);
        assert_eq!(t.after_mm[line_of(9)], 0.01);
        assert_eq!(t.allowed_mm[line_of(10)], 0.01);
        assert_eq!(t.after_mm[line_of(10)], 0.0);
        assert_eq!(t.program_mm(&p), 0.0);
        assert_eq!(t.distinct_mm(&p), vec![0.0, 0.01, 0.05]);
    }

    #[test]
    fn without_path_mode_the_default_is_in_force() {
        let p = parse_str("t.nc", "G21 G90\nG0 X1\nG1 X10 F600\n").unwrap();
        let t = Tolerances::of(&p, 0.02);
        assert_eq!(t.program_mm(&p), 0.02);
        assert_eq!(t.distinct_mm(&p), vec![0.02]);
        assert!((TOLERANCE_SLACK_MM - 2.5e-5).abs() < 1e-12);
        assert_eq!(slack_mm([0.0, 1.0, -2.0]), TOLERANCE_SLACK_MM);
        // 64-128 mm: ulp 7.63e-6 mm
        assert!((slack_mm([-100.0, 0.0, 0.0]) - (2.0e-5 + 4.0 * 7.62939453125e-6)).abs() < 1e-9);
    }
}
