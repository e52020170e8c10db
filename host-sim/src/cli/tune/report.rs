//! `gantry tune`'s report: what was measured and set, the stops before and after, as
//! JSON (keys are public interface) and as text.

use super::notch::NotchStep;
use super::stop::{StopCheck, SETTLE_UM};
use crate::cli::IdentifyJson;
use crate::studies::filters::LoopJson;
use crate::studies::freqresp::{AxisResponse, ModeJson};
use controller_core::filter::FilterConfig;
use serde::Serialize;

/// A notch `filter::place` puts at a resonance.
#[derive(Clone, Debug, Serialize)]
pub struct NotchJson {
    pub freq_hz: f32,
    pub width_hz: f32,
    pub depth_db: f32,
}

/// The shaper set (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct ShaperJson {
    pub kind: String,
    pub freq_hz: f32,
    pub damping_ratio: f32,
}

/// `gantry tune`'s report (JSON keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct TuneReport {
    pub axis: String,
    pub identify: IdentifyJson,
    pub response: AxisResponse,
    pub bandwidth_rad_s: f32,
    /// The resonance shaped (the strongest measured).
    pub mode: Option<ModeJson>,
    pub shaper: Option<ShaperJson>,
    /// Kinds the machine's shaper history does not hold at that mode.
    pub shaper_refused: Vec<String>,
    /// The settings steps 4 and 5 set (key, value), in order (the filter stages only when
    /// they were accepted).
    pub settings: Vec<(String, String)>,
    /// The notches placed at the measured loop's crossover (applied when `notch_verdict`
    /// is `accepted`).
    pub notches_placed: Vec<NotchJson>,
    /// Resonances too close to the bandwidth for a notch (`filter::Placement::
    /// near_bandwidth`, below 1.5× it): the shaper is their remedy.
    pub in_band_resonances: usize,
    /// The loop on the laws measured on the machine before the notches and with them
    /// (`cargo sim filters`' keys: margins, error, points, failed).
    pub loop_without: Option<LoopJson>,
    pub loop_with: Option<LoopJson>,
    /// `accepted`, `none placed`, or why the notches were not kept.
    pub notch_verdict: String,
    /// The path tolerance at which the shaped axis keeps its full acceleration, mm (the
    /// shaper's deviation takes half of it); `null` without a shaper.
    pub full_acc_tolerance_mm: Option<f32>,
    pub before: Option<StopCheck>,
    pub after: Option<StopCheck>,
    pub after_full_acc: Option<StopCheck>,
    /// `applied`, `dry run`, `rolled back (...)`, or why nothing was applied.
    pub outcome: String,
}

impl TuneReport {
    /// The filters step's findings into the report.
    pub fn take_notches(&mut self, n: NotchStep) {
        self.notches_placed = n
            .placed
            .iter()
            .filter_map(|f| match *f {
                FilterConfig::Notch {
                    freq_hz,
                    width_hz,
                    depth_db,
                } => Some(NotchJson {
                    freq_hz,
                    width_hz,
                    depth_db,
                }),
                FilterConfig::LowPass { .. } => None,
            })
            .collect();
        self.in_band_resonances = n.near_bandwidth;
        self.loop_without = n.without;
        self.loop_with = n.with;
        self.notch_verdict = n.verdict;
        self.settings.extend(n.applied);
    }

    /// The command's success: the settings are applied and verified.
    pub fn applied(&self) -> bool {
        self.outcome == "applied"
    }
}

fn stop_cell(s: Option<&StopCheck>) -> String {
    match s {
        None => "-".into(),
        Some(s) => format!(
            "peak {:.2} µm, {} (stop at {:.0} mm/s²)",
            s.peak_um,
            match s.settle_ms {
                None => "not settled within the capture".into(),
                Some(0.0) => format!("never left the {SETTLE_UM} µm band"),
                Some(m) => format!("within {SETTLE_UM} µm after {m:.1} ms"),
            },
            s.acc_mm_s2,
        ),
    }
}

/// A measured loop in words: its crossover and margins.
pub fn loop_cell(l: &LoopJson) -> String {
    let hz = |f: Option<f32>| f.map_or("-".into(), |f| format!("{f:.1} Hz"));
    match (&l.margins, &l.error) {
        (Some(m), _) => format!(
            "{}crossover {}, phase margin {:.1}°, gain margins {:.1} dB (at {}) and {:.1} dB below; {} points",
            if m.stable { "" } else { "UNSTABLE, " },
            hz(m.gain_crossover_hz),
            m.phase_margin_deg,
            m.gain_margin_db,
            hz(m.phase_crossover_hz),
            m.lower_gain_margin_db,
            l.points.len()
        ),
        (None, e) => format!(
            "no margins ({}); {} points",
            e.as_deref().unwrap_or("-"),
            l.points.len()
        ),
    }
}

/// The report as text.
pub fn table(r: &TuneReport) -> String {
    let mut t = String::new();
    let id = &r.identify;
    let num = |v: Option<f32>| v.map_or("-".into(), |v| format!("{v}"));
    t += &format!(
        "tune {}: {}\n  model      J {} B {} f+ {} f- {} mN·m (nrmse {:.3}){}\n",
        r.axis,
        r.outcome,
        num(id.j),
        num(id.b),
        num(id.f_pos),
        num(id.f_neg),
        id.nrmse,
        if id.accepted { ", accepted" } else { "" }
    );
    let modes: Vec<String> = r
        .response
        .resonances
        .iter()
        .map(|m| {
            format!(
                "{:.2} Hz ζ {:.4} (+{:.1} dB)",
                m.freq_hz, m.damping_ratio, m.peak_db
            )
        })
        .collect();
    t += &format!(
        "  modes      {}\n  bandwidth  {} rad/s (the laws' setting)\n",
        if modes.is_empty() {
            "none".into()
        } else {
            modes.join(", ")
        },
        r.bandwidth_rad_s,
    );
    t += &match &r.shaper {
        Some(s) => format!(
            "  shaper     {} at {:.2} Hz, ζ {:.4}\n",
            s.kind, s.freq_hz, s.damping_ratio
        ),
        None => "  shaper     none\n".into(),
    };
    if !r.shaper_refused.is_empty() {
        t += &format!(
            "             (the history does not hold {} at this mode)\n",
            r.shaper_refused.join(", ")
        );
    }
    for (what, l) in [("loop", &r.loop_without), ("with notch", &r.loop_with)] {
        if let Some(l) = l {
            t += &format!("  {what:<10} {}\n", loop_cell(l));
        }
    }
    for n in &r.notches_placed {
        t += &format!(
            "  notch      {:.2} Hz, width {:.2} Hz, depth {:.1} dB\n",
            n.freq_hz, n.width_hz, n.depth_db
        );
    }
    if !r.notch_verdict.is_empty() {
        t += &format!(
            "  notches    {}; {} resonance(s) within 1.5× the loop's crossover (the shaper's)\n",
            r.notch_verdict, r.in_band_resonances
        );
    }
    for (k, v) in &r.settings {
        t += &format!("  set        {k} = {v}\n");
    }
    if let Some(tol) = r.full_acc_tolerance_mm {
        t += &format!(
            "  tolerance  the shaper keeps {}'s full acceleration from planner.tolerance_mm = {tol:.4} mm on; below, the machine lowers it\n",
            r.axis
        );
    }
    t += &format!(
        "  before     {}\n  after      {}\n  same acc.  {}\n",
        stop_cell(r.before.as_ref()),
        stop_cell(r.after.as_ref()),
        stop_cell(r.after_full_acc.as_ref())
    );
    t
}
