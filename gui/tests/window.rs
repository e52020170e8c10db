//! The real window under X (CI runs it under Xvfb with Mesa's software OpenGL): the
//! `gantry-gui` program, on the simulated gantry served in real time, loads square.nc,
//! homes, runs it to its end and writes a screenshot of itself. The screenshot is not
//! empty, and its stable regions (the jog pad and the tab bar, which no machine state
//! changes at the end of a run) match the references in tests/reference/ pixel for
//! pixel within a small mean difference (font rasterisation). Ignored without a display:
//! `xvfb-run -a cargo test -p gantry-gui --test window -- --ignored`.
//! `GANTRY_GUI_SHOT=FILE` keeps the screenshot; `GANTRY_GUI_WRITE_REFERENCE=1` writes the
//! references anew from this run (after a deliberate change of those regions).

use image::{GenericImageView, RgbaImage};
use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

/// The regions compared: name, x, y, width, height (pixels of the 1400x900 window).
const STABLE: [(&str, u32, u32, u32, u32); 2] =
    [("jog_pad", 0, 62, 282, 174), ("tabs", 292, 66, 408, 30)];
/// Largest mean absolute difference per channel accepted in a stable region (0-255).
const MEAN_DIFF_MAX: f64 = 3.0;

fn reference(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/reference")
        .join(format!("{name}.png"))
}

fn mean_abs_diff(a: &RgbaImage, b: &RgbaImage) -> f64 {
    let total: u64 = a
        .pixels()
        .zip(b.pixels())
        .map(|(p, q)| {
            (0..3)
                .map(|i| u64::from(p.0[i].abs_diff(q.0[i])))
                .sum::<u64>()
        })
        .sum();
    total as f64 / (3.0 * f64::from(a.width() * a.height()))
}

#[test]
#[ignore = "needs a display: xvfb-run -a cargo test -p gantry-gui --test window -- --ignored"]
fn the_window_runs_a_program_and_shows_it() {
    let shot = std::env::var_os("GANTRY_GUI_SHOT")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            std::env::temp_dir().join(format!("gantry-gui-{}.png", std::process::id()))
        });
    let program = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/programs/square.nc");
    let mut child = Command::new(env!("CARGO_BIN_EXE_gantry-gui"))
        .args(["--sim", "--program"])
        .arg(&program)
        .args(["--run", "--size", "1400x900", "--screenshot"])
        .arg(&shot)
        .spawn()
        .expect("start gantry-gui");
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("gantry-gui's status") {
            break s;
        }
        if t0.elapsed() > Duration::from_secs(240) {
            let _ = child.kill();
            panic!("gantry-gui did not finish within 240 s");
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(
        status.success(),
        "gantry-gui: {status} (the run did not complete?)"
    );

    let img = image::open(&shot).expect("the screenshot").to_rgba8();
    assert_eq!((img.width(), img.height()), (1400, 900));
    // not empty: a window full of text, buttons and a path has many colours
    let mut colours: Vec<[u8; 4]> = img.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 200,
        "{} colours in the screenshot",
        colours.len()
    );
    // the tool path drawn: the central area is not one colour
    let centre = img.view(400, 150, 900, 600).to_image();
    let mut c: Vec<[u8; 4]> = centre.pixels().map(|p| p.0).collect();
    c.sort_unstable();
    c.dedup();
    assert!(c.len() > 20, "{} colours in the tool path's area", c.len());

    let write = std::env::var_os("GANTRY_GUI_WRITE_REFERENCE").is_some();
    for (name, x, y, w, h) in STABLE {
        let got = img.view(x, y, w, h).to_image();
        if write {
            got.save(reference(name)).expect("write the reference");
            continue;
        }
        let want = image::open(reference(name))
            .unwrap_or_else(|e| panic!("reference {name}: {e}"))
            .to_rgba8();
        assert_eq!(got.dimensions(), want.dimensions(), "{name}");
        let d = mean_abs_diff(&got, &want);
        assert!(
            d <= MEAN_DIFF_MAX,
            "{name}: mean difference {d:.2} per channel (max {MEAN_DIFF_MAX})"
        );
    }
}
