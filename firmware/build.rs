//! Build script of the firmware.
//!
//! * Copies `firmware/memory.x` into `OUT_DIR` and puts it on the linker search
//!   path (cortex-m-rt's `link.x`, passed by `.cargo/config.toml`, includes it); for the
//!   QEMU build with the CCM RAM region moved into the emulator's larger SRAM.
//! * Writes `OUT_DIR/board_expect.rs` from `firmware/twin/expect.toml` (the board's
//!   register configuration after init, which the board twin checks too): one
//!   `(address, shift, width, value, what)` entry per field, read back by the firmware's
//!   boot self-check (`board::self_check`).
//! * Adds `-Tdefmt.x` for the firmware binary only (`rustc-link-arg-bins`), so other
//!   thumb binaries in the workspace do not need defmt.
//! * With the `qemu` feature: the QEMU rig's scenario table. Every
//!   `host-sim/scenarios/qemu/*.toml` is loaded and resolved with gantry-scenario (the
//!   very code host-sim runs them with) into the core's `RunConfig`, serialised with
//!   postcard, and written to `OUT_DIR/qemu_scenarios.rs` as
//!   `pub static SCENARIOS: &[(&str, &[u8])]` (name = file stem, sorted). The firmware
//!   decodes the one named on its semihosting command line at boot. There is no second
//!   copy of any scenario to keep in step. `LINK_RUN`: the link rig's machine,
//!   `host-sim/scenarios/gcode.toml` resolved the same way. `GANTRY_CONTROL_HZ` sets every scenario's
//!   rate, except a `…_<N>khz` file's (`gantry_scenario::file::load_at_rate`, which
//!   `host-sim qemu-verdict --rate-hz` uses too).

use std::{env, fs, path::PathBuf};

fn main() {
    let manifest_dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=GANTRY_CONTROL_HZ");

    #[cfg(feature = "qemu")]
    qemu::scenario_table(&manifest_dir, &out);

    if !env::var("TARGET").unwrap_or_default().starts_with("thumb") {
        return;
    }
    let memory_x = manifest_dir.join("memory.x");
    println!("cargo:rerun-if-changed={}", memory_x.display());
    let layout = fs::read_to_string(&memory_x).expect("read memory.x");
    // QEMU's STM32F405 has no CCM RAM but 192 KiB of SRAM: the 64 KiB above the board's
    // 128 KiB stand in for it (same size, same use)
    #[cfg(feature = "qemu")]
    let layout = layout.replace(
        "CCMRAM : ORIGIN = 0x10000000",
        "CCMRAM : ORIGIN = 0x20020000",
    );
    // and its rig's statics (the simulated run, the scenario's state) need 85 KiB above
    // the stack: 40 KiB of stack there, against the board's 44 (memory.x)
    #[cfg(feature = "qemu")]
    let layout = layout
        .replace(
            "STACK : ORIGIN = 0x20000000, LENGTH = 44K",
            "STACK : ORIGIN = 0x20000000, LENGTH = 40K",
        )
        .replace(
            "RAM   : ORIGIN = 0x2000B000, LENGTH = 84K",
            "RAM   : ORIGIN = 0x2000A000, LENGTH = 88K",
        );
    fs::write(out.join("memory.x"), layout).expect("write memory.x into OUT_DIR");
    board_expect::table(&manifest_dir, &out);
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}

mod board_expect {
    //! The register table of `firmware/twin/expect.toml` as register fields (RM0090's
    //! addresses), for the firmware's boot self-check.
    use std::fmt::Write as _;
    use std::{fs, path::Path};

    fn fail(msg: String) -> ! {
        panic!("firmware/twin/expect.toml: {msg}");
    }

    /// RM0090 table 1 (the STM32F407's peripheral base addresses) and the Cortex-M4 SCB.
    fn base(periph: &str) -> Option<u32> {
        Some(match periph {
            "RCC" => 0x4002_3800,
            "FLASH" => 0x4002_3C00,
            "TIM1" => 0x4001_0000,
            "TIM2" => 0x4000_0000,
            "TIM3" => 0x4000_0400,
            "TIM4" => 0x4000_0800,
            "TIM5" => 0x4000_0C00,
            "USART2" => 0x4000_4400,
            "IWDG" => 0x4000_3000,
            "SYSCFG" => 0x4001_3800,
            "EXTI" => 0x4001_3C00,
            "SCB" => 0xE000_ED00,
            _ => return None,
        })
    }

    /// Register offsets (RM0090 6.3, 3.9, 17.4, 18.4, 30.6, 21.4, 9.2, 12.3; PM0214 4.4),
    /// and the field a name stands for when it is not a register (`BOR_LEV`: OPTCR bits
    /// 2-3).
    fn offset(periph: &str, reg: &str) -> Option<(u32, u8, u8)> {
        let whole = |o| Some((o, 0, 32));
        match (periph, reg) {
            ("RCC", "PLLCFGR") => whole(0x04),
            ("FLASH", "ACR") => whole(0x00),
            ("FLASH", "BOR_LEV") => Some((0x14, 2, 2)),
            (p, r) if p.starts_with("TIM") => whole(match r {
                "CR1" => 0x00,
                "SMCR" => 0x08,
                "DIER" => 0x0C,
                "CCMR1" => 0x18,
                "CCMR2" => 0x1C,
                "CCER" => 0x20,
                "PSC" => 0x28,
                "ARR" => 0x2C,
                "BDTR" => 0x44,
                _ => return None,
            }),
            ("USART2", "BRR") => whole(0x08),
            ("IWDG", "PR") => whole(0x04),
            ("IWDG", "RLR") => whole(0x08),
            ("SCB", "SHPR3") => whole(0x20),
            ("SYSCFG", "EXTICR1") => whole(0x08),
            ("EXTI", "IMR") => whole(0x00),
            ("EXTI", "RTSR") => whole(0x08),
            ("EXTI", "FTSR") => whole(0x0C),
            _ => None,
        }
    }

    fn int(v: &toml::Value, what: &str) -> u32 {
        v.as_integer()
            .and_then(|i| u32::try_from(i).ok())
            .unwrap_or_else(|| fail(format!("{what}: not a 32-bit unsigned number")))
    }

    fn text<'a>(e: &'a toml::Value, key: &str, at: &str) -> &'a str {
        e.get(key)
            .and_then(|v| v.as_str())
            .unwrap_or_else(|| fail(format!("{at}: no `{key}`")))
    }

    pub fn table(manifest_dir: &Path, out: &Path) {
        let path = manifest_dir.join("twin/expect.toml");
        println!("cargo:rerun-if-changed={}", path.display());
        let raw = fs::read_to_string(&path).unwrap_or_else(|e| fail(format!("{e}")));
        let t: toml::Table = raw.parse().unwrap_or_else(|e| fail(format!("{e}")));
        let rate_hz: u32 = std::env::var("GANTRY_CONTROL_HZ")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(10_000);
        let mut rows = Vec::new();
        for (i, e) in t
            .get("register")
            .and_then(|v| v.as_array())
            .into_iter()
            .flatten()
            .enumerate()
        {
            let at = format!("register entry {}", i + 1);
            if e.get("defect").is_some() {
                continue; // a known defect: the board shows it; nothing to check
            }
            let periph = text(e, "periph", &at);
            let reg = text(e, "reg", &at);
            let what = text(e, "what", &at);
            let (addr, mut shift, mut width) = if periph == "NVIC_IPR" {
                let n: u32 = reg.parse().unwrap_or_else(|_| {
                    fail(format!("{at}: NVIC_IPR `{reg}` is not an interrupt number"))
                });
                (0xE000_E400 + (n & !3), (8 * (n % 4)) as u8, 8)
            } else {
                let b = base(periph).unwrap_or_else(|| {
                    fail(format!("{at}: peripheral `{periph}` has no address here"))
                });
                let (o, sh, w) = offset(periph, reg).unwrap_or_else(|| {
                    fail(format!(
                        "{at}: register `{periph}.{reg}` has no offset here"
                    ))
                });
                (b + o, sh, w)
            };
            if let Some(f) = e.get("field") {
                let f = f
                    .as_str()
                    .unwrap_or_else(|| fail(format!("{at}: `field` is not a string")));
                let parts: Vec<&str> = f.split(':').collect();
                match parts.as_slice() {
                    ["bits", lo, w] => {
                        shift += lo
                            .parse::<u8>()
                            .unwrap_or_else(|_| fail(format!("{at}: field `{f}`")));
                        width = w
                            .parse::<u8>()
                            .unwrap_or_else(|_| fail(format!("{at}: field `{f}`")));
                    }
                    _ => fail(format!("{at}: field `{f}` is not `bits:LO:WIDTH`")),
                }
            }
            // `tick_clock_hz`: a control-rate timer's ARR, from the build's rate
            let value = match (e.get("value"), e.get("tick_clock_hz")) {
                (Some(v), None) => int(v, &at),
                (None, Some(c)) => (int(c, &at) / rate_hz.max(1)).saturating_sub(1),
                _ => fail(format!("{at}: want one of `value` and `tick_clock_hz`")),
            };
            rows.push((addr, shift, width, value, format!("{periph}.{reg}: {what}")));
        }
        for (i, p) in t
            .get("pin")
            .and_then(|v| v.as_array())
            .into_iter()
            .flatten()
            .enumerate()
        {
            let at = format!("pin entry {}", i + 1);
            let pin = text(p, "pin", &at);
            let what = text(p, "what", &at);
            let port = pin
                .as_bytes()
                .get(1)
                .copied()
                .filter(|c| (b'A'..=b'E').contains(c));
            let n: Option<u32> = pin
                .get(2..)
                .and_then(|n| n.parse().ok())
                .filter(|n| *n < 16);
            let (Some(port), Some(n)) = (port, n) else {
                fail(format!("{at}: `{pin}` is not a pin PA0..PE15"))
            };
            let gpio = 0x4002_0000 + 0x400 * u32::from(port - b'A');
            for (key, off, shift, width) in [
                ("mode", 0x00, 2 * n, 2),
                ("otype", 0x04, n, 1),
                ("pull", 0x0C, 2 * n, 2),
                ("af", if n < 8 { 0x20 } else { 0x24 }, 4 * (n % 8), 4),
            ] {
                if let Some(v) = p.get(key) {
                    rows.push((
                        gpio + off,
                        shift as u8,
                        width,
                        int(v, &at),
                        format!("{pin} {key}: {what}"),
                    ));
                }
            }
        }
        let mut src = String::from(
            "// @generated by firmware/build.rs from firmware/twin/expect.toml\n\
             pub static BOARD_EXPECT: &[Expect] = &[\n",
        );
        for (addr, shift, width, value, what) in rows {
            writeln!(
                src,
                "    Expect {{ addr: 0x{addr:08x}, shift: {shift}, width: {width}, value: 0x{value:x}, what: {what:?} }},"
            )
            .expect("write to a String");
        }
        src.push_str("];\n");
        fs::write(out.join("board_expect.rs"), src).expect("write board_expect.rs");
    }
}

#[cfg(feature = "qemu")]
mod qemu {
    use gantry_scenario::{Mode, Numeric, Resolved};
    use std::fmt::Write as _;
    use std::{fs, path::Path};

    /// A build failure with a message naming the file and what is wrong.
    fn fail(msg: String) -> ! {
        panic!("{msg}");
    }

    fn stem(path: &Path) -> String {
        path.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    }

    /// Writes `OUT_DIR/qemu_scenarios.rs`.
    pub fn scenario_table(manifest_dir: &Path, out: &Path) {
        // the build's control rate applies to the scenarios too (plant step, servo,
        // figures), except those whose name states their own (`…_20khz`)
        let rate_hz = std::env::var("GANTRY_CONTROL_HZ").ok().map(|v| {
            v.trim()
                .parse::<u32>()
                .unwrap_or_else(|_| fail(format!("GANTRY_CONTROL_HZ={v}: not a number")))
        });
        let dir = manifest_dir.join("../host-sim/scenarios/qemu");
        // The directory (new files) and every machine description the files include.
        println!("cargo:rerun-if-changed={}", dir.display());
        println!(
            "cargo:rerun-if-changed={}",
            manifest_dir.join("../host-sim/machines").display()
        );
        let mut files: Vec<_> = fs::read_dir(&dir)
            .unwrap_or_else(|e| fail(format!("read {}: {e}", dir.display())))
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        if files.is_empty() {
            fail(format!("no QEMU scenario files in {}", dir.display()));
        }
        let mut code = String::from(
            "/// The QEMU scenarios: (name = file stem, postcard bytes of the resolved\n\
             /// `controller_core::sim::run::RunConfig`), sorted by name. Generated by\n\
             /// firmware/build.rs from host-sim/scenarios/qemu/*.toml.\n\
             pub static SCENARIOS: &[(&str, &[u8])] = &[\n",
        );
        for path in &files {
            println!("cargo:rerun-if-changed={}", path.display());
            let name = stem(path);
            let file = gantry_scenario::file::load_at_rate(path, rate_hz)
                .unwrap_or_else(|e| fail(e.to_string()));
            let runs: Vec<&str> = file.runs.iter().map(|r| r.name.as_str()).collect();
            if runs != [name.as_str()] {
                fail(format!(
                    "{}: a QEMU scenario file holds exactly one run named like the file \
                     (`{name}`); it has {runs:?}",
                    path.display()
                ));
            }
            let resolved =
                Resolved::new(&file.file, &file.runs[0]).unwrap_or_else(|e| fail(e.to_string()));
            if resolved.mode != Mode::Discrete || resolved.numeric != Numeric::F32 {
                fail(format!(
                    "{}: the firmware runs the servo step in f32 at its control rate: \
                     QEMU scenarios need mode = \"discrete\" and numeric = \"f32\"",
                    path.display()
                ));
            }
            let bytes = postcard::to_allocvec(&resolved.run)
                .unwrap_or_else(|e| fail(format!("{}: postcard: {e}", path.display())));
            let _ = writeln!(code, "    ({name:?}, &{bytes:?}),");
        }
        code.push_str("];\n");
        // The link rig's machine: the simulated gantry of `gantry --sim` and `cargo sim
        // gcode` (host-sim/scenarios/gcode.toml), at its own rate.
        let gcode = manifest_dir.join("../host-sim/scenarios/gcode.toml");
        println!("cargo:rerun-if-changed={}", gcode.display());
        let file = gantry_scenario::file::load_at_rate(&gcode, None)
            .unwrap_or_else(|e| fail(e.to_string()));
        let first = file
            .runs
            .first()
            .unwrap_or_else(|| fail(format!("{}: no run", gcode.display())));
        let resolved = Resolved::new(&file.file, first).unwrap_or_else(|e| fail(e.to_string()));
        let bytes = postcard::to_allocvec(&resolved.run)
            .unwrap_or_else(|e| fail(format!("{}: postcard: {e}", gcode.display())));
        let _ = writeln!(
            code,
            "/// The link rig's machine (host-sim/scenarios/gcode.toml, postcard `RunConfig`).\n\
             pub static LINK_RUN: &[u8] = &{bytes:?};"
        );
        fs::write(out.join("qemu_scenarios.rs"), code).expect("write qemu_scenarios.rs");
    }
}
