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
//! Figures: the executed reference against the programmed path (corner deviation: the
//! planner's blending) and against the tolerance in force at each move (violations), the
//! true (simulated) tool position against the programmed path (contour error), the
//! planned per-axis velocity, acceleration and jerk against the planner's limits, the feed
//! reached on feed moves over the achievable one, and the machine time over a lower bound
//! no planner within the limits can beat.
//!
//! Modules: [`distance`] (exact distance to a move's path), [`cursor`] (the search over the
//! moves near the tool), [`tolerance`] (the tolerance in force at each move), [`directions`]
//! (axis limits along a direction), [`metrics`] (the figures, sample by sample) and
//! [`bound`] (the lower bound of the machine time).
//!
//! [`Servo::set_planner_reference`]: controller_core::servo::Servo::set_planner_reference

pub mod bound;
pub mod cursor;
pub mod directions;
pub mod distance;
pub mod metrics;
pub mod tolerance;

pub use distance::length;
pub use metrics::{MetricSample, PathMetrics};

use crate::builtin;
use crate::gcode::{self, check_travel, compress, MoveKind, ParseOptions, Program, Travel};
use crate::studies::resolve_all;
use anyhow::{anyhow, bail, Result};
use controller_core::motion::planner::{Blend, PathSample, Plane, PlannerConfig, Segment};
use controller_core::servo::{Command, ServoState};
use controller_core::settings::{Settings, FACTORY, TOOL_COUNT};
use controller_core::sim::run::{RunConfig, SimRun};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

/// The planner used here: the machine's (the board's sizes: `MACHINE_SEGMENTS` segment
/// slots, `MACHINE_SPANS` spans, the split channels' spans and steps between the halves).
pub type Planner = controller_core::machine::MachinePlanner;

/// Simulated time allowed for homing a machine that homes, s.
const HOMING_TIMEOUT_S: f64 = 120.0;
/// Periods at rest after the program ends before the run stops (settling of the servo).
const SETTLE_PERIODS: u32 = 200;
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
    let parse_started = Instant::now();
    let program = match load_program_with(program_path, &options, &travel) {
        Ok(p) => p,
        Err(e) => return Ok(GcodeReport::rejected(&name, &e, limits, tol)),
    };
    let parse_s = parse_started.elapsed().as_secs_f64();
    let compress_started = Instant::now();
    let (segs, compression) = segments(&program, tol);
    let compress_s = compress_started.elapsed().as_secs_f64();
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
    let mut metrics = PathMetrics::new(&program, &segs, limits, tol, 1.5 * dt);
    let mut fault = None;
    let mut finished_at = None;
    let mut rest = 0u32;
    // periods the servo held the program's start for the brakes to open: the program's
    // time begins after them (its clock stood still)
    let mut held_periods = 0u64;
    loop {
        while next < segs.len() && mp.free_slots() > 0 {
            mp.push(&segs[next].seg).map_err(|e| {
                let line = program
                    .moves
                    .get(segs[next].moves.start)
                    .map_or(0, |m| m.line);
                anyhow!("{name}:{line}: the planner rejected the move: {e:?}")
            })?;
            next += 1;
            if let Some(b) = &bar {
                b.set_position(next as u64);
            }
        }
        // the program's clock stands still while the servo holds its start for the brakes
        // to open (`Servo::motion_held`), as the machine's supervisor does
        let held = run.servo().motion_held();
        let sample: PathSample = if held {
            PathSample::default()
        } else {
            let s = mp.tick();
            run.servo_mut().set_planner_reference(&s);
            s
        };
        let snap = *run.control_with(&[]);
        let truth = run.world().state().map(|s| s.pos);
        run.finish_period();
        k += 1;
        if held {
            held_periods += 1;
        } else {
            along += f64::from(sample.path_speed_mm_s.abs()) * dt;
            metrics.add(
                &MetricSample {
                    t_s: (k - held_periods) as f64 * dt,
                    tag: sample.tag as usize,
                    planned_mm: sample.pos_mm.to_array().map(f64::from),
                    vel_mm_s: sample.vel_mm_s.to_array().map(f64::from),
                    acc_mm_s2: sample.acc_mm_s2.to_array().map(f64::from),
                    actual_mm: truth,
                    along_mm: along,
                },
                finished_at.is_none(),
                k.is_multiple_of(every),
            );
        }

        if snap.state == ServoState::Fault || snap.state == ServoState::Stopping {
            let f = run.servo().faults().first();
            fault = Some(format!("{f:?}"));
            mp.abort();
            run_while(&mut run, ServoState::Stopping, 1_000_000)?;
            break;
        }
        if !held && finished_at.is_none() && next == segs.len() && mp.is_idle() {
            finished_at = Some(k - held_periods);
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
    let duration_s = finished_at.unwrap_or(k - held_periods) as f64 * dt;
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
    let mut report = metrics.report(&program, segs.len(), duration_s, limits, fault, realtime);
    report.compression = compression;
    report.compute = ComputeJson {
        parse_s,
        compress_s,
        run_s: compute_s,
    };
    Ok(report)
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
