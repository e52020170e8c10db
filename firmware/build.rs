//! Linker setup for the firmware binary.
//!
//! * Copies the workspace's `memory.x` into `OUT_DIR` and puts it on the linker search
//!   path (cortex-m-rt's `link.x`, passed by `.cargo/config.toml`, includes it).
//! * Adds `-Tdefmt.x` for the firmware binary only (`rustc-link-arg-bins`), so other
//!   thumb binaries in the workspace do not need defmt.
//!
//! Host builds (unit tests of the library) get neither.

use std::{env, fs, path::PathBuf};

fn main() {
    let manifest_dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let memory_x = manifest_dir.join("..").join("memory.x");
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=GANTRY_CONTROL_HZ");

    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
    fs::copy(&memory_x, out.join("memory.x")).expect("copy memory.x into OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
