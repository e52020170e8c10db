//! The open loop of one axis measured on the running machine: a sine torque is added at
//! the motor (the simulated world's [`World::set_effort_offset`], where a drive's
//! machine analyser adds its test signal) while the servo jogs the axis on its own laws,
//! estimators and output filters; the effort the servo commands against the sum the
//! plant receives is the loop `L = C·F·P`, whatever the law (a sliding-mode law's
//! describing function at the measured amplitude):
//!
//! ```text
//! v = u + d,  u = -L v   =>   L(jω) = -U(jω) / V(jω)
//! ```
//!
//! Each frequency is its own run from rest: armed, jogged at [`TRAVEL_MM_S`] (the
//! friction stays one-sided, as in the open-loop `freqresp`), settled, then one DFT bin of
//! `u` and `v` over whole cycles. The sine's torque is the rigid body's for a velocity
//! amplitude of [`VELOCITY_AMPLITUDE_MM_S`], `Ĵ 2πf v`, at most [`MAX_TORQUE_FRACTION`] of
//! the identification's torque cap (above that the position amplitude falls as `1/f²`
//! and the counts' quantisation, evened out by the travel, is averaged over the cycles).
//!
//! [`World::set_effort_offset`]: controller_core::sim::world::World::set_effort_offset

use anyhow::{anyhow, Result};
use controller_core::axes::Axis;
use controller_core::filter::AxisFilterConfig;
use controller_core::servo::{Command, ServoState};
use controller_core::sim::run::RunConfig;
use std::f64::consts::PI;

/// The jog the sine rides on, mm/s (above the Stribeck region, well above the sine's
/// velocity amplitude: the motion never reverses).
pub const TRAVEL_MM_S: f32 = 20.0;
/// The sine's velocity amplitude on a rigid body, mm/s.
pub const VELOCITY_AMPLITUDE_MM_S: f64 = 3.0;
/// The sine's largest torque, as a fraction of the identification's torque cap.
pub const MAX_TORQUE_FRACTION: f64 = 0.5;
/// From arming to the jog's cruise: the brakes open (70 ms), the jog ramps, s.
const START_S: f64 = 0.4;
/// Settling with the sine on, before the measurement: at least this long, s, and
/// [`SETTLE_CYCLES`] cycles (a mode of ζ 0.04 at 35 Hz decays by e in 0.11 s).
const SETTLE_S: f64 = 0.35;
const SETTLE_CYCLES: f64 = 6.0;
/// The measurement: at least this long, s, and [`MEASURE_CYCLES`] whole cycles.
const MEASURE_S: f64 = 0.2;
const MEASURE_CYCLES: f64 = 8.0;
/// The jog is sent again this often (its timeout is 0.3 s), periods.
const JOG_EVERY: u32 = 500;

/// The loop's gain at one frequency.
#[derive(Clone, Copy, Debug)]
pub struct LoopPoint {
    pub freq_hz: f32,
    /// `L(jω)`, real and imaginary.
    pub gain: (f32, f32),
    /// The amplitude of the sine's torque, mN·m.
    pub torque_mnm: f64,
}

/// How one run of the measurement went wrong.
#[derive(Clone, Debug)]
pub struct LoopFailure {
    pub freq_hz: f32,
    pub why: String,
}

/// `n` log-spaced frequencies from `lo_hz` to `hi_hz`.
pub fn log_grid(lo_hz: f32, hi_hz: f32, n: usize) -> Vec<f32> {
    let r = (f64::from(hi_hz) / f64::from(lo_hz)).ln() / (n.max(2) - 1) as f64;
    (0..n)
        .map(|k| (f64::from(lo_hz) * (r * k as f64).exp()) as f32)
        .collect()
}

/// One DFT bin's running sums.
#[derive(Default)]
struct Bin {
    re: f64,
    im: f64,
}

impl Bin {
    fn add(&mut self, x: f64, phase: f64) {
        self.re += x * phase.cos();
        self.im -= x * phase.sin();
    }

    fn over(&self, other: &Bin) -> (f64, f64) {
        let d = other.re * other.re + other.im * other.im;
        (
            (self.re * other.re + self.im * other.im) / d,
            (self.im * other.re - self.re * other.im) / d,
        )
    }
}

/// The loop of `axis` at `freq_hz` with `filters` on the servo's outputs, the axis'
/// inertia `inertia` (mN·m per mm/s², e.g. the one `freqresp` measures) setting the
/// sine's torque. A run that faults or stops is an error naming what happened.
pub fn measure_point(
    base: &RunConfig,
    axis: Axis,
    filters: &[AxisFilterConfig; 3],
    freq_hz: f32,
    inertia: f64,
) -> Result<LoopPoint> {
    let mut cfg = *base;
    cfg.servo.filters = *filters;
    let mut run = super::driven_run(cfg)?;
    let i = axis.index();
    let rate = f64::from(cfg.servo.rate_hz);
    let f = f64::from(freq_hz);
    let w = 2.0 * PI * f / rate;
    let cap = f64::from(cfg.servo.identify.torque_cap_mnm) * MAX_TORQUE_FRACTION;
    let torque = (inertia * 2.0 * PI * f * VELOCITY_AMPLITUDE_MM_S).min(cap);
    let start = (START_S * rate) as u32;
    let settle = (SETTLE_S.max(SETTLE_CYCLES / f) * rate) as u32;
    let measure = ((MEASURE_S.max(MEASURE_CYCLES / f) * f).ceil() / f * rate).round() as u32;
    let delay = cfg.world.imperfections.command_delay_periods == 1;
    let (mut u_bin, mut v_bin) = (Bin::default(), Bin::default());
    let mut prev_u = 0.0;
    let jog = Command::Jog {
        axis,
        vel_mm_s: TRAVEL_MM_S,
    };
    let end = start + settle + measure;
    for k in 0..end {
        let cmds: &[Command] = match k {
            0 => &[Command::Arm],
            _ if k % JOG_EVERY == 1 => std::slice::from_ref(&jog),
            _ => &[],
        };
        let sine = if k >= start {
            let n = f64::from(k - start);
            torque * (w * n).sin()
        } else {
            0.0
        };
        let mut offset = [0.0; 3];
        offset[i] = sine;
        run.world_mut().set_effort_offset(offset);
        let s = *run.control_with(cmds);
        if !matches!(s.state, ServoState::Idle | ServoState::Jog) && k > 0 {
            let why = match run.servo().faults().first() {
                Some(r) => format!(
                    "{:?} fault on {}",
                    r.fault.kind,
                    r.fault.axis.map_or("the system", |a| a.name())
                ),
                None => format!("{:?}", s.state),
            };
            return Err(anyhow!("{why} after {:.3} s", f64::from(k) / rate));
        }
        let u = f64::from(s.effort[i]);
        // what the plant receives this period: the servo's effort (a period late when
        // the amplifier delays it) and the sine
        let applied = if delay { prev_u } else { u };
        prev_u = u;
        if k >= start + settle {
            let phase = w * f64::from(k - start);
            u_bin.add(applied, phase);
            v_bin.add(applied + sine, phase);
        }
        run.finish_period();
    }
    let (re, im) = u_bin.over(&v_bin);
    Ok(LoopPoint {
        freq_hz,
        gain: (-re as f32, -im as f32),
        torque_mnm: torque,
    })
}

/// The loop of `axis` over `grid` (in parallel), with the runs that failed.
pub fn measure(
    base: &RunConfig,
    axis: Axis,
    filters: &[AxisFilterConfig; 3],
    grid: &[f32],
    inertia: f64,
) -> Result<(Vec<LoopPoint>, Vec<LoopFailure>)> {
    let results = crate::jobs::run_all(grid, |f| {
        Ok(
            measure_point(base, axis, filters, *f, inertia).map_err(|e| LoopFailure {
                freq_hz: *f,
                why: format!("{e:#}"),
            }),
        )
    })?;
    let (mut ok, mut failed) = (Vec::new(), Vec::new());
    for r in results {
        match r {
            Ok(p) => ok.push(p),
            Err(e) => failed.push(e),
        }
    }
    Ok((ok, failed))
}
