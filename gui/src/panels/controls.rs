//! The left panel: the jog pad (continuous while a button is held, or exact steps) and
//! the program (file, load, run, feed hold, resume, abort, progress with line and time
//! left).

use crate::app::GantryApp;
use crate::session::Command;
use controller_core::machine::messages::MachineState;
use egui::RichText;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Jog speeds offered, mm/s.
pub const JOG_SPEEDS_MM_S: [f32; 4] = [1.0, 5.0, 20.0, 50.0];
/// Jog steps offered, mm.
pub const JOG_STEPS_MM: [f32; 4] = [0.01, 0.1, 1.0, 10.0];
/// A held jog button resends its jog this often (the machine's jog timeout is longer).
const JOG_REPEAT: Duration = Duration::from_millis(100);

/// The panel's own state.
#[derive(Debug)]
pub struct Controls {
    /// Continuous (true) or steps.
    pub continuous: bool,
    pub speed_mm_s: f32,
    pub step_mm: f32,
    /// The jog a held button keeps alive: axis, signed speed, last sent.
    held: Option<(usize, f32, Instant)>,
    pub program_path: String,
    /// When the running program started (for the time left).
    run_started: Option<Instant>,
}

impl Default for Controls {
    fn default() -> Self {
        Self {
            continuous: true,
            speed_mm_s: 5.0,
            step_mm: 1.0,
            held: None,
            program_path: String::new(),
            run_started: None,
        }
    }
}

/// The programs beside the project (host-sim/programs/*.nc), for the picker.
fn known_programs() -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = ["host-sim/programs", "../host-sim/programs"]
        .iter()
        .filter_map(|d| std::fs::read_dir(d).ok())
        .flat_map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "nc"))
        .collect();
    out.sort();
    out
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        jog(app, ui);
        ui.separator();
        program(app, ui);
    });
}

fn jog(app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.heading("Jog");
    let state = app.live.status.as_ref().map(|s| s.state);
    let free = app.lost.is_none()
        && app.busy.as_deref().is_none_or(|b| b.starts_with("jog"))
        && matches!(state, Some(MachineState::Idle) | Some(MachineState::Jog));
    ui.horizontal(|ui| {
        ui.selectable_value(&mut app.controls.continuous, true, "continuous");
        ui.selectable_value(&mut app.controls.continuous, false, "steps");
    });
    ui.horizontal(|ui| {
        if app.controls.continuous {
            for v in JOG_SPEEDS_MM_S {
                ui.selectable_value(&mut app.controls.speed_mm_s, v, format!("{v} mm/s"));
            }
        } else {
            for s in JOG_STEPS_MM {
                ui.selectable_value(&mut app.controls.step_mm, s, format!("{s} mm"));
            }
        }
    });
    let mut pressed: Option<(usize, f32)> = None;
    let mut clicked: Option<(usize, f32)> = None;
    let mut pad = |ui: &mut egui::Ui, label: &str, axis: usize, sign: f32| {
        let r = ui.add_enabled(
            free,
            egui::Button::new(label).min_size(egui::vec2(44.0, 30.0)),
        );
        if r.is_pointer_button_down_on() {
            pressed = Some((axis, sign));
        }
        if r.clicked() {
            clicked = Some((axis, sign));
        }
    };
    egui::Grid::new("jogpad").show(ui, |ui| {
        ui.label("");
        pad(ui, "Y+", 1, 1.0);
        ui.label("");
        pad(ui, "Z+", 2, 1.0);
        ui.end_row();
        pad(ui, "X−", 0, -1.0);
        ui.label("");
        pad(ui, "X+", 0, 1.0);
        ui.label("");
        ui.end_row();
        ui.label("");
        pad(ui, "Y−", 1, -1.0);
        ui.label("");
        pad(ui, "Z−", 2, -1.0);
        ui.end_row();
    });
    if app.controls.continuous {
        let now = Instant::now();
        match (pressed, app.controls.held) {
            (Some((axis, sign)), held) => {
                let v = sign * app.controls.speed_mm_s;
                let due = held.is_none_or(|(a, hv, t)| {
                    a != axis || hv != v || now.duration_since(t) >= JOG_REPEAT
                });
                if due {
                    app.send(Command::Jog { axis, vel_mm_s: v });
                    app.controls.held = Some((axis, v, now));
                }
                ui.ctx().request_repaint_after(JOG_REPEAT);
            }
            (None, Some((axis, _, _))) => {
                app.send(Command::Jog {
                    axis,
                    vel_mm_s: 0.0,
                });
                app.controls.held = None;
            }
            (None, None) => {}
        }
    } else if let Some((axis, sign)) = clicked {
        app.send(Command::Step {
            axis,
            step_mm: sign * app.controls.step_mm,
        });
    }
    if !free {
        ui.label(RichText::new("jog: arm and home first; not while a command runs").weak());
    }
}

fn program(app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.heading("Program");
    let idle = app.busy.is_none() && app.lost.is_none();
    ui.horizontal(|ui| {
        ui.add(
            egui::TextEdit::singleline(&mut app.controls.program_path)
                .hint_text("G-code file")
                .desired_width(170.0),
        );
        if ui
            .add_enabled(
                idle && !app.controls.program_path.is_empty(),
                egui::Button::new("Load"),
            )
            .clicked()
        {
            let p = PathBuf::from(app.controls.program_path.trim());
            app.send(Command::Load(p));
        }
    });
    let known = known_programs();
    if !known.is_empty() {
        egui::ComboBox::from_label("examples")
            .selected_text("choose…")
            .show_ui(ui, |ui| {
                for p in known {
                    let name = p.file_name().map(|n| n.to_string_lossy().to_string());
                    if ui
                        .selectable_label(false, name.unwrap_or_default())
                        .clicked()
                    {
                        app.controls.program_path = p.display().to_string();
                        app.send(Command::Load(p));
                    }
                }
            });
    }
    let state = app.live.latest.as_ref().map(|t| t.state);
    let running = matches!(state, Some(MachineState::Run { .. }));
    let held = matches!(state, Some(MachineState::Run { held: true }));
    ui.horizontal(|ui| {
        let loaded = app.program.is_some();
        if ui
            .add_enabled(idle && loaded, egui::Button::new("Run"))
            .on_hover_text("homes and arms first when needed, then runs the loaded program")
            .clicked()
        {
            if let Some(p) = &app.program {
                let path = p.path.clone();
                app.controls.run_started = Some(Instant::now());
                app.send(Command::Run(path));
            }
        }
        let op = app.session.as_ref().map(|s| s.operator.clone());
        if ui
            .add_enabled(running && !held, egui::Button::new("Hold"))
            .on_hover_text("feed hold: decelerates on the path")
            .clicked()
        {
            if let Some(o) = &op {
                o.hold();
            }
        }
        if ui.add_enabled(held, egui::Button::new("Resume")).clicked() {
            if let Some(o) = &op {
                o.resume();
            }
        }
        if ui
            .add_enabled(running, egui::Button::new("Abort"))
            .on_hover_text("stops on the path; the rest of the program is dropped")
            .clicked()
        {
            if let Some(o) = &op {
                o.stop();
            }
        }
    });
    if let Some(p) = &app.program {
        ui.label(format!(
            "{}: {} lines, {} moves",
            p.path
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().to_string()),
            p.lines,
            p.moves.len()
        ));
        let b = p.bounds_mm;
        ui.label(
            RichText::new(format!(
                "X {:.1}…{:.1}  Y {:.1}…{:.1}  Z {:.1}…{:.1} mm",
                b[0][0], b[0][1], b[1][0], b[1][1], b[2][0], b[2][1]
            ))
            .small(),
        );
        if let Some(frac) = progress(app) {
            let eta = app.controls.run_started.filter(|_| running).and_then(|t0| {
                let e = t0.elapsed().as_secs_f64();
                (frac > 0.01).then(|| e * (1.0 - frac) / frac)
            });
            let line = app
                .live
                .latest
                .as_ref()
                .and_then(|t| p.moves.get(t.tag as usize))
                .map_or(0, |m| m.line);
            let text = match eta {
                Some(s) => format!("line {line}, {:.0} %, {s:.0} s left", 100.0 * frac),
                None => format!("line {line}, {:.0} %", 100.0 * frac),
            };
            ui.add(egui::ProgressBar::new(frac as f32).text(text));
        }
    }
    if let Some(r) = &app.report {
        ui.label(
            RichText::new(format!(
                "last run: {} in {:.2} s, contour max {:.4} mm, rms {:.4} mm",
                r.status, r.duration_s, r.contour_max_mm, r.contour_rms_mm
            ))
            .small(),
        );
    }
}

/// How far the running (or last) program is, 0-1, by path length up to the executor's
/// segment (its tag is the index of the first move it covers).
pub fn progress(app: &GantryApp) -> Option<f64> {
    let p = app.program.as_ref()?;
    let t = app.live.latest.as_ref()?;
    let total: f64 = p.moves.iter().map(|m| m.length_mm()).sum();
    if total <= 0.0 {
        return None;
    }
    let done: f64 = p
        .moves
        .iter()
        .take(t.tag as usize)
        .map(|m| m.length_mm())
        .sum();
    let ended = app
        .live
        .status
        .as_ref()
        .is_some_and(|s| s.program_done && !matches!(t.state, MachineState::Run { .. }));
    Some(if ended {
        1.0
    } else {
        (done / total).clamp(0.0, 1.0)
    })
}
