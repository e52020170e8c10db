//! `host-sim gcode FILE`: a G-code program run on a simulated machine through the planner
//! and the servo step the board runs, measured against the programmed path.
//!
//! The program is parsed and checked against the machine's travel first; a rejected
//! program runs nothing. Then the machine (controller-core [`Machine`], the board's
//! supervisor, planner and servo step, in a simulated run) gets the requests a host sends
//! over the link: arm, home if the machine homes, `Run`, the program's segments while its
//! request queue has room, the end of the program. The machine executes them, plans,
//! samples its planner's reference each period, runs the servo step against the simulated
//! machine, stops at the program's end, and aborts on a fault: this runner only sends
//! and measures.
//!
//! Figures: the executed reference against the programmed path (corner deviation: the
//! planner's blending) and against the tolerance in force at each move (violations), the
//! true (simulated) tool position against the programmed path (contour error), the
//! planned per-axis velocity, acceleration and jerk against the planner's limits, the feed
//! reached on feed moves over the achievable one, and the machine time over a lower bound
//! no planner within the limits can beat.
//!
//! [`Machine`]: controller_core::machine::Machine

use crate::gcode::measure::{length, MetricSample, PathMetrics};
use crate::gcode::program::{
    decimal, load_program_with, parse_options, segments, travel_of, PlanSegment,
};
use crate::gcode::report::{limits_of, realtime_ratio, ComputeJson, GcodeReport};
use crate::gcode::{MoveKind, Program};
use crate::sim_gantry::machine_and_planner_with;
use anyhow::{anyhow, bail, Result};
use controller_core::machine::messages::{Outcome, ProgramEnd, Request};
use controller_core::machine::scope::Scope;
use controller_core::machine::{MachineMemory, MachinePlanner};
use controller_core::motion::planner::PathSample;
use controller_core::motion::planner::PlannerConfig;
use controller_core::servo::ServoState;
use controller_core::settings::{Settings, FACTORY};
use controller_core::sim::run::{RunConfig, SimRun};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use std::time::Instant;

/// The simulated run of a program: the machine with its planner (the board's sizes:
/// `MACHINE_SEGMENTS` segment slots, `MACHINE_SPANS` spans, the split channels' spans and
/// steps between the halves, both halves in the period), boxed.
pub type ProgramRun = SimRun<f32, Box<MachineMemory<MachinePlanner>>, MachinePlanner>;

/// Simulated time allowed for homing a machine that homes, s.
const HOMING_TIMEOUT_S: f64 = 120.0;
/// Periods at rest after the program ends before the run stops (settling of the servo).
const SETTLE_PERIODS: u32 = 200;
/// Programs whose simulation takes longer than this many periods get a progress bar
/// (10 s of machine time at 10 kHz: about a second of compute).
const PROGRESS_PERIODS: u64 = 100_000;
/// One plot sample every this many periods at most (the plots keep ≤ ~20,000 points).
const PLOT_POINTS: u64 = 20_000;

/// The simulated run of a program on the machine `cfg` (made to hold until commanded and
/// to run until stopped) with the planner `pcfg`: its memory (planner, scope, no
/// compensation tables) boxed.
pub fn program_run(cfg: &mut RunConfig, pcfg: &PlannerConfig) -> Result<ProgramRun> {
    cfg.hold = true;
    cfg.periods = u32::MAX;
    cfg.inject = None;
    cfg.program = false;
    let memory = Box::new(MachineMemory {
        planner: MachinePlanner::BLANK,
        scope: Scope::new(),
        comp: controller_core::motion::compensation::CompTables::NONE,
        comp_entry: controller_core::machine::CompEntry::NONE,
        response: controller_core::machine::ResponseRecord::EMPTY,
        shaper: controller_core::motion::shaper::ShaperStage::NONE,
        queue: controller_core::machine::RequestQueue::new(),
        next_settings: None,
        settings: controller_core::settings::FACTORY,
    });
    SimRun::with_memory(cfg, pcfg, memory).map_err(|e| anyhow!("invalid machine: {e}"))
}

/// Run until the servo leaves `state` (homing) or `max` periods pass.
fn run_while(run: &mut ProgramRun, state: ServoState, max: u64) -> Result<()> {
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

/// `r` sent and executed (a servo request's outcome is known after its period); its
/// refusal is the error.
fn request(run: &mut ProgramRun, r: Request, what: &str) -> Result<()> {
    let before = run.machine().executed();
    run.machine_mut().submit(r);
    run.control_with(&[]);
    run.finish_period();
    if run.machine().executed() == before {
        bail!("{what}: the machine did not execute the request");
    }
    match run.machine().last() {
        Outcome::Refused(why) => bail!("{what} refused: {why}"),
        _ => Ok(()),
    }
}

/// Arm; `Run` (a machine that homes refuses it before: home, then `Run`): the machine
/// then runs its planner.
pub fn arm_home_and_run(run: &mut ProgramRun) -> Result<()> {
    request(run, Request::Arm, "arming")?;
    if request(run, Request::Run, "running the program").is_ok() {
        return Ok(());
    }
    request(run, Request::Home, "homing")?;
    let dt = run.servo().period_s();
    run_while(run, ServoState::Homing, (HOMING_TIMEOUT_S / dt) as u64)?;
    if run.servo().state() != ServoState::Idle {
        bail!(
            "homing failed: state {:?}, fault {:?}",
            run.servo().state(),
            run.servo().faults().first()
        );
    }
    request(run, Request::Run, "running the program")
}

/// The progress bar of a long simulation, over its `segments`.
fn progress_bar(segments: usize) -> ProgressBar {
    let b = ProgressBar::new(segments as u64);
    b.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} segments, {elapsed} ({eta} left)")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    b
}

/// Segments from `segs[next..]` into the machine's request queue while it has room, as
/// the link streams them, then the end of the program; the index of the next one to send
/// (`segs.len() + 1` once the end was sent).
pub fn stream(run: &mut ProgramRun, segs: &[PlanSegment], mut next: usize) -> usize {
    while next <= segs.len() && run.machine().free_slots() > 0 {
        let r = match segs.get(next) {
            Some(s) => Request::Segment(s.seg),
            None => Request::EndProgram,
        };
        run.machine_mut().submit(r);
        next += 1;
    }
    next
}

/// The periods a program may take at most (a generous bound on its machine time: every
/// move at 1 mm/s plus its dwells), and an estimate of those it takes (for the progress
/// bar and the plots' decimation).
pub fn period_bounds(program: &Program, dt: f64) -> (u64, u64) {
    let path_length_mm: f64 = program.moves.iter().map(length).sum();
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
    (max_periods, estimate)
}

/// One period's figures' sample: the planner's reference at program time `t_s`, the true
/// tool position and the distance along the reference, mm.
fn metric_sample(sample: &PathSample, t_s: f64, truth_mm: [f64; 3], along_mm: f64) -> MetricSample {
    MetricSample {
        t_s,
        tag: sample.tag as usize,
        planned_mm: sample.pos_mm.to_array().map(f64::from),
        vel_mm_s: sample.vel_mm_s.to_array().map(f64::from),
        acc_mm_s2: sample.acc_mm_s2.to_array().map(f64::from),
        actual_mm: truth_mm,
        along_mm,
    }
}

/// The machine stopped on a fault (its supervisor aborted the program): run until the
/// servo has stopped; the fault, as the report names it.
pub fn stop_on_fault(run: &mut ProgramRun) -> Result<String> {
    let f = run.servo().faults().first();
    let fault = format!("{f:?}");
    run_while(run, ServoState::Stopping, 1_000_000)?;
    Ok(fault)
}

/// Why the machine stopped the program before its end, with the G-code line of the
/// segment it was on.
/// A positioning or study run's program after period `k`: completed (`true`), still
/// running (`false`), or the error: a fault (the machine brought to rest first), a
/// refusal, or no end within `max_periods`.
pub fn program_completed(
    run: &mut ProgramRun,
    program: &Program,
    name: &str,
    k: u64,
    max_periods: u64,
) -> Result<bool> {
    match run.machine().program_end() {
        ProgramEnd::Running => {}
        ProgramEnd::Completed => return Ok(true),
        ProgramEnd::Fault(_) => bail!("{name}: {}", stop_on_fault(run)?),
        _ => return Err(refusal(run, program, name)),
    }
    if k >= max_periods {
        bail!("{name}: the program did not finish within {max_periods} periods");
    }
    Ok(false)
}

pub fn refusal(run: &ProgramRun, program: &Program, name: &str) -> anyhow::Error {
    let tag = run.machine().path_sample().tag as usize;
    let line = program.moves.get(tag).map_or(0, |m| m.line);
    match run.machine().last() {
        Outcome::Refused(why) => anyhow!("{name}:{line}: the machine refused the program: {why}"),
        _ => anyhow!("{name}:{line}: the machine stopped the program"),
    }
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
    let none = [controller_core::motion::compensation::AxisCompensation::NONE; 3];
    run_compensated(program_path, machine, settings, &none, progress)
}

/// [`run_with_settings`] with the axes' backlash and lead-screw compensation `comp`
/// entered before the machine arms, as `gantry comp load` enters them on a board
/// (`cargo sim gcode --comp DIR`).
pub fn run_compensated(
    program_path: &Path,
    machine: Option<&Path>,
    settings: &Settings,
    comp: &[controller_core::motion::compensation::AxisCompensation; 3],
    progress: bool,
) -> Result<GcodeReport> {
    let (mut cfg, pcfg) = machine_and_planner_with(machine, settings)?;
    let limits = limits_of(&pcfg);
    let tol = decimal(pcfg.tolerance_mm);
    let name = program_path.display().to_string();
    let travel = travel_of(&cfg)?;
    let mut run = program_run(&mut cfg, &pcfg)?;
    for (axis, c) in controller_core::axes::Axis::ALL.into_iter().zip(comp) {
        run.machine_mut()
            .set_compensation(axis, *c)
            .map_err(|e| anyhow!("compensation of {axis:?}: {e:?}"))?;
    }
    // the input shapers (`--set shaper.y.kind=zv`), their deviation counted inside the
    // planner's tolerance by the machine
    run.machine_mut()
        .set_shapers(&settings.shaper.shapers())
        .map_err(|e| anyhow!("input shapers: {e:?}"))?;
    let start = run.world().state().map(|s| s.pos);
    // rejected before any motion
    if let Err(e) = load_program_with(program_path, &parse_options(settings, start), &travel) {
        return Ok(GcodeReport::rejected(&name, &e, limits, tol));
    }

    arm_home_and_run(&mut run)?;
    let dt = run.servo().period_s();
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

    let (max_periods, estimate) = period_bounds(&program, dt);
    let bar = (progress && estimate > PROGRESS_PERIODS).then(|| progress_bar(segs.len()));
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
        next = stream(&mut run, &segs, next);
        if let Some(b) = &bar {
            b.set_position(next.min(segs.len()) as u64);
        }
        // the program's clock stands still while the servo holds its start for the brakes
        // to open (`Servo::motion_held`): the machine's supervisor does not tick it
        let held = run.servo().motion_held();
        run.control_with(&[]);
        let sample: PathSample = *run.machine().path_sample();
        let truth = run.world().tool_pos();
        run.finish_period();
        k += 1;
        if held {
            held_periods += 1;
        } else {
            along += f64::from(sample.path_speed_mm_s.abs()) * dt;
            let m = metric_sample(&sample, (k - held_periods) as f64 * dt, truth, along);
            metrics.add(&m, finished_at.is_none(), k.is_multiple_of(every));
        }

        match run.machine().program_end() {
            ProgramEnd::Running => {}
            ProgramEnd::Completed => {
                if finished_at.is_none() {
                    finished_at = Some(k - held_periods);
                }
            }
            ProgramEnd::Fault(_) => {
                fault = Some(stop_on_fault(&mut run)?);
                break;
            }
            _ => return Err(refusal(&run, &program, &name)),
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
    let realtime = realtime_ratio(k as f64 * dt, compute_s);
    let mut report = metrics.report(&program, segs.len(), duration_s, limits, fault, realtime);
    report.compression = compression;
    report.compute = ComputeJson {
        parse_s,
        compress_s,
        run_s: compute_s,
    };
    Ok(report)
}

/// Where the tool stood at the end of one dwell of a positioning program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DwellReading {
    /// The dwell's G-code line.
    pub line: u32,
    /// The programmed position (machine mm).
    pub nominal_mm: [f64; 3],
    /// The true tool position in the dwell's last period (the simulated laser
    /// interferometer, mm).
    pub tool_mm: [f64; 3],
}

/// Run the positioning program `program_path` (moves and `G4` dwells) on `machine` with
/// the axes' backlash and lead-screw compensation `comp` entered, as the machine's
/// settings would, and read the tool where each dwell ends: ISO 230-2's bidirectional
/// positioning test with a laser at the tool, in simulation.
pub fn run_positioning(
    program_path: &Path,
    machine: Option<&Path>,
    comp: &[controller_core::motion::compensation::AxisCompensation; 3],
) -> Result<Vec<DwellReading>> {
    let (mut cfg, pcfg) = machine_and_planner_with(machine, &FACTORY)?;
    let travel = travel_of(&cfg)?;
    let mut run = program_run(&mut cfg, &pcfg)?;
    for (axis, c) in controller_core::axes::Axis::ALL.into_iter().zip(comp) {
        run.machine_mut()
            .set_compensation(axis, *c)
            .map_err(|e| anyhow!("compensation of {axis:?}: {e:?}"))?;
    }
    arm_home_and_run(&mut run)?;
    let here = run
        .servo()
        .planner_start_mm()
        .ok_or_else(|| anyhow!("the servo is not running the planner"))?;
    let name = program_path.display().to_string();
    let program = load_program_with(
        program_path,
        &parse_options(&FACTORY, here.map(f64::from)),
        &travel,
    )
    .map_err(|e| anyhow!("{e}"))?;
    let (segs, _) = segments(&program, decimal(pcfg.tolerance_mm));
    let (max_periods, _) = period_bounds(&program, run.servo().period_s());
    let mut readings: Vec<Option<DwellReading>> = vec![None; program.moves.len()];
    let (mut next, mut k) = (0usize, 0u64);
    loop {
        next = stream(&mut run, &segs, next);
        run.control_with(&[]);
        let tag = run.machine().path_sample().tag as usize;
        let tool_mm = run.world().tool_pos();
        run.finish_period();
        k += 1;
        if let Some(m) = program.moves.get(tag) {
            if matches!(m.kind, MoveKind::Dwell { .. }) {
                readings[tag] = Some(DwellReading {
                    line: m.line,
                    nominal_mm: m.from,
                    tool_mm,
                });
            }
        }
        if program_completed(&mut run, &program, &name, k, max_periods)? {
            break;
        }
    }
    Ok(readings.into_iter().flatten().collect())
}
