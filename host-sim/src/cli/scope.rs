//! `gantry scope`: arm the machine's scope (signals, samples, decimation, pre-trigger,
//! trigger: `controller_core::machine::scope`), optionally run a program while it waits,
//! read the complete capture out chunk by chunk over the reliable channel, and write it
//! as CSV (and a figure beside it, `output::scope_plots`).

use super::client::{expect_done, Client};
use super::{Transport, POLL_MS};
use anyhow::{bail, Context, Result};
use controller_core::machine::messages::{Outcome, Request};
use controller_core::machine::scope::{ScopeConfig, ScopeState, Signal, Trigger, SCOPE_CHANNELS};
use std::path::Path;

/// A capture as read: the signals' names, and per sample the time from the trigger (s)
/// and the values.
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    pub names: Vec<String>,
    pub rows: Vec<(f64, Vec<f32>)>,
}

fn signal_names() -> String {
    Signal::names()
        .map(|(k, a)| match a {
            Some(a) => format!("{k}.{a}"),
            None => k.to_string(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// `pos.x,tracking.x` → the signals, in order (an unknown name is an error that lists the
/// known ones).
pub fn parse_signals(list: &str) -> Result<Vec<Signal>> {
    let names: Vec<&str> = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    if names.is_empty() || names.len() > SCOPE_CHANNELS {
        bail!(
            "--signals: 1 to {SCOPE_CHANNELS} signals, got {}",
            names.len()
        );
    }
    names
        .iter()
        .map(|n| {
            Signal::from_name(n).with_context(|| {
                format!(
                    "--signals: unknown signal `{n}` (known: {})",
                    signal_names()
                )
            })
        })
        .collect()
}

/// `now`, `fault`, `rising:SIGNAL:LEVEL` or `falling:SIGNAL:LEVEL`.
pub fn parse_trigger(t: &str) -> Result<Trigger> {
    let parts: Vec<&str> = t.split(':').collect();
    Ok(match parts.as_slice() {
        ["now"] => Trigger::Now,
        ["fault"] => Trigger::Fault,
        [edge @ ("rising" | "falling"), sig, level] => {
            let signal = Signal::from_name(sig).with_context(|| {
                format!(
                    "--trigger: unknown signal `{sig}` (known: {})",
                    signal_names()
                )
            })?;
            let level: f32 = level
                .parse()
                .ok()
                .filter(|l: &f32| l.is_finite())
                .with_context(|| format!("--trigger: level `{level}` is not a number"))?;
            if *edge == "rising" {
                Trigger::Rising { signal, level }
            } else {
                Trigger::Falling { signal, level }
            }
        }
        _ => {
            bail!("--trigger: `{t}` is not now, fault, rising:SIGNAL:LEVEL or falling:SIGNAL:LEVEL")
        }
    })
}

/// Arm `cfg` (checked here first, with the machine's own check), run `during` (e.g. a
/// program) while it waits, then wait up to `timeout_s` of machine time for the capture
/// and read it; `rate_hz` is the machine's control rate.
pub fn capture<T: Transport>(
    c: &mut Client<T>,
    cfg: ScopeConfig,
    names: Vec<String>,
    rate_hz: u32,
    timeout_s: f32,
    during: impl FnOnce(&mut Client<T>) -> Result<()>,
) -> Result<Capture> {
    if !(timeout_s > 0.0 && timeout_s <= 3600.0) {
        bail!("--timeout-s must be within (0, 3600], got {timeout_s}");
    }
    arm(c, cfg)?;
    during(c)?;
    let t0 = c.last_period();
    let timeout_periods = (f64::from(timeout_s) * f64::from(rate_hz)) as u32;
    loop {
        let s = c.status()?;
        match s.scope {
            ScopeState::Done => break,
            ScopeState::Off => bail!("the scope was disarmed (a new session?)"),
            ScopeState::Waiting | ScopeState::Triggered => {}
        }
        if s.period.wrapping_sub(t0) > timeout_periods {
            bail!(
                "the scope did not {} within {timeout_s} s of machine time",
                if s.scope == ScopeState::Waiting {
                    "trigger"
                } else {
                    "complete"
                }
            );
        }
        c.sleep_ms(POLL_MS)?;
    }
    read(c, names, rate_hz)
}

/// Arm `cfg` (checked here first, then by the machine): a running capture is dropped.
pub fn arm<T: Transport>(c: &mut Client<T>, cfg: ScopeConfig) -> Result<()> {
    if let Err(why) = cfg.check() {
        bail!("{why}");
    }
    expect_done("scope arm", c.exec(Request::ScopeArm(cfg))?)?;
    Ok(())
}

/// Read the completed capture (its signals named `names`, in order); `rate_hz` is the
/// machine's control rate.
pub fn read<T: Transport>(c: &mut Client<T>, names: Vec<String>, rate_hz: u32) -> Result<Capture> {
    let mut values = Vec::new();
    let (mut total, mut trigger_at, mut every) = (1usize, 0usize, 1u16);
    while values.len() < total {
        let chunk = match c.exec(Request::ScopeRead {
            offset: values.len() as u16,
        })? {
            Outcome::Scope(chunk) => chunk,
            Outcome::Refused(why) => bail!("scope read refused: {why}"),
            other => bail!("scope read: unexpected answer {other:?}"),
        };
        if usize::from(chunk.offset) != values.len() || chunk.values.is_empty() {
            bail!(
                "scope read: chunk at {} is not the one asked for",
                chunk.offset
            );
        }
        total = usize::from(chunk.total);
        trigger_at = usize::from(chunk.trigger_at);
        every = chunk.every_periods.max(1);
        values.extend_from_slice(&chunk.values);
    }
    let ch = names.len().max(1);
    let dt = f64::from(every) / f64::from(rate_hz.max(1));
    let rows = values
        .chunks(ch)
        .enumerate()
        .map(|(i, v)| ((i as f64 - trigger_at as f64) * dt, v.to_vec()))
        .collect();
    Ok(Capture { names, rows })
}

/// The capture as CSV: `t_s` (from the trigger), then one column per signal.
pub fn write_csv(path: &Path, cap: &Capture) -> Result<()> {
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("cannot write {}", path.display()))?;
    let mut head = vec!["t_s".to_string()];
    head.extend(cap.names.iter().cloned());
    w.write_record(&head)?;
    for (t, v) in &cap.rows {
        let mut row = vec![format!("{t:.6}")];
        row.extend(v.iter().map(|x| x.to_string()));
        w.write_record(&row)?;
    }
    w.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signals_and_triggers_parse_and_bad_ones_name_themselves() {
        assert_eq!(
            parse_signals("pos.x, tracking.z,contour").unwrap(),
            [Signal::Pos(0), Signal::Tracking(2), Signal::Contour]
        );
        let e = parse_signals("pos.x,speed.y").unwrap_err().to_string();
        assert!(e.contains("`speed.y`") && e.contains("tracking.x"), "{e}");
        assert!(parse_signals("pos.x,pos.y,pos.z,vel.x,vel.y").is_err());
        assert!(parse_signals("").is_err());
        assert_eq!(parse_trigger("fault").unwrap(), Trigger::Fault);
        assert_eq!(
            parse_trigger("falling:vel.y:-2.5").unwrap(),
            Trigger::Falling {
                signal: Signal::Vel(1),
                level: -2.5
            }
        );
        for bad in [
            "rising:pos.x",
            "rising:pos.q:1",
            "falling:pos.x:abc",
            "edge",
            "rising:pos.x:nan",
        ] {
            assert!(parse_trigger(bad).is_err(), "{bad}");
        }
    }
}
