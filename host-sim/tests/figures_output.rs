//! What the quick start (`cargo sim`, the paper study with its defaults) writes: the
//! figures only, under 10 MB; the CSV traces (about 100 MB) only with `--traces`.

use std::path::{Path, PathBuf};

use crate::common;
use common::host_sim;

fn scratch(name: &str) -> PathBuf {
    common::scratch("host-sim-figs", name)
}

/// (files, bytes) in `dir` whose name ends with `ext`, and all bytes.
fn sizes(dir: &Path, ext: &str) -> (usize, u64, u64) {
    let (mut n, mut bytes, mut all) = (0, 0, 0);
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let len = e.metadata().unwrap().len();
        all += len;
        if e.file_name().to_string_lossy().ends_with(ext) {
            n += 1;
            bytes += len;
        }
    }
    (n, bytes, all)
}

#[test]
fn the_quick_start_writes_its_figures_in_under_10_mb() {
    let d = scratch("quick");
    let out = d.join("paper");
    // the quick start's defaults but the folder (out/paper there)
    let o = host_sim(&["--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (csv, _, all) = sizes(&out, ".csv");
    let (png, _, _) = sizes(&out, ".png");
    let (svg, _, _) = sizes(&out, ".svg");
    assert_eq!(csv, 0, "no CSV traces without --traces");
    assert_eq!((png, svg), (7, 7), "the paper's 7 figures as PNG and SVG");
    assert!(all < 10_000_000, "{all} bytes");
    assert!(String::from_utf8_lossy(&o.stdout).contains("--traces"));
    let _ = std::fs::remove_dir_all(&d);
}

/// The built-in paper study cut to 0.5 s (its runs and figures, small traces).
fn short_paper(dir: &Path) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("scenarios/paper.toml"))
        .unwrap()
        .replace("horizon_s = 15.0", "horizon_s = 0.5")
        .replace(
            "\"../machines/paper_axis.toml\"",
            &format!("\"{}\"", root.join("machines/paper_axis.toml").display()),
        );
    let p = dir.join("paper_short.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn traces_writes_one_csv_per_run() {
    let d = scratch("traces");
    let f = short_paper(&d);
    let f = f.to_str().unwrap();
    let without = d.join("without");
    let o = host_sim(&["--scenario", f, "--out", without.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(sizes(&without, ".csv").0, 0);
    assert_eq!(sizes(&without, ".png").0, 7);
    let with = d.join("with");
    let o = host_sim(&[
        "paper",
        "--scenario",
        f,
        "--out",
        with.to_str().unwrap(),
        "--traces",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // every run of the study: Table 1 (2 references x 3 laws x nominal/disturbed), Table 3
    // (4 laws x nominal/disturbed) and Table 3 as the firmware runs it (4 laws x f32/fixed)
    assert_eq!(sizes(&with, ".csv").0, 28);
    assert_eq!(sizes(&with, ".png").0, 7);
    let csv = std::fs::read_to_string(with.join("t3_PID_nominal.csv")).unwrap();
    assert!(
        csv.starts_with("t_s,ref_x,ref_y,ref_z,pos_x"),
        "{}",
        &csv[..40]
    );
    // --traces without figures is a contradiction, refused
    let o = host_sim(&["--scenario", f, "--no-plots", "--traces"]);
    assert!(!o.status.success());
    let _ = std::fs::remove_dir_all(&d);
}
