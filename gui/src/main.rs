//! `gantry-gui` (also `gantry gui`, `cargo gui`): the operator's window on a machine.
//! `--sim` serves the simulated gantry in real time from this process; `--served PTY`,
//! `--qemu`, `--twin PTY` and `--port DEV` as for `gantry`.

use anyhow::{Context, Result};
use clap::Parser;
use gantry_gui::app::{GantryApp, Script, Tab};
use gantry_gui::session::Session;
use host_sim::cli::machine::MachineArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::sync::{Arc, OnceLock};

#[derive(Parser)]
#[command(
    name = "gantry-gui",
    about = "The gantry operator's window: read-out, jog, program and tool path, live plots, scope, settings, identification, tuning",
    version
)]
struct Cli {
    #[command(flatten)]
    machine: MachineArgs,
    /// Load this G-code program at start (its tool path shows at once).
    /// Example: `--program host-sim/programs/square.nc`.
    #[arg(long, value_name = "FILE")]
    program: Option<PathBuf>,
    /// Run the loaded program at start (homing and arming first), as `gantry run` does.
    #[arg(long, requires = "program")]
    run: bool,
    /// Write a PNG of the window, then close: when the program ended (with --run), else
    /// after --after-s seconds. Exit status 1 when the run did not complete.
    #[arg(long, value_name = "FILE")]
    screenshot: Option<PathBuf>,
    /// Seconds after start for the screenshot (or to close), without --run.
    #[arg(long, value_name = "S")]
    after_s: Option<f64>,
    /// The tab shown at start: path (its XY view), path-3d (its 3-D view), plots, scope,
    /// settings, identify or tune.
    #[arg(long, default_value = "path", value_parser = ["path", "path-3d", "plots", "scope", "settings", "identify", "tune"])]
    tab: String,
    /// The window's size in pixels, WxH.
    #[arg(long, default_value = "1400x900", value_name = "WxH")]
    size: String,
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Nice value of the window's threads (this one and those it starts: the renderer's):
/// below the link's and the served machine's, which were started before.
const WINDOW_NICE: libc::c_int = 10;

/// Lower the calling thread's priority (Linux: the nice value is per thread, inherited by
/// the threads it starts); a failure only leaves the priority as it was.
fn lower_this_threads_priority() {
    // SAFETY: setpriority only reads its arguments; `0` names the calling thread.
    let r = unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, WINDOW_NICE) };
    if r != 0 {
        eprintln!("gantry-gui: could not lower the window's priority (the link keeps its own)");
    }
}

fn size(text: &str) -> Result<[f32; 2]> {
    let (w, h) = text
        .split_once('x')
        .with_context(|| format!("--size must be WxH in pixels, got `{text}`"))?;
    let px = |v: &str| -> Result<f32> {
        let n: u32 = v
            .parse()
            .with_context(|| format!("--size: `{v}` is not a number of pixels"))?;
        anyhow::ensure!(
            (200..=8000).contains(&n),
            "--size: {n} px is outside 200-8000"
        );
        Ok(n as f32)
    };
    Ok([px(w)?, px(h)?])
}

fn run(cli: Cli) -> Result<ExitCode> {
    cli.machine.check()?;
    if let Some(s) = cli.after_s {
        anyhow::ensure!(
            (0.0..=86_400.0).contains(&s),
            "--after-s must be within 0-86400 s, got {s}"
        );
    }
    let size = size(&cli.size)?;
    let three_d = cli.tab == "path-3d";
    let tab = match cli.tab.as_str() {
        "plots" => Tab::Plots,
        "scope" => Tab::Scope,
        "settings" => Tab::Settings,
        "identify" => Tab::Identify,
        "tune" => Tab::Tune,
        _ => Tab::Path,
    };
    if let Some(p) = &cli.program {
        anyhow::ensure!(p.is_file(), "--program: no such file {}", p.display());
    }
    // the simulated machine in real time, served from here
    let (_served, machine) = if cli.machine.sim {
        let (s, m) = gantry_gui::served::Served::start(&cli.machine)?;
        (Some(s), m)
    } else {
        (None, cli.machine.clone())
    };
    let code = std::sync::Arc::new(std::sync::atomic::AtomicI32::new(0));
    let script = Script {
        exit_code: code.clone(),
        program: cli.program,
        run: cli.run,
        screenshot: cli.screenshot,
        after_s: cli.after_s,
        tab,
    };
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("gantry")
            .with_inner_size(size),
        ..Default::default()
    };
    // the session first, then the window's own threads at a lower priority: on a loaded
    // computer the link (and the served machine) get the CPU before the drawing does
    let window: Arc<OnceLock<egui::Context>> = Arc::default();
    let wake = window.clone();
    let session = Session::start(machine.clone(), move || {
        if let Some(ctx) = wake.get() {
            ctx.request_repaint();
        }
    });
    lower_this_threads_priority();
    eframe::run_native(
        "gantry",
        options,
        Box::new(move |cc| {
            let _ = window.set(cc.egui_ctx.clone());
            let mut app = GantryApp::with_session(machine, script, session);
            if three_d {
                app.path_view.projection = gantry_gui::panels::path::Projection::ThreeD;
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the window: {e}"))?;
    Ok(ExitCode::from(code.load(Ordering::SeqCst) as u8))
}
