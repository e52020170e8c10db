//! The scope tab: `gantry scope` in a form. The machine's scope records up to four signals
//! at the control rate (or every n-th period) into its own buffer, triggered at once, on
//! a fault or on a signal crossing a level, with samples kept from before the trigger;
//! then the session reads the capture out. The form writes the same text the command
//! line takes (`--signals pos.x,ref.x`, `--trigger rising:vel.x:5`) and parses it with
//! the command line's own parsers (`host_sim::cli::scope::parse_signals`,
//! `parse_trigger`), so the two cannot disagree. The capture is plotted against the time
//! from the trigger, one plot per signal, and written as CSV with `gantry scope`'s
//! writer.

use crate::app::GantryApp;
use crate::session::Command;
use anyhow::{anyhow, bail, Result};
use controller_core::machine::scope::{
    ScopeConfig, ScopeState, Signal, SCOPE_CHANNELS, SCOPE_VALUES,
};
use egui::{Color32, RichText};
use host_sim::cli::scope::{parse_signals, parse_trigger, write_csv, Capture};
use std::path::Path;

/// Longest wait the form offers, s of machine time (`capture`'s own bound).
const MAX_TIMEOUT_S: f32 = 3600.0;
const ERROR_RED: Color32 = Color32::from_rgb(220, 50, 47);
/// The figure's colours (`host_sim::output::scope_plots`): signal blue, trigger red.
const LINE_BLUE: Color32 = Color32::from_rgb(31, 119, 180);
const TRIGGER_RED: Color32 = Color32::from_rgb(214, 39, 40);

/// What starts the capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TriggerKind {
    /// At once (after the pre-trigger samples).
    #[default]
    Now,
    /// When a fault latches.
    Fault,
    /// The signal goes from below the level to at or above it.
    Rising,
    /// The signal goes from above the level to at or below it.
    Falling,
}

impl TriggerKind {
    const ALL: [Self; 4] = [Self::Now, Self::Fault, Self::Rising, Self::Falling];
    fn label(self) -> &'static str {
        match self {
            Self::Now => "immediate",
            Self::Fault => "on a fault",
            Self::Rising => "rising edge",
            Self::Falling => "falling edge",
        }
    }
}

/// The tab's state: the form (with `gantry scope`'s defaults) and the last capture.
#[derive(Debug)]
pub struct ScopePanel {
    pub capture: Option<Capture>,
    /// The chosen signals (empty slots are unused), at most [`SCOPE_CHANNELS`].
    pub signals: [String; SCOPE_CHANNELS],
    /// Samples per signal.
    pub samples: u16,
    /// One sample every this many control periods.
    pub every: u16,
    /// Samples kept from before the trigger.
    pub pre: u16,
    pub trigger: TriggerKind,
    pub trigger_signal: String,
    pub level: f32,
    /// Give up after this much machine time, s.
    pub timeout_s: f32,
    /// Where "Save CSV" writes.
    pub csv_path: String,
    /// Run the loaded program while the scope waits (`gantry scope --run`).
    pub run_program: bool,
}

impl Default for ScopePanel {
    fn default() -> Self {
        // gantry scope's defaults: --signals pos.x,ref.x,tracking.x --samples 500
        // --every 1 --pre 0 --trigger now --timeout-s 10
        Self {
            capture: None,
            signals: [
                "pos.x".into(),
                "ref.x".into(),
                "tracking.x".into(),
                String::new(),
            ],
            samples: 500,
            every: 1,
            pre: 0,
            trigger: TriggerKind::Now,
            trigger_signal: "vel.x".into(),
            level: 1.0,
            timeout_s: 10.0,
            csv_path: "out/scope.csv".into(),
            run_program: false,
        }
    }
}

/// Every signal name the scope knows (`pos.x`, …, `contour`, `feed_ratio`).
pub fn signal_names() -> Vec<String> {
    Signal::names()
        .map(|(k, a)| match a {
            Some(a) => format!("{k}.{a}"),
            None => k.to_string(),
        })
        .collect()
}

/// A signal's unit by its name: the one host-sim's scope figure labels it with.
pub use host_sim::output::scope_plots::signal_unit;

impl ScopePanel {
    /// The chosen signals' names, in order.
    pub fn names(&self) -> Vec<String> {
        self.signals
            .iter()
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect()
    }

    /// `--signals` as the command line would be given it.
    pub fn signals_text(&self) -> String {
        self.names().join(",")
    }

    /// `--trigger` as the command line would be given it.
    pub fn trigger_text(&self) -> String {
        match self.trigger {
            TriggerKind::Now => "now".into(),
            TriggerKind::Fault => "fault".into(),
            TriggerKind::Rising => format!("rising:{}:{}", self.trigger_signal, self.level),
            TriggerKind::Falling => format!("falling:{}:{}", self.trigger_signal, self.level),
        }
    }

    /// The capture to arm and its signals' names, built as `gantry scope` builds them
    /// (its parsers, its checks), or why not.
    pub fn config(&self) -> Result<(ScopeConfig, Vec<String>)> {
        let text = self.signals_text();
        let channels = parse_signals(&text)?;
        let cfg = ScopeConfig {
            channels: heapless::Vec::from_slice(&channels)
                .map_err(|_| anyhow!("--signals: at most {SCOPE_CHANNELS}"))?,
            samples: self.samples,
            every_periods: self.every,
            pre_trigger: self.pre,
            trigger: parse_trigger(&self.trigger_text())?,
        };
        if let Err(why) = cfg.check() {
            bail!("{why}");
        }
        if !(self.timeout_s > 0.0 && self.timeout_s <= MAX_TIMEOUT_S) {
            bail!(
                "timeout must be within (0, {MAX_TIMEOUT_S}] s, got {}",
                self.timeout_s
            );
        }
        Ok((cfg, self.names()))
    }

    /// Most samples per signal the buffer holds with the chosen signals.
    pub fn max_samples(&self) -> u16 {
        let n = self.names().len().max(1);
        u16::try_from(SCOPE_VALUES / n).unwrap_or(u16::MAX)
    }
}

/// The capture's signal `i` as plot points: (time from the trigger, ms; value).
pub fn series_ms(cap: &Capture, i: usize) -> Vec<[f64; 2]> {
    cap.rows
        .iter()
        .filter_map(|(t_s, v)| v.get(i).map(|y| [t_s * 1e3, f64::from(*y)]))
        .collect()
}

fn state_words(s: ScopeState) -> &'static str {
    match s {
        ScopeState::Off => "off (nothing armed)",
        ScopeState::Waiting => "waiting for the trigger",
        ScopeState::Triggered => "triggered, recording",
        ScopeState::Done => "capture complete",
    }
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    let free = app.busy.is_none() && app.lost.is_none() && app.session.is_some();
    let names = signal_names();
    let p = &mut app.scope;
    ui.horizontal_wrapped(|ui| {
        ui.label("Signals");
        for (i, slot) in p.signals.iter_mut().enumerate() {
            let shown = if slot.is_empty() {
                "—".to_string()
            } else {
                format!("{slot} ({})", signal_unit(slot))
            };
            egui::ComboBox::from_id_salt(("scope-signal", i))
                .selected_text(shown)
                .show_ui(ui, |ui| {
                    ui.selectable_value(slot, String::new(), "— (none)");
                    for n in &names {
                        ui.selectable_value(slot, n.clone(), n.as_str());
                    }
                });
        }
    });
    ui.horizontal_wrapped(|ui| {
        let max = p.max_samples();
        ui.label("Samples");
        ui.add(egui::DragValue::new(&mut p.samples).range(1..=max))
            .on_hover_text(format!(
                "samples per signal: samples × signals ≤ {SCOPE_VALUES} (≤ {max} with these)"
            ));
        ui.label("every");
        ui.add(egui::DragValue::new(&mut p.every).range(1..=u16::MAX))
            .on_hover_text("one sample every this many control periods (decimation)");
        ui.label("periods");
        let rate_hz = f64::from(app.live.rate_hz.max(1));
        ui.label(
            RichText::new(format!(
                "= {:.1} ms recorded",
                f64::from(p.samples) * f64::from(p.every) / rate_hz * 1e3
            ))
            .weak(),
        );
        ui.separator();
        ui.label("pre-trigger");
        ui.add(egui::DragValue::new(&mut p.pre).range(0..=p.samples.saturating_sub(1)))
            .on_hover_text("samples kept from before the trigger (fewer than the samples)");
        ui.label("timeout");
        ui.add(
            egui::DragValue::new(&mut p.timeout_s)
                .range(0.1..=MAX_TIMEOUT_S)
                .speed(0.5)
                .suffix(" s"),
        )
        .on_hover_text("give up when the capture is not complete after this much machine time");
    });
    ui.horizontal_wrapped(|ui| {
        ui.label("Trigger");
        for k in TriggerKind::ALL {
            ui.selectable_value(&mut p.trigger, k, k.label());
        }
        if matches!(p.trigger, TriggerKind::Rising | TriggerKind::Falling) {
            ui.label("on");
            egui::ComboBox::from_id_salt("scope-trigger-signal")
                .selected_text(p.trigger_signal.clone())
                .show_ui(ui, |ui| {
                    for n in &names {
                        ui.selectable_value(&mut p.trigger_signal, n.clone(), n.as_str());
                    }
                });
            ui.label("level");
            ui.add(
                egui::DragValue::new(&mut p.level)
                    .speed(0.1)
                    .suffix(format!(" {}", signal_unit(&p.trigger_signal))),
            );
        }
    });
    let program = app.program.as_ref().map(|l| l.path.clone());
    ui.horizontal_wrapped(|ui| {
        let label = match &program {
            Some(path) => format!("run {} while the scope waits", path.display()),
            None => "run the loaded program while the scope waits (load one first)".into(),
        };
        ui.add_enabled(
            program.is_some(),
            egui::Checkbox::new(&mut p.run_program, label),
        )
        .on_hover_text(
            "gantry scope --run: homes and arms, then runs the program while the scope \
                 waits for its trigger. Without it, the window's other commands wait until \
                 the capture is complete (one command at a time): capture at rest, on a \
                 fault, or with a program here.",
        );
    });
    let run = program.filter(|_| p.run_program);
    let config = p.config();
    let mut command_line = format!(
        "arm the scope and read the capture: gantry scope --signals {} --samples {} \
         --every {} --pre {} --trigger {} --timeout-s {}",
        p.signals_text(),
        p.samples,
        p.every,
        p.pre,
        p.trigger_text(),
        p.timeout_s
    );
    if let Some(path) = &run {
        command_line.push_str(&format!(" --run {}", path.display()));
    }
    let timeout_s = p.timeout_s;
    let state = app.live.status.as_ref().map(|s| s.scope);
    let mut arm = false;
    ui.horizontal(|ui| {
        let ok = config.is_ok();
        arm = ui
            .add_enabled(free && ok, egui::Button::new("Capture"))
            .on_hover_text(command_line)
            .on_disabled_hover_text(if ok {
                "the machine is busy or not connected"
            } else {
                "fix the configuration first"
            })
            .clicked();
        if let Err(e) = &config {
            ui.label(RichText::new(format!("{e:#}")).color(ERROR_RED));
        }
        if let Some(s) = state {
            ui.separator();
            ui.label(format!("scope: {}", state_words(s)));
        }
    });
    if arm {
        if let Ok((config, names)) = config {
            app.send(Command::Scope {
                config,
                names,
                timeout_s,
                run,
            });
        }
    }
    ui.horizontal(|ui| {
        ui.label("CSV file");
        ui.add(egui::TextEdit::singleline(&mut app.scope.csv_path).desired_width(260.0));
        let can = app.scope.capture.is_some() && !app.scope.csv_path.trim().is_empty();
        if ui
            .add_enabled(can, egui::Button::new("Save CSV"))
            .on_hover_text(
                "t_s (from the trigger), then one column per signal (gantry scope's CSV)",
            )
            .clicked()
        {
            if let Some(cap) = &app.scope.capture {
                let path = app.scope.csv_path.trim().to_string();
                let line = match write_csv(Path::new(&path), cap) {
                    Ok(()) => format!("scope: {} samples written to {path}", cap.rows.len()),
                    Err(e) => format!("scope: {e:#}"),
                };
                app.say(line);
            }
        }
    });
    ui.separator();
    let Some(cap) = &app.scope.capture else {
        ui.label("No capture yet: choose the signals and the trigger, then Capture.");
        return;
    };
    plot(ui, cap);
}

/// One plot per signal, their time axes linked, a red line at the trigger.
fn plot(ui: &mut egui::Ui, cap: &Capture) {
    let n = cap.names.len().max(1);
    let height = ((ui.available_height() - 8.0 * n as f32) / n as f32).max(90.0);
    let link = egui::Id::unique("scope-time");
    egui::ScrollArea::vertical()
        .auto_shrink([false, false])
        .show(ui, |ui| {
            for (i, name) in cap.names.iter().enumerate() {
                let unit = signal_unit(name);
                let label = if unit.is_empty() {
                    name.clone()
                } else {
                    format!("{name} [{unit}]")
                };
                egui_plot::Plot::new(("scope-plot", i))
                    .height(height)
                    // (one width for all: the linked time axes then line up)
                    .y_axis_min_width(64.0)
                    .link_axis(link, [true, false])
                    .link_cursor(link, [true, false])
                    .legend(egui_plot::Legend::default())
                    .x_axis_label(if i + 1 == n {
                        "time from the trigger, ms"
                    } else {
                        ""
                    })
                    .y_axis_label(label.clone())
                    .show(ui, |plot| {
                        plot.line(
                            egui_plot::Line::new(label.clone(), series_ms(cap, i)).color(LINE_BLUE),
                        );
                        plot.vline(egui_plot::VLine::new("trigger", 0.0).color(TRIGGER_RED));
                    });
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::machine::scope::Trigger;

    #[test]
    fn the_default_form_is_gantry_scopes_default_command_line() {
        let (cfg, names) = ScopePanel::default().config().unwrap();
        // gantry scope OUT (defaults): --signals pos.x,ref.x,tracking.x --samples 500
        // --every 1 --pre 0 --trigger now
        let expected = ScopeConfig {
            channels: heapless::Vec::from_slice(&[
                Signal::Pos(0),
                Signal::Ref(0),
                Signal::Tracking(0),
            ])
            .unwrap(),
            samples: 500,
            every_periods: 1,
            pre_trigger: 0,
            trigger: Trigger::Now,
        };
        assert_eq!(cfg, expected);
        assert_eq!(names, ["pos.x", "ref.x", "tracking.x"]);
    }

    #[test]
    fn a_form_builds_what_the_command_lines_parsers_build_from_the_same_text() {
        let p = ScopePanel {
            signals: [
                "vel.y".into(),
                String::new(),
                "effort.y".into(),
                "contour".into(),
            ],
            samples: 400,
            every: 5,
            pre: 100,
            trigger: TriggerKind::Falling,
            trigger_signal: "vel.y".into(),
            level: -2.5,
            ..ScopePanel::default()
        };
        assert_eq!(p.signals_text(), "vel.y,effort.y,contour");
        assert_eq!(p.trigger_text(), "falling:vel.y:-2.5");
        let (cfg, names) = p.config().unwrap();
        let cli = ScopeConfig {
            channels: heapless::Vec::from_slice(&parse_signals("vel.y,effort.y,contour").unwrap())
                .unwrap(),
            samples: 400,
            every_periods: 5,
            pre_trigger: 100,
            trigger: parse_trigger("falling:vel.y:-2.5").unwrap(),
        };
        assert_eq!(cfg, cli);
        assert_eq!(
            cfg.trigger,
            Trigger::Falling {
                signal: Signal::Vel(1),
                level: -2.5
            }
        );
        assert_eq!(names, ["vel.y", "effort.y", "contour"]);
    }

    #[test]
    fn bad_forms_are_refused_with_the_reason() {
        let none = ScopePanel {
            signals: Default::default(),
            ..ScopePanel::default()
        };
        assert!(none.config().unwrap_err().to_string().contains("1 to 4"));
        // 3 signals × 700 samples > 2048
        let big = ScopePanel {
            samples: 700,
            ..ScopePanel::default()
        };
        assert_eq!(big.max_samples(), 682);
        assert!(big.config().unwrap_err().to_string().contains("2048"));
        let pre = ScopePanel {
            pre: 500,
            ..ScopePanel::default()
        };
        assert!(pre
            .config()
            .unwrap_err()
            .to_string()
            .contains("pre-trigger"));
        let level = ScopePanel {
            trigger: TriggerKind::Rising,
            level: f32::NAN,
            ..ScopePanel::default()
        };
        assert!(level.config().is_err());
        let timeout = ScopePanel {
            timeout_s: 0.0,
            ..ScopePanel::default()
        };
        assert!(timeout
            .config()
            .unwrap_err()
            .to_string()
            .contains("timeout"));
    }

    #[test]
    fn every_signal_name_parses_and_the_plot_is_in_ms_from_the_trigger() {
        let names = signal_names();
        assert_eq!(names.len(), 7 * 3 + 2);
        for n in &names {
            assert!(Signal::from_name(n).is_some(), "{n}");
        }
        assert_eq!(signal_unit("vel.z"), "mm/s");
        assert_eq!(signal_unit("effort.x"), "mN·m");
        assert_eq!(signal_unit("feed_ratio"), "");
        let cap = Capture {
            names: vec!["pos.x".into(), "vel.x".into()],
            rows: vec![
                (-0.002, vec![1.0, 2.0]),
                (0.0, vec![1.5, 2.5]),
                (0.001, vec![2.0]),
            ],
        };
        assert_eq!(series_ms(&cap, 0), [[-2.0, 1.0], [0.0, 1.5], [1.0, 2.0]]);
        // a short row gives no point rather than a panic
        assert_eq!(series_ms(&cap, 1), [[-2.0, 2.0], [0.0, 2.5]]);
    }
}
