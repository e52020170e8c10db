//! `host-sim gcode FILE`: a G-code program run on a simulated machine through the planner
//! and the servo step the board runs, measured against the programmed path.
//!
//! The program is parsed and checked against the machine's travel first; a rejected
//! program runs nothing. Then, as on the board: arm, (home if the machine homes), `Run`;
//! each period the planner plans ahead and its executor samples the reference
//! ([`MotionPlanner::tick`]), the servo takes it ([`Servo::set_planner_reference`]) and
//! runs its period against the simulated machine. Segments are streamed into the
//! planner's fixed queue as slots free up, as the link does.
//!
//! Figures: the planned reference against the programmed path (corner deviation: the
//! planner's blending), the true (simulated) tool position against the programmed path
//! (contour error), the planned per-axis velocity, acceleration and jerk against the
//! planner's limits, and the feed actually reached on feed moves.
//!
//! [`Servo::set_planner_reference`]: controller_core::servo::Servo::set_planner_reference

use crate::builtin;
use crate::gcode::{self, check_travel, MoveKind, ParseOptions, Program, Travel};
use crate::studies::resolve_all;
use anyhow::{anyhow, bail, Result};
use controller_core::motion::planner::{
    Blend, MotionPlanner, PathSample, Plane, PlannerConfig, Segment,
};
use controller_core::servo::{Command, ServoState};
use controller_core::settings::{Settings, FACTORY, TOOL_COUNT};
use controller_core::sim::run::{RunConfig, SimRun};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The planner used here: 64 segment slots, 256 spans, 128 spans in the executor's
/// channel, 32 steps buffered (the board's sizes).
pub type Planner = MotionPlanner<64, 256, 128, 32>;

/// Simulated time allowed for homing a machine that homes, s.
const HOMING_TIMEOUT_S: f64 = 120.0;
/// Periods at rest after the program ends before the run stops (settling of the servo).
const SETTLE_PERIODS: u32 = 200;
/// Moves either side of the current one searched for the nearest programmed point (a
/// blend spans one junction; short CAM segments may put the tool a few moves away).
const SEARCH_WINDOW: usize = 4;
/// Programs whose simulation takes longer than this many periods get a progress bar
/// (10 s of machine time at 10 kHz: about a second of compute).
const PROGRESS_PERIODS: u64 = 100_000;
/// One plot sample every this many periods at most (the plots keep ≤ ~20,000 points).
const PLOT_POINTS: u64 = 20_000;

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
    /// `completed`, `rejected` (nothing ran) or `fault` (the machine stopped on a fault).
    pub status: String,
    pub error: Option<ErrorJson>,
    /// Segments given to the planner (moves, arcs and dwells).
    pub segments: usize,
    /// Machine time from `Run` until the planner is idle again, s.
    pub duration_s: f64,
    /// Length of the programmed path, mm.
    pub path_length_mm: f64,
    /// Largest distance of the planned reference from the programmed path, mm.
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
    /// The planner's default path tolerance (G64 without P), mm.
    pub tolerance_mm: f64,
    /// Mean of the path speed over the programmed feed, over the periods on feed moves.
    pub feed_ratio_mean: f64,
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
    /// Feed ratio (path speed over the programmed feed; 0 on rapids and dwells) and the
    /// distance along the reference, mm.
    pub feed_ratio: Vec<f64>,
    pub along_mm: Vec<f64>,
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
            duration_s: 0.0,
            path_length_mm: 0.0,
            corner_deviation_max_mm: 0.0,
            contour_max_mm: 0.0,
            contour_rms_mm: 0.0,
            max_vel_mm_s: [0.0; 3],
            max_acc_mm_s2: [0.0; 3],
            max_jerk_mm_s3: [0.0; 3],
            limits,
            tolerance_mm: tol,
            feed_ratio_mean: 0.0,
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

fn plane_of(p: gcode::Plane) -> Plane {
    match p {
        gcode::Plane::XY => Plane::XY,
        gcode::Plane::ZX => Plane::ZX,
        gcode::Plane::YZ => Plane::YZ,
    }
}

fn f32s(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// The planner segments of `program`, tagged with the index of their move; `None` for a
/// move that only changes the blend mode.
pub fn segments(program: &Program) -> Vec<Segment> {
    let mut blend = Blend::Default;
    let mut out = Vec::with_capacity(program.moves.len());
    for (i, m) in program.moves.iter().enumerate() {
        let tag = u32::try_from(i).unwrap_or(u32::MAX);
        let seg = match m.kind {
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
                plane_of(plane),
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
                    // G61: every programmed point exactly; with a tolerance of 0 the planner
                    // stops at corners and passes smooth junctions (collinear lines, a line
                    // tangent to an arc) without stopping, as LinuxCNC's exact path
                    gcode::Blend::ExactPath => Blend::Tolerance(0.0),
                    // (the naive-CAM tolerance Q is the path compressor's; the planner blends
                    // within P)
                    gcode::Blend::Tolerance { mm, .. } => Blend::Tolerance(mm as f32),
                    gcode::Blend::MachineDefault => Blend::Default,
                };
                continue;
            }
        };
        let seg = match seg.motion {
            controller_core::motion::planner::Motion::Dwell { .. } => seg,
            _ => seg.with_blend(blend),
        };
        out.push(seg);
    }
    out
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// The point of an arc move at fraction `f` of its sweep (radius and normal coordinate
/// linear in the angle, as the planner interpolates them).
fn arc_point(
    from: [f64; 3],
    to: [f64; 3],
    center: [f64; 3],
    plane: gcode::Plane,
    cw: bool,
    sweep: f64,
    f: f64,
) -> [f64; 3] {
    let [i1, i2, n] = plane.axes();
    let (a0, b0) = (from[i1] - center[i1], from[i2] - center[i2]);
    let (a1, b1) = (to[i1] - center[i1], to[i2] - center[i2]);
    let (r0, r1) = (a0.hypot(b0), a1.hypot(b1));
    let psi = b0.atan2(a0) + if cw { -sweep * f } else { sweep * f };
    let r = r0 + (r1 - r0) * f;
    let mut q = [0.0; 3];
    q[i1] = center[i1] + r * psi.cos();
    q[i2] = center[i2] + r * psi.sin();
    q[n] = from[n] + (to[n] - from[n]) * f;
    q
}

/// Distance from `p` to the path of move `m`, mm (0 for moves that do not move).
fn distance(p: [f64; 3], m: &gcode::Move) -> Option<f64> {
    match m.kind {
        MoveKind::Rapid { to } | MoveKind::Line { to, .. } => {
            let ab = sub(to, m.from);
            let ap = sub(p, m.from);
            let l2 = dot(ab, ab);
            let t = if l2 > 0.0 {
                (dot(ap, ab) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            Some(norm(sub(ap, ab.map(|x| x * t))))
        }
        MoveKind::Arc {
            to,
            center,
            plane,
            clockwise,
            sweep_rad,
            ..
        } => {
            let [i1, i2, n] = plane.axes();
            let at = |f: f64| arc_point(m.from, to, center, plane, clockwise, sweep_rad, f);
            // the angle of `p` along the sweep, in each turn; the nearest of those points
            let psi0 = (m.from[i2] - center[i2]).atan2(m.from[i1] - center[i1]);
            let psi = (p[i2] - center[i2]).atan2(p[i1] - center[i1]);
            let tau = std::f64::consts::TAU;
            let d0 = if clockwise { psi0 - psi } else { psi - psi0 }.rem_euclid(tau);
            let mut best = norm(sub(p, at(0.0))).min(norm(sub(p, at(1.0))));
            let mut k = 0.0;
            while d0 + k * tau <= sweep_rad + tau {
                let f = ((d0 + k * tau) / sweep_rad).clamp(0.0, 1.0);
                best = best.min(norm(sub(p, at(f))));
                k += 1.0;
            }
            let _ = (i1, i2, n);
            Some(best)
        }
        MoveKind::Dwell { .. } | MoveKind::Pause | MoveKind::SetBlend(_) => None,
    }
}

/// Length of the path of move `m`, mm ([`gcode::Move::length_mm`]).
pub fn length(m: &gcode::Move) -> f64 {
    m.length_mm()
}

/// Distance from `p` to the programmed path near move `tag`.
pub fn path_distance(p: [f64; 3], moves: &[gcode::Move], tag: usize) -> f64 {
    let lo = tag.saturating_sub(SEARCH_WINDOW);
    let hi = (tag + SEARCH_WINDOW + 1).min(moves.len());
    moves
        .get(lo..hi)
        .unwrap_or_default()
        .iter()
        .filter_map(|m| distance(p, m))
        .fold(f64::INFINITY, f64::min)
}

/// One reference sample for [`PathMetrics`].
#[derive(Clone, Copy, Debug)]
pub struct MetricSample {
    pub t_s: f64,
    /// Segment tag (index of the program's move).
    pub tag: usize,
    /// The planned reference: position, velocity, acceleration.
    pub planned_mm: [f64; 3],
    pub vel_mm_s: [f64; 3],
    pub acc_mm_s2: [f64; 3],
    /// The tool's position (true, or as measured).
    pub actual_mm: [f64; 3],
    pub feed_ratio: f64,
    /// Distance along the reference so far, mm (0 when not known).
    pub along_mm: f64,
}

/// The figures of a program run, accumulated sample by sample against the programmed
/// path; one implementation for `cargo sim gcode` (every period) and `gantry run`
/// (telemetry samples).
pub struct PathMetrics<'a> {
    moves: &'a [gcode::Move],
    feed_move: Vec<bool>,
    /// Largest time between samples over which a jerk is estimated, s.
    max_gap_s: f64,
    prev: Option<(f64, [f64; 3])>,
    vmax: [f64; 3],
    amax: [f64; 3],
    jmax: [f64; 3],
    dev_max: f64,
    c_max: f64,
    c_sq: f64,
    c_n: u64,
    feed_sum: f64,
    feed_n: u64,
    pub trace: Trace,
}

impl<'a> PathMetrics<'a> {
    pub fn new(program: &'a Program, limits: LimitsJson, max_gap_s: f64) -> Self {
        Self {
            moves: &program.moves,
            feed_move: program
                .moves
                .iter()
                .map(|m| matches!(m.kind, MoveKind::Line { .. } | MoveKind::Arc { .. }))
                .collect(),
            max_gap_s,
            prev: None,
            vmax: [0.0; 3],
            amax: [0.0; 3],
            jmax: [0.0; 3],
            dev_max: 0.0,
            c_max: 0.0,
            c_sq: 0.0,
            c_n: 0,
            feed_sum: 0.0,
            feed_n: 0,
            trace: Trace {
                limits: Some(limits),
                ..Trace::default()
            },
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
        let contour = (moving || record).then(|| path_distance(s.actual_mm, self.moves, s.tag));
        if let (true, Some(c)) = (moving, contour) {
            self.dev_max = self
                .dev_max
                .max(path_distance(s.planned_mm, self.moves, s.tag));
            self.c_max = self.c_max.max(c);
            self.c_sq += c * c;
            self.c_n += 1;
            if self.feed_move.get(s.tag).copied().unwrap_or(false) {
                self.feed_sum += s.feed_ratio;
                self.feed_n += 1;
            }
        }
        if let (true, Some(c)) = (record, contour) {
            let t = &mut self.trace;
            t.t_s.push(s.t_s);
            t.pos_mm.push(s.actual_mm);
            t.contour_mm.push(c);
            t.vel_mm_s.push(s.vel_mm_s);
            t.acc_mm_s2.push(s.acc_mm_s2);
            t.feed_ratio.push(s.feed_ratio);
            t.along_mm.push(s.along_mm);
        }
    }

    /// The report of a run that ended (`fault`: why it stopped early).
    #[allow(clippy::too_many_arguments)]
    pub fn report(
        self,
        program: &Program,
        segments: usize,
        duration_s: f64,
        limits: LimitsJson,
        tolerance_mm: f64,
        fault: Option<String>,
        realtime_ratio: f64,
    ) -> GcodeReport {
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
            duration_s,
            path_length_mm: program.moves.iter().map(length).sum(),
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
            tolerance_mm,
            feed_ratio_mean: if self.feed_n > 0 {
                self.feed_sum / self.feed_n as f64
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

/// The scenario (built-in `gcode.toml`, or on `machine`) resolved, and the planner's
/// configuration at the machine's rate.
pub fn machine_and_planner(machine: Option<&Path>) -> Result<(RunConfig, PlannerConfig)> {
    machine_and_planner_with(machine, &FACTORY)
}

/// [`machine_and_planner`] with the planner configured from `settings` instead of the
/// factory settings (`cargo sim gcode --set`).
pub fn machine_and_planner_with(
    machine: Option<&Path>,
    settings: &Settings,
) -> Result<(RunConfig, PlannerConfig)> {
    let file = match machine {
        Some(m) => builtin::load_on_machine("gcode.toml", m)?,
        None => builtin::load("gcode.toml")?,
    };
    let runs = resolve_all(&file)?;
    let r = runs
        .first()
        .ok_or_else(|| anyhow!("gcode.toml has no run"))?;
    // the settings' planner (controller-core settings, the factory's from GANTRY_PLANNER
    // unless `--set`), its speeds capped at the machine's own limits (a `--machine` may
    // be slower)
    let mut cfg = settings.planner_config(r.run.servo.rate_hz);
    for (v, safety) in cfg.vel_max_mm_s.iter_mut().zip(&r.run.servo.safety.axes) {
        if safety.vel_max_mm_s.is_finite() && safety.vel_max_mm_s > 0.0 {
            *v = v.min(safety.vel_max_mm_s);
        }
    }
    if r.study.is_some() {
        bail!("gcode.toml: no study table expected (the planner's limits are settings)");
    }
    Ok((r.run, cfg))
}

/// An `f32` setting as the decimal it was written as (0.01, not 0.009999999776).
pub fn decimal(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

pub fn limits_of(c: &PlannerConfig) -> LimitsJson {
    LimitsJson {
        vel: c.vel_max_mm_s.map(decimal),
        acc: c.acc_max_mm_s2.map(decimal),
        jerk: c.jerk_max_mm_s3.map(decimal),
    }
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

/// Run until the servo leaves `state` (homing) or `max` periods pass.
fn run_while(run: &mut SimRun<f32>, state: ServoState, max: u64) -> Result<()> {
    let mut k = 0u64;
    while run.servo().state() == state {
        if k >= max {
            bail!("the machine stayed in {state:?} for {max} periods");
        }
        run.control_with(&[]);
        run.finish_period();
        k += 1;
    }
    Ok(())
}

/// Run `program_path` on the built-in gantry or on `machine`; a rejected program is a
/// report with status `rejected`, not an error (errors: the machine file, a refused
/// command, a planner that never finishes).
pub fn run(program_path: &Path, machine: Option<&Path>, progress: bool) -> Result<GcodeReport> {
    run_with_settings(program_path, machine, &FACTORY, progress)
}

/// [`run`] with `settings` in place of the factory settings: the planner's limits and
/// tolerances, the work offsets and the tool table (`cargo sim gcode --set`).
pub fn run_with_settings(
    program_path: &Path,
    machine: Option<&Path>,
    settings: &Settings,
    progress: bool,
) -> Result<GcodeReport> {
    let (mut cfg, pcfg) = machine_and_planner_with(machine, settings)?;
    let limits = limits_of(&pcfg);
    let tol = decimal(pcfg.tolerance_mm);
    let name = program_path.display().to_string();
    let travel = travel_of(&cfg)?;
    cfg.hold = true;
    cfg.periods = u32::MAX;
    cfg.inject = None;
    let mut run = SimRun::<f32>::new(&cfg).map_err(|e| anyhow!("invalid machine: {e}"))?;
    let start = run.world().state().map(|s| s.pos);
    // rejected before any motion
    if let Err(e) = load_program_with(program_path, &parse_options(settings, start), &travel) {
        return Ok(GcodeReport::rejected(&name, &e, limits, tol));
    }

    // arm; home when the machine homes
    let s = *run.control_with(&[Command::Arm]);
    run.finish_period();
    if let Some((_, why)) = s.refused {
        bail!("arming refused: {}", why.message());
    }
    let s = *run.control_with(&[Command::Run]);
    let dt = run.servo().period_s();
    if s.refused.is_some() {
        let s = *run.control_with(&[Command::Home]);
        run.finish_period();
        if let Some((_, why)) = s.refused {
            bail!("homing refused: {}", why.message());
        }
        run_while(&mut run, ServoState::Homing, (HOMING_TIMEOUT_S / dt) as u64)?;
        if run.servo().state() != ServoState::Idle {
            bail!(
                "homing failed: state {:?}, fault {:?}",
                run.servo().state(),
                run.servo().faults().first()
            );
        }
        let s = *run.control_with(&[Command::Run]);
        if let Some((_, why)) = s.refused {
            bail!("running the program refused: {}", why.message());
        }
    }
    run.finish_period();
    let here = run
        .servo()
        .planner_start_mm()
        .ok_or_else(|| anyhow!("the servo is not running the planner"))?;
    // the program from where the machine stands now (after homing, if any)
    let options = parse_options(settings, here.map(f64::from));
    let program = match load_program_with(program_path, &options, &travel) {
        Ok(p) => p,
        Err(e) => return Ok(GcodeReport::rejected(&name, &e, limits, tol)),
    };
    let segs = segments(&program);
    let mut mp = Box::new(Planner::new(&pcfg, here).map_err(|e| anyhow!("planner: {e:?}"))?);

    let path_length_mm: f64 = program.moves.iter().map(length).sum();
    // a generous bound on the machine time: every move at 1 mm/s plus its dwells
    let dwell_s: f64 = program
        .moves
        .iter()
        .map(|m| match m.kind {
            MoveKind::Dwell { s } => s,
            _ => 0.0,
        })
        .sum();
    let max_periods = ((path_length_mm + dwell_s + 10.0) / dt) as u64 + 100_000;
    let estimate = ((path_length_mm / 20.0 + dwell_s) / dt) as u64;
    let bar = (progress && estimate > PROGRESS_PERIODS).then(|| {
        let b = ProgressBar::new(segs.len() as u64);
        b.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} segments, {elapsed} ({eta} left)")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    });
    let every = (estimate / PLOT_POINTS).max(1);

    let started = Instant::now();
    let mut next = 0usize;
    let mut k = 0u64;
    let mut along = 0.0f64;
    // (every period: a jerk between consecutive periods)
    let mut metrics = PathMetrics::new(&program, limits, 1.5 * dt);
    let mut fault = None;
    let mut finished_at = None;
    let mut rest = 0u32;
    loop {
        while next < segs.len() && mp.free_slots() > 0 {
            mp.push(&segs[next]).map_err(|e| {
                let line = program
                    .moves
                    .get(segs[next].tag as usize)
                    .map_or(0, |m| m.line);
                anyhow!("{name}:{line}: the planner rejected the move: {e:?}")
            })?;
            next += 1;
            if let Some(b) = &bar {
                b.set_position(next as u64);
            }
        }
        let sample: PathSample = mp.tick();
        run.servo_mut().set_planner_reference(&sample);
        let snap = *run.control_with(&[]);
        let truth = run.world().state().map(|s| s.pos);
        run.finish_period();
        k += 1;
        along += f64::from(sample.path_speed_mm_s.abs()) * dt;
        metrics.add(
            &MetricSample {
                t_s: k as f64 * dt,
                tag: sample.tag as usize,
                planned_mm: sample.pos_mm.to_array().map(f64::from),
                vel_mm_s: sample.vel_mm_s.to_array().map(f64::from),
                acc_mm_s2: sample.acc_mm_s2.to_array().map(f64::from),
                actual_mm: truth,
                feed_ratio: f64::from(sample.feed_ratio),
                along_mm: along,
            },
            finished_at.is_none(),
            k.is_multiple_of(every),
        );

        if snap.state == ServoState::Fault || snap.state == ServoState::Stopping {
            let f = run.servo().faults().first();
            fault = Some(format!("{f:?}"));
            mp.abort();
            run_while(&mut run, ServoState::Stopping, 1_000_000)?;
            break;
        }
        if finished_at.is_none() && next == segs.len() && mp.is_idle() {
            finished_at = Some(k);
        }
        if finished_at.is_some() {
            rest += 1;
            if rest >= SETTLE_PERIODS {
                break;
            }
        }
        if k >= max_periods {
            bail!("{name}: the program did not finish within {max_periods} periods");
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let compute_s = started.elapsed().as_secs_f64();
    let duration_s = finished_at.unwrap_or(k) as f64 * dt;
    if fault.is_none() {
        // back to Idle, holding the end point
        run.control_with(&[Command::Stop]);
        run.finish_period();
    }
    let realtime = if compute_s > 0.0 {
        k as f64 * dt / compute_s
    } else {
        0.0
    };
    Ok(metrics.report(
        &program,
        segs.len(),
        duration_s,
        limits,
        tol,
        fault,
        realtime,
    ))
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
        "  {} segments, {:.1} mm of path in {:.3} s (feed ratio {:.3} on feed moves)",
        r.segments, r.path_length_mm, r.duration_s, r.feed_ratio_mean
    );
    let _ = writeln!(
        s,
        "  corner deviation (planned vs programmed) max {:.4} mm (tolerance {} mm)",
        r.corner_deviation_max_mm, r.tolerance_mm
    );
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
    let _ = writeln!(
        s,
        "  simulated {:.1}x faster than real time",
        r.realtime_ratio
    );
    s
}
