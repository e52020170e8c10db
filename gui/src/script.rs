//! What the window does by itself when started with `--program`, `--run`,
//! `--screenshot` or `--after-s`: load, run (homing first), then write a screenshot of
//! the window as it is and close. CI drives the real window under Xvfb this way, and the
//! screenshots in docs/ are made with it.

use crate::app::GantryApp;
use crate::session::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// The script's progress.
#[derive(Debug)]
pub struct ScriptState {
    started: Instant,
    run_sent: bool,
    /// The screenshot was asked for.
    shot_asked: bool,
    /// The screenshot was written (or failed).
    shot_done: Arc<AtomicBool>,
}

impl Default for ScriptState {
    fn default() -> Self {
        Self {
            started: Instant::now(),
            run_sent: false,
            shot_asked: false,
            shot_done: Arc::new(AtomicBool::new(false)),
        }
    }
}

/// One frame's step of the script.
pub fn step(app: &mut GantryApp, ctx: &egui::Context) {
    if app.script.run && !app.script_state.run_sent && app.busy.is_none() {
        if let (true, Some(p)) = (app.connected, &app.program) {
            let path = p.path.clone();
            app.script_state.run_sent = true;
            app.send(Command::Run(path));
        }
    }
    let run_over = app.script.run && app.script_state.run_sent && app.runs_ended > 0;
    let due = if app.script.run {
        run_over
    } else {
        app.script
            .after_s
            .is_some_and(|s| app.script_state.started.elapsed().as_secs_f64() >= s)
    };
    let failed = app.lost.is_some() && (app.script.run || app.script.screenshot.is_some());
    if (due || failed) && !app.script_state.shot_asked {
        if app.script.run && app.report.as_ref().is_none_or(|r| r.status != "completed") {
            app.script.exit_code.store(1, Ordering::SeqCst);
        }
        if failed {
            app.script.exit_code.store(1, Ordering::SeqCst);
        }
        app.script_state.shot_asked = true;
        match app.script.screenshot.clone() {
            Some(path) => {
                let done = app.script_state.shot_done.clone();
                let code = app.script.exit_code.clone();
                let wake = ctx.clone();
                ctx.request_screenshot(move |image| {
                    if let Err(e) = save_png(&path, &image) {
                        eprintln!("gantry-gui: {e:#}");
                        code.store(1, Ordering::SeqCst);
                    } else {
                        eprintln!("gantry-gui: screenshot {}", path.display());
                    }
                    done.store(true, Ordering::SeqCst);
                    wake.request_repaint();
                });
                ctx.request_repaint();
            }
            None => app.script_state.shot_done.store(true, Ordering::SeqCst),
        }
    }
    if app.script_state.shot_asked && app.script_state.shot_done.load(Ordering::SeqCst) {
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }
    if app.script.run || app.script.after_s.is_some() {
        ctx.request_repaint_after(std::time::Duration::from_millis(50));
    }
}

/// Write `image` as a PNG.
pub fn save_png(path: &std::path::Path, image: &egui::ColorImage) -> anyhow::Result<()> {
    use anyhow::Context;
    let [w, h] = image.size;
    let rgba: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    let img = image::RgbaImage::from_raw(w as u32, h as u32, rgba)
        .context("the screenshot's pixels do not fill its size")?;
    img.save(path)
        .with_context(|| format!("cannot write the screenshot {}", path.display()))
}
