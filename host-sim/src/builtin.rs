//! The built-in scenario and machine files (`host-sim/scenarios/`, `host-sim/machines/`),
//! compiled into the binary so every study runs on a machine without the source tree, and
//! loading of scenario files from disk with the same schema, and resolving a file's runs.

use anyhow::{Context, Result};
use gantry_scenario::file::{load_str_with, EmbeddedIncludes, ScenarioFile};
use gantry_scenario::Resolved;
use std::path::Path;

/// `(path relative to host-sim/scenarios/, contents)` of every built-in file; machine files
/// are named as the scenarios include them (`../machines/...`).
pub const FILES: &[(&str, &str)] = &[
    ("paper.toml", include_str!("../scenarios/paper.toml")),
    (
        "helix_discrete_10khz.toml",
        include_str!("../scenarios/helix_discrete_10khz.toml"),
    ),
    (
        "seeds_contouring.toml",
        include_str!("../scenarios/seeds_contouring.toml"),
    ),
    (
        "seeds_friction.toml",
        include_str!("../scenarios/seeds_friction.toml"),
    ),
    (
        "seeds_helix.toml",
        include_str!("../scenarios/seeds_helix.toml"),
    ),
    (
        "estimators_paper.toml",
        include_str!("../scenarios/estimators_paper.toml"),
    ),
    (
        "estimators_physical.toml",
        include_str!("../scenarios/estimators_physical.toml"),
    ),
    ("faults.toml", include_str!("../scenarios/faults.toml")),
    ("identify.toml", include_str!("../scenarios/identify.toml")),
    ("gcode.toml", include_str!("../scenarios/gcode.toml")),
    ("circle.toml", include_str!("../scenarios/circle.toml")),
    ("freqresp.toml", include_str!("../scenarios/freqresp.toml")),
    (
        "flexible_frame.toml",
        include_str!("../scenarios/flexible_frame.toml"),
    ),
    (
        "../machines/paper_axis.toml",
        include_str!("../machines/paper_axis.toml"),
    ),
    (
        "../machines/gantry.toml",
        include_str!("../machines/gantry.toml"),
    ),
    (
        "../machines/gantry_flexible.toml",
        include_str!("../machines/gantry_flexible.toml"),
    ),
];

/// A built-in scenario file by name (e.g. `paper.toml`).
pub fn load(name: &str) -> Result<ScenarioFile> {
    load_with(name, "")
}

/// A built-in scenario file with `overrides` (TOML) merged over its base scenario.
pub fn load_with(name: &str, overrides: &str) -> Result<ScenarioFile> {
    let (_, text) = FILES
        .iter()
        .find(|(n, _)| *n == name)
        .with_context(|| format!("no built-in scenario file {name}"))?;
    Ok(load_str_with(
        &format!("built-in {name}"),
        text,
        &EmbeddedIncludes(FILES),
        overrides,
    )?)
}

/// A built-in study file run on the machine file `machine` instead of the one it names
/// (its own machine overrides still apply on top).
pub fn load_on_machine(name: &str, machine: &Path) -> Result<ScenarioFile> {
    let (_, text) = FILES
        .iter()
        .find(|(n, _)| *n == name)
        .with_context(|| format!("no built-in scenario file {name}"))?;
    let mut table: toml::Table = text.parse().context("built-in study file")?;
    let abs = std::fs::canonicalize(machine)
        .with_context(|| format!("machine file {}", machine.display()))?;
    match table.get_mut("machine") {
        Some(toml::Value::Table(m)) => {
            m.insert(
                "file".into(),
                toml::Value::String(abs.display().to_string()),
            );
        }
        _ => anyhow::bail!("built-in {name} has no [machine] table"),
    }
    let dir = abs.parent().unwrap_or(Path::new("/")).to_path_buf();
    Ok(load_str_with(
        &format!("built-in {name} on {}", machine.display()),
        &table.to_string(),
        &gantry_scenario::file::DirIncludes(dir),
        "",
    )?)
}

/// A scenario file from disk.
pub fn load_path(path: &Path) -> Result<ScenarioFile> {
    Ok(gantry_scenario::load(path)?)
}

/// A built-in file by name, or the given file from disk.
pub fn load_or(name: &str, path: Option<&Path>) -> Result<ScenarioFile> {
    match path {
        Some(p) => load_path(p),
        None => load(name),
    }
}

/// Resolve every run of a file (each is validated; the first invalid one is the error).
pub fn resolve_all(file: &ScenarioFile) -> Result<Vec<Resolved>> {
    file.runs
        .iter()
        .map(|r| Resolved::new(&file.file, r).map_err(Into::into))
        .collect()
}
