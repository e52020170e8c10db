//! The report of one G-code program run (`host-sim gcode`, `gantry run`): its JSON (keys
//! are public interface), the decimated samples the plots draw, and the table for the
//! terminal.

use crate::gcode::program::decimal;
use crate::gcode::{self, compress};
use controller_core::motion::planner::PlannerConfig;
use serde::Serialize;

/// Where a rejected program is wrong (keys are public interface).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ErrorJson {
    pub line: Option<u32>,
    pub message: String,
}

/// The planner's limits as the JSON reports them.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct LimitsJson {
    pub vel: [f64; 3],
    pub acc: [f64; 3],
    pub jerk: [f64; 3],
}

/// The report of one program (keys are public interface; see the README).
#[derive(Clone, Debug, Serialize)]
pub struct GcodeReport {
    pub program: String,
    /// `completed`, `rejected` (nothing ran), `fault` (the machine stopped on a fault) or,
    /// from `gantry run`, `aborted` (stopped by the host, a lost link, a refused segment or
    /// a disarm: `program_end` says which).
    pub status: String,
    pub error: Option<ErrorJson>,
    /// Segments executed: the planner's segments (moves, arcs, dwells and the primitives
    /// runs of short moves were merged into) the machine ran to their end. In `gantry run`
    /// from the machine's status (the segment its executor was on when the program ended,
    /// and whether it completed); equal to `segments_planned` when the program completed.
    pub segments: usize,
    /// Segments the program gave the planner (what `segments` counted before it counted
    /// what executed).
    pub segments_planned: usize,
    /// The machine reported the program done (every segment executed, machine at rest):
    /// false after an abort.
    pub program_done: bool,
    /// How the program ended, as the machine reports it: `completed`, `not_started`
    /// (rejected), `aborted_by_fault(<kind>)`, `aborted_by_host`, `aborted_by_link_loss`,
    /// `aborted_segment_refused`, `aborted_stopped` (a disarm).
    pub program_end: String,
    /// The program's moves (those that move or wait): the segments without compression.
    pub moves: usize,
    /// What the path compressor did (`gcode::compress`): chords considered, primitives
    /// they became (lines, arcs).
    pub compression: compress::Stats,
    /// Compute time of the host's part, s: parsing with the travel check, compression,
    /// and the run (planner and, in `cargo sim gcode`, the simulated machine).
    pub compute: ComputeJson,
    /// Machine time from `Run` until the planner is idle again, s.
    pub duration_s: f64,
    /// Length of the path executed, mm: the programmed length of the segments in
    /// `segments` (the one in progress when a program stopped is not counted); the
    /// programmed path's length when the program completed.
    pub path_length_mm: f64,
    /// Length of the programmed path, mm.
    pub path_length_planned_mm: f64,
    /// Largest distance of the executed reference (the executor's sample each period) from
    /// the programmed path, mm.
    pub corner_deviation_max_mm: f64,
    /// Largest and RMS distance of the true tool position from the programmed path, mm
    /// (RMS over the periods in motion).
    pub contour_max_mm: f64,
    pub contour_rms_mm: f64,
    /// Per axis, the planned reference's largest |v|, |a|, |j|.
    pub max_vel_mm_s: [f64; 3],
    pub max_acc_mm_s2: [f64; 3],
    pub max_jerk_mm_s3: [f64; 3],
    pub limits: LimitsJson,
    /// The program's own tolerance: the smallest in force on any feed move (G64 P in mm,
    /// the configured default under G64 or no path mode, 0 under G61), mm.
    pub tolerance_mm: f64,
    /// The distinct tolerances in force on the program's moves, ascending, mm.
    pub tolerances_mm: Vec<f64>,
    /// The configured tolerance of G64 without P (`planner.tolerance_mm`), mm.
    pub tolerance_default_mm: f64,
    /// Program moves at which the executed reference deviated beyond the tolerance in force
    /// (plus [`tolerance::TOLERANCE_SLACK_MM`]), the worst excess, mm, and the first G-code
    /// lines of those moves.
    pub tolerance_violations: usize,
    pub tolerance_violation_max_mm: f64,
    pub tolerance_violation_lines: Vec<u32>,
    /// Mean of the path speed over the achievable feed (the programmed feed, or the axes'
    /// velocity limits projected on the programmed tangent where they allow less), over
    /// the samples whose nearest programmed point is on a feed move.
    pub feed_ratio_mean: f64,
    /// A lower bound of the machine time no planner within the limits and tolerances can
    /// beat ([`bound`]), s, and `duration_s` over it.
    pub time_bound_s: f64,
    pub time_ratio_to_bound: f64,
    /// Words accepted but ignored (`S`, `M3`, …), as reported by the parser.
    pub ignored: Vec<String>,
    /// The fault that stopped the machine (status `fault`).
    pub fault: Option<String>,
    /// Machine time over compute time of the simulation (> 1: faster than real time).
    pub realtime_ratio: f64,
    /// Settings the run wrote back to the machine (`gantry run`: the work offsets and tools
    /// the program's G10 changed), `(key, value)`; not part of the JSON.
    #[serde(skip)]
    pub settings_written: Vec<(String, String)>,
    #[serde(skip)]
    pub trace: Trace,
}

/// Compute times of a run (keys of the JSON's `compute`).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct ComputeJson {
    pub parse_s: f64,
    pub compress_s: f64,
    pub run_s: f64,
}

/// Decimated samples for the plots.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    pub t_s: Vec<f64>,
    /// True tool position, mm, and its distance from the programmed path, mm.
    pub pos_mm: Vec<[f64; 3]>,
    pub contour_mm: Vec<f64>,
    /// Planned per-axis velocity and acceleration.
    pub vel_mm_s: Vec<[f64; 3]>,
    pub acc_mm_s2: Vec<[f64; 3]>,
    /// Feed ratio (path speed over the achievable feed; 0 on rapids and dwells) and the
    /// distance along the reference, mm.
    pub feed_ratio: Vec<f64>,
    pub along_mm: Vec<f64>,
    /// Per sample: the segment running is a rapid (G0/G28 move), drawn apart from the cuts.
    pub rapid: Vec<bool>,
    pub limits: Option<LimitsJson>,
}

impl GcodeReport {
    pub fn rejected(program: &str, e: &gcode::Error, limits: LimitsJson, tol: f64) -> Self {
        Self {
            program: program.to_string(),
            status: "rejected".into(),
            error: Some(ErrorJson {
                line: e.line,
                message: e.to_string(),
            }),
            segments: 0,
            segments_planned: 0,
            program_done: false,
            program_end: "not_started".into(),
            moves: 0,
            compression: compress::Stats::default(),
            compute: ComputeJson::default(),
            duration_s: 0.0,
            path_length_mm: 0.0,
            path_length_planned_mm: 0.0,
            corner_deviation_max_mm: 0.0,
            contour_max_mm: 0.0,
            contour_rms_mm: 0.0,
            max_vel_mm_s: [0.0; 3],
            max_acc_mm_s2: [0.0; 3],
            max_jerk_mm_s3: [0.0; 3],
            limits,
            tolerance_mm: tol,
            tolerances_mm: Vec::new(),
            tolerance_default_mm: tol,
            tolerance_violations: 0,
            tolerance_violation_max_mm: 0.0,
            tolerance_violation_lines: Vec::new(),
            feed_ratio_mean: 0.0,
            time_bound_s: 0.0,
            time_ratio_to_bound: 0.0,
            ignored: Vec::new(),
            fault: None,
            realtime_ratio: 0.0,
            settings_written: Vec::new(),
            trace: Trace::default(),
        }
    }

    pub fn completed(&self) -> bool {
        self.status == "completed"
    }
}

pub fn limits_of(c: &PlannerConfig) -> LimitsJson {
    LimitsJson {
        vel: c.vel_max_mm_s.map(decimal),
        acc: c.acc_max_mm_s2.map(decimal),
        jerk: c.jerk_max_mm_s3.map(decimal),
    }
}

/// The report as a table for the terminal.
pub fn table(r: &GcodeReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "program {}: {}", r.program, r.status);
    if let Some(e) = &r.error {
        let _ = writeln!(s, "  {}", e.message);
        return s;
    }
    if let Some(f) = &r.fault {
        let _ = writeln!(s, "  stopped on a fault: {f}");
    }
    let _ = writeln!(
        s,
        "  {} segments, {:.1} mm of path in {:.3} s (feed ratio {:.3} of the achievable feed on feed moves)",
        r.segments, r.path_length_mm, r.duration_s, r.feed_ratio_mean
    );
    let _ = writeln!(
        s,
        "  time bound {:.3} s: the run took {:.3} times the least any planner within the limits could",
        r.time_bound_s, r.time_ratio_to_bound
    );
    let tolerances: Vec<String> = r.tolerances_mm.iter().map(|t| t.to_string()).collect();
    let _ = writeln!(
        s,
        "  corner deviation (executed reference vs programmed) max {:.4} mm (program tolerance {} mm; in force: {} mm; default {} mm)",
        r.corner_deviation_max_mm,
        r.tolerance_mm,
        tolerances.join(", "),
        r.tolerance_default_mm
    );
    if r.tolerance_violations > 0 {
        let lines: Vec<String> = r
            .tolerance_violation_lines
            .iter()
            .map(|l| l.to_string())
            .collect();
        let _ = writeln!(
            s,
            "  TOLERANCE VIOLATED at {} moves, by up to {:.4} mm (lines {}{})",
            r.tolerance_violations,
            r.tolerance_violation_max_mm,
            lines.join(", "),
            if r.tolerance_violations > lines.len() {
                ", …"
            } else {
                ""
            }
        );
    } else {
        let _ = writeln!(s, "  within the tolerance in force at every move");
    }
    let _ = writeln!(
        s,
        "  contour error (actual vs programmed) max {:.4} mm, RMS {:.4} mm",
        r.contour_max_mm, r.contour_rms_mm
    );
    for (i, ax) in ["x", "y", "z"].iter().enumerate() {
        let _ = writeln!(
            s,
            "  {ax}: |v| {:7.1} / {:6.0} mm/s   |a| {:7.1} / {:6.0} mm/s²   |j| {:9.0} / {:7.0} mm/s³",
            r.max_vel_mm_s[i],
            r.limits.vel[i],
            r.max_acc_mm_s2[i],
            r.limits.acc[i],
            r.max_jerk_mm_s3[i],
            r.limits.jerk[i]
        );
    }
    if !r.ignored.is_empty() {
        let _ = writeln!(s, "  ignored words: {}", r.ignored.join(", "));
    }
    if !r.settings_written.is_empty() {
        let written: Vec<String> = r
            .settings_written
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect();
        let _ = writeln!(s, "  settings written (G10): {}", written.join(", "));
    }
    let _ = writeln!(s, "  {}", speed_words(r.realtime_ratio));
    s
}

/// Machine time over the compute time it took (0 when none was measured).
pub fn realtime_ratio(machine_s: f64, compute_s: f64) -> f64 {
    if compute_s > 0.0 {
        machine_s / compute_s
    } else {
        0.0
    }
}

/// Machine time over wall time, in words that read right on both sides of 1 ("5.0x
/// slower", not "0.2x faster").
pub fn speed_words(ratio: f64) -> String {
    if !ratio.is_finite() || ratio <= 0.0 {
        "machine time over wall time: not measured".into()
    } else if (0.95..=1.05).contains(&ratio) {
        format!("ran at real time ({ratio:.2}x)")
    } else if ratio >= 1.0 {
        format!("ran {ratio:.1}x faster than real time")
    } else {
        format!("ran {:.1}x slower than real time", 1.0 / ratio)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_speed_ratio_reads_right_on_both_sides_of_one() {
        assert_eq!(speed_words(62.0), "ran 62.0x faster than real time");
        assert_eq!(speed_words(0.2), "ran 5.0x slower than real time");
        assert_eq!(speed_words(1.0), "ran at real time (1.00x)");
        assert_eq!(speed_words(0.97), "ran at real time (0.97x)");
        assert!(speed_words(0.0).contains("not measured"));
    }
}
