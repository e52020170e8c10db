//! Puts this crate's `memory.x` on the linker path for the thumb build (cortex-m-rt's
//! `link.x`, passed by the workspace's `.cargo/config.toml`, includes it) and keeps the
//! exported kernels from being garbage-collected by the linker.

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR is set by cargo"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x into OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    // Keep every exported `insns_*` function: nothing in the binary calls them (the
    // emulator does), so section GC would drop them.
    println!("cargo:rustc-link-arg-bins=--no-gc-sections");
}
