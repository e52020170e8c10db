//! The tuning tab: a wizard per axis for what `gantry tune` does. (1) What it does and how
//! far the axis moves. (2) The choices: the shaper (auto, none or a kind) and, for an axis
//! without a model, the identification's window. (3) Tune, with the machine's progress.
//! (4) The result: the measured mode, the shaper and feed-forward set, the stop before and
//! after at the encoder, in words and numbers, and what the tolerance costs. (5) Save.

use crate::app::GantryApp;
use crate::session::Command;
use controller_core::machine::messages::MachineState;
use controller_core::motion::shaper::ShaperKind;
use egui::{Color32, RichText};
use host_sim::cli::tune::report::loop_cell;
use host_sim::cli::tune::{ShaperChoice, StopCheck, TuneReport, SETTLE_UM};
use host_sim::cli::AXES;

use super::identify::{axis_head, window_for, AxisHead, DEFAULT_WINDOW_MM};

const GOOD_GREEN: Color32 = Color32::from_rgb(80, 160, 60);
const DOUBT_GOLD: Color32 = Color32::from_rgb(181, 137, 0);
const BAD_RED: Color32 = Color32::from_rgb(220, 50, 47);

/// Largest identification window the form takes, mm (the gantry's travel is ±150 mm).
const MAX_WINDOW_MM: f32 = 150.0;

/// The shaper choices the form offers, as `gantry tune --shaper` names them.
pub fn shaper_choices() -> Vec<(&'static str, ShaperChoice)> {
    let mut v = vec![("auto", ShaperChoice::Auto), ("none", ShaperChoice::Off)];
    v.extend(ShaperKind::ALL.map(|k| (k.name(), ShaperChoice::Kind(k))));
    v
}

/// The tab's state.
#[derive(Debug)]
pub struct TunePanel {
    /// Every tuning this session, oldest first.
    pub reports: Vec<TuneReport>,
    /// The axis the wizard shows (0 X, 1 Y, 2 Z).
    pub axis: usize,
    /// Index into [`shaper_choices`].
    pub shaper: usize,
    /// Half-width of travel for an axis without a model, mm.
    pub window_mm: f32,
}

impl Default for TunePanel {
    fn default() -> Self {
        Self {
            reports: Vec::new(),
            axis: 0,
            shaper: 0,
            window_mm: DEFAULT_WINDOW_MM,
        }
    }
}

impl TunePanel {
    /// The newest report of `axis`.
    pub fn latest(&self, axis: usize) -> Option<&TuneReport> {
        let name = AXES.get(axis)?;
        self.reports.iter().rev().find(|r| r.axis == *name)
    }
}

/// A tuning's result in words.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Applied; the peak at the same acceleration fell by this factor.
    Applied { peak_ratio: Option<f64> },
    /// Measured only.
    DryRun,
    /// The stop rang more (or could not be taken): everything set was put back.
    RolledBack(String),
}

impl Verdict {
    pub fn words(&self) -> String {
        match self {
            Self::Applied {
                peak_ratio: Some(k),
            } => format!("applied: the stop's peak at the same acceleration is {k:.1}× lower"),
            Self::Applied { peak_ratio: None } => "applied".into(),
            Self::DryRun => "measured only (dry run): nothing set".into(),
            Self::RolledBack(why) => format!("put back: {why}"),
        }
    }
    fn colour(&self) -> Color32 {
        match self {
            Self::Applied { .. } => GOOD_GREEN,
            Self::DryRun => DOUBT_GOLD,
            Self::RolledBack(_) => BAD_RED,
        }
    }
}

/// The verdict on `r`.
pub fn verdict(r: &TuneReport) -> Verdict {
    if r.applied() {
        let ratio = match (&r.before, &r.after_full_acc) {
            (Some(b), Some(a)) if a.peak_um > 0.0 => Some(b.peak_um / a.peak_um),
            _ => None,
        };
        Verdict::Applied { peak_ratio: ratio }
    } else if r.outcome == "dry run" {
        Verdict::DryRun
    } else {
        let why = r
            .outcome
            .strip_prefix("rolled back (")
            .unwrap_or(&r.outcome);
        Verdict::RolledBack(why.trim_end_matches(')').to_string())
    }
}

/// A stop in words.
pub fn stop_words(s: Option<&StopCheck>) -> String {
    match s {
        None => "—".into(),
        Some(s) => {
            let settle = match s.settle_ms {
                None => "not settled within the capture".to_string(),
                Some(m) if m <= 0.0 => format!("never outside ±{SETTLE_UM} µm"),
                Some(m) => format!("within ±{SETTLE_UM} µm after {m:.1} ms"),
            };
            format!(
                "peak {:.2} µm, {settle}, stopping at {:.0} mm/s²",
                s.peak_um, s.acc_mm_s2
            )
        }
    }
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    let mut axis = app.tune.axis;
    let AxisHead {
        axis,
        name,
        missing,
        homed,
        free,
        status,
    } = axis_head(app, &mut axis, ui);
    app.tune.axis = axis;
    egui::ScrollArea::vertical()
        .auto_shrink([false, false])
        .show(ui, |ui| {
            ui.heading(format!("1. What tuning {name} does"));
            ui.label(format!(
                "Five steps, about two minutes: identify {name} (its model goes into the \
                 settings, 5–10 s), measure its frequency response (a stepped sine, 5–300 Hz, \
                 about 95 s),                  a 60 mm rapid stop centred on its travel as the reference, the friction \
                 feed-forward and an input shaper at its strongest resonance set, and the \
                 stop twice more to verify. When the stop rings more than before, everything \
                 set is put back."
            ));
            ui.label(
                RichText::new(format!(
                    "The {name} axis WILL MOVE, 60 mm at its rapid speed. The machine homes \
                     first. Keep clear, and keep the stop button at hand."
                ))
                .strong()
                .color(DOUBT_GOLD),
            );
            let window = window_for(missing, homed, false, app.tune.window_mm);
            if window.is_some() {
                ui.horizontal(|ui| {
                    ui.label("Identification window ±W");
                    ui.add(
                        egui::DragValue::new(&mut app.tune.window_mm)
                            .range(1.0..=MAX_WINDOW_MM)
                            .speed(0.5)
                            .suffix(" mm"),
                    );
                });
                ui.label(
                    RichText::new(
                        "An axis without a model cannot be homed: it is identified and measured \
                         within ±W mm of where it stands (jog it to the middle first).",
                    )
                    .weak(),
                );
            }
            let choices = shaper_choices();
            ui.horizontal(|ui| {
                ui.label("Shaper");
                let current = choices.get(app.tune.shaper).map_or("auto", |c| c.0);
                egui::ComboBox::from_id_salt("tune-shaper")
                    .selected_text(current)
                    .show_ui(ui, |ui| {
                        for (i, (label, _)) in choices.iter().enumerate() {
                            ui.selectable_value(&mut app.tune.shaper, i, *label);
                        }
                    });
            });
            ui.separator();

            ui.heading(format!("2. Tune {name}"));
            let fault = status
                .as_ref()
                .is_some_and(|s| s.state == MachineState::Fault);
            if ui
                .add_enabled(
                    free && !fault,
                    egui::Button::new(RichText::new(format!("Tune {name}")).strong()),
                )
                .on_disabled_hover_text(if fault {
                    "reset the fault first"
                } else {
                    "the machine is busy or not connected"
                })
                .clicked()
            {
                let shaper = choices
                    .get(app.tune.shaper)
                    .map_or(ShaperChoice::Auto, |c| c.1);
                app.send(Command::Tune {
                    axis,
                    window_mm: window,
                    shaper,
                });
            }
            if let Some(b) = app.busy.as_deref().filter(|b| b.starts_with("tune")) {
                let running = status
                    .as_ref()
                    .is_some_and(|s| s.state == MachineState::Identify);
                let p = status.as_ref().map_or(0.0, |s| s.progress.clamp(0.0, 1.0));
                if running {
                    ui.add(
                        egui::ProgressBar::new(p)
                            .text(format!("{b}: measuring, {:.0} %", 100.0 * p)),
                    );
                } else {
                    ui.label(format!("{b}: homing, moving or stopping…"));
                }
            }
            ui.separator();

            ui.heading("3. Result");
            match app.tune.latest(axis) {
                None => {
                    ui.label(format!("No tuning of {name} yet."));
                }
                Some(r) => result(ui, r),
            }
            ui.separator();

            ui.heading("4. Keep it");
            ui.label(
                "The settings stay until the machine restarts: Settings, Save to flash, keeps \
                 them (with the outputs off).",
            );
        });
}

fn result(ui: &mut egui::Ui, r: &TuneReport) {
    let v = verdict(r);
    ui.label(RichText::new(v.words()).color(v.colour()).strong());
    egui::Grid::new("tune-result")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(RichText::new(k).strong());
                ui.label(v);
                ui.end_row();
            };
            row(
                "mode",
                r.mode.map_or("none found".into(), |m| {
                    format!("{:.2} Hz, ζ {:.4}, +{:.1} dB", m.freq_hz, m.damping_ratio, m.peak_db)
                }),
            );
            row(
                "shaper",
                r.shaper.as_ref().map_or("none".into(), |s| {
                    format!("{} at {:.2} Hz, ζ {:.4}", s.kind, s.freq_hz, s.damping_ratio)
                }),
            );
            for (k, val) in &r.settings {
                row("set", format!("{k} = {val}"));
            }
            row("before", stop_words(r.before.as_ref()));
            row("after", stop_words(r.after.as_ref()));
            row("same acceleration", stop_words(r.after_full_acc.as_ref()));
            if let Some(t) = r.full_acc_tolerance_mm {
                row(
                    "tolerance",
                    format!(
                        "the shaper keeps the full acceleration from planner.tolerance_mm = {t:.4} mm on"
                    ),
                );
            }
            for (k, l) in [("loop", &r.loop_without), ("loop with notches", &r.loop_with)] {
                if let Some(l) = l {
                    row(k, loop_cell(l));
                }
            }
            for n in &r.notches_placed {
                row(
                    "notch",
                    format!(
                        "{:.2} Hz, width {:.2} Hz, depth {:.1} dB",
                        n.freq_hz, n.width_hz, n.depth_db
                    ),
                );
            }
            if !r.notch_verdict.is_empty() {
                row("notches", r.notch_verdict.clone());
            }
        });
    ui.label(
        RichText::new(
            "Measured at the encoder (the tool moves more). Notches are kept only when the \
             loop measured with them has 6 dB of gain margin and 30° of phase margin.",
        )
        .weak(),
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::sysid::frequency::FrequencyResponse;
    use host_sim::cli::IdentifyJson;
    use host_sim::studies::freqresp::AxisResponse;

    fn stop(peak_um: f64, settle_ms: Option<f64>) -> StopCheck {
        StopCheck {
            peak_um,
            settle_ms,
            acc_mm_s2: 2000.0,
        }
    }

    fn report(outcome: &str) -> TuneReport {
        TuneReport {
            axis: "y".into(),
            identify: IdentifyJson {
                axis: "y".into(),
                status: "done".into(),
                j: Some(0.18),
                b: Some(0.4),
                f_pos: Some(60.0),
                f_neg: Some(-50.0),
                nrmse: 0.017,
                r2: 0.999,
                machine_time_s: 5.0,
                accepted: true,
            },
            response: AxisResponse::of(
                &FrequencyResponse::new(),
                "done".into(),
                3.0,
                [-50.0, 50.0],
                None,
                None,
            ),
            bandwidth_rad_s: 157.0,
            mode: None,
            shaper: None,
            shaper_refused: Vec::new(),
            settings: Vec::new(),
            notches_placed: Vec::new(),
            in_band_resonances: 0,
            loop_without: None,
            loop_with: None,
            notch_verdict: String::new(),
            full_acc_tolerance_mm: Some(0.1337),
            before: Some(stop(8.75, Some(48.0))),
            after: Some(stop(1.25, Some(0.0))),
            after_full_acc: Some(stop(4.28, Some(0.0))),
            outcome: outcome.into(),
        }
    }

    #[test]
    fn verdicts_name_the_improvement_or_why_it_was_put_back() {
        match verdict(&report("applied")) {
            Verdict::Applied {
                peak_ratio: Some(k),
            } => assert!((k - 8.75 / 4.28).abs() < 1e-9, "{k}"),
            other => panic!("{other:?}"),
        }
        assert_eq!(verdict(&report("dry run")), Verdict::DryRun);
        let v = verdict(&report(
            "rolled back (at the same acceleration the peak after the stop rose from 8.75 to 9.90 µm)",
        ));
        assert_eq!(
            v,
            Verdict::RolledBack(
                "at the same acceleration the peak after the stop rose from 8.75 to 9.90 µm".into()
            )
        );
        assert!(v.words().starts_with("put back: "));
    }

    #[test]
    fn stops_read_in_words() {
        assert_eq!(
            stop_words(Some(&stop(8.75, Some(48.0)))),
            "peak 8.75 µm, within ±5 µm after 48.0 ms, stopping at 2000 mm/s²"
        );
        assert_eq!(
            stop_words(Some(&stop(4.28, Some(0.0)))),
            "peak 4.28 µm, never outside ±5 µm, stopping at 2000 mm/s²"
        );
        assert_eq!(
            stop_words(Some(&stop(12.0, None))),
            "peak 12.00 µm, not settled within the capture, stopping at 2000 mm/s²"
        );
        assert_eq!(stop_words(None), "—");
    }

    #[test]
    fn the_shaper_choices_are_the_command_lines() {
        let c = shaper_choices();
        assert_eq!(c.len(), 8);
        for (name, choice) in c {
            assert_eq!(ShaperChoice::parse(name).unwrap(), choice, "{name}");
        }
        assert_eq!(TunePanel::default().window_mm, DEFAULT_WINDOW_MM);
    }
}
