//! The figures of a program run, accumulated sample by sample against the programmed
//! path; one implementation for `cargo sim gcode` (a sample every control period) and
//! `gantry run` (telemetry samples).
//!
//! Per sample: the executed reference's and the tool's nearest programmed points
//! ([`PathCursor`], within the current segment's moves), the reference's deviation
//! against the tolerance in force there ([`Tolerances`]), and its path speed over the
//! achievable feed (the programmed feed, or less where the axes' velocity limits projected
//! on the programmed tangent allow less). At the end, the lower bound of the machine time
//! ([`bound::time_bound_s`]).

use super::bound;
use super::cursor::{PathCursor, ProgramPath, REACH_MARGIN_MM, REACH_TOLERANCES};
use super::directions::projected;
use super::distance;
#[cfg(test)]
use super::tolerance::TOLERANCE_SLACK_MM;
use super::tolerance::{slack_mm, Tolerances};
use crate::gcode::program::PlanSegment;
use crate::gcode::report::{GcodeReport, LimitsJson, Trace};
use crate::gcode::{MoveKind, Program};
use controller_core::num::vec3::Vec3;
use std::ops::Range;

/// The reference's nearest programmed point moves at most this much faster than the
/// largest speed the axes allow (`√Σ vel_i²`): inside a curve of radius R at distance d
/// it moves R/(R − d) times as fast (1.02 for d = 0.01 mm on R = 0.5 mm), blends and
/// rounding add little; 1.25 is a wide margin for the cursor's reach.
const REACH_SPEED_FACTOR: f64 = 1.25;
/// G-code lines of offending moves the report lists (the first, in program order).
pub const VIOLATION_LINES_SHOWN: usize = 5;

/// One sample for [`PathMetrics`].
#[derive(Clone, Copy, Debug)]
pub struct MetricSample {
    pub t_s: f64,
    /// Segment tag: the index of the first program move the segment covers.
    pub tag: usize,
    /// The executed reference: position, velocity, acceleration.
    pub planned_mm: [f64; 3],
    pub vel_mm_s: [f64; 3],
    pub acc_mm_s2: [f64; 3],
    /// The tool's position (true, or as measured).
    pub actual_mm: [f64; 3],
    /// Distance along the reference so far, mm (0 when not known).
    pub along_mm: f64,
}

/// The figures of a run, sample by sample.
pub struct PathMetrics<'a> {
    path: ProgramPath<'a>,
    /// Per move: the end of the range of the segment whose tag it is (its first move).
    segment_end: Vec<usize>,
    tol: Tolerances,
    vel_limit: [f64; 3],
    /// Fastest the nearest programmed point can move, mm/s, and the search margin, mm.
    reach_mm_s: f64,
    margin_mm: f64,
    /// Largest time between samples over which a jerk is estimated, s.
    max_gap_s: f64,
    prev: Option<(f64, [f64; 3])>,
    last_t_s: Option<f64>,
    reference: PathCursor,
    tool: PathCursor,
    vmax: [f64; 3],
    amax: [f64; 3],
    jmax: [f64; 3],
    dev_max: f64,
    c_max: f64,
    c_sq: f64,
    c_n: u64,
    feed_sum: f64,
    feed_n: u64,
    /// Per move: the reference deviated beyond the tolerance in force there.
    violated: Vec<bool>,
    violation_max_mm: f64,
    pub trace: Trace,
}

impl<'a> PathMetrics<'a> {
    /// `segments`: what the run gives the planner ([`super::segments`]);
    /// `tolerance_default_mm`: the configured tolerance of G64 without P.
    pub fn new(
        program: &'a Program,
        segments: &[PlanSegment],
        limits: LimitsJson,
        tolerance_default_mm: f64,
        max_gap_s: f64,
    ) -> Self {
        let n = program.moves.len();
        let mut segment_end = vec![0; n];
        for s in segments {
            if let Some(e) = segment_end.get_mut(s.moves.start) {
                *e = s.moves.end;
            }
        }
        let tol = Tolerances::of(program, tolerance_default_mm);
        let tol_max = tol.in_force_mm.iter().copied().fold(0.0, f64::max);
        Self {
            path: ProgramPath::new(&program.moves),
            segment_end,
            vel_limit: limits.vel,
            reach_mm_s: REACH_SPEED_FACTOR * Vec3::from_array(limits.vel).norm(),
            margin_mm: REACH_MARGIN_MM + REACH_TOLERANCES * tol_max,
            tol,
            max_gap_s,
            prev: None,
            last_t_s: None,
            reference: PathCursor::default(),
            tool: PathCursor::default(),
            vmax: [0.0; 3],
            amax: [0.0; 3],
            jmax: [0.0; 3],
            dev_max: 0.0,
            c_max: 0.0,
            c_sq: 0.0,
            c_n: 0,
            feed_sum: 0.0,
            feed_n: 0,
            violated: vec![false; n],
            violation_max_mm: 0.0,
            trace: Trace {
                limits: Some(limits),
                ..Trace::default()
            },
        }
    }

    /// The program moves the segment with this tag covers.
    fn covered(&self, tag: usize) -> Range<usize> {
        match self.segment_end.get(tag) {
            Some(&end) if end > tag => tag..end,
            _ => tag..tag.saturating_add(1),
        }
    }

    /// Account one sample; `moving`: the program is still running (the distances and the
    /// feed count only then); `record`: keep it for the plots.
    pub fn add(&mut self, s: &MetricSample, moving: bool, record: bool) {
        for i in 0..3 {
            self.vmax[i] = self.vmax[i].max(s.vel_mm_s[i].abs());
            self.amax[i] = self.amax[i].max(s.acc_mm_s2[i].abs());
        }
        if let Some((t0, a0)) = self.prev {
            let dt = s.t_s - t0;
            if dt > 0.0 && dt <= self.max_gap_s {
                for ((j, a), a0) in self.jmax.iter_mut().zip(s.acc_mm_s2).zip(a0) {
                    *j = j.max(((a - a0) / dt).abs());
                }
            }
        }
        self.prev = Some((s.t_s, s.acc_mm_s2));
        // how far along the path the nearest points can have moved since the last sample
        let reach = self
            .last_t_s
            .map_or(0.0, |t0| self.reach_mm_s * (s.t_s - t0).max(0.0))
            + self.margin_mm;
        self.last_t_s = Some(s.t_s);
        let covered = self.covered(s.tag);
        let mut feed_ratio = 0.0;
        if moving {
            if let Some(f) = self.reference.nearest(
                s.planned_mm,
                &self.path,
                covered.clone(),
                reach,
                self.margin_mm,
            ) {
                let d = f.near.dist_mm;
                self.dev_max = self.dev_max.max(d);
                let allowed = self.tol.allowed_mm.get(f.k).copied().unwrap_or(0.0);
                let excess = d - allowed - slack_mm(s.planned_mm);
                if excess > 0.0 {
                    if let Some(v) = self.violated.get_mut(f.k) {
                        *v = true;
                    }
                    self.violation_max_mm = self.violation_max_mm.max(excess);
                }
                if let Some(feed) = self.path.moves.get(f.k).and_then(|m| feed_of(&m.kind)) {
                    let achievable = feed.min(projected(self.vel_limit, f.near.tangent));
                    if achievable > 0.0 {
                        feed_ratio = Vec3::from_array(s.vel_mm_s).norm() / achievable;
                        self.feed_sum += feed_ratio;
                        self.feed_n += 1;
                    }
                }
            }
        }
        if !(moving || record) {
            return;
        }
        let contour = self
            .tool
            .nearest(s.actual_mm, &self.path, covered, reach, self.margin_mm)
            .map_or(0.0, |f| f.near.dist_mm);
        if moving {
            self.c_max = self.c_max.max(contour);
            self.c_sq += contour * contour;
            self.c_n += 1;
        }
        if record {
            let t = &mut self.trace;
            t.t_s.push(s.t_s);
            t.pos_mm.push(s.actual_mm);
            t.contour_mm.push(contour);
            t.vel_mm_s.push(s.vel_mm_s);
            t.acc_mm_s2.push(s.acc_mm_s2);
            t.feed_ratio.push(feed_ratio);
            t.along_mm.push(s.along_mm);
            t.rapid.push(matches!(
                self.path.moves.get(s.tag).map(|m| &m.kind),
                Some(MoveKind::Rapid { .. })
            ));
        }
    }

    /// The report of a run that ended (`fault`: why it stopped early).
    pub fn report(
        self,
        program: &Program,
        segments: usize,
        duration_s: f64,
        limits: LimitsJson,
        fault: Option<String>,
        realtime_ratio: f64,
    ) -> GcodeReport {
        let bound_s = bound::time_bound_s(program, &self.tol, &limits);
        let mut lines: Vec<u32> = program
            .moves
            .iter()
            .zip(&self.violated)
            .filter(|(_, v)| **v)
            .map(|(m, _)| m.line)
            .collect();
        let violations = lines.len();
        lines.dedup();
        lines.truncate(VIOLATION_LINES_SHOWN);
        GcodeReport {
            program: program.name.clone(),
            status: if fault.is_some() {
                "fault"
            } else {
                "completed"
            }
            .into(),
            error: None,
            segments,
            segments_planned: segments,
            program_done: fault.is_none(),
            program_end: match &fault {
                None => "completed".into(),
                Some(f) => format!("aborted_by_fault({f})"),
            },
            moves: program
                .moves
                .iter()
                .filter(|m| !matches!(m.kind, MoveKind::SetBlend(_)))
                .count(),
            compression: Default::default(),
            compute: Default::default(),
            duration_s,
            path_length_mm: program.moves.iter().map(distance::length).sum(),
            path_length_planned_mm: program.moves.iter().map(distance::length).sum(),
            corner_deviation_max_mm: self.dev_max,
            contour_max_mm: self.c_max,
            contour_rms_mm: if self.c_n > 0 {
                (self.c_sq / self.c_n as f64).sqrt()
            } else {
                0.0
            },
            max_vel_mm_s: self.vmax,
            max_acc_mm_s2: self.amax,
            max_jerk_mm_s3: self.jmax,
            limits,
            tolerance_mm: self.tol.program_mm(program),
            tolerances_mm: self.tol.distinct_mm(program),
            tolerance_default_mm: self.tol.default_mm,
            tolerance_violations: violations,
            tolerance_violation_max_mm: self.violation_max_mm,
            tolerance_violation_lines: lines,
            feed_ratio_mean: if self.feed_n > 0 {
                self.feed_sum / self.feed_n as f64
            } else {
                0.0
            },
            time_bound_s: bound_s,
            time_ratio_to_bound: if bound_s > 0.0 {
                duration_s / bound_s
            } else {
                0.0
            },
            ignored: program.ignored.iter().map(|w| w.word.clone()).collect(),
            fault,
            realtime_ratio,
            settings_written: Vec::new(),
            trace: self.trace,
        }
    }
}

/// The programmed feed of a feed move, mm/s.
fn feed_of(kind: &MoveKind) -> Option<f64> {
    match *kind {
        MoveKind::Line { feed_mm_s, .. } | MoveKind::Arc { feed_mm_s, .. } => Some(feed_mm_s),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::parse_str;
    use crate::gcode::program::segments;

    const LIMITS: LimitsJson = LimitsJson {
        vel: [250.0; 3],
        acc: [2000.0; 3],
        jerk: [1.0e5; 3],
    };

    fn sample(t_s: f64, tag: usize, at: [f64; 3], vel: [f64; 3]) -> MetricSample {
        MetricSample {
            t_s,
            tag,
            planned_mm: at,
            vel_mm_s: vel,
            acc_mm_s2: [0.0; 3],
            actual_mm: at,
            along_mm: 0.0,
        }
    }

    #[test]
    fn each_part_is_checked_against_its_own_tolerance() {
        let p = parse_str(
            "m.nc",
            "G21 G90 G61\nG1 X10 F600\nG64 P0.05\nG1 Y10\nG1 X0\nG61\nG1 Y0\n",
        )
        .unwrap();
        let (segs, _) = segments(&p, 0.01);
        let tag = |line: u32| segs.iter().find(|s| p.moves[s.moves.start].line == line);
        let tag = |line: u32| tag(line).map(|s| s.seg.tag as usize).unwrap();
        let mut m = PathMetrics::new(&p, &segs, LIMITS, 0.01, 1.0);
        // 0.03 mm beside the G61 line (exact at both ends): a violation
        m.add(
            &sample(0.0, tag(2), [5.0, 0.03, 0.0], [0.0; 3]),
            true,
            false,
        );
        // 0.03 mm beside the G64 P0.05 lines: within
        m.add(
            &sample(1.0, tag(4), [10.03, 5.0, 0.0], [0.0; 3]),
            true,
            false,
        );
        m.add(
            &sample(2.0, tag(5), [5.0, 10.04, 0.0], [0.0; 3]),
            true,
            false,
        );
        // 0.06 mm beside a P0.05 line: a violation by 0.01 mm
        m.add(
            &sample(3.0, tag(5), [4.0, 10.06, 0.0], [0.0; 3]),
            true,
            false,
        );
        // the last line (G61) starts at a P0.05 junction: 0.05 allowed near its start too
        m.add(
            &sample(4.0, tag(7), [0.04, 9.0, 0.0], [0.0; 3]),
            true,
            false,
        );
        let r = m.report(&p, segs.len(), 5.0, LIMITS, None, 0.0);
        assert_eq!(r.tolerances_mm, vec![0.0, 0.05]);
        assert_eq!(r.tolerance_mm, 0.0);
        assert_eq!(r.tolerance_default_mm, 0.01);
        assert_eq!(r.tolerance_violations, 2);
        assert_eq!(r.tolerance_violation_lines, vec![2, 5]);
        assert!(
            (r.tolerance_violation_max_mm - (0.03 - TOLERANCE_SLACK_MM)).abs() < 1e-12,
            "{}",
            r.tolerance_violation_max_mm
        );
        assert!((r.corner_deviation_max_mm - 0.06).abs() < 1e-12);
        assert!(r.time_bound_s > 0.0);
        assert!((r.time_ratio_to_bound - 5.0 / r.time_bound_s).abs() < 1e-12);
    }

    #[test]
    fn the_feed_ratio_is_over_what_the_axes_allow_along_the_path() {
        // F60000 = 1000 mm/s, four times what X allows; the diagonal allows 250·√2
        let p = parse_str(
            "f.nc",
            "G21 G90\nG1 X100 F60000\nG1 X200 Y100\nG1 X210 F300\n",
        )
        .unwrap();
        let (segs, _) = segments(&p, 0.0);
        let mut m = PathMetrics::new(&p, &segs, LIMITS, 0.01, 1.0);
        m.add(
            &sample(0.0, 0, [50.0, 0.0, 0.0], [250.0, 0.0, 0.0]),
            true,
            false,
        );
        m.add(
            &sample(1.0, 1, [150.0, 50.0, 0.0], [250.0, 250.0, 0.0]),
            true,
            false,
        );
        // the feed itself where it is below the axes' limit: 5 mm/s at 4 mm/s reads 0.8
        m.add(
            &sample(2.0, 2, [205.0, 100.0, 0.0], [4.0, 0.0, 0.0]),
            true,
            false,
        );
        let r = m.report(&p, segs.len(), 3.0, LIMITS, None, 0.0);
        let want = (1.0 + 1.0 + 0.8) / 3.0;
        assert!(
            (r.feed_ratio_mean - want).abs() < 1e-12,
            "{}",
            r.feed_ratio_mean
        );
    }
}
