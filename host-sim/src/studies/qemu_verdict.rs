//! `host-sim qemu-verdict FILE --log LOG`: the verdict of one QEMU scenario. The real
//! firmware binary ran the scenario in QEMU (`firmware/qemu/run-all`) and printed its
//! true-state figures as one `gantry-figures` line, every number as its IEEE-754 bits;
//! host-sim runs the same scenario file through the same core code and the figures must
//! agree bit for bit. Prints `qemu <name> passed` or `qemu <name> FAILED: <why>`.

use super::resolve_all;
use crate::engine::discrete;
use anyhow::{bail, Context, Result};
use gantry_scenario::file::ScenarioFile;
use gantry_scenario::{Mode, Numeric};

/// The figures line the firmware prints.
pub const FIGURES_TAG: &str = "gantry-figures";

/// Named figures: `(key, values)` in the firmware's order.
pub type NamedFigures = Vec<(&'static str, Vec<f64>)>;

/// The figures of `r` in the `gantry-figures` line's order.
fn named(r: &crate::engine::RunResult) -> NamedFigures {
    vec![
        ("itse", r.itse.to_vec()),
        ("itse_window", r.itse_window.to_vec()),
        ("iae", r.iae.to_vec()),
        ("max_abs_error", r.max_abs_error.to_vec()),
        ("contour_max", vec![r.contour_max]),
        ("contour_rms", vec![r.contour_rms]),
        ("tv_u", r.tv_u.to_vec()),
        ("peak_u", r.peak_u.to_vec()),
    ]
}

/// The parsed `key=<hex>,...` fields of a figures line.
pub type Fields = Vec<(String, Vec<f64>)>;

/// Parse `key=<hex>,<hex>` fields of the figures line for run `name` in `log`.
pub fn parse_line(log: &str, name: &str) -> Result<(u64, Fields)> {
    let line = log
        .lines()
        .find(|l| {
            l.contains(FIGURES_TAG) && l.split_whitespace().any(|w| w == format!("name={name}"))
        })
        .with_context(|| format!("no `{FIGURES_TAG} name={name}` line in the firmware's log"))?;
    let start = line.find(FIGURES_TAG).unwrap_or(0) + FIGURES_TAG.len();
    let mut samples = None;
    let mut fields = Vec::new();
    for word in line[start..].split_whitespace() {
        let Some((k, v)) = word.split_once('=') else {
            continue;
        };
        match k {
            "name" => {}
            "samples" => samples = Some(v.parse::<u64>().context("samples")?),
            _ => {
                let vals = v
                    .split(',')
                    .map(|h| {
                        u64::from_str_radix(h.trim_start_matches("0x"), 16)
                            .map(f64::from_bits)
                            .with_context(|| format!("`{k}`: `{h}` is not hex bits"))
                    })
                    .collect::<Result<Vec<_>>>()?;
                fields.push((k.to_string(), vals));
            }
        }
    }
    Ok((samples.context("no samples= field")?, fields))
}

/// Compare host-sim's figures for the single run of `file` with the log's; `Ok(None)` is a
/// pass, `Ok(Some(why))` a disagreement.
pub fn verdict(file: &ScenarioFile, log: &str) -> Result<(String, Option<String>)> {
    let runs = resolve_all(file)?;
    let [r] = runs.as_slice() else {
        bail!("{}: a QEMU scenario file has exactly one run", file.file);
    };
    if r.mode != Mode::Discrete || r.numeric != Numeric::F32 {
        bail!(
            "{}: QEMU scenarios run in discrete mode in f32 (the firmware's)",
            file.file
        );
    }
    let ours = discrete::run::<f32>(r, &mut ())?;
    let (samples, theirs) = match parse_line(log, &r.name) {
        Ok(x) => x,
        Err(e) => return Ok((r.name.clone(), Some(format!("{e:#}")))),
    };
    let mut why = Vec::new();
    if samples != u64::from(r.run.periods) {
        why.push(format!(
            "{samples} periods recorded, expected {}",
            r.run.periods
        ));
    }
    for (key, vals) in named(&ours) {
        match theirs.iter().find(|(k, _)| k == key) {
            None => why.push(format!("`{key}` missing")),
            Some((_, t)) if t.len() != vals.len() => {
                why.push(format!("`{key}` has {} values", t.len()))
            }
            Some((_, t)) => {
                for (i, (a, b)) in vals.iter().zip(t).enumerate() {
                    if a.to_bits() != b.to_bits() {
                        why.push(format!("{key}[{i}] firmware {b:e} != host-sim {a:e}"));
                    }
                }
            }
        }
    }
    Ok((r.name.clone(), (!why.is_empty()).then(|| why.join("; "))))
}
