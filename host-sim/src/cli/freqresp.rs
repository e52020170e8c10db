//! `gantry freqresp AXIS`: one axis' frequency response from effort to encoder measured
//! on the machine (issue 24, items 2 and 8 on a board): the machine runs its stepped sine
//! ([`Request::MeasureResponse`], the servo's `Command::MeasureResponse`: the
//! identification's window, torque cap and safe stops), the host reads the points over
//! the link ([`Request::ResponseRead`]) and finds the resonances and anti-resonances
//! with the code `cargo sim freqresp` runs ([`AxisResponse::of`],
//! `sysid::frequency::find_modes`): the same table, JSON and Bode plot. The loop on the
//! laws ([`Request::MeasureLoop`], `gantry tune`'s filters) runs and reads the same way
//! ([`measure_loop`]).

use super::client::{expect_done, Client};
use super::{driven_window, fault_text, get_f64, ready, wait_with_progress, Transport, AXES};
use crate::studies::freqresp::{status_text, AxisResponse, FreqRespReport};
use anyhow::{bail, Result};
use controller_core::machine::messages::{MachineState, Outcome, Request, ResponseState};
use controller_core::sysid::frequency::{FrequencyResponse, ResponsePoint};
use controller_core::sysid::IdentifyStatus;

/// Reads of [`Request::ResponseRead`] at most: the record holds
/// `sysid::frequency::MAX_POINTS` points, a chunk at least one (a machine whose chunks
/// stop advancing is refused, not waited for).
const MAX_READS: usize = controller_core::sysid::frequency::MAX_POINTS;

/// Measure axis `i` (see [`driven_window`] for `window_half_mm`) and report it as
/// `cargo sim freqresp` reports an axis (`machine`: what the report names as the machine).
pub fn measure<T: Transport>(
    c: &mut Client<T>,
    i: usize,
    window_half_mm: Option<f32>,
    machine: &str,
) -> Result<FreqRespReport> {
    let name = AXES[i];
    let window = driven_window(c, i, window_half_mm, "freqresp")?;
    let window_mm = match window {
        Some(w) => w.map(f64::from),
        None => {
            let key = |end: &str| format!("axis.{name}.travel.{end}");
            [get_f64(c, &key("min_mm"))?, get_f64(c, &key("max_mm"))?]
        }
    };
    let run = run_points(
        c,
        i,
        Request::MeasureResponse {
            axis: i as u8,
            window_mm: window,
        },
        "frequency response",
    )?;
    let response = AxisResponse::of(
        &run.points,
        run.status,
        run.machine_time_s,
        window_mm,
        None,
        None,
    );
    Ok(FreqRespReport {
        machine: machine.to_string(),
        axes: [(name.to_string(), response)].into_iter().collect(),
    })
}

/// A stepped sine's run on the machine: its points, how it ended, how long it took.
pub struct PointsRun {
    pub points: FrequencyResponse,
    /// `done`, or why it stopped (as `freqresp` reports it).
    pub status: String,
    pub machine_time_s: f64,
}

/// Axis `i`'s open loop on its laws (`L(jω)`, [`Request::MeasureLoop`]; see
/// [`driven_window`] for `window_half_mm`): the machine armed (the laws hold the axis),
/// the points as measured.
pub fn measure_loop<T: Transport>(
    c: &mut Client<T>,
    i: usize,
    window_half_mm: Option<f32>,
) -> Result<PointsRun> {
    let window = driven_window(c, i, window_half_mm, "tune")?;
    ready(c, false)?;
    run_points(
        c,
        i,
        Request::MeasureLoop {
            axis: i as u8,
            window_mm: window,
        },
        "loop",
    )
}

/// Start `request` (a stepped sine on axis `i`), wait for it, read its points.
fn run_points<T: Transport>(
    c: &mut Client<T>,
    i: usize,
    request: Request,
    what: &str,
) -> Result<PointsRun> {
    let name = AXES[i];
    let p0 = c.status()?.period;
    expect_done(&format!("{what} {name}"), c.exec(request)?)?;
    let s = wait_with_progress(
        c,
        MachineState::Identify,
        &format!("measuring {name}'s {what}"),
    )?;
    let machine_time_s = f64::from(s.period.wrapping_sub(p0)) / f64::from(c.control_rate_hz());
    let (points, state) = read_points(c, i)?;
    let status = match state {
        ResponseState::Done => status_text(IdentifyStatus::Done),
        ResponseState::Aborted => format!(
            "aborted after {} points ({:?}, {})",
            points.len(),
            s.state,
            fault_text(&s)
        ),
    };
    Ok(PointsRun {
        points,
        status,
        machine_time_s,
    })
}

/// The last measurement's points, read a chunk at a time, in rising frequency; and how it
/// ended.
pub fn read_points<T: Transport>(
    c: &mut Client<T>,
    i: usize,
) -> Result<(FrequencyResponse, ResponseState)> {
    let mut frf = FrequencyResponse::new();
    let mut first: u8 = 0;
    for _ in 0..MAX_READS {
        let chunk = match c.exec(Request::ResponseRead { first })? {
            Outcome::Response(chunk) => chunk,
            Outcome::Refused(why) => {
                bail!("freqresp {}: reading the points refused: {why}", AXES[i])
            }
            other => bail!(
                "freqresp {}: the machine answered {other:?} to a read of its points",
                AXES[i]
            ),
        };
        if usize::from(chunk.axis) != i {
            bail!(
                "freqresp {}: the machine's last measurement is of axis {}",
                AXES[i],
                AXES.get(usize::from(chunk.axis)).copied().unwrap_or("?")
            );
        }
        for p in &chunk.points {
            frf.push(ResponsePoint {
                freq_hz: p.freq_hz,
                re: p.re,
                im: p.im,
            });
        }
        let next = usize::from(chunk.first) + chunk.points.len();
        if next >= usize::from(chunk.total) {
            return Ok((frf, chunk.state));
        }
        if chunk.points.is_empty() {
            bail!(
                "freqresp {}: the machine sent no points from {first} of {}",
                AXES[i],
                chunk.total
            );
        }
        first = next as u8;
    }
    bail!(
        "freqresp {}: more than {MAX_READS} reads for the points",
        AXES[i]
    )
}
