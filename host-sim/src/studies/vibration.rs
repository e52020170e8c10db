//! `host-sim vibration [--machine FILE] [--json FILE]`: the residual vibration at the tool
//! after a 200 mm/s rapid stop, unshaped and with every input shaper that fits the board's
//! history at each axis' measured mode (issue 24, items 4 and 7; controller-core
//! `motion::shaper`). The goal it checks: "≥ 5× lower peak, settled to 5 µm ≥ 3× sooner".
//!
//! 1. Each axis' mode (frequency and damping ratio) is measured, not read from the machine
//!    file: the strongest resonance of `freqresp`'s response ([`super::freqresp`]).
//! 2. Each axis alone runs a G-code program through the machine the board runs, as
//!    `host-sim gcode` does ([`crate::gcode::runner`]): a slow approach to one end of a
//!    [`MOVE_MM`] stretch, a dwell, a `G0` rapid to the other end at [`RAPID_MM_S`], and a
//!    dwell of [`OBSERVE_S`] while the tool is watched.
//! 3. The figures, at the tool (the simulated tool-side position, as `circle` and
//!    `compensation` measure): from the period the reference the servo follows has stopped
//!    at the end, the peak |tool − rest| and the time until the tool stays within
//!    [`SETTLE_UM`] of its rest.
//! 4. Two planners: "stiff" (jerk [`STIFF_JERK_MM_S3`] on every axis: a near-trapezoid,
//!    whose acceleration steps excite the modes) and the factory's own jerk.
//! 5. Shaped runs shape the moving axis only, with every kind `ShaperStage::configure`
//!    accepts at the measured mode; the headline is the kind with the lowest peak.
//!
//! About the rest: on the flexible gantry the tool does not come to rest at the programmed
//! end but up to ~25 µm from it (X, Y: the screw's lead error, ±15 µm periodic, and the
//! nut's 20 µm backlash; every axis: its guides' friction catching the tool, ±21 µm on Y),
//! with or without a shaper: a static error, which the compensation tables take up
//! (`host-sim compensation`), not a vibration. So the vibration is measured about where
//! the tool rests (its mean over the observation's last [`REST_TAIL_S`]), and the static
//! error is reported beside it (`rest_um`, and `peak_from_end_um` with it included).
//!
//! Equal acceleration: the machine counts a shaper's contour deviation inside the
//! planner's path tolerance and lowers the shaped axis' acceleration when it takes more
//! than half of it (Y's ZV at 2000 mm/s² deviates by 0.05 mm, five times the factory
//! 0.01 mm: the acceleration would drop tenfold, and a gentler stop rings less whether
//! shaped or not). A single-axis rapid has no corner to blend, so the shaped runs get a
//! path tolerance wide enough to keep the unshaped run's acceleration: the figures
//! compare the shaper, not a slower stop. The effective acceleration is reported.

use super::freqresp::{self, ModeJson};
use crate::gcode::program::{decimal, parse_options, segments, travel_of};
use crate::gcode::runner::{
    arm_home_and_run, period_bounds, program_completed, program_run, stream,
};
use crate::gcode::{self, check_travel, MoveKind};
use crate::jobs;
use crate::sim_gantry::machine_and_planner_with;
use anyhow::{anyhow, bail, Result};
use controller_core::axes::Axis;
use controller_core::motion::planner::PlannerConfig;
use controller_core::motion::shaper::{AxisShapers, ShaperConfig, ShaperKind, ShaperStage};
use controller_core::settings::FACTORY;
use controller_core::sim::run::RunConfig;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The rapid's speed (the goal's), mm/s: the planner's speed limit in these runs, so `G0`
/// moves at it.
pub const RAPID_MM_S: f32 = 200.0;
/// Length of the measured rapid, centred on the travel's middle, mm: at 2000 mm/s² the
/// axis reaches 200 mm/s within 12 mm, so it cruises for at least 30 mm.
pub const MOVE_MM: f64 = 60.0;
/// Feed of the approach to the rapid's start, mm/min (slow: it must not ring).
pub const APPROACH_FEED_MM_MIN: f64 = 1200.0;
/// Dwell between the approach and the rapid, s.
pub const PRE_DWELL_S: f64 = 0.3;
/// Dwell after the rapid, while the tool is watched, s.
pub const OBSERVE_S: f64 = 0.5;
/// The settling band, µm.
pub const SETTLE_UM: f64 = 5.0;
/// The rest is the tool's mean over the observation's last this many seconds.
pub const REST_TAIL_S: f64 = 0.05;
/// The stiff planner's jerk on every axis, mm/s³.
pub const STIFF_JERK_MM_S3: f32 = 1.0e6;
/// The goal: the shaped peak at least this many times lower...
pub const GOAL_PEAK_RATIO: f64 = 5.0;
/// ... and settled this many times sooner.
pub const GOAL_SETTLE_RATIO: f64 = 3.0;

/// The machine studied when none is given.
pub fn default_machine() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("machines/gantry_flexible.toml")
}

/// The planner of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlannerKind {
    /// Jerk [`STIFF_JERK_MM_S3`] on every axis.
    Stiff,
    /// The factory settings' planner.
    Factory,
}

impl PlannerKind {
    pub const ALL: [PlannerKind; 2] = [Self::Stiff, Self::Factory];

    pub fn name(self) -> &'static str {
        match self {
            Self::Stiff => "stiff",
            Self::Factory => "factory",
        }
    }
}

/// One stop's figures at the tool (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct StopFigures {
    /// `unshaped`, or the shaper's Klipper name (`zv`, `mzv`, ...).
    pub kind: String,
    /// Largest |tool − rest| from the reference's stop on, µm (rest: where the tool
    /// comes to rest, module docs "About the rest").
    pub peak_um: f64,
    /// From the reference's stop until the tool stays within [`SETTLE_UM`] of its rest,
    /// ms; `None` (JSON null) when it was still outside in the last [`REST_TAIL_S`].
    pub settle_ms: Option<f64>,
    /// Rest − the programmed end: the static error (the screw's lead error, the nut's
    /// backlash, the tool caught by its guides' friction), µm.
    pub rest_um: f64,
    /// Largest |tool − programmed end| from the stop on (the static error included), µm.
    pub peak_from_end_um: f64,
    /// The tool's range over the last [`REST_TAIL_S`] (small: it had come to rest), µm.
    pub tail_range_um: f64,
    /// From the planner's stop to the shaped reference's (the shaper's delay), ms.
    pub shaper_delay_ms: f64,
    /// The moving axis' acceleration limit the planner ran with, mm/s².
    pub acc_mm_s2: f64,
}

/// One axis' stop with one planner, unshaped and shaped.
#[derive(Clone, Debug, Serialize)]
pub struct StopJson {
    pub planner: PlannerKind,
    pub jerk_mm_s3: f64,
    pub unshaped: StopFigures,
    /// Every kind that fits the history at the axis' mode.
    pub shaped: Vec<StopFigures>,
    /// The shaped run with the lowest peak (none when no kind fits).
    pub best: Option<StopFigures>,
    /// Unshaped over best: peak, settling time (`None` when either did not settle; a
    /// shaped run that never left the band, 0 ms, is credited with one period).
    pub peak_ratio: Option<f64>,
    pub settle_ratio: Option<f64>,
    /// Both ratios reach the goal's.
    pub goal_met: bool,
}

/// One axis.
#[derive(Clone, Debug, Serialize)]
pub struct AxisJson {
    pub axis: char,
    /// The measured mode the shapers are tuned to (`None`: no resonance measured, the
    /// axis stays unshaped).
    pub mode_hz: Option<f64>,
    pub damping_ratio: Option<f64>,
    /// Kinds `ShaperStage::configure` refused at this mode (too long for the history).
    pub refused: Vec<String>,
    /// The rapid: from, to, mm.
    pub from_mm: f64,
    pub to_mm: f64,
    pub stops: Vec<StopJson>,
}

/// The whole study.
#[derive(Clone, Debug, Serialize)]
pub struct VibrationReport {
    pub machine: String,
    pub rapid_mm_s: f64,
    pub settle_band_um: f64,
    pub axes: Vec<AxisJson>,
}

/// The measured mode an axis is shaped for: its strongest resonance.
pub fn strongest(res: &[ModeJson]) -> Option<ModeJson> {
    res.iter()
        .copied()
        .max_by(|a, b| a.peak_db.total_cmp(&b.peak_db))
}

/// The shaper of `kind` at `mode` (the measured damping ratio, within the kind's range).
fn shaper_at(kind: ShaperKind, mode: &ModeJson) -> ShaperConfig {
    let mut c = ShaperConfig::new(kind, mode.freq_hz as f32);
    c.damping_ratio = (mode.damping_ratio as f32).clamp(0.0, kind.max_damping_ratio());
    c
}

/// `axis` shaped with `c`, the others not.
pub fn only(axis: Axis, c: ShaperConfig) -> AxisShapers {
    let mut s = AxisShapers::NONE;
    match axis {
        Axis::X => s.x = Some(c),
        Axis::Y => s.y = Some(c),
        Axis::Z => s.z = Some(c),
    }
    s
}

/// The kinds the board's shaper stage takes at `mode` on `axis` (period `period_s`), and
/// the names of those it refuses.
pub fn fitting_kinds(
    axis: Axis,
    mode: &ModeJson,
    period_s: f32,
) -> (Vec<ShaperConfig>, Vec<String>) {
    let (mut ok, mut refused) = (Vec::new(), Vec::new());
    for kind in ShaperKind::ALL {
        let c = shaper_at(kind, mode);
        let mut stage = ShaperStage::NONE;
        match stage.configure(&only(axis, c), period_s) {
            Ok(()) => ok.push(c),
            Err(_) => refused.push(kind.name().to_string()),
        }
    }
    (ok, refused)
}

/// The planner of `kind` for these runs: `base` (the factory's) at [`RAPID_MM_S`], with
/// the stiff jerk for [`PlannerKind::Stiff`].
pub fn planner_of(base: &PlannerConfig, kind: PlannerKind) -> PlannerConfig {
    let mut p = *base;
    for v in &mut p.vel_max_mm_s {
        *v = v.min(RAPID_MM_S);
    }
    if kind == PlannerKind::Stiff {
        p.jerk_max_mm_s3 = [STIFF_JERK_MM_S3; 3];
    }
    p
}

/// The rapid of `axis` on machine `cfg`: from, to (centred on its travel), mm.
fn stretch(cfg: &RunConfig, axis: Axis) -> Result<(f64, f64)> {
    let t = cfg.servo.travel.axes[axis.index()];
    let (lo, hi) = (f64::from(t.min_mm), f64::from(t.max_mm));
    let mid = if lo.is_finite() && hi.is_finite() {
        if hi - lo < MOVE_MM + 2.0 {
            bail!(
                "axis {}: the travel [{lo}, {hi}] mm is shorter than the {MOVE_MM} mm rapid",
                letter(axis)
            );
        }
        0.5 * (lo + hi)
    } else {
        0.0
    };
    Ok((mid - 0.5 * MOVE_MM, mid + 0.5 * MOVE_MM))
}

/// The axis' G-code letter (the JSON's `axis`).
fn letter(axis: Axis) -> char {
    ['X', 'Y', 'Z'][axis.index()]
}

/// The program of one stop: approach `from` slowly, dwell, rapid to `to`, dwell.
fn program_text(axis: Axis, from: f64, to: f64) -> String {
    let a = letter(axis);
    format!(
        "(residual vibration, axis {a})\nG21 G90 G94 G61\nG1 {a}{from:.4} F{APPROACH_FEED_MM_MIN}\n\
         G4 P{PRE_DWELL_S}\nG0 {a}{to:.4}\nG4 P{OBSERVE_S}\nM2\n"
    )
}

/// What one run of the program recorded from the rapid on, per period: whether the
/// reference the servo follows and the planner's own (before the shaper) were still
/// moving on the axis, and the tool's position, mm.
struct Trace {
    planner_moving: Vec<bool>,
    reference_moving: Vec<bool>,
    tool_mm: Vec<f64>,
    dt_s: f64,
    acc_mm_s2: f64,
}

/// Below this the reference has stopped (mm, mm/s): the shaped reference drains to the
/// programmed end bit for bit, so these only absorb `f32` rounding.
const STOPPED_MM: f64 = 1e-5;
const STOPPED_MM_S: f64 = 1e-3;

/// Run the stop of `axis` from `from` to `to` on machine `base` with planner `pcfg`,
/// shaped by `shapers`.
fn run_stop(
    base: &RunConfig,
    pcfg: &PlannerConfig,
    axis: Axis,
    (from, to): (f64, f64),
    shapers: &AxisShapers,
) -> Result<Trace> {
    let i = axis.index();
    let mut cfg = *base;
    let travel = travel_of(&cfg)?;
    let mut pcfg = *pcfg;
    // (equal acceleration, module docs: the tolerance widened until the shaper's deviation
    // at the unshaped acceleration takes at most half of it)
    let mut probe = ShaperStage::NONE;
    probe
        .configure(shapers, pcfg.period_s)
        .map_err(|e| anyhow!("axis {}: shaper refused: {e:?}", axis.name()))?;
    let dev = probe.bound().deviation_bound_axes_mm(pcfg.acc_max_mm_s2);
    pcfg.tolerance_mm = pcfg.tolerance_mm.max(2.0 * dev * 1.001);
    let mut run = program_run(&mut cfg, &pcfg)?;
    run.machine_mut()
        .set_shapers(shapers)
        .map_err(|e| anyhow!("axis {}: shapers refused: {e:?}", axis.name()))?;
    let effective = run
        .machine()
        .planner_config()
        .map_err(|e| anyhow!("axis {}: {}", axis.name(), e.message()))?;
    arm_home_and_run(&mut run)?;
    let here = run
        .servo()
        .planner_start_mm()
        .ok_or_else(|| anyhow!("the servo is not running the planner"))?;
    let name = format!("vibration_{}.nc", axis.name().to_ascii_lowercase());
    let program = gcode::parse_str_with(
        &name,
        &program_text(axis, from, to),
        &parse_options(&FACTORY, here.map(f64::from)),
    )
    .map_err(|e| anyhow!("{e}"))?;
    check_travel(&program, &travel).map_err(|e| anyhow!("{e}"))?;
    let rapid = program
        .moves
        .iter()
        .position(|m| matches!(m.kind, MoveKind::Rapid { .. }))
        .ok_or_else(|| anyhow!("{name}: no rapid"))?;
    let (segs, _) = segments(&program, decimal(pcfg.tolerance_mm));
    let dt = run.servo().period_s();
    let (max_periods, _) = period_bounds(&program, dt);
    let mut trace = Trace {
        planner_moving: Vec::new(),
        reference_moving: Vec::new(),
        tool_mm: Vec::new(),
        dt_s: dt,
        acc_mm_s2: f64::from(effective.acc_max_mm_s2[i]),
    };
    let (mut next, mut k) = (0usize, 0u64);
    let mut started = false;
    loop {
        next = stream(&mut run, &segs, next);
        run.control_with(&[]);
        let s = *run.machine().path_sample();
        let tool = run.world().tool_pos()[i];
        run.finish_period();
        k += 1;
        // (the executor's tag is the rapid's from its first period on; the shaped
        // position lags it, which the stop's detection below allows for)
        started |= s.tag as usize >= rapid;
        if started {
            let pos = f64::from(s.pos_mm.to_array()[i]);
            let vel = f64::from(s.vel_mm_s.to_array()[i]);
            trace
                .reference_moving
                .push((pos - to).abs() > STOPPED_MM || vel.abs() > STOPPED_MM_S);
            // (the planner's own motion: its path speed, which the shaper leaves as is)
            trace
                .planner_moving
                .push(s.path_speed_mm_s.abs() > STOPPED_MM_S as f32);
            trace.tool_mm.push(tool);
        }
        if program_completed(&mut run, &program, &name, k, max_periods)? {
            break;
        }
    }
    Ok(trace)
}

/// The figures of a trace ending at `to`.
fn figures(kind: &str, t: &Trace, to: f64) -> Result<StopFigures> {
    let last_moving = |m: &[bool]| m.iter().rposition(|&b| b).map_or(0, |k| k + 1);
    let stop = last_moving(&t.reference_moving);
    let planner_stop = last_moving(&t.planner_moving);
    let tail = ((REST_TAIL_S / t.dt_s) as usize).max(1);
    let after = t
        .tool_mm
        .get(stop..)
        .filter(|a| a.len() > 2 * tail)
        .ok_or_else(|| anyhow!("{kind}: the reference did not stop long enough before the end"))?;
    let tail_mm = &after[after.len() - tail..];
    let rest = tail_mm.iter().sum::<f64>() / tail as f64;
    let tail_range_um = 1e3
        * (tail_mm.iter().fold(f64::MIN, |m, x| m.max(*x))
            - tail_mm.iter().fold(f64::MAX, |m, x| m.min(*x)));
    let err_um: Vec<f64> = after.iter().map(|x| (x - rest) * 1e3).collect();
    let peak_um = err_um.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let settle_ms = match err_um.iter().rposition(|e| e.abs() > SETTLE_UM) {
        None => Some(0.0),
        Some(k) if k + 1 < err_um.len() - tail => Some((k + 1) as f64 * t.dt_s * 1e3),
        Some(_) => None,
    };
    Ok(StopFigures {
        kind: kind.to_string(),
        peak_um,
        settle_ms,
        rest_um: (rest - to) * 1e3,
        peak_from_end_um: after
            .iter()
            .fold(0.0f64, |m, x| m.max((x - to).abs() * 1e3)),
        tail_range_um,
        shaper_delay_ms: stop.saturating_sub(planner_stop) as f64 * t.dt_s * 1e3,
        acc_mm_s2: t.acc_mm_s2,
    })
}

/// One job of the study: an axis, a planner, a shaper (or none).
struct Job {
    axis: Axis,
    planner: PlannerKind,
    shaper: Option<ShaperConfig>,
}

/// Unshaped over shaped (`None` when either is missing); the shaped one at least `floor`.
fn ratio(unshaped: Option<f64>, shaped: Option<f64>, floor: f64) -> Option<f64> {
    Some(unshaped? / shaped?.max(floor))
}

/// Run the study on `machine` (default: [`default_machine`]).
pub fn run(machine: Option<&Path>) -> Result<VibrationReport> {
    let path = machine.map_or_else(default_machine, Path::to_path_buf);
    let open = freqresp::run(Some(&path))?;
    let modes: Vec<Option<ModeJson>> = Axis::ALL
        .iter()
        .map(|a| {
            open.axes
                .get(a.name())
                .and_then(|r| strongest(&r.resonances))
        })
        .collect();
    run_with_modes(&path, &modes)
}

/// The study on the machine file `path` with each axis' mode given (what [`run`]
/// measured; a test may pass it directly): `modes[axis]`, `None` for an unshaped axis.
pub fn run_with_modes(path: &Path, modes: &[Option<ModeJson>]) -> Result<VibrationReport> {
    run_axes(path, modes, &Axis::ALL)
}

/// [`run_with_modes`] on `axes` only.
pub fn run_axes(path: &Path, modes: &[Option<ModeJson>], axes: &[Axis]) -> Result<VibrationReport> {
    let (cfg, factory) = machine_and_planner_with(Some(path), &FACTORY)?;
    let period_s = 1.0 / cfg.servo.rate_hz as f32;
    let mut jobs = Vec::new();
    let mut per_axis = Vec::new();
    for &axis in axes {
        let mode = modes.get(axis.index()).copied().flatten();
        let (kinds, refused) = match &mode {
            Some(m) => fitting_kinds(axis, m, period_s),
            None => (Vec::new(), Vec::new()),
        };
        for planner in PlannerKind::ALL {
            for shaper in std::iter::once(None).chain(kinds.iter().copied().map(Some)) {
                jobs.push(Job {
                    axis,
                    planner,
                    shaper,
                });
            }
        }
        per_axis.push((axis, mode, refused, stretch(&cfg, axis)?));
    }
    let figs = jobs::run_all(&jobs, |j| {
        let (from, to) = stretch(&cfg, j.axis)?;
        let shapers = j.shaper.map_or(AxisShapers::NONE, |c| only(j.axis, c));
        let t = run_stop(
            &cfg,
            &planner_of(&factory, j.planner),
            j.axis,
            (from, to),
            &shapers,
        )?;
        figures(j.shaper.map_or("unshaped", |c| c.kind.name()), &t, to)
    })?;
    let mut axes_json = Vec::new();
    for (axis, mode, refused, (from, to)) in per_axis {
        let mut stops = Vec::new();
        for planner in PlannerKind::ALL {
            let mut unshaped = None;
            let mut shaped = Vec::new();
            for (j, f) in jobs.iter().zip(&figs) {
                if j.axis == axis && j.planner == planner {
                    match j.shaper {
                        None => unshaped = Some(f.clone()),
                        Some(_) => shaped.push(f.clone()),
                    }
                }
            }
            let unshaped =
                unshaped.ok_or_else(|| anyhow!("axis {}: no unshaped run", axis.name()))?;
            let best = shaped
                .iter()
                .min_by(|a, b| a.peak_um.total_cmp(&b.peak_um))
                .cloned();
            // (a shaped run settled at once is credited with one period)
            let period_ms = f64::from(period_s) * 1e3;
            let peak_ratio = best
                .as_ref()
                .map(|b| unshaped.peak_um / b.peak_um.max(1e-3));
            let settle_ratio = best
                .as_ref()
                .and_then(|b| ratio(unshaped.settle_ms, b.settle_ms, period_ms));
            let goal_met = peak_ratio.is_some_and(|r| r >= GOAL_PEAK_RATIO)
                && settle_ratio.is_some_and(|r| r >= GOAL_SETTLE_RATIO);
            stops.push(StopJson {
                planner,
                jerk_mm_s3: f64::from(planner_of(&factory, planner).jerk_max_mm_s3[axis.index()]),
                unshaped,
                shaped,
                best,
                peak_ratio,
                settle_ratio,
                goal_met,
            });
        }
        axes_json.push(AxisJson {
            axis: letter(axis),
            mode_hz: mode.map(|m| m.freq_hz),
            damping_ratio: mode.map(|m| m.damping_ratio),
            refused,
            from_mm: from,
            to_mm: to,
            stops,
        });
    }
    Ok(VibrationReport {
        machine: path.display().to_string(),
        rapid_mm_s: f64::from(RAPID_MM_S),
        settle_band_um: SETTLE_UM,
        axes: axes_json,
    })
}

fn ms(v: Option<f64>) -> String {
    v.map_or("never".to_string(), |v| format!("{v:.1}"))
}

fn times(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |v| format!("{v:.1}×"))
}

/// The report as a table.
pub fn table(r: &VibrationReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Residual vibration at the tool after a {} mm/s rapid stop on {} (settled: within {} µm; goal: peak ≥ {GOAL_PEAK_RATIO}× lower, settled ≥ {GOAL_SETTLE_RATIO}× sooner)",
        r.rapid_mm_s, r.machine, r.settle_band_um
    );
    for a in &r.axes {
        let mode = match (a.mode_hz, a.damping_ratio) {
            (Some(f), Some(z)) => format!("mode {f:.2} Hz ζ {z:.4}"),
            _ => "no resonance measured: unshaped".to_string(),
        };
        let refused = if a.refused.is_empty() {
            String::new()
        } else {
            format!("; too long for the history: {}", a.refused.join(", "))
        };
        let _ = writeln!(
            s,
            "{}: {mode}{refused}; rapid {:.1} → {:.1} mm",
            a.axis, a.from_mm, a.to_mm
        );
        let _ = writeln!(
            s,
            "  {:<8} {:<9} {:>9} {:>10} {:>9} {:>12} {:>9} {:>10}",
            "planner",
            "shaper",
            "peak µm",
            "settle ms",
            "rest µm",
            "from end µm",
            "delay ms",
            "acc mm/s²"
        );
        for st in &a.stops {
            for f in std::iter::once(&st.unshaped).chain(&st.shaped) {
                let mark = if st.best.as_ref().is_some_and(|b| b.kind == f.kind) {
                    " *"
                } else {
                    ""
                };
                let _ = writeln!(
                    s,
                    "  {:<8} {:<9} {:>9.2} {:>10} {:>9.2} {:>12.2} {:>9.1} {:>10.0}{mark}",
                    st.planner.name(),
                    f.kind,
                    f.peak_um,
                    ms(f.settle_ms),
                    f.rest_um,
                    f.peak_from_end_um,
                    f.shaper_delay_ms,
                    f.acc_mm_s2
                );
            }
            // (a shaped tool that never left the band: its ratio is only a floor)
            let settle = match &st.best {
                Some(b) if b.settle_ms == Some(0.0) => {
                    format!("at once (≥ {})", times(st.settle_ratio))
                }
                _ => format!("{} sooner", times(st.settle_ratio)),
            };
            let _ = writeln!(
                s,
                "  {:<8} best {}: peak {} lower, settled {settle}: goal {}",
                st.planner.name(),
                st.best.as_ref().map_or("-", |b| b.kind.as_str()),
                times(st.peak_ratio),
                if st.goal_met { "met" } else { "not met" }
            );
        }
    }
    s
}
