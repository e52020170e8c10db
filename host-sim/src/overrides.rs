//! `--set KEY=VALUE`: settings overrides of one run (`cargo sim gcode FILE --set
//! planner.servo_reserve=0`), applied to a settings tree key by key with controller-core's
//! [`Settings::set`] (through [`Settings::set_text`]): each value is checked against its
//! key's type and range and the whole tree against the servo configuration, exactly as
//! `gantry settings set` on a machine. The first bad assignment is an error naming it, and
//! nothing is applied.
//!
//! A run only takes some of the keys: [`used_by_gcode_run`] says which for `cargo sim
//! gcode` (its laws, estimator and machine come from the scenario and machine files, not
//! from settings; the feed-forward and the output filters do come from the settings). A key it would silently ignore is an error too, so that a benchmark
//! never reports figures for a setting that did not apply.

use anyhow::{anyhow, bail, Result};
use controller_core::settings::Settings;

/// Key prefixes `cargo sim gcode` takes from the settings: the planner's own
/// (`planner.*`), the input shapers of its reference (`shaper.*`) and the work offsets and
/// tools the program is interpreted in.
const GCODE_RUN_PREFIXES: [&str; 4] = ["planner.", "shaper.", "work.", "tool."];
/// Per-axis keys `cargo sim gcode` takes: `axis.<a>.planner.*`, the planner's limits,
/// `axis.<a>.feedforward.*` and `axis.<a>.filter.*`, the servo's feed-forward and output
/// filters.
const GCODE_RUN_AXIS_INFIXES: [&str; 3] = [".planner.", ".feedforward.", ".filter."];

/// Whether `cargo sim gcode` uses the setting `key`: the planner's (`planner.*`,
/// `axis.<a>.planner.*`), the input shapers (`shaper.*`), the feed-forward and the output
/// filters (`axis.<a>.feedforward.*`, `axis.<a>.filter.*`), the work offsets (`work.*`)
/// and the tool table (`tool.*`).
pub fn used_by_gcode_run(key: &str) -> bool {
    GCODE_RUN_PREFIXES.iter().any(|p| key.starts_with(p))
        || (key.starts_with("axis.") && GCODE_RUN_AXIS_INFIXES.iter().any(|i| key.contains(i)))
}

/// `KEY=VALUE` split at the first `=`, both trimmed and not empty.
pub fn parse_assignment(text: &str) -> Result<(&str, &str)> {
    let (key, value) = text
        .split_once('=')
        .ok_or_else(|| anyhow!("--set `{text}`: expected KEY=VALUE"))?;
    let (key, value) = (key.trim(), value.trim());
    if key.is_empty() || value.is_empty() {
        bail!("--set `{text}`: expected KEY=VALUE");
    }
    Ok((key, value))
}

/// The settings of a `cargo sim gcode` run: `base` with every assignment of `assignments`
/// (`KEY=VALUE`, in order; a later one of the same key wins) set at the machine's control
/// rate `rate_hz`. Errors name the assignment: a malformed one, an unknown key, a value of
/// the wrong type or outside the key's range, a tree the servo configuration refuses, a
/// key the run does not use ([`used_by_gcode_run`]).
pub fn gcode_run_settings(
    base: &Settings,
    assignments: &[String],
    rate_hz: u32,
) -> Result<Settings> {
    let mut s = *base;
    for a in assignments {
        let (key, value) = parse_assignment(a)?;
        s.set_text(key, value, rate_hz)
            .map_err(|e| anyhow!("--set `{a}`: {e}"))?;
        if !used_by_gcode_run(key) {
            bail!(
                "--set `{a}`: {key} is not used by `cargo sim gcode` (it takes planner.*, \
                 axis.<a>.planner.*, axis.<a>.feedforward.*, axis.<a>.filter.*, shaper.*, \
                 work.* and tool.*; the laws and the machine come from the scenario and \
                 machine files)"
            );
        }
    }
    Ok(s)
}
