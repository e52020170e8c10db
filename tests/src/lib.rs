//! Helpers shared by the cross-crate tests: built-in scenario runs by name, with
//! overrides, and scenarios written inline in a test (they may include the built-in
//! machine files as `../machines/*.toml`).

use gantry_scenario::file::{load_str, EmbeddedIncludes};
use gantry_scenario::Resolved;
use host_sim::builtin;
use host_sim::builtin::resolve_all;
use host_sim::engine::discrete::{self, Observer};
use host_sim::engine::{simulate, RunResult};

/// Resolve run `run` of built-in file `file` with `overrides` (TOML merged over the base
/// scenario).
pub fn resolve_builtin(file: &str, run: &str, overrides: &str) -> Resolved {
    let f = builtin::load_with(file, overrides).expect("built-in file loads");
    let runs = resolve_all(&f).expect("runs resolve");
    runs.into_iter()
        .find(|r| r.name == run)
        .unwrap_or_else(|| panic!("{file} has no run {run}"))
}

/// Resolve and simulate run `run` of built-in file `file` with `overrides`.
pub fn run_builtin(file: &str, run: &str, overrides: &str) -> RunResult {
    simulate(&resolve_builtin(file, run, overrides)).expect("run simulates")
}

/// The single run of an inline scenario text.
pub fn resolve_text(text: &str) -> Resolved {
    let f = load_str(
        "inline test scenario",
        text,
        &EmbeddedIncludes(builtin::FILES),
    )
    .expect("inline scenario loads");
    let mut runs = resolve_all(&f).expect("inline scenario resolves");
    assert_eq!(runs.len(), 1, "one run expected");
    runs.remove(0)
}

/// Simulate a resolved discrete f32 run, watched by `obs` every period.
pub fn run_observed(r: &Resolved, obs: &mut impl Observer<f32>) -> RunResult {
    discrete::run::<f32>(r, obs).expect("run simulates")
}
