//! `host-sim qemu-verdict FILE --log LOG`: the verdict of one QEMU scenario. The real
//! firmware binary ran the scenario in QEMU (`firmware/qemu/run-all`) and printed its
//! true-state figures as one `gantry-figures` line, every number as its IEEE-754 bits;
//! host-sim runs the same scenario file through the same core code and the figures must
//! agree bit for bit. Prints `qemu <name> passed` or `qemu <name> FAILED: <why>`.
//!
//! The line (one line; the firmware's `src/qemu/report.rs` prints it):
//!
//! ```text
//! gantry-figures name=<name> samples=<u64> itse=<h>,<h>,<h> itse_window=<h>,<h>,<h>
//!   iae=<h>,<h>,<h> max_abs_error=<h>,<h>,<h> contour_max=<h> contour_rms=<h>
//!   tv_u=<h>,<h>,<h> peak_u=<h>,<h>,<h> fault=<fault> injected=<period>
//! ```
//!
//! - `<h>`: the IEEE-754 bits of an `f64` figure in lower-case hex (`f64::to_bits`, no
//!   `0x`);
//! - `fault`: the run's first latched fault as `<kind>:<axis>:<period>` (`FaultKind::name`,
//!   `x`/`y`/`z` or `-` for a system fault, the servo's period counter at detection), or
//!   `none`;
//! - `injected`: the run's period of the scenario's fault injection
//!   (`SimRun::injected_at`), or `none`.
//!
//! Both fault fields must equal host-sim's own run (its `SimRun::injected_at()` and
//! `servo().faults().first()` after the last period), and a scenario that injects a fault
//! must end with one latched (a fault the firmware did not detect is a failure even if
//! host-sim agrees).

use crate::builtin::resolve_all;
use crate::engine::discrete::{self, Observer, PeriodView};
use anyhow::{bail, Context, Result};
use controller_core::servo::faults::FaultRecord;
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

/// The fields of a `gantry-figures` line.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FiguresLine {
    pub samples: u64,
    /// `(key, values)` of the hex-encoded figures, in the line's order.
    pub figures: Vec<(String, Vec<f64>)>,
    /// The `fault=` field as printed (`none` or `<kind>:<axis>:<period>`).
    pub fault: String,
    /// The `injected=` field as printed (`none` or the period).
    pub injected: String,
}

/// `fault=` of a fault record (the firmware's format).
pub fn fault_field(f: Option<FaultRecord>) -> String {
    match f {
        Some(r) => format!(
            "{}:{}:{}",
            r.fault.kind.name(),
            r.fault.axis.map_or("-", |a| a.name()),
            r.period
        ),
        None => "none".into(),
    }
}

/// `injected=` of an injection period (the firmware's format).
pub fn injected_field(k: Option<u32>) -> String {
    k.map_or_else(|| "none".into(), |k| k.to_string())
}

/// Parse the figures line for run `name` in `log`.
pub fn parse_line(log: &str, name: &str) -> Result<FiguresLine> {
    let line = log
        .lines()
        .find(|l| {
            l.contains(FIGURES_TAG) && l.split_whitespace().any(|w| w == format!("name={name}"))
        })
        .with_context(|| format!("no `{FIGURES_TAG} name={name}` line in the firmware's log"))?;
    let start = line.find(FIGURES_TAG).unwrap_or(0) + FIGURES_TAG.len();
    let mut samples = None;
    let mut fault = None;
    let mut injected = None;
    let mut figures = Vec::new();
    for word in line[start..].split_whitespace() {
        let Some((k, v)) = word.split_once('=') else {
            continue;
        };
        match k {
            "name" => {}
            "samples" => samples = Some(v.parse::<u64>().context("samples")?),
            "fault" => fault = Some(v.to_string()),
            "injected" => injected = Some(v.to_string()),
            _ => {
                let vals = v
                    .split(',')
                    .map(|h| {
                        u64::from_str_radix(h.trim_start_matches("0x"), 16)
                            .map(f64::from_bits)
                            .with_context(|| format!("`{k}`: `{h}` is not hex bits"))
                    })
                    .collect::<Result<Vec<_>>>()?;
                figures.push((k.to_string(), vals));
            }
        }
    }
    Ok(FiguresLine {
        samples: samples.context("no samples= field")?,
        figures,
        fault: fault.context("no fault= field")?,
        injected: injected.context("no injected= field")?,
    })
}

/// The fault fields of host-sim's run, after its last period.
#[derive(Default)]
struct Faults {
    injected: Option<u32>,
    first: Option<FaultRecord>,
}

impl Observer<f32> for Faults {
    fn period(&mut self, run: &PeriodView<'_, f32>) {
        self.injected = run.injected_at;
        self.first = run.servo.faults().first();
    }
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
    let mut faults = Faults::default();
    let ours = discrete::run::<f32>(r, &mut faults)?;
    let theirs = match parse_line(log, &r.name) {
        Ok(x) => x,
        Err(e) => return Ok((r.name.clone(), Some(format!("{e:#}")))),
    };
    let mut why = Vec::new();
    // the firmware logs the rate it ran the scenario at; both sides must agree on it
    let rate_line = format!("periods at {} Hz", r.run.servo.rate_hz);
    if !log.contains(&rate_line) {
        why.push(format!(
            "the firmware did not run at {} Hz (no `{rate_line}` line): build and verdict \
             rates differ",
            r.run.servo.rate_hz
        ));
    }
    if theirs.samples != u64::from(r.run.periods) {
        why.push(format!(
            "{} periods recorded, expected {}",
            theirs.samples, r.run.periods
        ));
    }
    for (key, vals) in named(&ours) {
        match theirs.figures.iter().find(|(k, _)| k == key) {
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
    let (fault, injected) = (fault_field(faults.first), injected_field(faults.injected));
    if theirs.fault != fault {
        why.push(format!(
            "fault: firmware {} != host-sim {fault}",
            theirs.fault
        ));
    }
    if theirs.injected != injected {
        why.push(format!(
            "injected: firmware {} != host-sim {injected}",
            theirs.injected
        ));
    }
    if r.run.inject.is_some() && theirs.fault == "none" {
        why.push("the injected fault was not detected".into());
    }
    Ok((r.name.clone(), (!why.is_empty()).then(|| why.join("; "))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::axes::Axis;
    use controller_core::servo::faults::{Fault, FaultKind};

    #[test]
    fn parses_the_fault_fields_and_the_figures() {
        let log = "INFO  gantry-figures name=a samples=3 itse=3ff0000000000000,0,4000000000000000 \
                   fault=encoder_stuck:x:4021 injected=4000";
        let l = parse_line(log, "a").unwrap();
        assert_eq!(l.samples, 3);
        assert_eq!(l.figures, vec![("itse".to_string(), vec![1.0, 0.0, 2.0])]);
        assert_eq!(
            (l.fault.as_str(), l.injected.as_str()),
            ("encoder_stuck:x:4021", "4000")
        );
        let rec = FaultRecord {
            fault: Fault::on(FaultKind::EncoderStuck, Axis::X),
            period: 4021,
            value: 0.0,
        };
        assert_eq!(fault_field(Some(rec)), l.fault);
        assert_eq!(injected_field(Some(4000)), l.injected);
        let sys = FaultRecord {
            fault: Fault::system(FaultKind::EStop),
            period: 7,
            value: 0.0,
        };
        assert_eq!(fault_field(Some(sys)), "estop:-:7");
        assert_eq!(
            (fault_field(None), injected_field(None)),
            ("none".into(), "none".into())
        );
        // a line without the fault fields is rejected
        assert!(parse_line("gantry-figures name=a samples=1 itse=0", "a").is_err());
    }
}
