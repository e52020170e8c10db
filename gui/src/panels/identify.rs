//! The identification tab: a wizard per axis (X, Y, Z) for what `gantry identify` does.
//! (1) What it does, and that the axis moves: an axis of a machine without a model cannot
//! be homed (nothing arms), so it is identified within ±W mm of where it stands; a machine
//! with models is homed and identifies around mid-travel. (2) Identify, with the
//! machine's own progress. (3) The result with units and a verdict in words. (4) Accept:
//! the model goes into the settings (`Command::Accept`, `Request::AcceptIdentified` after
//! a disarm), then a reminder to save them to flash.

use crate::app::GantryApp;
use crate::session::Command;
use controller_core::machine::messages::MachineState;
use egui::{Color32, RichText};
use host_sim::cli::{IdentifyJson, AXES};

/// A validation fit this good is a model to accept. The project's record
/// (docs/identification.md §6, §7): healthy identifications validate at R² ≥ 0.9955 and
/// NRMSE ≤ 0.022 on 60 simulated axes, a consistent gain change still validates at
/// R² 0.97–0.99, while inconsistent data (a drive gain changing mid-run) gives R²
/// 0.44–0.93. So 0.97 separates the two.
pub const GOOD_R2: f32 = 0.97;
/// NRMSE at most this for a good fit (twice the worst healthy case of the study).
pub const GOOD_NRMSE: f32 = 0.05;
/// Below this R² the model does not describe the axis (the inconsistent runs' range).
pub const POOR_R2: f32 = 0.93;
/// The window offered for an axis that cannot be homed, mm either side (the study's
/// machines stayed within ±42 mm of a ±50 mm window; 20 mm is modest on any axis).
pub const DEFAULT_WINDOW_MM: f32 = 20.0;
/// Largest window the form takes, mm (the gantry's travel is ±150 mm).
const MAX_WINDOW_MM: f32 = 150.0;

const GOOD_GREEN: Color32 = Color32::from_rgb(80, 160, 60);
const DOUBT_GOLD: Color32 = Color32::from_rgb(181, 137, 0);
const BAD_RED: Color32 = Color32::from_rgb(220, 50, 47);

/// The tab's state.
#[derive(Debug)]
pub struct IdentifyPanel {
    /// Every identification this session, oldest first.
    pub results: Vec<IdentifyJson>,
    /// The axis the wizard shows (0 X, 1 Y, 2 Z).
    pub axis: usize,
    /// Half-width of travel for an axis identified where it stands, mm.
    pub window_mm: f32,
    /// Identify where the axis stands (±window) even though it could be homed.
    pub in_place: bool,
}

impl Default for IdentifyPanel {
    fn default() -> Self {
        Self {
            results: Vec::new(),
            axis: 0,
            window_mm: DEFAULT_WINDOW_MM,
            in_place: false,
        }
    }
}

impl IdentifyPanel {
    /// The newest result of `axis`.
    pub fn latest(&self, axis: usize) -> Option<&IdentifyJson> {
        let name = AXES.get(axis)?;
        self.results.iter().rev().find(|r| r.axis == *name)
    }
}

/// How good a result is, in words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// It finished and validates well: accept it.
    Good,
    /// It finished, but the validation is mediocre: identify again (mind what moves the
    /// axis, the window) before accepting.
    Doubtful,
    /// The model does not describe the axis.
    Poor,
    /// It did not finish (stopped, a fault, left its window).
    Failed,
}

impl Verdict {
    pub fn words(self) -> &'static str {
        match self {
            Self::Good => "good fit: accept it",
            Self::Doubtful => "mediocre fit: identify again before accepting",
            Self::Poor => "poor fit: the model does not describe the axis",
            Self::Failed => "did not finish",
        }
    }
    fn colour(self) -> Color32 {
        match self {
            Self::Good => GOOD_GREEN,
            Self::Doubtful => DOUBT_GOLD,
            Self::Poor | Self::Failed => BAD_RED,
        }
    }
}

/// The verdict on `r` from its validation (R², NRMSE).
pub fn verdict(r: &IdentifyJson) -> Verdict {
    if r.status != "done" || r.j.is_none() {
        Verdict::Failed
    } else if !(r.r2.is_finite() && r.nrmse.is_finite()) || r.r2 < POOR_R2 {
        Verdict::Poor
    } else if r.r2 >= GOOD_R2 && r.nrmse <= GOOD_NRMSE {
        Verdict::Good
    } else {
        Verdict::Doubtful
    }
}

/// How the machine would identify an axis: `Some(window)` within ±window of where it
/// stands, `None` homed and around mid-travel. A machine with any axis lacking a model
/// cannot arm (hence cannot home) and must use a window; a homed axis identifies at
/// mid-travel whatever the form says, as `host_sim::cli::identify` decides.
pub fn window_for(model_missing: u8, homed: bool, in_place: bool, window_mm: f32) -> Option<f32> {
    (model_missing != 0 || in_place && !homed).then_some(window_mm)
}

/// The settings now hold `r`'s model (the values read after an accept match it).
pub fn stored(values: &[(String, String)], r: &IdentifyJson) -> bool {
    let get = |field: &str| -> Option<f32> {
        let key = format!("axis.{}.model.{field}", r.axis);
        values
            .iter()
            .find(|(k, _)| *k == key)
            .and_then(|(_, v)| v.parse().ok())
    };
    let near = |a: Option<f32>, b: Option<f32>| match (a, b) {
        (Some(a), Some(b)) => (a - b).abs() <= 1e-4 * a.abs().max(b.abs()).max(1e-6),
        _ => false,
    };
    near(get("inertia"), r.j)
        && near(get("viscous"), r.b)
        && near(get("coulomb_pos_mnm"), r.f_pos)
        && near(get("coulomb_neg_mnm"), r.f_neg)
}

fn num(v: Option<f32>, digits: usize) -> String {
    v.map_or("—".into(), |v| format!("{v:.digits$}"))
}

/// An axis wizard's head (identification, tuning): the axis chooser, and what the
/// status says of the chosen axis.
pub struct AxisHead {
    pub axis: usize,
    pub name: &'static str,
    /// Axes without a model (bits).
    pub missing: u8,
    pub homed: bool,
    /// The session is free for a command.
    pub free: bool,
    pub status: Option<controller_core::machine::messages::Status>,
}

/// Draw the axis chooser on `axis` and read the status for it.
pub fn axis_head(app: &GantryApp, axis: &mut usize, ui: &mut egui::Ui) -> AxisHead {
    let status = app.live.status.clone();
    let free = app.busy.is_none() && app.lost.is_none() && app.session.is_some();
    ui.horizontal(|ui| {
        ui.label("Axis");
        for (i, name) in ["X", "Y", "Z"].iter().enumerate() {
            ui.selectable_value(axis, i, *name);
        }
    });
    let a = (*axis).min(2);
    ui.separator();
    AxisHead {
        axis: a,
        name: ["X", "Y", "Z"][a],
        missing: status.as_ref().map_or(0, |s| s.model_missing),
        homed: status.as_ref().is_some_and(|s| s.homed & (1 << a) != 0),
        free,
        status,
    }
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    let mut axis = app.identify.axis;
    let AxisHead {
        axis,
        name,
        missing,
        homed,
        free,
        status,
    } = axis_head(app, &mut axis, ui);
    app.identify.axis = axis;
    egui::ScrollArea::vertical()
        .auto_shrink([false, false])
        .show(ui, |ui| {
            // 1: what it does
            ui.heading(format!("1. What identifying {name} does"));
            ui.label(
                "The machine drives the axis itself: steady speeds both ways, then \
                 accelerations, then a short back-and-forth it did not fit, to validate the \
                 model (inertia J, viscous friction B, Coulomb friction f+ and f−). It takes \
                 about 5–10 s of machine time.",
            );
            ui.label(
                RichText::new(format!(
                    "The {name} axis WILL MOVE. Keep clear of it, and keep the stop button at hand."
                ))
                .strong()
                .color(DOUBT_GOLD),
            );
            if missing != 0 {
                let which: Vec<&str> = (0..3)
                    .filter(|i| missing & (1 << i) != 0)
                    .map(|i| ["X", "Y", "Z"][i])
                    .collect();
                ui.label(format!(
                    "Without a model for {} nothing can arm, so the machine cannot home: it \
                     identifies {name} within ±W mm of where it stands now, with the outputs \
                     going on for the identification only.",
                    which.join(", ")
                ));
            } else if homed {
                ui.label(format!(
                    "{name} is homed: it moves to the middle of its travel and identifies there."
                ));
            } else {
                ui.label(format!(
                    "The machine homes first (arming it), then {name} moves to the middle of \
                     its travel and identifies there."
                ));
                ui.checkbox(
                    &mut app.identify.in_place,
                    "identify where it stands instead (no homing)",
                );
            }
            let window = window_for(
                missing,
                homed,
                app.identify.in_place,
                app.identify.window_mm,
            );
            if window.is_some() {
                ui.horizontal(|ui| {
                    ui.label("Window ±W");
                    ui.add(
                        egui::DragValue::new(&mut app.identify.window_mm)
                            .range(1.0..=MAX_WINDOW_MM)
                            .speed(0.5)
                            .suffix(" mm"),
                    );
                });
                ui.label(
                    RichText::new(format!(
                        "Make sure {name} has at least {:.0} mm of room on BOTH sides of where \
                         it stands (jog it to the middle first): the machine does not know its \
                         travel before homing, and stops the axis if it leaves the window. \
                         Wider windows allow faster, better-excited runs; {DEFAULT_WINDOW_MM:.0} \
                         mm is a safe start.",
                        app.identify.window_mm
                    ))
                    .weak(),
                );
            }
            ui.separator();

            // 2: identify
            ui.heading(format!("2. Identify {name}"));
            let running = status
                .as_ref()
                .is_some_and(|s| s.state == MachineState::Identify);
            let fault = status
                .as_ref()
                .is_some_and(|s| s.state == MachineState::Fault);
            if ui
                .add_enabled(
                    free && !fault,
                    egui::Button::new(RichText::new(format!("Identify {name}")).strong()),
                )
                .on_hover_text("the axis moves; the stop button stops it at once")
                .on_disabled_hover_text(if fault {
                    "reset the fault first"
                } else {
                    "the machine is busy or not connected"
                })
                .clicked()
            {
                app.send(Command::Identify {
                    axis,
                    window_mm: window,
                    accept: false,
                });
            }
            if running {
                let p = status.as_ref().map_or(0.0, |s| s.progress.clamp(0.0, 1.0));
                ui.add(
                    egui::ProgressBar::new(p)
                        .text(format!("identifying {name}: {:.0} %", 100.0 * p)),
                );
            } else if let Some(b) = app.busy.as_deref().filter(|b| b.starts_with("identify")) {
                ui.label(format!("{b}: preparing (homing, moving to mid-travel)…"));
            }
            ui.separator();

            // 3: results
            ui.heading("3. Results");
            results_table(app, ui);
            ui.separator();

            // 4: accept
            ui.heading(format!("4. Accept {name}'s model"));
            let latest = app.identify.latest(axis).cloned();
            match latest {
                None => {
                    ui.label(format!("No result for {name} yet."));
                }
                Some(r) => {
                    let v = verdict(&r);
                    let in_settings = r.accepted || stored(&app.settings.values, &r);
                    ui.label(RichText::new(v.words()).color(v.colour()));
                    if in_settings {
                        ui.label(
                            RichText::new(format!("{name}'s model is in the settings."))
                                .color(GOOD_GREEN),
                        );
                    }
                    let can = free && v != Verdict::Failed && !in_settings;
                    if ui
                        .add_enabled(can, egui::Button::new(format!("Accept {name}")))
                        .on_hover_text(if v == Verdict::Good {
                            "store this model in the settings (the law's gains follow from \
                             it); the machine disarms first, since a new model changes the law"
                        } else {
                            "this fit is not a good one: accepting stores it anyway (the \
                             law's gains follow from it); identifying again is better. The \
                             machine disarms first, since a new model changes the law"
                        })
                        .clicked()
                    {
                        app.send(Command::Accept { axis });
                    }
                    if in_settings {
                        ui.label(
                            "The model is in the machine's settings until it restarts: \
                             Settings, Save to flash, keeps it (with the outputs off).",
                        );
                    }
                }
            }
        });
}

fn results_table(app: &GantryApp, ui: &mut egui::Ui) {
    if app.identify.results.is_empty() {
        ui.label("None yet.");
        return;
    }
    egui::Grid::new("identify-results")
        .num_columns(10)
        .striped(true)
        .show(ui, |ui| {
            for h in [
                "axis",
                "status",
                "J mN·m/(mm/s²)",
                "B mN·m/(mm/s)",
                "f+ mN·m",
                "f− mN·m",
                "NRMSE",
                "R²",
                "time s",
                "verdict",
            ] {
                ui.label(RichText::new(h).strong());
            }
            ui.end_row();
            for r in &app.identify.results {
                let v = verdict(r);
                ui.label(r.axis.to_uppercase());
                ui.label(&r.status);
                ui.label(num(r.j, 5));
                ui.label(num(r.b, 5));
                ui.label(num(r.f_pos, 2));
                ui.label(num(r.f_neg, 2));
                ui.label(format!("{:.4}", r.nrmse));
                ui.label(format!("{:.4}", r.r2));
                ui.label(format!("{:.2}", r.machine_time_s));
                let mut words = v.words().to_string();
                if r.accepted || stored(&app.settings.values, r) {
                    words.push_str(" (in the settings)");
                }
                ui.label(RichText::new(words).color(v.colour()));
                ui.end_row();
            }
        });
    ui.label(
        RichText::new(format!(
            "J, B and f± are per unit of the drive's command (mN·m at the motor, mm at the \
             table). Good fit: R² ≥ {GOOD_R2} and NRMSE ≤ {GOOD_NRMSE} on the validation \
             move; below R² {POOR_R2} the model does not describe the axis."
        ))
        .weak(),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(r2: f32, nrmse: f32) -> IdentifyJson {
        IdentifyJson {
            axis: "y".into(),
            status: "done".into(),
            j: Some(0.082),
            b: Some(0.0125),
            f_pos: Some(31.5),
            f_neg: Some(-29.75),
            nrmse,
            r2,
            machine_time_s: 5.6,
            accepted: false,
        }
    }

    #[test]
    fn verdicts_follow_the_projects_validation_record() {
        // the study's healthy runs: R² ≥ 0.9955, NRMSE ≤ 0.022
        assert_eq!(verdict(&result(0.9955, 0.022)), Verdict::Good);
        assert_eq!(verdict(&result(0.97, 0.05)), Verdict::Good);
        assert_eq!(verdict(&result(0.96, 0.03)), Verdict::Doubtful);
        assert_eq!(verdict(&result(0.99, 0.08)), Verdict::Doubtful);
        // the inconsistent runs: 0.44–0.93
        assert_eq!(verdict(&result(0.44, 0.2)), Verdict::Poor);
        assert_eq!(verdict(&result(0.92, 0.1)), Verdict::Poor);
        assert_eq!(verdict(&result(f32::NAN, 0.01)), Verdict::Poor);
        let mut failed = result(0.0, 0.0);
        failed.status = "failed (Fault, left its window)".into();
        failed.j = None;
        assert_eq!(verdict(&failed), Verdict::Failed);
    }

    #[test]
    fn a_machine_without_models_identifies_in_a_window() {
        // any axis without a model: nothing arms, a window whatever else
        assert_eq!(window_for(0b010, false, false, 20.0), Some(20.0));
        assert_eq!(window_for(0b001, true, false, 20.0), Some(20.0));
        // models everywhere: homed (or homing first) and mid-travel
        assert_eq!(window_for(0, false, false, 20.0), None);
        assert_eq!(window_for(0, true, false, 20.0), None);
        // where it stands, on request, only while not homed
        assert_eq!(window_for(0, false, true, 35.0), Some(35.0));
        assert_eq!(window_for(0, true, true, 35.0), None);
    }

    #[test]
    fn a_stored_model_is_recognised_in_the_settings() {
        let r = result(0.99, 0.02);
        let mut values = vec![
            ("axis.y.model.known".to_string(), "true".to_string()),
            ("axis.y.model.inertia".to_string(), "0.082".to_string()),
            ("axis.y.model.viscous".to_string(), "0.0125".to_string()),
            (
                "axis.y.model.coulomb_pos_mnm".to_string(),
                "31.5".to_string(),
            ),
            (
                "axis.y.model.coulomb_neg_mnm".to_string(),
                "-29.75".to_string(),
            ),
        ];
        assert!(stored(&values, &r));
        values[1].1 = "0.09".into();
        assert!(!stored(&values, &r));
        assert!(!stored(&[], &r));
    }

    #[test]
    fn the_newest_result_of_an_axis_is_the_one_offered() {
        let mut p = IdentifyPanel::default();
        p.results.push(result(0.5, 0.3));
        p.results.push(result(0.99, 0.02));
        assert_eq!(p.latest(1).map(|r| r.r2), Some(0.99));
        assert!(p.latest(0).is_none());
        assert!(p.latest(7).is_none());
        assert_eq!(p.window_mm, DEFAULT_WINDOW_MM);
    }
}
