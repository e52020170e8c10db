//! Reading scenario files.
//!
//! A file is one TOML document: the base scenario ([`crate::schema::Scenario`]), plus
//! optionally
//!
//! - `[[case]]` tables: each has a `name`, optionally `variants = [..]` (the variants it
//!   runs with; default all), and any keys of the scenario, which override the base;
//! - `[[variant]]` tables: each has a `name` and overrides applied after the case's.
//!
//! Every case runs with every variant it allows; the run is named `<case>_<variant>` (or
//! the one that exists, or the base `name` when there are neither). Overrides merge
//! table by table; a value that is not a table replaces the base's, and so does a
//! one-key table holding a table or a name over another with a different key (the way
//! the file spells an enum variant: `{ pid = {..} }` over `{ smc = {..} }` or over
//! `{ tuned = "dsmc" }` switches the law).
//!
//! After merging, any table with an `all` key gets it merged under each of `x`, `y`, `z`.
//! `machine = { file = "machines/gantry.toml", ... }` includes a machine description
//! (path relative to the including file) under the keys given beside `file`.
//!
//! Limits: files over [`MAX_FILE_BYTES`] are refused; run names are `[A-Za-z0-9_-]+`.

use crate::schema::Scenario;
use std::path::{Path, PathBuf};
use toml::{Table, Value};

/// Largest scenario or machine file accepted: 1 MiB.
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// Why a file or run was refused: which file, which run, what.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{file}{}: {message}", run.as_ref().map(|r| format!(": run `{r}`")).unwrap_or_default())]
pub struct ScenarioError {
    pub file: String,
    pub run: Option<String>,
    pub message: String,
}

impl ScenarioError {
    pub fn new(file: &str, run: Option<&str>, message: impl Into<String>) -> Self {
        Self {
            file: file.to_string(),
            run: run.map(str::to_string),
            message: message.into(),
        }
    }
}

/// One run of a file.
#[derive(Clone, Debug)]
pub struct Run {
    /// `<case>_<variant>`, `<case>`, `<variant>` or the scenario's name.
    pub name: String,
    pub case: Option<String>,
    pub variant: Option<String>,
    /// The machine file the run's `machine` table included (`machine.file`), if any.
    pub machine_file: Option<String>,
    pub scenario: Scenario,
}

/// A loaded file: its runs in file order (cases outer, variants inner).
#[derive(Clone, Debug)]
pub struct ScenarioFile {
    /// How the file was named (its path, or a built-in's name).
    pub file: String,
    /// The base scenario's `name`.
    pub name: String,
    pub runs: Vec<Run>,
}

impl ScenarioFile {
    /// The run named `name`.
    pub fn run(&self, name: &str) -> Result<&Run, ScenarioError> {
        self.runs.iter().find(|r| r.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.runs.iter().map(|r| r.name.as_str()).collect();
            ScenarioError::new(
                &self.file,
                None,
                format!("no run `{name}` (runs: {})", names.join(", ")),
            )
        })
    }
}

/// Reads an include by its path relative to the including file.
pub trait Includes {
    fn read(&self, rel: &str) -> Result<String, String>;
}

/// Includes from the file system, relative to a directory.
pub struct DirIncludes(pub PathBuf);

impl Includes for DirIncludes {
    fn read(&self, rel: &str) -> Result<String, String> {
        read_capped(&self.0.join(rel))
    }
}

/// Includes from a fixed list of `(relative path, contents)` (built-in files).
pub struct EmbeddedIncludes<'a>(pub &'a [(&'a str, &'a str)]);

impl Includes for EmbeddedIncludes<'_> {
    fn read(&self, rel: &str) -> Result<String, String> {
        let rel = rel.trim_start_matches("./");
        self.0
            .iter()
            .find(|(n, _)| *n == rel)
            .map(|(_, t)| t.to_string())
            .ok_or_else(|| format!("no built-in file `{rel}`"))
    }
}

/// Read a file, refusing anything over [`MAX_FILE_BYTES`].
pub fn read_capped(path: &Path) -> Result<String, String> {
    read_regular(path, MAX_FILE_BYTES)
}

/// Read a regular file of at most `max_bytes` as text. A named pipe, a device or a
/// directory is refused before it is opened (opening a pipe waits for a writer, a device
/// such as /dev/zero never ends), and the read itself stops after `max_bytes` + 1 bytes
/// whatever the file's size said.
pub fn read_regular(path: &Path, max_bytes: u64) -> Result<String, String> {
    use std::io::Read;
    let meta =
        std::fs::metadata(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if !meta.is_file() {
        return Err(format!(
            "{} is not a regular file (pipes, devices and directories are refused)",
            path.display()
        ));
    }
    let too_big = |n: u64| {
        format!(
            "{} is {n} bytes or more; files here are limited to {max_bytes} bytes",
            path.display()
        )
    };
    if meta.len() > max_bytes {
        return Err(too_big(meta.len()));
    }
    let file =
        std::fs::File::open(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut bytes = Vec::new();
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_big(bytes.len() as u64));
    }
    String::from_utf8(bytes).map_err(|e| {
        format!(
            "{} is not UTF-8 text (byte {})",
            path.display(),
            e.utf8_error().valid_up_to()
        )
    })
}

/// Load a scenario file from disk (includes relative to its directory).
pub fn load(path: &Path) -> Result<ScenarioFile, ScenarioError> {
    let name = path.display().to_string();
    let text = read_capped(path).map_err(|m| ScenarioError::new(&name, None, m))?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    load_str(&name, &text, &DirIncludes(dir))
}

/// Load a scenario file from its text; `file` names it in errors.
pub fn load_str(
    file: &str,
    text: &str,
    includes: &dyn Includes,
) -> Result<ScenarioFile, ScenarioError> {
    load_str_with(file, text, includes, "")
}

/// Load a scenario file from its text with `overrides` (TOML) merged over its base
/// scenario, before its cases and variants (e.g. a command's options, or a test's change).
pub fn load_str_with(
    file: &str,
    text: &str,
    includes: &dyn Includes,
    overrides: &str,
) -> Result<ScenarioFile, ScenarioError> {
    let err = |run: Option<&str>, m: String| ScenarioError::new(file, run, m);
    if text.len() as u64 > MAX_FILE_BYTES {
        return Err(err(None, format!("file is over {MAX_FILE_BYTES} bytes")));
    }
    let mut base: Table = text
        .parse()
        .map_err(|e: toml::de::Error| err(None, format!("invalid TOML: {e}")))?;
    let mut over: Table = overrides
        .parse()
        .map_err(|e: toml::de::Error| err(None, format!("invalid overrides: {e}")))?;
    let base_machine = include_machine(&mut base, includes).map_err(|m| err(None, m))?;
    let over_machine = include_machine(&mut over, includes).map_err(|m| err(None, m))?;
    let base_machine = over_machine.or(base_machine);
    merge(&mut base, over);
    let cases = take_array(&mut base, "case").map_err(|m| err(None, m))?;
    let variants = take_array(&mut base, "variant").map_err(|m| err(None, m))?;
    let base_name = match base.get("name") {
        Some(Value::String(s)) => s.clone(),
        _ => return Err(err(None, "missing `name` (a string)".into())),
    };
    check_name(&base_name).map_err(|m| err(None, m))?;

    let mut runs = Vec::new();
    let case_list: Vec<Option<Table>> = if cases.is_empty() {
        vec![None]
    } else {
        cases.into_iter().map(Some).collect()
    };
    for case in case_list {
        let (case_name, allowed, case_over) = match case {
            Some(mut c) => {
                let n = entry_name(&mut c, "case").map_err(|m| err(None, m))?;
                let allowed = match c.remove("variants") {
                    None => None,
                    Some(Value::Array(a)) => Some(
                        a.into_iter()
                            .map(|v| match v {
                                Value::String(s) => Ok(s),
                                _ => Err(err(Some(&n), "`variants` must be names".into())),
                            })
                            .collect::<Result<Vec<_>, _>>()?,
                    ),
                    Some(_) => return Err(err(Some(&n), "`variants` must be an array".into())),
                };
                (Some(n), allowed, c)
            }
            None => (None, None, Table::new()),
        };
        let variant_list: Vec<Option<Table>> = if variants.is_empty() {
            vec![None]
        } else {
            variants.iter().cloned().map(Some).collect()
        };
        for variant in variant_list {
            let (variant_name, var_over) = match variant {
                Some(mut v) => (
                    Some(entry_name(&mut v, "variant").map_err(|m| err(None, m))?),
                    v,
                ),
                None => (None, Table::new()),
            };
            if let (Some(allowed), Some(v)) = (&allowed, &variant_name) {
                if !allowed.contains(v) {
                    continue;
                }
            }
            let name = match (&case_name, &variant_name) {
                (Some(c), Some(v)) => format!("{c}_{v}"),
                (Some(c), None) => c.clone(),
                (None, Some(v)) => v.clone(),
                (None, None) => base_name.clone(),
            };
            let mut t = base.clone();
            let mut co = case_over.clone();
            let case_machine =
                include_machine(&mut co, includes).map_err(|m| err(Some(&name), m))?;
            merge(&mut t, co);
            let mut vo = var_over;
            let variant_machine =
                include_machine(&mut vo, includes).map_err(|m| err(Some(&name), m))?;
            let machine_file = variant_machine
                .or(case_machine)
                .or_else(|| base_machine.clone());
            merge(&mut t, vo);
            expand_all(&mut t);
            let scenario: Scenario =
                serde_path_to_error::deserialize(Value::Table(t)).map_err(|e| {
                    let path = e.path().to_string();
                    let inner = e.into_inner();
                    err(Some(&name), format!("`{path}`: {}", inner.message().trim()))
                })?;
            runs.push(Run {
                name,
                case: case_name.clone(),
                variant: variant_name,
                machine_file,
                scenario,
            });
        }
    }
    if let Some(c) = allowed_unknown(&runs) {
        return Err(err(None, c));
    }
    let mut seen = std::collections::BTreeSet::new();
    for r in &runs {
        if !seen.insert(r.name.clone()) {
            return Err(err(Some(&r.name), "two runs have this name".into()));
        }
    }
    Ok(ScenarioFile {
        file: file.to_string(),
        name: base_name,
        runs,
    })
}

/// A file whose cases allow no variant that exists runs nothing for that case: refuse.
fn allowed_unknown(runs: &[Run]) -> Option<String> {
    if runs.is_empty() {
        Some("no runs (every case excludes every variant)".into())
    } else {
        None
    }
}

/// `[A-Za-z0-9_-]+`, at most 64 characters.
pub fn check_name(name: &str) -> Result<(), String> {
    if name.is_empty()
        || name.len() > 64
        || !name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
    {
        return Err(format!(
            "name `{name}` must be 1 to 64 characters of [A-Za-z0-9_-]"
        ));
    }
    Ok(())
}

fn take_array(t: &mut Table, key: &str) -> Result<Vec<Table>, String> {
    match t.remove(key) {
        None => Ok(Vec::new()),
        Some(Value::Array(a)) => a
            .into_iter()
            .map(|v| match v {
                Value::Table(t) => Ok(t),
                _ => Err(format!("`{key}` entries must be tables ([[{key}]])")),
            })
            .collect(),
        Some(_) => Err(format!("`{key}` must be an array of tables ([[{key}]])")),
    }
}

fn entry_name(t: &mut Table, what: &str) -> Result<String, String> {
    match t.remove("name") {
        Some(Value::String(s)) => {
            check_name(&s).map_err(|m| format!("{what}: {m}"))?;
            Ok(s)
        }
        _ => Err(format!("every [[{what}]] needs a `name` (a string)")),
    }
}

/// Replace `machine = { file = "...", <overrides> }` by the file's table with the
/// overrides merged in; the file's path, when there was one.
fn include_machine(t: &mut Table, includes: &dyn Includes) -> Result<Option<String>, String> {
    let Some(Value::Table(m)) = t.get_mut("machine") else {
        return Ok(None);
    };
    let Some(file) = m.remove("file") else {
        return Ok(None);
    };
    let Value::String(rel) = file else {
        return Err("`machine.file` must be a path (a string)".into());
    };
    if rel.contains("..") && rel.matches("..").count() > 4 {
        return Err(format!("`machine.file` {rel}: too many parent directories"));
    }
    let text = includes.read(&rel)?;
    let mut included: Table = text
        .parse()
        .map_err(|e: toml::de::Error| format!("machine file {rel}: invalid TOML: {e}"))?;
    if included.contains_key("file") {
        return Err(format!(
            "machine file {rel}: nested includes are not supported"
        ));
    }
    let overrides = std::mem::take(m);
    merge(&mut included, overrides);
    *m = included;
    Ok(Some(rel))
}

/// Merge `over` into `base` (see the module docs).
pub fn merge(base: &mut Table, over: Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(Value::Table(b)), Value::Table(o)) => {
                let switches_variant = is_variant(b) && is_variant(&o) && b.keys().ne(o.keys());
                if switches_variant {
                    *b = o;
                } else {
                    merge(b, o);
                }
            }
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// A one-key table whose value is a table or a name: how the file spells an enum variant
/// (`{ pid = {..} }`, `{ tuned = "pid" }`; never a per-axis table keyed `all`, `x`, `y`,
/// `z`).
fn is_variant(t: &Table) -> bool {
    match t.iter().next() {
        Some((k, Value::Table(_) | Value::String(_))) if t.len() == 1 => {
            !matches!(k.as_str(), "all" | "x" | "y" | "z")
        }
        _ => false,
    }
}

/// Merge every `all` key under `x`, `y`, `z` of its table, recursively.
pub fn expand_all(t: &mut Table) {
    if let Some(all) = t.remove("all") {
        for axis in ["x", "y", "z"] {
            let mut v = all.clone();
            if let Some(own) = t.remove(axis) {
                match (&mut v, own) {
                    (Value::Table(a), Value::Table(o))
                        if !(is_variant(a) && is_variant(&o) && a.keys().ne(o.keys())) =>
                    {
                        merge(a, o)
                    }
                    (_, o) => v = o,
                }
            }
            t.insert(axis.to_string(), v);
        }
    }
    for (_, v) in t.iter_mut() {
        match v {
            Value::Table(sub) => expand_all(sub),
            Value::Array(a) => {
                for e in a {
                    if let Value::Table(sub) = e {
                        expand_all(sub);
                    }
                }
            }
            _ => {}
        }
    }
}

/// Load a QEMU scenario file at the firmware's control rate: with `rate_hz` (the build's
/// `GANTRY_CONTROL_HZ`) every file runs at that rate — plant step, servo and figures —
/// except a file whose name states its own rate (`…_20khz`), which keeps it. The
/// firmware's build script and `host-sim qemu-verdict` both load through here, so the
/// two sides simulate the same run.
pub fn load_at_rate(path: &Path, rate_hz: Option<u32>) -> Result<ScenarioFile, ScenarioError> {
    let name = path.display().to_string();
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let fixed = stated_rate_khz(&stem).is_some();
    let text = read_capped(path).map_err(|m| ScenarioError::new(&name, None, m))?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let overrides = match rate_hz {
        Some(r) if !fixed => format!("[machine]\nrate_hz = {r}\n"),
        _ => String::new(),
    };
    load_str_with(&name, &text, &DirIncludes(dir), &overrides)
}

/// The rate a file name states (`…_20khz` → 20), if any.
pub fn stated_rate_khz(stem: &str) -> Option<u32> {
    let digits = stem.strip_suffix("khz")?.rsplit('_').next()?;
    digits.parse().ok()
}

#[cfg(test)]
mod tests {

    #[test]
    fn qemu_rates_follow_the_build_unless_the_name_states_one() {
        assert_eq!(stated_rate_khz("gantry_dsmc_helix_20khz"), Some(20));
        assert_eq!(stated_rate_khz("paper_helix_dsmc"), None);
        assert_eq!(stated_rate_khz("x_fastkhz"), None);
        let dir =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/qemu");
        let rate = |file: &str, build: Option<u32>| {
            let f = load_at_rate(&dir.join(file), build).unwrap();
            let r = crate::Resolved::new(&f.file, &f.runs[0]).unwrap();
            (r.run.servo.rate_hz, r.run.periods)
        };
        assert_eq!(rate("paper_helix_dsmc.toml", None).0, 10_000);
        let (hz, periods) = rate("paper_helix_dsmc.toml", Some(20_000));
        assert_eq!(hz, 20_000);
        // the same simulated time: twice the periods
        assert_eq!(periods, 2 * rate("paper_helix_dsmc.toml", None).1);
        assert_eq!(rate("gantry_dsmc_helix_20khz.toml", Some(10_000)).0, 20_000);
    }

    use super::*;

    #[test]
    fn all_merges_under_axes_and_variants_switch() {
        let mut t: Table = r#"
laws.all = { tuned = "dob_smc" }
laws.x = { dob_smc = { a = 1.0 } }
enc.all = { counts = 1, counter = "bits32" }
enc.z = { counter = "bits16" }
"#
        .parse()
        .unwrap();
        expand_all(&mut t);
        let laws = t["laws"].as_table().unwrap();
        assert_eq!(laws["x"].as_table().unwrap().len(), 1, "{laws:?}");
        assert!(laws["x"].get("dob_smc").is_some());
        assert_eq!(laws["y"]["tuned"].as_str(), Some("dob_smc"));
        assert_eq!(t["enc"]["z"]["counter"].as_str(), Some("bits16"));
        assert_eq!(t["enc"]["z"]["counts"].as_integer(), Some(1));
    }
}
