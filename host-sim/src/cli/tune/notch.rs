//! `gantry tune`'s output filters, accepted on the loop measured on the machine:
//!
//! 1. the loop on the laws, `L(jω)`, measured as the axis runs
//!    ([`freqresp::measure_loop`], the machine's `Request::MeasureLoop`): its gain
//!    crossover is the loop's bandwidth, its margins are reported;
//! 2. notches placed from the measured resonances at that bandwidth (controller-core
//!    `filter::place`, as `cargo sim filters` places them); they take the place of the
//!    axis' notches, its low-pass stages stay;
//! 3. **predicted** first, `L·F_new/F_old` on the measured points: a set that would fail
//!    the margins never reaches the machine;
//! 4. applied (outputs off, one settings transaction) and the loop measured again: kept
//!    when it is stable with gain margins ≥ 6 dB and a phase margin ≥ 30°
//!    (`filter::accept`, every reason named by [`verdict`]), else the stages are put back.

use super::super::client::Client;
use super::super::{apply_settings, freqresp, get, Transport, AXES};
use super::stop::switch_off;
use crate::studies::filters::{loop_json, verdict, LoopJson};
use crate::studies::freqresp::ModeJson;
use anyhow::{anyhow, Context, Result};
use controller_core::filter::{
    margins_of_samples, place, AxisFilterConfig, FilterChain, FilterConfig, Resonance, MAX_STAGES,
};
use controller_core::machine::messages::{MachineState, Request};
use controller_core::sysid::frequency::FrequencyResponse;

/// What the filters step found and did.
#[derive(Clone, Debug, Default)]
pub struct NotchStep {
    /// The loop as the machine ran it before (with the other settings of the tune).
    pub without: Option<LoopJson>,
    /// The loop with the placed stages (measured only when the prediction passed).
    pub with: Option<LoopJson>,
    /// The stages placed (the axis' low-pass stages and the new notches, in order).
    pub placed: Vec<FilterConfig>,
    /// Resonances too close to the measured bandwidth for a notch (below 1.5× it).
    pub near_bandwidth: usize,
    /// `accepted`, `none placed`, `placed (dry run)`, or why not.
    pub verdict: String,
    /// The stage settings in use after the step (empty when nothing changed) and their
    /// values before (to put back with the rest).
    pub applied: Vec<(String, String)>,
    pub previous: Vec<(String, String)>,
}

/// Run the step on axis `i` with the resonances `freqresp` measured; `apply: false`
/// stops after the prediction (a dry run changes no setting).
pub fn run<T: Transport>(
    c: &mut Client<T>,
    i: usize,
    window_half_mm: Option<f32>,
    resonances: &[ModeJson],
    apply: bool,
) -> Result<NotchStep> {
    let mut out = NotchStep::default();
    let (points, without, margins) = measure(c, i, window_half_mm)?;
    out.without = Some(without);
    let Some(bw_hz) = margins.and_then(|m| m.gain_crossover_hz) else {
        out.verdict = "no bandwidth: the loop has no margins".into();
        return Ok(out);
    };
    let period_s = 1.0 / c.control_rate_hz() as f32;
    let modes: Vec<Resonance> = resonances.iter().map(ModeJson::resonance).collect();
    let notches =
        place(&modes, bw_hz, period_s, false).map_err(|e| anyhow!("placing the notches: {e:?}"))?;
    out.near_bandwidth = usize::from(notches.near_bandwidth);
    if notches.filters.is_empty() {
        out.verdict = "none placed".into();
        return Ok(out);
    }
    let name = AXES[i];
    let old = stages(c, name)?;
    let mut new: Vec<FilterConfig> = old
        .iter()
        .copied()
        .filter(|f| matches!(f, FilterConfig::LowPass { .. }))
        .collect();
    new.extend_from_slice(notches.filters.stages());
    out.placed = new.clone();
    if new.len() > MAX_STAGES {
        out.verdict = format!("refused: {} stages, the axis has {MAX_STAGES}", new.len());
        return Ok(out);
    }
    let predicted = predict(&points, &old, &new, period_s)?;
    if predicted != "accepted" {
        out.verdict = format!("refused before it was applied (predicted: {predicted})");
        return Ok(out);
    }
    if !apply {
        out.verdict = "placed (dry run: predicted accepted)".into();
        return Ok(out);
    }
    out.previous = stage_settings(name, &old);
    out.applied = stage_settings(name, &new);
    switch_off(c)?;
    apply_settings(c, &out.applied)?;
    let measured = measure(c, i, window_half_mm);
    let (with_verdict, with) = match measured {
        Ok((_, with, m)) => (
            verdict(m.as_ref(), &with.failed, with.points.len()),
            Some(with),
        ),
        Err(e) => (format!("refused: the loop measurement failed: {e:#}"), None),
    };
    out.with = with;
    if with_verdict != "accepted" {
        put_back(c, &out.previous)?;
        out.applied.clear();
    }
    out.verdict = with_verdict;
    Ok(out)
}

/// Put the stages back (after a reset when the measurement ended in a fault).
fn put_back<T: Transport>(c: &mut Client<T>, previous: &[(String, String)]) -> Result<()> {
    if c.status()?.state == MachineState::Fault {
        // (the outputs are off: the loop that rang is gone)
        let _ = c.exec(Request::Reset)?;
    }
    switch_off(c)?;
    apply_settings(c, previous)
}

/// The loop measured on the machine: its points, JSON and margins. A run that stops
/// early gives the points it measured, named as failed.
fn measure<T: Transport>(
    c: &mut Client<T>,
    i: usize,
    window_half_mm: Option<f32>,
) -> Result<(
    FrequencyResponse,
    LoopJson,
    Option<controller_core::filter::Margins>,
)> {
    let run = freqresp::measure_loop(c, i, window_half_mm)?;
    let pts: Vec<_> = run
        .points
        .points()
        .iter()
        .map(|p| (p.freq_hz, (p.re, p.im)))
        .collect();
    let failed = if run.status == "done" {
        Vec::new()
    } else {
        vec![(pts.first().map_or(0.0, |p| p.0), run.status.clone())]
    };
    let (json, m) = loop_json(&pts, failed);
    Ok((run.points, json, m))
}

/// The verdict on the measured loop `points` with the stages `old` replaced by `new`.
fn predict(
    points: &FrequencyResponse,
    old: &[FilterConfig],
    new: &[FilterConfig],
    period_s: f32,
) -> Result<String> {
    let chain = |s: &[FilterConfig]| -> Result<FilterChain<f64, MAX_STAGES>> {
        let cfg = AxisFilterConfig::new(s).map_err(|e| anyhow!("the stages: {e:?}"))?;
        FilterChain::new(&cfg, period_s).map_err(|e| anyhow!("the stages: {e:?}"))
    };
    let (f_old, f_new) = (chain(old)?, chain(new)?);
    let (freqs, gains): (Vec<f32>, Vec<(f32, f32)>) = points
        .points()
        .iter()
        .map(|p| {
            let l = controller_core::filter::response::C64::from_pair((p.re, p.im));
            let f = f_new
                .response_c64(p.freq_hz)
                .over(f_old.response_c64(p.freq_hz));
            (p.freq_hz, l.times(f).to_pair())
        })
        .unzip();
    let m = margins_of_samples(&freqs, &gains).ok();
    Ok(verdict(m.as_ref(), &[], freqs.len()))
}

/// The axis' filter stages in use, read from its settings.
fn stages<T: Transport>(c: &mut Client<T>, name: &str) -> Result<Vec<FilterConfig>> {
    let mut out = Vec::new();
    for n in 1..=MAX_STAGES {
        let key = |f: &str| format!("axis.{name}.filter.stage{n}.{f}");
        let num = |c: &mut Client<T>, f: &str| -> Result<f32> {
            get(c, &key(f))?
                .parse()
                .with_context(|| format!("setting {} is not a number", key(f)))
        };
        match get(c, &key("kind"))?.as_str() {
            "notch" => out.push(FilterConfig::Notch {
                freq_hz: num(c, "freq_hz")?,
                width_hz: num(c, "width_hz")?,
                depth_db: num(c, "depth_db")?,
            }),
            "low_pass" => out.push(FilterConfig::LowPass {
                cutoff_hz: num(c, "freq_hz")?,
                q: num(c, "q")?,
            }),
            _ => {}
        }
    }
    Ok(out)
}

/// The settings that make `stages` the axis' stages (the rest `none`).
fn stage_settings(name: &str, stages: &[FilterConfig]) -> Vec<(String, String)> {
    let mut v = Vec::new();
    for n in 1..=MAX_STAGES {
        let key = |f: &str| format!("axis.{name}.filter.stage{n}.{f}");
        match stages.get(n - 1) {
            Some(FilterConfig::Notch {
                freq_hz,
                width_hz,
                depth_db,
            }) => {
                v.push((key("kind"), "notch".into()));
                v.push((key("freq_hz"), freq_hz.to_string()));
                v.push((key("width_hz"), width_hz.to_string()));
                v.push((key("depth_db"), depth_db.to_string()));
            }
            Some(FilterConfig::LowPass { cutoff_hz, q }) => {
                v.push((key("kind"), "low_pass".into()));
                v.push((key("freq_hz"), cutoff_hz.to_string()));
                v.push((key("q"), q.to_string()));
            }
            None => v.push((key("kind"), "none".into())),
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::filter::pid_response;
    use controller_core::sysid::frequency::ResponsePoint;

    /// A PID on a mass (J 0.064, crossover near 45 Hz, phase margin ~65°), 1-400 Hz.
    fn pid_loop() -> FrequencyResponse {
        let (j, kp, ki, kd) = (0.064f64, 1707.0f32, 48_300.0f32, 18.1f32);
        let mut r = FrequencyResponse::new();
        for k in 0..64 {
            let f = (1.0f64 * (400.0f64).powf(k as f64 / 63.0)) as f32;
            let c = controller_core::filter::response::C64::from_pair(pid_response(kp, ki, kd, f));
            let w = 2.0 * std::f64::consts::PI * f64::from(f);
            let (re, im) = c.scale(-1.0 / (j * w * w)).to_pair();
            r.push(ResponsePoint { freq_hz: f, re, im });
        }
        r
    }

    /// A notch well above the crossover passes the prediction; one at the crossover,
    /// where the loop needs its phase, does not, and the margin it breaks is named.
    #[test]
    fn the_prediction_refuses_a_notch_that_takes_the_loops_phase() {
        let l = pid_loop();
        let above = FilterConfig::Notch {
            freq_hz: 150.0,
            width_hz: 20.0,
            depth_db: 6.0,
        };
        assert_eq!(predict(&l, &[], &[above], 1e-4).unwrap(), "accepted");
        let at = FilterConfig::Notch {
            freq_hz: 45.0,
            width_hz: 30.0,
            depth_db: 30.0,
        };
        let v = predict(&l, &[], &[at], 1e-4).unwrap();
        assert!(v.starts_with("refused") && v.contains("margin"), "{v}");
        // a loop measured with `at` in place: the prediction takes it out before it puts
        // the new one in (kept, it would still refuse)
        let cfg = AxisFilterConfig::new(&[at]).unwrap();
        let f_at = FilterChain::<f64, MAX_STAGES>::new(&cfg, 1e-4).unwrap();
        let mut with_at = FrequencyResponse::new();
        for p in l.points() {
            let h = controller_core::filter::response::C64::from_pair((p.re, p.im))
                .times(f_at.response_c64(p.freq_hz));
            let (re, im) = h.to_pair();
            with_at.push(ResponsePoint { re, im, ..*p });
        }
        assert_eq!(
            predict(&with_at, &[at], &[above], 1e-4).unwrap(),
            "accepted"
        );
        assert!(predict(&with_at, &[], &[above], 1e-4)
            .unwrap()
            .starts_with("refused"));
    }

    /// The stages written as settings name each stage's keys, the rest `none`.
    #[test]
    fn stages_become_their_settings() {
        let s = stage_settings(
            "x",
            &[
                FilterConfig::LowPass {
                    cutoff_hz: 400.0,
                    q: 0.5,
                },
                FilterConfig::Notch {
                    freq_hz: 90.0,
                    width_hz: 12.0,
                    depth_db: 4.9,
                },
            ],
        );
        let get = |k: &str| s.iter().find(|(key, _)| key == k).map(|(_, v)| v.as_str());
        assert_eq!(get("axis.x.filter.stage1.kind"), Some("low_pass"));
        assert_eq!(get("axis.x.filter.stage1.freq_hz"), Some("400"));
        assert_eq!(get("axis.x.filter.stage2.kind"), Some("notch"));
        assert_eq!(get("axis.x.filter.stage2.depth_db"), Some("4.9"));
        assert_eq!(get("axis.x.filter.stage3.kind"), Some("none"));
        assert_eq!(get("axis.x.filter.stage4.kind"), Some("none"));
    }
}
