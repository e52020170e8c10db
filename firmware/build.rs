//! Build script of the firmware.
//!
//! * Copies the workspace's `memory.x` into `OUT_DIR` and puts it on the linker search
//!   path (cortex-m-rt's `link.x`, passed by `.cargo/config.toml`, includes it).
//! * Adds `-Tdefmt.x` for the firmware binary only (`rustc-link-arg-bins`), so other
//!   thumb binaries in the workspace do not need defmt.
//! * Turns host-sim's figures for the QEMU scenario (`qemu/host-sim-reference.json`,
//!   written by `host-sim run qemu/helix-scenario.toml --json ...`) into Rust constants
//!   (`OUT_DIR/host_sim_reference.rs`, included by `src/scenario.rs`): the QEMU run's
//!   verdict compares against exactly what host-sim computed.
//!
//! Host builds (unit tests of the library) get the reference constants but no link setup.

use std::{env, fs, path::PathBuf};

fn main() {
    let manifest_dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=GANTRY_CONTROL_HZ");

    host_sim_reference(&manifest_dir, &out);

    if !env::var("TARGET").unwrap_or_default().starts_with("thumb") {
        return;
    }
    let memory_x = manifest_dir.join("..").join("memory.x");
    println!("cargo:rerun-if-changed={}", memory_x.display());
    fs::copy(&memory_x, out.join("memory.x")).expect("copy memory.x into OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}

fn host_sim_reference(manifest_dir: &std::path::Path, out: &std::path::Path) {
    let path = manifest_dir.join("qemu").join("host-sim-reference.json");
    println!("cargo:rerun-if-changed={}", path.display());
    let text = fs::read_to_string(&path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
    let json: serde_json::Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("parse {}: {e}", path.display()));
    let num = |v: &serde_json::Value, what: &str| -> f64 {
        v.as_f64()
            .unwrap_or_else(|| panic!("{}: `{what}` is not a number", path.display()))
    };
    let triple = |key: &str| -> [f64; 3] {
        let a = json[key]
            .as_array()
            .filter(|a| a.len() == 3)
            .unwrap_or_else(|| panic!("{}: `{key}` must be an array of 3", path.display()));
        [num(&a[0], key), num(&a[1], key), num(&a[2], key)]
    };
    let name = json["name"].as_str().unwrap_or("?").to_owned();
    let itse = triple("itse");
    let max_abs = triple("max_abs_error");
    let contour_max = num(&json["contour_max"], "contour_max");
    let contour_rms = num(&json["contour_rms"], "contour_rms");
    let code = format!(
        "/// host-sim's figures for scenario `{name}` (from qemu/host-sim-reference.json).\n\
         pub const HOST_SIM: Reference = Reference {{\n    \
         itse: [{:e}, {:e}, {:e}],\n    \
         tracking_max: [{:e}, {:e}, {:e}],\n    \
         contour_max: {contour_max:e},\n    \
         contour_rms: {contour_rms:e},\n}};\n",
        itse[0], itse[1], itse[2], max_abs[0], max_abs[1], max_abs[2],
    );
    fs::write(out.join("host_sim_reference.rs"), code).expect("write host_sim_reference.rs");
}
