//! `cargo fw-run`'s probe-rs runner (.cargo/config.toml) leaves the firmware's own fault
//! path alone: probe-rs catches HardFault and reset by default (since its PR #3224), which
//! halts the core at the HardFault vector before the handler's outputs-off stores run, and
//! can hold it halted out of a watchdog reset with every pin floating
//! (../shared/spec/board-review.md, defect 1).

fn runner() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../.cargo/config.toml");
    let text = std::fs::read_to_string(path).expect(".cargo/config.toml");
    let config: toml::Table = text.parse().expect(".cargo/config.toml is TOML");
    config["target"]["thumbv7em-none-eabihf"]["runner"]
        .as_str()
        .expect("a runner string for thumbv7em-none-eabihf")
        .to_string()
}

#[test]
fn the_runner_is_probe_rs_for_the_f407_without_hardfault_or_reset_catch() {
    let r = runner();
    let words: Vec<&str> = r.split_whitespace().collect();
    assert_eq!(&words[..2], ["probe-rs", "run"], "runner: {r}");
    let chip = words.iter().position(|w| *w == "--chip").expect("--chip");
    assert_eq!(words.get(chip + 1), Some(&"STM32F407VGTx"), "runner: {r}");
    for flag in ["--no-catch-hardfault", "--no-catch-reset"] {
        assert!(words.contains(&flag), "runner lacks {flag}: {r}");
    }
    // the deprecated spellings turn the catch on
    for flag in ["--catch-hardfault", "--catch-reset"] {
        assert!(!words.contains(&flag), "runner has {flag}: {r}");
    }
}
