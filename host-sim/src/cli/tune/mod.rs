//! `gantry tune AXIS`: one guided command from an untuned axis to a tuned one, on the
//! machine, over the link (issue 24, item 8):
//!
//! 1. **identify** the axis (`gantry identify --accept`): its model `J, B, f+, f-` goes
//!    into the settings, so the model-based laws' gains follow it at the law's bandwidth
//!    (`axis.<a>.law.bandwidth_rad_s`, `--bandwidth-rad-s` changes it);
//! 2. **measure the frequency response** (`gantry freqresp`): the resonances;
//! 3. **the reference before**: a rapid stop of the axis (the residual-vibration program
//!    of `cargo sim vibration`: approach, dwell, `G0` over
//!    [`crate::studies::vibration::MOVE_MM`], dwell) with the
//!    settings as they were, its tracking error after the stop captured by the machine's
//!    scope at the control rate;
//! 4. **apply** (one settings transaction): the friction feed-forward from the identified
//!    Coulomb terms (`axis.<a>.feedforward.coulomb_*`), and an input shaper of the kind
//!    asked for (`auto`: the first of [`AUTO_KINDS`] the machine's shaper history holds)
//!    at the strongest measured resonance;
//! 5. **the loop and its filters** ([`notch`]): the loop on the laws measured on the
//!    machine (`Request::MeasureLoop`), notches placed from the resonances at its
//!    measured crossover, predicted on the measured loop, applied and the loop measured
//!    again: kept only on its margins (6 dB, 30°);
//! 6. **verify**: the same stop again, twice. The machine counts a shaper's contour
//!    deviation inside the path tolerance (`planner.tolerance_mm`) and lowers the shaped
//!    axis' acceleration when it takes more than half of it, so a gentler stop would ring
//!    less with or without the shaper: the stop is taken once as the user will run it
//!    (`after`) and once with the tolerance raised for that run to what keeps the full
//!    acceleration (`after_full_acc`, the shaper's own effect at the acceleration of
//!    `before`). When that one's tracking error peak after the stop is more than
//!    [`WORSE_RATIO`] times the one before, everything steps 4 and 5 set is put back and
//!    the command fails.
//!
//! Nothing is saved: `gantry settings save` keeps the result for the next boot. The model
//! of step 1 stays accepted when step 4 is put back (it is `gantry identify --accept`'s).
//!
//! The report and its text: [`report`]; the stop, its program and capture: [`stop`]; the
//! loop and the filters: [`notch`].
//!
//! Measured at the encoder: a tool-side sensor is what a machine lacks, so the figures are
//! the motor's (the beam's swing shows there through the coupling; the tool moves more,
//! `cargo sim vibration` measures it on a simulated machine).
//!
//! A dry run measures the loop and places and predicts the notches, and applies nothing.

pub mod notch;
pub mod report;
pub mod stop;

pub use report::{table, NotchJson, ShaperJson, TuneReport};
use stop::{
    full_acc_stop, full_acc_tolerance, program_text, stop_check, stretch, switch_off, Stop,
};
pub use stop::{StopCheck, SETTLE_UM};

use super::client::Client;
use super::{apply_settings, freqresp, get, identify, IdentifyJson, Transport, AXES};
use crate::studies::freqresp::ModeJson;
use crate::studies::vibration::{fitting_kinds, strongest};
use anyhow::{anyhow, bail, Context, Result};
use controller_core::motion::shaper::{ShaperConfig, ShaperKind};
use std::path::Path;

/// The kinds `--shaper auto` tries, in order: MZV first (Klipper's recommendation for
/// most machines, docs/Resonance_Compensation.md: "mzv ... a good choice"; shorter than
/// ZVD and EI, so the machine lowers the shaped axis' acceleration less to keep its
/// deviation inside the path tolerance), ZV when MZV's 0.75 periods do not fit the
/// history (a low mode: at 35 Hz and 10 kHz only ZV and MZV do).
pub const AUTO_KINDS: [ShaperKind; 2] = [ShaperKind::Mzv, ShaperKind::Zv];

/// The verification fails (and the change is put back) when the tracking error's peak
/// after the stop exceeds the one before by this factor: the encoder's counts (0.6 µm on
/// the gantry) and where the samples fall move a peak of a few µm by about a tenth.
pub const WORSE_RATIO: f64 = 1.1;

/// Which shaper `tune` sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShaperChoice {
    /// The first of [`AUTO_KINDS`] that fits.
    Auto,
    /// None (an existing one is switched off).
    Off,
    Kind(ShaperKind),
}

impl ShaperChoice {
    /// `auto`, `none` or a kind's name (`zv`, `mzv`, `zvd`, `ei`, `2hump_ei`, `3hump_ei`).
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(Self::Auto),
            "none" => Ok(Self::Off),
            _ => ShaperKind::ALL
                .into_iter()
                .find(|k| k.name() == s)
                .map(Self::Kind)
                .ok_or_else(|| {
                    let names: Vec<_> = ShaperKind::ALL.iter().map(|k| k.name()).collect();
                    anyhow!(
                        "--shaper: `{s}` is not auto, none or one of {}",
                        names.join(", ")
                    )
                }),
        }
    }
}

/// What `tune` is asked to do.
#[derive(Clone, Debug)]
pub struct TuneOptions {
    pub axis: usize,
    /// As `gantry identify --window-mm`.
    pub window_half_mm: Option<f32>,
    /// The law's bandwidth to set; `None` keeps the machine's.
    pub bandwidth_rad_s: Option<f32>,
    pub shaper: ShaperChoice,
    /// Measure and report; change no setting (the model is not accepted, so a machine
    /// without one is not verified).
    pub dry_run: bool,
    /// The session's telemetry period, s (the stops' accelerations are read from it).
    pub telemetry_period_s: f64,
}

/// Run the whole procedure on axis `o.axis`.
pub fn tune<T: Transport>(c: &mut Client<T>, o: &TuneOptions, out: &Path) -> Result<TuneReport> {
    let name = AXES
        .get(o.axis)
        .ok_or_else(|| anyhow!("axis must be x, y or z"))?;
    if let Some(bw) = o.bandwidth_rad_s {
        if !(bw.is_finite() && bw > 0.0) {
            bail!("--bandwidth-rad-s must be a positive number, got {bw}");
        }
    }
    eprintln!("1/6 identifying {name}");
    let id = identify(c, &[o.axis], !o.dry_run, o.window_half_mm)?
        .pop()
        .ok_or_else(|| anyhow!("identify reported nothing"))?;
    if id.status != "done" {
        bail!("identification of {name} did not finish: {}", id.status);
    }
    eprintln!("2/6 measuring {name}'s frequency response");
    let fr = freqresp::measure(c, o.axis, o.window_half_mm, "the machine over the link")?;
    let response = fr
        .axes
        .get(*name)
        .cloned()
        .ok_or_else(|| anyhow!("freqresp reported no axis {name}"))?;
    if response.status != "done" {
        bail!(
            "the frequency response of {name} did not finish: {}",
            response.status
        );
    }
    let bw_key = format!("axis.{name}.law.bandwidth_rad_s");
    let bandwidth_rad_s = match o.bandwidth_rad_s {
        Some(b) => b,
        None => get(c, &bw_key)?
            .parse()
            .with_context(|| format!("setting {bw_key} is not a number"))?,
    };
    let period_s = 1.0 / c.control_rate_hz() as f32;
    let mode = strongest(&response.resonances);
    let (shaper, shaper_refused) = choose_shaper(o.axis, o.shaper, mode.as_ref(), period_s);
    let settings = changes(name, &id, o, &shaper);
    let full_acc_tolerance_mm = match &shaper {
        Some(s) => Some(full_acc_tolerance(c, o.axis, s, period_s)?),
        None => None,
    };
    let mut r = TuneReport {
        axis: name.to_string(),
        identify: id,
        response,
        bandwidth_rad_s,
        mode,
        shaper: shaper.map(|s| ShaperJson {
            kind: s.kind.name().into(),
            freq_hz: s.freq_hz,
            damping_ratio: s.damping_ratio,
        }),
        shaper_refused,
        settings,
        notches_placed: Vec::new(),
        in_band_resonances: 0,
        loop_without: None,
        loop_with: None,
        notch_verdict: String::new(),
        full_acc_tolerance_mm,
        before: None,
        after: None,
        after_full_acc: None,
        outcome: String::new(),
    };
    if o.dry_run {
        eprintln!("5/6 measuring {name}'s loop");
        let n = notch::run(c, o.axis, o.window_half_mm, &r.response.resonances, false)?;
        r.take_notches(n);
        r.outcome = "dry run".into();
        return Ok(r);
    }
    verify(c, o, &mut r, out)?;
    Ok(r)
}

/// Steps 3-5: the reference stop, the settings of `r` applied, the stops after; the
/// settings put back when the stop at the same acceleration rings more (`r.outcome`).
fn verify<T: Transport>(
    c: &mut Client<T>,
    o: &TuneOptions,
    r: &mut TuneReport,
    out: &Path,
) -> Result<()> {
    let name = AXES[o.axis];
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the folder {}", out.display()))?;
    eprintln!("3/6 the rapid stop before");
    let (from, to) = stretch(c, o.axis)?;
    let program = out.join(format!("tune_stop_{name}.ngc"));
    std::fs::write(&program, program_text(o.axis, from, to))
        .with_context(|| format!("cannot write {}", program.display()))?;
    let stop = Stop {
        axis: o.axis,
        program: &program,
        to_mm: to,
        telemetry_period_s: o.telemetry_period_s,
    };
    let before = stop_check(c, &stop)?;
    eprintln!("4/6 applying");
    let mut previous = current(c, &r.settings)?;
    switch_off(c)?;
    apply_settings(c, &r.settings)?;
    eprintln!("5/6 the loop and its filters");
    let n = notch::run(c, o.axis, o.window_half_mm, &r.response.resonances, true)?;
    previous.extend(n.previous.iter().cloned());
    r.take_notches(n);
    eprintln!("6/6 the rapid stop after");
    let after = stop_check(c, &stop);
    let full = match (&after, r.full_acc_tolerance_mm) {
        (Ok(_), Some(tol)) => full_acc_stop(c, &stop, tol),
        (Ok(a), None) => Ok(a.clone()),
        (Err(e), _) => Err(anyhow!("{e:#}")),
    };
    let worse = judge(&before, &full);
    r.before = Some(before);
    r.after = after.ok();
    r.after_full_acc = full.ok();
    r.outcome = match worse {
        None => "applied".into(),
        Some(why) => {
            switch_off(c)?;
            apply_settings(c, &previous)?;
            format!("rolled back ({why})")
        }
    };
    Ok(())
}

/// Why the settings go back, if they do: the stop at the same acceleration `full` rang
/// more than [`WORSE_RATIO`] times the reference `before`, or could not be taken.
fn judge(before: &StopCheck, full: &Result<StopCheck>) -> Option<String> {
    match full {
        Ok(a) => (a.peak_um > WORSE_RATIO * before.peak_um).then(|| {
            format!(
                "at the same acceleration the peak after the stop rose from {:.2} to {:.2} µm",
                before.peak_um, a.peak_um
            )
        }),
        Err(e) => Some(format!("the verification failed: {e:#}")),
    }
}

/// The shaper of `choice` at `mode` on `axis`, and the kinds the history refuses there.
fn choose_shaper(
    axis: usize,
    choice: ShaperChoice,
    mode: Option<&ModeJson>,
    period_s: f32,
) -> (Option<ShaperConfig>, Vec<String>) {
    let (Some(mode), Some(ax)) = (mode, controller_core::axes::Axis::from_index(axis)) else {
        return (None, Vec::new());
    };
    let (fits, refused) = fitting_kinds(ax, mode, period_s);
    let wanted: Vec<ShaperKind> = match choice {
        ShaperChoice::Off => Vec::new(),
        ShaperChoice::Auto => AUTO_KINDS.to_vec(),
        ShaperChoice::Kind(k) => vec![k],
    };
    let chosen = wanted
        .iter()
        .find_map(|k| fits.iter().find(|c| c.kind == *k).copied());
    (chosen, refused)
}

/// The settings step 4 sets for axis `name`.
fn changes(
    name: &str,
    id: &IdentifyJson,
    o: &TuneOptions,
    shaper: &Option<ShaperConfig>,
) -> Vec<(String, String)> {
    let mut v = Vec::new();
    if let Some(bw) = o.bandwidth_rad_s {
        v.push((format!("axis.{name}.law.bandwidth_rad_s"), bw.to_string()));
    }
    if let (Some(fp), Some(fn_)) = (id.f_pos, id.f_neg) {
        // the feed-forward's limits: forward ≥ 0, backward ≤ 0
        v.push((
            format!("axis.{name}.feedforward.coulomb_pos_mnm"),
            fp.max(0.0).to_string(),
        ));
        v.push((
            format!("axis.{name}.feedforward.coulomb_neg_mnm"),
            fn_.min(0.0).to_string(),
        ));
    }
    match shaper {
        Some(s) => {
            v.push((format!("shaper.{name}.kind"), s.kind.name().into()));
            v.push((format!("shaper.{name}.freq_hz"), s.freq_hz.to_string()));
            v.push((
                format!("shaper.{name}.damping_ratio"),
                s.damping_ratio.to_string(),
            ));
        }
        None if o.shaper == ShaperChoice::Off => {
            v.push((format!("shaper.{name}.kind"), "none".into()));
        }
        None => {}
    }
    v
}

/// The machine's values of the keys of `changes` (to put back).
fn current<T: Transport>(
    c: &mut Client<T>,
    changes: &[(String, String)],
) -> Result<Vec<(String, String)>> {
    changes
        .iter()
        .map(|(k, _)| Ok((k.clone(), get(c, k)?)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stop(peak_um: f64) -> StopCheck {
        StopCheck {
            peak_um,
            settle_ms: Some(0.0),
            acc_mm_s2: 2000.0,
        }
    }

    /// The settings stay up to 1.1× the reference's peak, go back above it or when the
    /// stop could not be taken.
    #[test]
    fn the_verdict_puts_back_what_rings_more() {
        let before = stop(8.75);
        assert_eq!(judge(&before, &Ok(stop(4.28))), None);
        assert_eq!(judge(&before, &Ok(stop(9.6))), None);
        let why = judge(&before, &Ok(stop(9.7))).expect("worse");
        assert!(why.contains("8.75 to 9.70"), "{why}");
        let why = judge(&before, &Err(anyhow!("the stop program did not complete"))).unwrap();
        assert!(why.contains("did not complete"), "{why}");
    }

    #[test]
    fn the_shaper_auto_takes_mzv_else_zv() {
        let mode = ModeJson {
            freq_hz: 35.0,
            damping_ratio: 0.0425,
            peak_db: 5.1,
        };
        let (s, refused) = choose_shaper(1, ShaperChoice::Auto, Some(&mode), 1e-4);
        assert_eq!(s.map(|s| s.kind), Some(ShaperKind::Mzv));
        assert!(refused.contains(&"zvd".to_string()), "{refused:?}");
        // at 25 Hz MZV's 0.75 periods (30 ms) exceed the 256-period history (25.6 ms at
        // 10 kHz), ZV's half period (20 ms) does not: ZV
        let mid = ModeJson {
            freq_hz: 25.0,
            ..mode
        };
        let (s, _) = choose_shaper(1, ShaperChoice::Auto, Some(&mid), 1e-4);
        assert_eq!(s.map(|s| s.kind), Some(ShaperKind::Zv));
        // at 12 Hz neither fits (62 and 42 ms): no shaper
        let low = ModeJson {
            freq_hz: 12.0,
            ..mode
        };
        assert_eq!(
            choose_shaper(1, ShaperChoice::Auto, Some(&low), 1e-4).0,
            None
        );
        // a kind the history refuses is not set, nor replaced by another
        let (s, _) = choose_shaper(1, ShaperChoice::Kind(ShaperKind::Ei), Some(&mode), 1e-4);
        assert_eq!(s, None);
        assert_eq!(
            choose_shaper(1, ShaperChoice::Off, Some(&mode), 1e-4).0,
            None
        );
    }
}
