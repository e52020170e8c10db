//! `host-sim filters [--machine FILE] [--write DIR]`: the output filters of each axis
//! placed from its measured response and accepted only on the measured loop's margins
//! (issue 24, item 3; controller-core `filter`):
//!
//! 1. the open-loop response effort → encoder and its resonances, as `freqresp`
//!    measures them through the servo step ([`super::freqresp`]);
//! 2. the loop `L = C·F·P` of the laws the contour is judged with (the circle study's:
//!    DSMC with contour coupling), measured on the running machine
//!    ([`super::loop_response`]): its gain crossover is the loop's bandwidth;
//! 3. notches placed from the resonances and that bandwidth (controller-core
//!    `filter::place`: a resonance closer than 1.5× the bandwidth gets none);
//! 4. the loop measured again with the placed filters: accepted when it is stable with
//!    gain margins ≥ 6 dB and a phase margin ≥ 30° (`filter::accept`), and every run of
//!    the measurement stayed in its jog.
//!
//! `--write DIR` writes the accepted axes' filters to `DIR/filters.toml`, the file
//! `circle --comp DIR` reads. `--check DIR` measures the loop with `DIR/filters.toml`'s
//! filters (entered by hand, or written before) instead of placing any, and gives each
//! axis the same verdict.

use super::freqresp::{self, AxisResponse};
use super::loop_response::{self, LoopFailure, LoopPoint};
use crate::builtin::{self, resolve_all};
use anyhow::{anyhow, Result};
use controller_core::axes::Axis;
use controller_core::filter::{
    accept, margins_of_samples, place, AxisFilterConfig, FilterConfig, Margins, Resonance,
    MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG,
};
use controller_core::sim::run::RunConfig;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// The loop's measured frequencies: from where the integrators dominate to above the
/// phase crossover (log-spaced; dense enough that the phase moves by less than 180°
/// between neighbours across a ζ 0.04 mode).
pub const GRID_LO_HZ: f32 = 5.0;
pub const GRID_HI_HZ: f32 = 500.0;
pub const GRID_POINTS: usize = 72;

/// A loop's margins (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct MarginsJson {
    pub stable: bool,
    pub gain_margin_db: f32,
    pub lower_gain_margin_db: f32,
    pub phase_margin_deg: f32,
    pub gain_crossover_hz: Option<f32>,
    pub phase_crossover_hz: Option<f32>,
}

impl From<&Margins> for MarginsJson {
    fn from(m: &Margins) -> Self {
        Self {
            stable: m.stable,
            gain_margin_db: m.gain_margin_db,
            lower_gain_margin_db: m.lower_gain_margin_db,
            phase_margin_deg: m.phase_margin_deg,
            gain_crossover_hz: m.gain_crossover_hz,
            phase_crossover_hz: m.phase_crossover_hz,
        }
    }
}

/// One measured loop.
#[derive(Clone, Debug, Serialize)]
pub struct LoopJson {
    /// `Ok` margins, or why there are none.
    pub margins: Option<MarginsJson>,
    pub error: Option<String>,
    /// Frequency, gain (dB), phase (degrees, unwrapped along the frequencies from the
    /// first point's value in (-360, 0]) of each point.
    pub points: Vec<[f32; 3]>,
    /// Runs that left the jog (a fault, an unstable loop), with why.
    pub failed: Vec<(f32, String)>,
}

/// One axis: what was placed and whether it was accepted.
#[derive(Clone, Debug, Serialize)]
pub struct AxisFilters {
    pub resonances: Vec<freqresp::ModeJson>,
    pub without: LoopJson,
    /// The filters placed (empty: none needed or none possible).
    pub placed: Vec<FilterConfig>,
    /// Resonances that need a notch but sit within 1.5× the bandwidth.
    pub near_bandwidth: u8,
    pub with: Option<LoopJson>,
    /// `accepted`, `none placed`, or why the placed filters were refused.
    pub verdict: String,
}

impl AxisFilters {
    /// The filters to enter: the placed ones when accepted.
    pub fn accepted(&self) -> Option<AxisFilterConfig> {
        (self.verdict == "accepted")
            .then(|| AxisFilterConfig::new(&self.placed).ok())
            .flatten()
    }
}

/// The whole study.
#[derive(Clone, Debug, Serialize)]
pub struct FiltersReport {
    pub machine: String,
    pub axes: BTreeMap<String, AxisFilters>,
}

/// A loop given as its points `(freq_hz, L)` in rising frequency, with the runs that
/// failed: its JSON and its margins if it has them (the simulated study's and
/// `gantry tune`'s, measured on a machine).
pub fn loop_json(
    points: &[(f32, (f32, f32))],
    failed: Vec<(f32, String)>,
) -> (LoopJson, Option<Margins>) {
    let freqs: Vec<f32> = points.iter().map(|p| p.0).collect();
    let gains: Vec<(f32, f32)> = points.iter().map(|p| p.1).collect();
    let m = margins_of_samples(&freqs, &gains);
    let json = LoopJson {
        margins: m.as_ref().ok().map(MarginsJson::from),
        error: m.as_ref().err().map(|e| format!("{e:?}")),
        points: points
            .iter()
            .zip(freqresp::unwrap_phases(
                gains.iter().map(|g| f64::from(g.1.atan2(g.0).to_degrees())),
            ))
            .map(|(&(f, (re, im)), phase)| {
                let db = 20.0 * re.hypot(im).max(1e-30).log10();
                [f, db, phase as f32]
            })
            .collect(),
        failed,
    };
    (json, m.ok())
}

/// The loop of `axis` measured over the study's grid with `filters` on the outputs: its
/// points (with the runs that left their jog) and its margins if it has them.
fn measured(
    base: &RunConfig,
    axis: Axis,
    filters: &[AxisFilterConfig; 3],
    inertia: f64,
) -> Result<(LoopJson, Option<Margins>)> {
    let grid = loop_response::log_grid(GRID_LO_HZ, GRID_HI_HZ, GRID_POINTS);
    let (pts, failed) = loop_response::measure(base, axis, filters, &grid, inertia)?;
    let pts: Vec<_> = pts
        .iter()
        .map(|p: &LoopPoint| (p.freq_hz, p.gain))
        .collect();
    let failed = failed
        .into_iter()
        .map(|f: LoopFailure| (f.freq_hz, f.why))
        .collect();
    Ok(loop_json(&pts, failed))
}

/// The loop of `axis` measured with `filters` on the outputs, and the verdict on them:
/// `accepted` when every run stayed in its jog and the margins pass `filter::accept`,
/// else `refused: ...` with every reason (the margin short of its bound, the runs that
/// faulted).
pub fn check(
    base: &RunConfig,
    axis: Axis,
    filters: &[AxisFilterConfig; 3],
    inertia: f64,
) -> Result<(LoopJson, String)> {
    let (with, m) = measured(base, axis, filters, inertia)?;
    let verdict = verdict(m.as_ref(), &with.failed, GRID_POINTS);
    Ok((with, verdict))
}

/// The verdict on a loop with filters: `accepted` when every one of its `runs` stayed in
/// its jog (`failed` lists those that did not) and its margins pass `filter::accept`,
/// else `refused: ...` with every reason (the margin short of its bound, the runs that
/// faulted).
pub fn verdict(m: Option<&Margins>, failed: &[(f32, String)], runs: usize) -> String {
    let mut why = Vec::new();
    match m {
        None => why.push("the loop has no margins".to_string()),
        Some(m) => {
            if !m.stable {
                why.push("the loop is unstable".into());
            }
            for (name, v, min, unit) in [
                ("gain margin", m.gain_margin_db, MIN_GAIN_MARGIN_DB, " dB"),
                (
                    "lower gain margin",
                    m.lower_gain_margin_db,
                    MIN_GAIN_MARGIN_DB,
                    " dB",
                ),
                (
                    "phase margin",
                    m.phase_margin_deg,
                    MIN_PHASE_MARGIN_DEG,
                    "°",
                ),
            ] {
                if !(v >= min) {
                    why.push(format!("{name} {v:.1}{unit} < {min}{unit}"));
                }
            }
            // (the same rule as `filter::accept`, every reason named)
            debug_assert_eq!(
                why.is_empty(),
                accept(m, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG).is_ok()
            );
        }
    }
    if let Some((f, first)) = failed.first() {
        why.push(format!(
            "{} of {runs} runs left the jog (at {f:.1} Hz: {first})",
            failed.len(),
        ));
    }
    if why.is_empty() {
        "accepted".to_string()
    } else {
        format!("refused: {}", why.join("; "))
    }
}

/// Place and check one axis' filters.
fn axis_filters(base: &RunConfig, axis: Axis, p: &AxisResponse) -> Result<AxisFilters> {
    let none = [AxisFilterConfig::NONE; 3];
    let (without, m0) = measured(base, axis, &none, p.inertia)?;
    let mut out = AxisFilters {
        resonances: p.resonances.clone(),
        without,
        placed: Vec::new(),
        near_bandwidth: 0,
        with: None,
        verdict: String::new(),
    };
    let Some(bw) = m0.and_then(|m| m.gain_crossover_hz) else {
        out.verdict = "no bandwidth: the loop without filters has no margins".into();
        return Ok(out);
    };
    let modes: Vec<Resonance> = p
        .resonances
        .iter()
        .map(super::freqresp::ModeJson::resonance)
        .collect();
    let period_s = 1.0 / base.servo.rate_hz as f32;
    let placed = place(&modes, bw, period_s, false).map_err(|e| anyhow!("placement: {e}"))?;
    out.placed = placed.filters.stages().to_vec();
    out.near_bandwidth = placed.near_bandwidth;
    if placed.filters.is_empty() {
        out.verdict = "none placed".into();
        return Ok(out);
    }
    let mut filters = none;
    filters[axis.index()] = placed.filters;
    let (with, verdict) = check(base, axis, &filters, p.inertia)?;
    out.with = Some(with);
    out.verdict = verdict;
    Ok(out)
}

/// The circle study's laws on the built-in flexible gantry.
const FLEXIBLE: &str = "[machine]\nfile = \"../machines/gantry_flexible.toml\"\n";

/// The run the loop is measured on: the circle study's laws on `machine` (default: the
/// built-in flexible gantry).
pub fn loop_base(machine: Option<&Path>) -> Result<RunConfig> {
    let file = match machine {
        Some(m) => builtin::load_on_machine("circle.toml", m)?,
        None => builtin::load_with("circle.toml", FLEXIBLE)?,
    };
    Ok(resolve_all(&file)?
        .first()
        .ok_or_else(|| anyhow!("circle.toml has no runs"))?
        .run)
}

/// Run the study on the built-in flexible gantry (or `machine`): place each axis'
/// filters and check them; with `given` (a `filters.toml`'s axes), check those instead
/// of placing (an axis without filters is measured without).
pub fn run(machine: Option<&Path>, given: Option<&[AxisFilterConfig; 3]>) -> Result<FiltersReport> {
    let open = freqresp::run(machine)?;
    let base = loop_base(machine)?;
    let mut axes = BTreeMap::new();
    for axis in Axis::ALL {
        let name = axis.name().to_string();
        let p = open
            .axes
            .get(&name)
            .ok_or_else(|| anyhow!("axis {name}: no open-loop response"))?;
        let a = match given {
            None => axis_filters(&base, axis, p)?,
            Some(g) => given_filters(&base, axis, p, &g[axis.index()])?,
        };
        axes.insert(name, a);
    }
    Ok(FiltersReport {
        machine: open.machine,
        axes,
    })
}

/// One axis' given filters checked on the measured loop.
fn given_filters(
    base: &RunConfig,
    axis: Axis,
    p: &AxisResponse,
    given: &AxisFilterConfig,
) -> Result<AxisFilters> {
    let none = [AxisFilterConfig::NONE; 3];
    let (without, _) = measured(base, axis, &none, p.inertia)?;
    let mut out = AxisFilters {
        resonances: p.resonances.clone(),
        without,
        placed: given.stages().to_vec(),
        near_bandwidth: 0,
        with: None,
        verdict: "none given".into(),
    };
    if !given.is_empty() {
        let mut filters = none;
        filters[axis.index()] = *given;
        let (with, verdict) = check(base, axis, &filters, p.inertia)?;
        out.with = Some(with);
        out.verdict = verdict;
    }
    Ok(out)
}

fn margins_cell(l: &LoopJson) -> String {
    match &l.margins {
        Some(m) => format!(
            "{:>6.1} Hz {:>6.1} dB {:>6.1}°{}",
            m.gain_crossover_hz.unwrap_or(f32::NAN),
            m.gain_margin_db.min(m.lower_gain_margin_db),
            m.phase_margin_deg,
            if m.stable { "" } else { " unstable" }
        ),
        None => format!("no margins ({})", l.error.as_deref().unwrap_or("-")),
    }
}

/// The report as a table.
pub fn table(r: &FiltersReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "Output filters on {}", r.machine);
    let _ = writeln!(
        s,
        "{:<4} {:<32} {:<40} {:<32} verdict",
        "axis", "loop without (fc, GM, PM)", "placed", "loop with (fc, GM, PM)"
    );
    for (name, a) in &r.axes {
        let placed = if a.placed.is_empty() && a.verdict == "none given" {
            "-".to_string()
        } else if a.placed.is_empty() {
            format!("- ({} near the bandwidth)", a.near_bandwidth)
        } else {
            a.placed.iter().map(describe).collect::<Vec<_>>().join(", ")
        };
        let with = a.with.as_ref().map_or("-".into(), margins_cell);
        let _ = writeln!(
            s,
            "{:<4} {:<32} {:<40} {:<32} {}",
            name,
            margins_cell(&a.without),
            placed,
            with,
            a.verdict
        );
    }
    s
}

fn describe(f: &FilterConfig) -> String {
    match *f {
        FilterConfig::Notch {
            freq_hz,
            width_hz,
            depth_db,
        } => format!("notch {freq_hz:.1} Hz w {width_hz:.1} Hz {depth_db:.1} dB"),
        FilterConfig::LowPass { cutoff_hz, q } => format!("low-pass {cutoff_hz:.0} Hz q {q:.2}"),
    }
}

/// The accepted axes' filters as a `filters.toml` (an axis without: left out), one
/// line per axis in the form `circle --comp` and machine files read.
pub fn filters_toml(r: &FiltersReport) -> String {
    let mut s = format!(
        "# Output filters placed by `host-sim filters` on {} and accepted on the\n\
         # measured loop's margins (gain >= {MIN_GAIN_MARGIN_DB} dB, phase >= {MIN_PHASE_MARGIN_DEG} deg).\n",
        r.machine
    );
    for (name, a) in &r.axes {
        let Some(f) = a.accepted() else { continue };
        let stages: Vec<String> = f.stages().iter().map(stage_toml).collect();
        let _ = writeln!(s, "{name} = [{}]", stages.join(", "));
    }
    s
}

/// One stage as an inline TOML table (`f32` printed to round-trip exactly).
fn stage_toml(f: &FilterConfig) -> String {
    match *f {
        FilterConfig::Notch {
            freq_hz,
            width_hz,
            depth_db,
        } => format!(
            "{{ notch = {{ freq_hz = {freq_hz:?}, width_hz = {width_hz:?}, depth_db = {depth_db:?} }} }}"
        ),
        FilterConfig::LowPass { cutoff_hz, q } => {
            format!("{{ low_pass = {{ cutoff_hz = {cutoff_hz:?}, q = {q:?} }} }}")
        }
    }
}
