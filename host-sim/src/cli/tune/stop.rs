//! `gantry tune`'s rapid stop: its program, the scope's capture of the tracking error
//! from the reference's arrival, and the figures read from it.

use crate::cli::client::{expect_done, Client};
use crate::cli::{apply_settings, get, ready, Transport, AXES};
use crate::studies::vibration::{only, APPROACH_FEED_MM_MIN, MOVE_MM};
use anyhow::{anyhow, bail, Context, Result};
use controller_core::machine::messages::{MachineState, Request};
use controller_core::machine::scope::{ScopeConfig, Signal, Trigger};
use controller_core::motion::shaper::{ShaperConfig, ShaperStage};
use serde::Serialize;
use std::path::Path;

/// A stop settles when the tracking error stays within this, µm (the study's band).
pub const SETTLE_UM: f64 = 5.0;

/// The scope's capture of a stop: this long after the reference arrives, s, and this
/// long before it.
const OBSERVE_S: f64 = 0.2;
const PRE_S: f64 = 0.01;
/// The scope's samples at most (one channel: `machine::scope::SCOPE_VALUES`).
const MAX_SAMPLES: f64 = 2000.0;
/// The reference has arrived when it is this close to the rapid's end, mm (the scope's
/// trigger: the reference rising through it; the approach, from either side, does not
/// rise through it: it ends 60 mm below).
const ARRIVED_MM: f64 = 0.05;
/// The dwell after the rapid, s: the capture and a margin.
const DWELL_S: f64 = OBSERVE_S + 0.3;

/// The residual vibration of one rapid stop, at the encoder (JSON keys are public
/// interface).
#[derive(Clone, Debug, Serialize)]
pub struct StopCheck {
    /// Largest |tracking error| from the planner's stop on, µm.
    pub peak_um: f64,
    /// From the planner's stop until the tracking error stays within [`SETTLE_UM`], ms
    /// (`null`: not within the capture).
    pub settle_ms: Option<f64>,
    /// The program's largest acceleration of the axis, mm/s² (a shaper's deviation may
    /// make the machine lower it).
    pub acc_mm_s2: f64,
}

/// The path tolerance at which `shaper` on axis `i` leaves the machine's accelerations as
/// they are (`shaped_planner_config`: the deviation at them takes half), mm.
pub(super) fn full_acc_tolerance<T: Transport>(
    c: &mut Client<T>,
    i: usize,
    shaper: &ShaperConfig,
    period_s: f32,
) -> Result<f32> {
    let axis = controller_core::axes::Axis::from_index(i).ok_or_else(|| anyhow!("axis {i}"))?;
    let mut stage = ShaperStage::NONE;
    stage
        .configure(&only(axis, *shaper), period_s)
        .map_err(|e| anyhow!("the shaper: {e:?}"))?;
    let mut acc = [0.0f32; 3];
    for (a, name) in acc.iter_mut().zip(AXES) {
        let key = format!("axis.{name}.planner.acc_max_mm_s2");
        *a = get(c, &key)?
            .parse()
            .with_context(|| format!("setting {key} is not a number"))?;
    }
    Ok(2.0 * stage.bound().deviation_bound_axes_mm(acc))
}

/// The stop with `planner.tolerance_mm` raised to `tol_mm` for it (at least the
/// machine's), put back after.
pub(super) fn full_acc_stop<T: Transport>(
    c: &mut Client<T>,
    stop: &Stop,
    tol_mm: f32,
) -> Result<StopCheck> {
    const KEY: &str = "planner.tolerance_mm";
    let was = get(c, KEY)?;
    let was_mm: f32 = was
        .parse()
        .with_context(|| format!("setting {KEY} = {was}"))?;
    switch_off(c)?;
    apply_settings(c, &[(KEY.into(), tol_mm.max(was_mm).to_string())])?;
    let r = stop_check(c, stop);
    switch_off(c)?;
    apply_settings(c, &[(KEY.into(), was)])?;
    r
}

/// Outputs off (the shapers and the model change only then).
pub(super) fn switch_off<T: Transport>(c: &mut Client<T>) -> Result<()> {
    if c.status()?.state != MachineState::Disabled {
        expect_done("disarm", c.exec(Request::Disarm)?)?;
        crate::cli::wait_while(c, |s| s.state == MachineState::Stopping)?;
    }
    Ok(())
}

/// The rapid of axis `i`: from, to (centred on its travel), mm.
pub(super) fn stretch<T: Transport>(c: &mut Client<T>, i: usize) -> Result<(f64, f64)> {
    let s = ready(c, true)?;
    let key = |end: &str| format!("axis.{}.travel.{end}", AXES[i]);
    let lo: f64 = get(c, &key("min_mm"))?.parse()?;
    let hi: f64 = get(c, &key("max_mm"))?.parse()?;
    let mid = if lo.is_finite() && hi.is_finite() {
        if hi - lo < MOVE_MM + 2.0 {
            bail!(
                "axis {}: the travel [{lo}, {hi}] mm is shorter than the {MOVE_MM} mm rapid",
                AXES[i]
            );
        }
        0.5 * (lo + hi)
    } else {
        f64::from(s.pos_mm[i])
    };
    Ok((mid - 0.5 * MOVE_MM, mid + 0.5 * MOVE_MM))
}

/// The stop's program: approach `from` slowly, dwell, rapid to `to`, dwell.
pub(super) fn program_text(i: usize, from: f64, to: f64) -> String {
    let a = AXES[i].to_ascii_uppercase();
    format!(
        "(gantry tune: rapid stop, axis {a})\nG21 G90 G94 G61\nG1 {a}{from:.4} F{APPROACH_FEED_MM_MIN}\n\
         G4 P0.3\nG0 {a}{to:.4}\nG4 P{DWELL_S}\nM2\n"
    )
}

/// One axis' stop as `tune` takes it.
pub(super) struct Stop<'a> {
    pub axis: usize,
    /// Its program ([`program_text`]), a rapid in + ending at `to_mm`.
    pub program: &'a Path,
    pub to_mm: f64,
    /// The session's telemetry period, s (the program's accelerations are read from it).
    pub telemetry_period_s: f64,
}

/// Run `stop`'s program while the scope records the axis' tracking error from just
/// before the reference arrives.
pub(super) fn stop_check<T: Transport>(c: &mut Client<T>, stop: &Stop) -> Result<StopCheck> {
    let (i, to) = (stop.axis, stop.to_mm);
    let rate_hz = f64::from(c.control_rate_hz());
    let span = (OBSERVE_S + PRE_S) * rate_hz;
    let every = (span / MAX_SAMPLES).ceil().max(1.0);
    let dt_s = every / rate_hz;
    let cfg = ScopeConfig {
        channels: heapless::Vec::from_slice(&[Signal::Tracking(i as u8)])
            .map_err(|_| anyhow!("one channel"))?,
        samples: (span / every).ceil() as u16,
        every_periods: every as u16,
        pre_trigger: (PRE_S / dt_s) as u16,
        trigger: Trigger::Rising {
            signal: Signal::Ref(i as u8),
            level: (to - ARRIVED_MM) as f32,
        },
    };
    let name = format!("tracking.{}", AXES[i]);
    let mut report = None;
    let cap = crate::cli::scope::capture(c, cfg, vec![name], c.control_rate_hz(), 30.0, |c| {
        let r = crate::cli::run_program(c, stop.program, stop.telemetry_period_s, false, None)?;
        if !r.completed() {
            bail!("the stop program did not complete: {}", r.status);
        }
        report = Some(r);
        Ok(())
    })?;
    let r = report.ok_or_else(|| anyhow!("the stop program did not run"))?;
    let err_um: Vec<f64> = cap
        .rows
        .iter()
        .filter(|(t, _)| *t >= 0.0)
        .filter_map(|(_, v)| v.first().map(|e| f64::from(*e) * 1e3))
        .collect();
    if err_um.is_empty() {
        bail!("the scope recorded nothing after the stop");
    }
    let peak_um = err_um.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let settle_ms = match err_um.iter().rposition(|e| e.abs() > SETTLE_UM) {
        None => Some(0.0),
        Some(k) if k + 1 < err_um.len() => Some((k + 1) as f64 * dt_s * 1e3),
        Some(_) => None,
    };
    Ok(StopCheck {
        peak_um,
        settle_ms,
        acc_mm_s2: r.max_acc_mm_s2[i],
    })
}
