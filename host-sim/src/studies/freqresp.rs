//! `host-sim freqresp [--machine FILE]`: each axis' frequency response from effort to
//! encoder, measured through the servo step exactly as the board measures it
//! (`Command::MeasureResponse`, from Disabled, inside a ±50 mm window around where the
//! axis stands; controller-core `sysid::frequency`), and its resonances and
//! anti-resonances ([`find_modes`]). On a machine whose axes have a frame
//! (`frame.mode_hz`, `frame.damping_ratio`, e.g. host-sim/machines/gantry_flexible.toml)
//! each measured resonance is compared with the frame's mode and with the linear
//! two-mass model's exact pole ([`model_mode`]: the frame plus the axis' viscous
//! friction, shared between the motor side and the guides as the world shares it).

use crate::builtin::{self, resolve_all};
use crate::jobs;
use anyhow::{anyhow, bail, Result};
use controller_core::axes::Axis;
use controller_core::plant::physical::PhysicalAxisConfig;
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::RunConfig;
use controller_core::sim::world::PlantConfig;
use controller_core::sysid::frequency::{
    find_modes, FrequencyResponse, Mode, ModeReport, MODE_DEFAULTS,
};
use controller_core::sysid::IdentifyStatus;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Half-width of the window each axis is measured in, around where it stands, mm (the
/// identification study's).
pub const WINDOW_HALF_MM: f32 = 50.0;
/// Periods a measurement may take before the study gives up (its own 180 s budget ends
/// it at 1.8 M periods at 10 kHz).
const MAX_PERIODS: u32 = 2_500_000;

/// One measured point (JSON keys are public interface).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PointJson {
    pub freq_hz: f64,
    /// `20 log10 |H|`, H in mm/(mN·m).
    pub magnitude_db: f64,
    /// `arg H`, unwrapped along the frequencies from the first point's value in
    /// (-360, 0] (a mass is -180).
    pub phase_deg: f64,
    /// `|H / H_rigid|` in dB: over the rigid-body line.
    pub relative_db: f64,
}

/// A resonance or anti-resonance.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ModeJson {
    pub freq_hz: f64,
    pub damping_ratio: f64,
    pub peak_db: f64,
}

impl ModeJson {
    /// As the filters' placement takes a measured resonance (`filter::place`).
    pub fn resonance(&self) -> controller_core::filter::Resonance {
        controller_core::filter::Resonance {
            freq_hz: self.freq_hz as f32,
            damping_ratio: self.damping_ratio as f32,
            peak_db: self.peak_db as f32,
        }
    }
}

impl From<&Mode> for ModeJson {
    fn from(m: &Mode) -> Self {
        Self {
            freq_hz: f64::from(m.freq_hz),
            damping_ratio: f64::from(m.damping_ratio),
            peak_db: f64::from(m.peak_db),
        }
    }
}

/// The machine file's mode of an axis and what the linear model makes of it.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MachineMode {
    /// `frame.mode_hz`, `frame.damping_ratio`.
    pub mode_hz: f64,
    pub damping_ratio: f64,
    /// The exact pole of the linear two-mass model (frame + the axis' viscous friction
    /// split between motor side and guides): frequency and damping the response has.
    pub model_hz: f64,
    pub model_damping_ratio: f64,
    /// The anti-resonance: `√(k / J_t)`, Hz.
    pub anti_resonance_hz: f64,
}

/// Measured against the machine file (and the model), per cent.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ModeErrors {
    pub freq_pct: f64,
    /// Against the frame's own `damping_ratio`.
    pub damping_pct: f64,
    /// Against the linear model's pole (the damping the guides' friction adds included).
    pub model_damping_pct: f64,
}

/// One axis' measurement.
#[derive(Clone, Debug, Serialize)]
pub struct AxisResponse {
    /// `done`, or why it stopped.
    pub status: String,
    pub machine_time_s: f64,
    /// The window the measurement ran within.
    pub window_mm: [f64; 2],
    /// The cap and what the run reached (the study sees every period; over the link
    /// `gantry freqresp` does not, and leaves these keys out).
    #[serde(flatten)]
    pub bounds: Option<RunBounds>,
    /// The rigid-body line: `J`, `B`.
    pub inertia: f64,
    pub viscous: f64,
    /// The delay the phase shows (removed before the modes are fitted), s.
    pub delay_s: f64,
    pub points: Vec<PointJson>,
    pub resonances: Vec<ModeJson>,
    pub anti_resonances: Vec<ModeJson>,
    /// The machine file's frame, when the axis has one.
    pub machine: Option<MachineMode>,
    /// The resonance nearest the machine's mode against it.
    pub error_pct: Option<ModeErrors>,
}

/// The torque cap a measurement ran under and how far it went.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct RunBounds {
    pub torque_cap_mnm: f64,
    /// Largest |motor position - start| and |effort| during the run.
    pub travel_max_mm: f64,
    pub effort_max_mnm: f64,
}

/// The whole study.
#[derive(Clone, Debug, Serialize)]
pub struct FreqRespReport {
    pub machine: String,
    pub axes: BTreeMap<String, AxisResponse>,
}

impl FreqRespReport {
    /// Every axis measured to the end.
    pub fn all_done(&self) -> bool {
        self.axes.values().all(|a| a.status == "done")
    }
}

/// A complex number for the model's pole.
#[derive(Clone, Copy, Debug)]
struct Cx(f64, f64);

impl Cx {
    fn mul(self, o: Cx) -> Cx {
        Cx(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: Cx) -> Cx {
        let d = o.0 * o.0 + o.1 * o.1;
        Cx(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn poly(c: &[f64], s: Cx) -> Cx {
        c.iter().fold(Cx(0.0, 0.0), |acc, k| {
            let m = acc.mul(s);
            Cx(m.0 + k, m.1)
        })
    }
}

/// The machine file's mode of `a` and the linear two-mass model's exact pole: the frame
/// (`plant/frame.rs`: `k = ω² J_m J_t / J`, `c = 2 ζ ω J_m J_t / J`) with the viscous
/// friction `B` split as the world splits it (the guides' share `φ B` on the tool, the rest
/// on the motor). The pole is the root near `j ω` of
/// `(J_m s² + (B_m + c) s + k)(J_t s² + (B_t + c) s + k) - (c s + k)²` over `s` (Newton).
pub fn model_mode(a: &PhysicalAxisConfig) -> Option<MachineMode> {
    let f = a.frame?;
    let j = f64::from(a.inertia);
    let rho = f64::from(f.tool_inertia_ratio);
    let (jm, jt) = ((1.0 - rho) * j, rho * j);
    let w = 2.0 * std::f64::consts::PI * f64::from(f.mode_hz);
    let mu = jm * jt / j;
    let (k, c) = (w * w * mu, 2.0 * f64::from(f.damping_ratio) * w * mu);
    let phi = f64::from(f.tool_friction_ratio);
    let (bt, bm) = (
        phi * f64::from(a.viscous),
        (1.0 - phi) * f64::from(a.viscous),
    );
    let p = [
        jm * jt,
        jm * (bt + c) + jt * (bm + c),
        (jm + jt) * k + bm * bt + c * (bm + bt),
        k * (bm + bt),
    ];
    let dp = [3.0 * p[0], 2.0 * p[1], p[2]];
    let mut s = Cx(0.0, w);
    for _ in 0..60 {
        let step = Cx::poly(&p, s).div(Cx::poly(&dp, s));
        s = Cx(s.0 - step.0, s.1 - step.1);
    }
    let wn = (s.0 * s.0 + s.1 * s.1).sqrt();
    Some(MachineMode {
        mode_hz: f64::from(f.mode_hz),
        damping_ratio: f64::from(f.damping_ratio),
        model_hz: wn / (2.0 * std::f64::consts::PI),
        model_damping_ratio: -s.0 / wn,
        anti_resonance_hz: (k / jt).sqrt() / (2.0 * std::f64::consts::PI),
    })
}

fn pct(measured: f64, truth: f64) -> f64 {
    100.0 * (measured - truth) / truth
}

/// What one axis' run gave: the points, the outcome, the travel and effort bounds.
struct Measured {
    frf: FrequencyResponse,
    status: IdentifyStatus,
    time_s: f64,
    travel_mm: f64,
    effort_mnm: f64,
    window_mm: [f64; 2],
}

/// Measure `axis` of the machine of run `base` through the servo step.
fn measure(base: &RunConfig, axis: Axis) -> Result<Measured> {
    let mut cfg = *base;
    // nothing else runs: the measured axis alone is driven (from Disabled)
    cfg.servo.model_known = [false; 3];
    let mut run = super::driven_run(cfg)?;
    let i = axis.index();
    let start = run.world().state()[i].pos;
    let at = start as f32;
    let window = [at - WINDOW_HALF_MM, at + WINDOW_HALF_MM];
    let s = run.control_with(&[Command::MeasureResponse {
        axis,
        window_mm: Some(window),
    }]);
    if let Some((_, why)) = s.refused {
        bail!(
            "axis {}: measurement refused: {}",
            axis.name(),
            why.message()
        );
    }
    run.finish_period();
    let mut frf = FrequencyResponse::new();
    let mut seen = None;
    let (mut travel, mut effort) = (0.0f64, 0.0f64);
    let mut k = 1u32;
    while run.servo().state() == ServoState::Identify {
        if k >= MAX_PERIODS {
            bail!("axis {}: the measurement did not end", axis.name());
        }
        let s = *run.control_with(&[]);
        if let Some((n, p)) = run.servo().response_point() {
            if seen != Some(n) {
                seen = Some(n);
                frf.push(p);
            }
        }
        effort = effort.max(f64::from(s.effort[i]).abs());
        run.finish_period();
        travel = travel.max((run.world().state()[i].pos - start).abs());
        k += 1;
    }
    let outcome = run.servo().response_outcome().ok_or_else(|| {
        anyhow!(
            "axis {}: the measurement did not run (state {:?}, fault {:?})",
            axis.name(),
            run.servo().state(),
            run.servo().faults().first()
        )
    })?;
    Ok(Measured {
        frf,
        status: outcome.status,
        time_s: f64::from(k) * run.servo().period_s(),
        travel_mm: travel,
        effort_mnm: effort,
        window_mm: window.map(f64::from),
    })
}

/// Phases (degrees) unwrapped along the frequencies: the first in (-360, 0], each next
/// one the nearest turn to its predecessor.
pub fn unwrap_phases(raw: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut last: Option<f64> = None;
    raw.map(|raw| {
        let phase = match last {
            Some(prev) => raw - 360.0 * ((raw - prev) / 360.0).round(),
            None if raw > 0.0 => raw - 360.0,
            None => raw,
        };
        last = Some(phase);
        phase
    })
    .collect()
}

/// The status word of a measurement's end: `done`, or why it stopped.
pub fn status_text(status: IdentifyStatus) -> String {
    match status {
        IdentifyStatus::Done => "done".to_string(),
        other => format!("{other:?}"),
    }
}

impl AxisResponse {
    /// The figures of a measured response `frf` (its rigid line, modes and points over the
    /// rigid line; [`find_modes`]), as the study and `gantry freqresp` report them;
    /// `machine`: the machine file's mode to compare the nearest resonance with.
    pub fn of(
        frf: &FrequencyResponse,
        status: String,
        machine_time_s: f64,
        window_mm: [f64; 2],
        bounds: Option<RunBounds>,
        machine: Option<MachineMode>,
    ) -> Self {
        let modes: ModeReport = find_modes(frf, &MODE_DEFAULTS).unwrap_or_default();
        let phases = unwrap_phases(frf.points().iter().map(|p| f64::from(p.phase_deg())));
        let points = frf
            .points()
            .iter()
            .zip(phases)
            .map(|(p, phase)| {
                let (rr, ri) = modes.rigid.response(p.freq_hz);
                let rigid_db = 10.0 * f64::from(rr * rr + ri * ri).max(1e-300).log10();
                PointJson {
                    freq_hz: f64::from(p.freq_hz),
                    magnitude_db: f64::from(p.magnitude_db()),
                    phase_deg: phase,
                    relative_db: f64::from(p.magnitude_db()) - rigid_db,
                }
            })
            .collect();
        let resonances: Vec<ModeJson> = modes.resonances().iter().map(ModeJson::from).collect();
        let error_pct = machine.and_then(|mm| {
            let near = resonances.iter().min_by(|a, b| {
                let d = |m: &ModeJson| (m.freq_hz / mm.mode_hz).ln().abs();
                d(a).total_cmp(&d(b))
            })?;
            Some(ModeErrors {
                freq_pct: pct(near.freq_hz, mm.mode_hz),
                damping_pct: pct(near.damping_ratio, mm.damping_ratio),
                model_damping_pct: pct(near.damping_ratio, mm.model_damping_ratio),
            })
        });
        Self {
            status,
            machine_time_s,
            window_mm,
            bounds,
            inertia: f64::from(modes.rigid.inertia),
            viscous: f64::from(modes.rigid.viscous),
            delay_s: f64::from(modes.delay_s),
            points,
            resonances,
            anti_resonances: modes.anti_resonances().iter().map(ModeJson::from).collect(),
            machine,
            error_pct,
        }
    }
}

/// Measure `axis` and find its modes; compare them with the machine file's `truth`.
pub fn measure_axis(base: &RunConfig, axis: Axis, truth: &PlantConfig) -> Result<AxisResponse> {
    let m = measure(base, axis)?;
    let machine = match truth {
        PlantConfig::Physical(a) => model_mode(a),
        PlantConfig::Paper(_) => None,
    };
    let torque_cap = match truth {
        PlantConfig::Physical(a) => {
            f64::from(base.servo.identify.torque_cap_mnm.min(a.torque_max_mnm))
        }
        PlantConfig::Paper(_) => f64::from(base.servo.identify.torque_cap_mnm),
    };
    Ok(AxisResponse::of(
        &m.frf,
        status_text(m.status),
        m.time_s,
        m.window_mm,
        Some(RunBounds {
            torque_cap_mnm: torque_cap,
            travel_max_mm: m.travel_mm,
            effort_max_mnm: m.effort_mnm,
        }),
        machine,
    ))
}

/// Run the study on the built-in flexible gantry (or `machine`).
pub fn run(machine: Option<&Path>) -> Result<FreqRespReport> {
    let file = match machine {
        Some(m) => builtin::load_on_machine("freqresp.toml", m)?,
        None => builtin::load("freqresp.toml")?,
    };
    let runs = resolve_all(&file)?;
    let base = runs
        .first()
        .ok_or_else(|| anyhow!("freqresp.toml has no runs"))?
        .run;
    let reports = jobs::run_all(&Axis::ALL, |a| {
        measure_axis(&base, *a, &base.world.plants[a.index()])
    })?;
    Ok(FreqRespReport {
        machine: machine.map_or(
            "host-sim/machines/gantry_flexible.toml (built in)".into(),
            |m| m.display().to_string(),
        ),
        axes: Axis::ALL
            .iter()
            .map(|a| a.name().to_string())
            .zip(reports)
            .collect(),
    })
}

/// The report as a table.
pub fn table(r: &FreqRespReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "Frequency response (effort to encoder) on {}", r.machine);
    let _ = writeln!(
        s,
        "{:<4} {:>9} {:>9} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>8}",
        "axis",
        "f meas",
        "f file",
        "err %",
        "ζ meas",
        "ζ file",
        "err %",
        "ζ model",
        "err %",
        "peak dB",
        "status"
    );
    for (name, a) in &r.axes {
        let res = a.resonances.first();
        let near = a.machine.and_then(|mm| {
            a.resonances.iter().min_by(|x, y| {
                let d = |m: &ModeJson| (m.freq_hz / mm.mode_hz).ln().abs();
                d(x).total_cmp(&d(y))
            })
        });
        let shown = near.or(res);
        let cell = |v: Option<f64>, p: usize| v.map_or("-".to_string(), |v| format!("{v:.p$}"));
        let _ = writeln!(
            s,
            "{:<4} {:>9} {:>9} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9} {:>8}",
            name,
            cell(shown.map(|m| m.freq_hz), 2),
            cell(a.machine.map(|m| m.mode_hz), 2),
            cell(a.error_pct.map(|e| e.freq_pct), 2),
            cell(shown.map(|m| m.damping_ratio), 4),
            cell(a.machine.map(|m| m.damping_ratio), 4),
            cell(a.error_pct.map(|e| e.damping_pct), 1),
            cell(a.machine.map(|m| m.model_damping_ratio), 4),
            cell(a.error_pct.map(|e| e.model_damping_pct), 1),
            cell(shown.map(|m| m.peak_db), 2),
            a.status
        );
    }
    for (name, a) in &r.axes {
        let list = |ms: &[ModeJson]| {
            ms.iter()
                .map(|m| {
                    format!(
                        "{:.2} Hz ζ {:.4} {:+.1} dB",
                        m.freq_hz, m.damping_ratio, m.peak_db
                    )
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        let bounds = a.bounds.map_or(String::new(), |b| {
            format!(
                "; travel {:.1} mm, effort {:.0} mN·m (cap {:.0})",
                b.travel_max_mm, b.effort_max_mnm, b.torque_cap_mnm
            )
        });
        let _ = writeln!(
            s,
            "{name}: J {:.4} B {:.3} delay {:.0} µs; resonances [{}]; anti-resonances [{}]{bounds}, {:.1} s",
            a.inertia,
            a.viscous,
            a.delay_s * 1e6,
            list(&a.resonances),
            list(&a.anti_resonances),
            a.machine_time_s
        );
    }
    s
}
