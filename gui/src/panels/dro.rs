//! The top bar: the machine's state in words, the digital read-out (position, feed,
//! program line), the latched fault in plain words, and the machine's buttons (arm,
//! disarm, reset, home, stop); and the message log at the bottom.

use crate::app::GantryApp;
use crate::session::Command;
use controller_core::machine::messages::MachineState;
use egui::{Color32, RichText};
use host_sim::cli::view;

/// The state's colour: green moving, blue armed at rest, grey off, red fault.
pub fn state_colour(s: MachineState) -> Color32 {
    match s {
        MachineState::Fault => Color32::from_rgb(220, 50, 47),
        MachineState::Disabled => Color32::GRAY,
        MachineState::Idle => Color32::from_rgb(38, 139, 210),
        MachineState::Stopping => Color32::from_rgb(203, 75, 22),
        _ => Color32::from_rgb(80, 160, 60),
    }
}

/// The state's short name.
pub fn state_name(s: MachineState) -> &'static str {
    match s {
        MachineState::Disabled => "DISARMED",
        MachineState::Idle => "IDLE",
        MachineState::Jog => "JOG",
        MachineState::Homing => "HOMING",
        MachineState::Run { held: false } => "RUN",
        MachineState::Run { held: true } => "HOLD",
        MachineState::Identify => "IDENTIFY",
        MachineState::Stopping => "STOPPING",
        MachineState::EncoderCheck => "ENCODER CHECK",
        MachineState::Fault => "FAULT",
    }
}

pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    ui.add_space(4.0);
    ui.horizontal(|ui| {
        let (state, words) = match (&app.live.status, &app.live.latest) {
            (Some(s), _) => (Some(s.state), view::state_words(s)),
            (None, Some(t)) => (Some(t.state), format!("{:?}", t.state)),
            _ => (None, String::new()),
        };
        match state {
            Some(st) => {
                ui.label(
                    RichText::new(state_name(st))
                        .strong()
                        .size(22.0)
                        .color(state_colour(st)),
                )
                .on_hover_text(words);
            }
            None => {
                let text = match &app.lost {
                    Some(_) => "NO SESSION",
                    None => "CONNECTING…",
                };
                ui.label(RichText::new(text).strong().size(22.0));
            }
        }
        ui.separator();
        let pos = app.live.pos_mm();
        for (i, name) in ["X", "Y", "Z"].iter().enumerate() {
            let homed = app
                .live
                .status
                .as_ref()
                .is_some_and(|s| s.homed & (1 << i) != 0);
            let v = pos.map_or("—".to_string(), |p| format!("{:>9.3}", p[i]));
            ui.label(RichText::new(*name).size(18.0).strong());
            ui.label(RichText::new(v).monospace().size(22.0))
                .on_hover_text(if homed { "homed" } else { "not homed" });
            if !homed {
                ui.label(RichText::new("(not homed)").color(Color32::GOLD))
                    .on_hover_text("not homed");
            }
        }
        ui.label("mm");
        ui.separator();
        if let Some(s) = &app.live.status {
            ui.label(RichText::new(format!("F {:>7.0} mm/min", view::feed_mm_min(s))).monospace());
        }
        if let (Some(t), Some(p)) = (&app.live.latest, &app.program) {
            if matches!(t.state, MachineState::Run { .. }) {
                if let Some(m) = p.moves.get(t.tag as usize) {
                    ui.separator();
                    ui.label(RichText::new(format!("line {}", m.line)).monospace());
                }
            }
        }
    });
    ui.horizontal(|ui| {
        let idle = app.busy.is_none() && app.lost.is_none();
        let state = app.live.status.as_ref().map(|s| s.state);
        if ui
            .add_enabled(
                idle && state == Some(MachineState::Disabled),
                egui::Button::new("Arm"),
            )
            .on_hover_text("outputs on, holding position (nothing moves)")
            .clicked()
        {
            app.send(Command::Arm);
        }
        if ui
            .add_enabled(
                app.lost.is_none()
                    && !matches!(
                        state,
                        Some(MachineState::Disabled) | Some(MachineState::Fault)
                    ),
                egui::Button::new("Disarm"),
            )
            .on_hover_text("outputs off")
            .clicked()
        {
            app.send(Command::Disarm);
        }
        if ui
            .add_enabled(
                idle && state == Some(MachineState::Fault),
                egui::Button::new("Reset"),
            )
            .on_hover_text("clear the latched fault (refused while its cause is present)")
            .clicked()
        {
            app.send(Command::Reset);
        }
        if ui
            .add_enabled(idle && state.is_some(), egui::Button::new("Home"))
            .on_hover_text("arm if needed, then home every axis")
            .clicked()
        {
            app.send(Command::Home);
        }
        let stop = egui::Button::new(RichText::new("STOP").strong().color(Color32::WHITE))
            .fill(Color32::from_rgb(200, 30, 30));
        if ui
            .add_enabled(app.session.is_some(), stop)
            .on_hover_text(
                "controlled stop of whatever moves (program, jog, homing, identification)",
            )
            .clicked()
        {
            if let Some(s) = &app.session {
                s.operator.stop();
            }
            app.say("stop".into());
        }
        ui.separator();
        if let Some(b) = &app.busy {
            ui.spinner();
            ui.label(b);
        }
        if app.lost.is_some() {
            let ctx = ui.ctx().clone();
            if ui.button("Reconnect").clicked() {
                app.reconnect(move || ctx.request_repaint());
            }
        }
    });
    if let Some(s) = &app.live.status {
        if let Some(f) = &s.first_fault {
            ui.label(
                RichText::new(format!("fault: {}", view::fault_words(f)))
                    .color(state_colour(MachineState::Fault))
                    .strong(),
            );
        }
        if s.model_missing != 0 {
            let axes: Vec<&str> = host_sim::cli::AXES
                .iter()
                .enumerate()
                .filter(|(i, _)| s.model_missing & (1 << i) != 0)
                .map(|(_, a)| *a)
                .collect();
            ui.label(
                RichText::new(format!(
                    "no model for axis {}: identify it (Identification tab) before arming",
                    axes.join(", ")
                ))
                .color(Color32::GOLD),
            );
        }
    }
    ui.add_space(2.0);
}

/// The message log (newest last).
pub fn log(app: &mut GantryApp, ui: &mut egui::Ui) {
    egui::ScrollArea::vertical()
        .stick_to_bottom(true)
        .auto_shrink([false, false])
        .show(ui, |ui| {
            for l in &app.log {
                ui.label(RichText::new(l).monospace());
            }
        });
}
