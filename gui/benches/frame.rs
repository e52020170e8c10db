//! The window's frame time: the whole UI pass (egui's `Context::run_ui` of
//! `GantryApp::frame`, every panel included) plus tessellation (`Context::tessellate`),
//! with a 10,000-segment program loaded, a 200,000-point trail, the 10 s history full
//! (10,000 samples) and 1 kHz telemetry flowing: 17 new samples taken through
//! `Live::take` before every frame (16.7 ms of machine time at 1 kHz), per tab. Rendering
//! on the GPU is not in it (no window); everything the CPU does for a frame is.
//!
//! `cargo bench -p gantry-gui --bench frame` prints one line per case: median and 99th
//! percentile frame time and the frames/s they allow against the 16.7 ms budget of 60/s.

use controller_core::machine::messages::{MachineState, Telemetry};
use gantry_gui::app::{GantryApp, Script, Tab};
use gantry_gui::live::TRAIL_MAX;
use gantry_gui::panels::path::Projection;
use gantry_gui::session::LoadedProgram;
use host_sim::cli::client::Tapped;
use host_sim::cli::machine::MachineArgs;
use host_sim::gcode::samples::{dense_contour, dense_contour_radius_mm};
use std::f64::consts::TAU;
use std::path::PathBuf;
use std::time::Instant;

/// Telemetry rate, Hz, and the control rate whose periods it counts.
const TELEMETRY_HZ: u32 = 1000;
const CONTROL_HZ: u32 = 10_000;
const FRAME_S: f64 = 1.0 / 60.0;
/// Frames measured per case (after the warm-up).
const FRAMES: usize = 300;
const WARM_UP: usize = 20;
/// Passes and segments per pass of the program: 4 × 2,500 = 10,000 G1 segments.
const PASSES: usize = 4;
const SEGMENTS_PER_PASS: usize = 2500;
/// Machine seconds per pass of the synthetic run (the trail goes round the contour).
const PASS_S: f64 = 50.0;

/// A synthetic but realistic sample `k` (1 kHz) of running the dense contour: the tool
/// on the contour with a few µm of tracking and contour error and some noise.
fn sample(k: u64) -> Telemetry {
    let t = k as f64 / f64::from(TELEMETRY_HZ);
    let pass = ((t / PASS_S) as usize).min(PASSES - 1);
    let theta = TAU * (t / PASS_S).fract();
    let r = dense_contour_radius_mm(theta);
    let z = -(pass as f64 + 1.0);
    let noise = ((k.wrapping_mul(2_654_435_761) % 1000) as f64 / 1000.0 - 0.5) * 0.002;
    let contour = 0.004 + 0.004 * (7.0 * theta).sin() + noise;
    let pos = [r * theta.cos(), r * theta.sin(), z].map(|v| v as f32);
    let w = TAU / PASS_S;
    let vel = [-r * w * theta.sin(), r * w * theta.cos(), 0.0].map(|v| v as f32);
    let mut signals = heapless::Vec::new();
    for v in [0.1 * theta.sin(), 0.1 * theta.cos(), 0.02 + noise] {
        let _ = signals.push(v as f32);
    }
    let seg = (theta / TAU * SEGMENTS_PER_PASS as f64) as u32;
    Telemetry {
        period: (k * u64::from(CONTROL_HZ / TELEMETRY_HZ)) as u32,
        state: MachineState::Run { held: false },
        pos_mm: pos,
        reference_mm: [pos[0] + 0.003, pos[1] - 0.002, pos[2]],
        ref_vel_mm_s: vel,
        ref_acc_mm_s2: [0.0; 3],
        contour_mm: contour as f32,
        feed_ratio: 1.0,
        // (moves: 3 header moves, then per pass its plunge and feed moves)
        tag: 5 + (pass * (SEGMENTS_PER_PASS + 1)) as u32 + seg,
        signals,
    }
}

struct Case {
    name: &'static str,
    tab: Tab,
    projection: Projection,
    /// Turn the 3-D view (or pan the 2-D one) a little every frame, as while dragging:
    /// the cached meshes are rebuilt every frame.
    moving: bool,
}

fn main() {
    // `cargo bench` passes `--bench`; a filter argument picks cases by name
    let filter: Option<String> = std::env::args().skip(1).find(|a| !a.starts_with("--"));
    let text = dense_contour(PASSES, SEGMENTS_PER_PASS);
    let program = match host_sim::gcode::parse_str("dense_contour.nc", &text) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("the benchmark's program does not parse: {e}");
            std::process::exit(1);
        }
    };
    let segments = program.moves.len();
    let loaded = LoadedProgram {
        path: PathBuf::from("dense_contour.nc"),
        moves: program.moves,
        bounds_mm: program.bounds_mm,
        lines: text.lines().count(),
    };
    let cases = [
        Case {
            name: "path 2-D (XY)",
            tab: Tab::Path,
            projection: Projection::XY,
            moving: false,
        },
        Case {
            name: "path 2-D (XY), panning",
            tab: Tab::Path,
            projection: Projection::XY,
            moving: true,
        },
        Case {
            name: "path 3-D",
            tab: Tab::Path,
            projection: Projection::ThreeD,
            moving: false,
        },
        Case {
            name: "path 3-D, turning",
            tab: Tab::Path,
            projection: Projection::ThreeD,
            moving: true,
        },
        Case {
            name: "live plots (10 s)",
            tab: Tab::Plots,
            projection: Projection::XY,
            moving: false,
        },
    ];
    println!(
        "frame benchmark: {segments} program moves, trail up to {TRAIL_MAX} points, \
         {TELEMETRY_HZ} Hz telemetry, 1600x1000 window, {} cores",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    for case in &cases {
        if filter
            .as_ref()
            .is_some_and(|f| !case.name.contains(f.as_str()))
        {
            continue;
        }
        let mut app = GantryApp::detached(MachineArgs::default(), Script::default());
        app.connected = true;
        app.live.rate_hz = CONTROL_HZ;
        app.live.decimation = CONTROL_HZ / TELEMETRY_HZ;
        app.live.signals = gantry_gui::session::DEFAULT_SIGNALS
            .iter()
            .map(|s| s.to_string())
            .collect();
        app.program = Some(loaded.clone());
        app.tab = case.tab;
        app.path_view.projection = case.projection;
        app.plots.window_s = 10.0;
        // the trail just short of its limit after the frames' samples (the live trail
        // halves at TRAIL_MAX)
        let per_frame = (f64::from(TELEMETRY_HZ) * FRAME_S).round() as u64;
        let frames = (WARM_UP + FRAMES) as u64;
        let mut k: u64 = 0;
        let pre = TRAIL_MAX as u64 - 1 - per_frame * frames;
        while k < pre {
            app.live.take(Tapped::Telemetry(sample(k)));
            k += 1;
        }
        let ctx = egui::Context::default();
        let mut times_ms = Vec::with_capacity(FRAMES);
        let mut trail_len = 0;
        let mut prims = 0;
        let mut vertices = 0;
        for f in 0..WARM_UP + FRAMES {
            let start = Instant::now();
            for _ in 0..per_frame {
                app.live.take(Tapped::Telemetry(sample(k)));
                k += 1;
            }
            if case.moving && f > 0 {
                match case.projection {
                    Projection::ThreeD => app.path_view.yaw_rad += 0.01,
                    _ => app.path_view.center_mm[0] += 0.05,
                }
            }
            let input = egui::RawInput {
                screen_rect: Some(egui::Rect::from_min_size(
                    egui::Pos2::ZERO,
                    egui::vec2(1600.0, 1000.0),
                )),
                time: Some(f as f64 * FRAME_S),
                predicted_dt: FRAME_S as f32,
                ..Default::default()
            };
            let out = ctx.run_ui(input, |ui| app.frame(ui));
            let ppp = out.pixels_per_point;
            let p = ctx.tessellate(out.shapes, ppp);
            prims = p.len();
            vertices = p
                .iter()
                .map(|c| match &c.primitive {
                    egui::epaint::Primitive::Mesh(m) => m.vertices.len(),
                    egui::epaint::Primitive::Callback(_) => 0,
                })
                .sum();
            let dt = start.elapsed().as_secs_f64() * 1e3;
            if f >= WARM_UP {
                times_ms.push(dt);
            }
            trail_len = app.live.trail.len();
        }
        times_ms.sort_by(f64::total_cmp);
        let q = |p: f64| times_ms[((times_ms.len() - 1) as f64 * p).round() as usize];
        let (med, p99, max) = (q(0.5), q(0.99), q(1.0));
        let budget = FRAME_S * 1e3;
        println!(
            "{:<26} median {med:6.2} ms  p99 {p99:6.2} ms  max {max:6.2} ms  -> {:5.0} frames/s \
             at the median, {:5.0} at p99 (budget {budget:.1} ms: {}); trail {trail_len} \
             points, history {} samples, {prims} meshes of {vertices} vertices",
            case.name,
            1e3 / med,
            1e3 / p99,
            if p99 <= budget {
                "kept"
            } else {
                "MISSED at p99"
            },
            app.live.history.len(),
        );
    }
}
