//! The open loop of one axis measured on the running machine ([`LoopMeasurement`]), the
//! way a drive's machine analyser measures it: the axis runs on its own laws, estimators
//! and output filters, following a reference that travels back and forth inside the
//! window, and a sine `d` is added to the effort the servo sends. With `u` the laws'
//! effort and `v = u + d` what the amplifier receives,
//!
//! ```text
//! u = -L v   =>   L(jω) = -U(jω) / V(jω)
//! ```
//!
//! whatever the law: a sliding-mode law has no transfer function, and this is its
//! describing function at the measured amplitude, the loop's own one-period delay and the
//! amplifier's included. The margins of [`crate::filter::margins_of_samples`] are read
//! from it, and a filter is accepted on them (`gantry tune`).
//!
//! The schedule is the stepped sine's ([`super::measure`]): the same grid, the highest
//! frequency first, each settled and then measured over whole cycles, one Hann-windowed
//! DFT bin of `u` and of `v` (no storage of samples); the travel reverses between two
//! frequencies. The travel (the reference's, [`LOOP_DEFAULTS`]) is well above the
//! sine's velocity amplitude, so the motion never reverses inside a measurement and the
//! friction is a constant force. The sine's amplitude is a rigid body's `Ĵ ω v` for a
//! velocity amplitude `v`, at most `excitation_fraction` of the torque cap; `Ĵ` is the
//! identification's inertia guess until the first (highest) frequency measures it from
//! the plant's response `X/V` (what the plant receives is known, so the plant's response
//! comes with the loop's).
//!
//! Safety: the rules of the identification where the law does not already hold the axis:
//! the outputs off at once (the run aborted) on a fault, a non-finite input, a position
//! outside the window, a speed above the limit, or the laws' effort above the torque cap
//! for [`SATURATION_LIMIT_S`]; the reference ramps to rest when the time budget is spent.
//! The reference itself never leaves the window's turn points.

use super::super::identifier::{AbortReason, AxisSample, IdentifyStatus};
use super::super::velocity_loop::{Ramp, RestWatch};
use super::config::{ResponseConfig, ResponseConfigError, ValidResponseConfig, RESPONSE_DEFAULTS};
use super::estimate::{Correlator, ResponsePoint};
use super::excitation::{Oscillator, Step};
use super::measure::ResponseOutput;
use crate::sysid::IdentifyConfig;
use crate::Real;

/// The loop measurement's defaults (those the identification's window, cap, speed limit
/// and inertia guess do not set: [`ResponseConfig::loop_from_identify`]):
/// - 48 frequencies from 5 to 400 Hz: the crossover (40-60 Hz on the gantry), the lower
///   phase crossing of a law with an integral term below it, the upper one above;
/// - travel 15 mm/s, a sine of 3 mm/s velocity amplitude (the simulated study's,
///   host-sim `studies::loop_response`): above the Stribeck region and never reversing;
/// - settled at least 0.35 s and 6 cycles, measured at least 0.2 s and 8 cycles (a mode
///   of ζ 0.04 at 35 Hz decays by e in 0.11 s);
/// - no dither (the laws' own noise is enough to even out the counts).
pub const LOOP_DEFAULTS: ResponseConfig = ResponseConfig {
    freq_min_hz: 5.0,
    freq_max_hz: 400.0,
    points: 48,
    bias_mm_s: 15.0,
    accel_amp_mm_s2: 1.0,
    vel_amp_mm_s: 3.0,
    pos_amp_mm: 0.0,
    dither_mnm: 0.0,
    settle_cycles: 6.0,
    settle_min_s: 0.35,
    settle_max_s: 1.2,
    reverse_settle_s: 0.4,
    start_settle_s: 0.6,
    measure_s: 0.2,
    measure_min_cycles: 8,
    ..RESPONSE_DEFAULTS
};

/// Longest time the laws' effort may stay at the torque cap, s (the identification's).
pub const SATURATION_LIMIT_S: f32 = 0.5;
/// Stopping gives up waiting after this long, s.
const STOP_TIMEOUT_S: f32 = 1.0;

impl ResponseConfig {
    /// The loop measurement's configuration: the identification's window, torque cap,
    /// speed limit and inertia guess, [`LOOP_DEFAULTS`] for the rest.
    pub fn loop_from_identify(c: &IdentifyConfig) -> Self {
        Self::from_identify_over(c, &LOOP_DEFAULTS)
    }
}

/// The reference the axis follows this period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopReference {
    pub pos_mm: f32,
    pub vel_mm_s: f32,
    pub acc_mm_s2: f32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Start,
    /// Travelling on to the turn point (the next frequency fits neither ahead nor
    /// behind), then reversing.
    ToTurn,
    Reverse,
    Settle {
        left: u32,
    },
    Measure {
        left: u32,
    },
    /// Ramping to rest: at the end (`None`) or after an abort reason that allows it.
    Stop(Option<AbortReason>),
    Finished,
}

/// A loop measurement of one axis (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct LoopMeasurement {
    s: ValidResponseConfig,
    k: u32,
    stage: Stage,
    status: IdentifyStatus,
    ramp: Ramp,
    /// The reference position and its rounding's compensation (Kahan), mm.
    pos_mm: f32,
    pos_c: f32,
    dir: f32,
    osc: Oscillator,
    point: usize,
    step: Step,
    amp_mnm: f32,
    j_est: f32,
    /// `u` (the laws') and `v` (applied, with the position's steps: the plant's response).
    u_corr: Correlator,
    v_corr: Correlator,
    prev_pos_mm: f32,
    stage_since: u32,
    saturated_since: Option<u32>,
    rest: RestWatch,
    last: Option<(u8, ResponsePoint)>,
    measured: u8,
}

impl LoopMeasurement {
    /// Validate `cfg` and prepare to start from rest at `start_pos_mm` (inside the
    /// window's turn points), travelling towards the farther one.
    pub fn new(cfg: &ResponseConfig, start_pos_mm: f32) -> Result<Self, ResponseConfigError> {
        let s = ValidResponseConfig::new(cfg)?;
        if !(start_pos_mm >= s.turn_min_mm && start_pos_mm <= s.turn_max_mm) {
            return Err(ResponseConfigError::StartOutsideWindow);
        }
        let c = s.c;
        let dir = if s.turn_max_mm - start_pos_mm >= start_pos_mm - s.turn_min_mm {
            1.0
        } else {
            -1.0
        };
        let step = Step::of(&s, 0);
        let mut m = Self {
            s,
            k: 0,
            stage: Stage::Start,
            status: IdentifyStatus::Running,
            ramp: Ramp::at_rest(),
            pos_mm: start_pos_mm,
            pos_c: 0.0,
            dir,
            osc: Oscillator::new(),
            point: 0,
            step,
            amp_mnm: 0.0,
            j_est: c.inertia_guess,
            u_corr: Correlator::new(1),
            v_corr: Correlator::new(1),
            prev_pos_mm: start_pos_mm,
            stage_since: 0,
            saturated_since: None,
            rest: RestWatch::default(),
            last: None,
            measured: 0,
        };
        let need = m.leg_mm(c.start_settle_s);
        if !(m.room(start_pos_mm) >= need) {
            return Err(ResponseConfigError::WindowTooShort {
                needed_mm: need,
                usable_mm: m.room(start_pos_mm),
            });
        }
        m.ramp.go(dir * c.bias_mm_s, c.accel_mm_s2, c.accel_mm_s2);
        m.amp_mnm = m.amplitude(step.freq_hz);
        Ok(m)
    }

    /// The reference of this period (before [`Self::step`]).
    pub fn reference(&self) -> LoopReference {
        LoopReference {
            pos_mm: self.pos_mm,
            vel_mm_s: self.ramp.v_mm_s,
            acc_mm_s2: self.ramp.a_mm_s2,
        }
    }

    /// The latest measured point (`L(jω)`) and its index in the grid.
    pub fn last_point(&self) -> Option<(u8, ResponsePoint)> {
        self.last
    }

    /// Points measured so far.
    pub fn measured(&self) -> u8 {
        self.measured
    }

    pub fn status(&self) -> IdentifyStatus {
        self.status
    }

    /// The inertia measured at the highest frequency (the guess before), mN·m/(mm/s²).
    pub fn inertia_estimate(&self) -> f32 {
        self.j_est
    }

    fn elapsed_since(&self, k0: u32) -> f32 {
        self.k.saturating_sub(k0) as f32 * self.s.c.period_s
    }

    /// The sine's amplitude at `freq_hz`: `Ĵ ω v`, within the cap's share.
    fn amplitude(&self, freq_hz: f32) -> f32 {
        let c = &self.s.c;
        let w = 2.0 * core::f32::consts::PI * freq_hz;
        (self.j_est * (w * c.vel_amp_mm_s).max(c.accel_amp_mm_s2))
            .min(c.excitation_fraction * c.torque_cap_mnm)
    }

    /// Room ahead of `pos` in the travel's direction, to the turn point, mm.
    fn room(&self, pos: f32) -> f32 {
        if self.dir > 0.0 {
            self.s.turn_max_mm - pos
        } else {
            pos - self.s.turn_min_mm
        }
    }

    /// Room behind `pos`, to the other turn point, mm.
    fn room_behind(&self, pos: f32) -> f32 {
        self.s.turn_max_mm - self.s.turn_min_mm - self.room(pos)
    }

    /// The distance a reversal or a stop takes, mm.
    fn stop_mm(&self) -> f32 {
        let c = &self.s.c;
        c.bias_mm_s * c.bias_mm_s / (2.0 * c.accel_mm_s2)
    }

    /// The travel the current frequency needs after a settling of at least `settle_s`,
    /// with the stop after it, mm.
    fn leg_mm(&self, settle_s: f32) -> f32 {
        let c = &self.s.c;
        let v = c.bias_mm_s;
        v * self.step.duration_s(c.period_s, settle_s) + v * v / c.accel_mm_s2
    }

    fn output(&self, effort_mnm: f32) -> ResponseOutput {
        ResponseOutput {
            effort_mnm: effort_mnm.finite_or_zero(),
            progress: (f32::from(self.measured) / self.s.points as f32).clamp(0.0, 1.0),
            status: self.status,
        }
    }

    /// Aborted: the outputs go off at once (the laws' effort too).
    fn give_up(&mut self, reason: AbortReason) -> ResponseOutput {
        self.stage = Stage::Finished;
        self.status = IdentifyStatus::Aborted(reason);
        self.output(0.0)
    }

    /// One control period: the measurement and the laws' effort `law_mnm` in, the effort
    /// to apply out (the laws' plus the sine); the reference moves on to the next
    /// period's.
    pub fn step(&mut self, m: &AxisSample, law_mnm: f32) -> ResponseOutput {
        if self.stage == Stage::Finished {
            return self.output(0.0);
        }
        self.k = self.k.saturating_add(1);
        let c = self.s.c;
        let limits = [c.window_min_mm, c.window_max_mm, c.velocity_limit_mm_s];
        if let Some(r) = m.abort_reason(law_mnm, limits) {
            return self.give_up(r);
        }
        if law_mnm.abs() >= c.torque_cap_mnm {
            let since = *self.saturated_since.get_or_insert(self.k);
            if self.elapsed_since(since) >= SATURATION_LIMIT_S {
                return self.give_up(AbortReason::Saturated);
            }
        } else {
            self.saturated_since = None;
        }
        if self.elapsed_since(0) > c.time_budget_s && !matches!(self.stage, Stage::Stop(_)) {
            self.stop(Some(AbortReason::TimeBudget));
        }
        let sc = self.osc.advance();
        let exciting = matches!(
            self.stage,
            Stage::ToTurn | Stage::Reverse | Stage::Settle { .. } | Stage::Measure { .. }
        );
        let v = if exciting {
            law_mnm + self.amp_mnm * sc.0
        } else {
            law_mnm
        };
        self.advance(m, law_mnm, v, sc);
        self.prev_pos_mm = m.pos_mm;
        self.move_reference();
        if self.stage == Stage::Finished {
            return self.output(law_mnm);
        }
        self.output(v)
    }

    /// The reference's next period: the ramp's velocity integrated (trapezoid).
    fn move_reference(&mut self) {
        let t = self.s.c.period_s;
        let v0 = self.ramp.v_mm_s;
        self.ramp.step(t);
        let dx = 0.5 * (v0 + self.ramp.v_mm_s) * t - self.pos_c;
        let next = self.pos_mm + dx;
        self.pos_c = (next - self.pos_mm) - dx;
        self.pos_mm = next;
    }

    /// Ramp the reference to rest (`why`: the abort reason, none at the end).
    fn stop(&mut self, why: Option<AbortReason>) {
        let a = self.s.c.accel_mm_s2;
        self.stage = Stage::Stop(why);
        if let Some(r) = why {
            self.status = IdentifyStatus::Stopping(r);
        }
        self.stage_since = self.k;
        self.rest.reset();
        self.ramp.go(0.0, a, a);
    }

    fn advance(&mut self, m: &AxisSample, u: f32, v: f32, sc: (f32, f32)) {
        match self.stage {
            Stage::Start => {
                if self.ramp.reached() {
                    self.begin_point(self.s.c.start_settle_s);
                }
            }
            Stage::ToTurn => {
                if self.room(self.pos_mm) <= self.stop_mm() {
                    self.reverse();
                }
            }
            Stage::Reverse => {
                if self.ramp.reached() {
                    self.dir = -self.dir;
                    self.begin_point(self.s.c.reverse_settle_s);
                }
            }
            Stage::Settle { left } => {
                self.stage = if left <= 1 {
                    self.u_corr = Correlator::new(self.step.measure_periods);
                    self.v_corr = Correlator::new(self.step.measure_periods);
                    Stage::Measure {
                        left: self.step.measure_periods,
                    }
                } else {
                    Stage::Settle { left: left - 1 }
                };
            }
            Stage::Measure { left } => {
                self.u_corr.add_effort(u, sc);
                self.v_corr.add_effort(v, sc);
                self.v_corr.add_step(m.pos_mm - self.prev_pos_mm, sc);
                if left > 1 {
                    self.stage = Stage::Measure { left: left - 1 };
                } else {
                    self.finish_point();
                    self.next_point();
                }
            }
            Stage::Stop(why) => {
                let timed_out = self.elapsed_since(self.stage_since) > STOP_TIMEOUT_S;
                if self.is_stopped(m) || timed_out {
                    self.stage = Stage::Finished;
                    self.status = match why {
                        Some(r) => IdentifyStatus::Aborted(r),
                        None => IdentifyStatus::Done,
                    };
                }
            }
            Stage::Finished => {}
        }
    }

    /// The point of the window just completed: `L = -U/V`; at the highest frequency the
    /// inertia from the plant's `X/V`.
    fn finish_point(&mut self) {
        let c = self.s.c;
        let (ur, ui) = self.u_corr.effort_bin();
        let (vr, vi) = self.v_corr.effort_bin();
        let vv = vr * vr + vi * vi;
        if vv > 0.0 {
            let p = ResponsePoint {
                freq_hz: self.step.freq_hz,
                re: -(ur * vr + ui * vi) / vv,
                im: -(ui * vr - ur * vi) / vv,
            };
            if p.re.is_finite() && p.im.is_finite() {
                self.last = Some((self.point.min(usize::from(u8::MAX)) as u8, p));
                self.measured = self.measured.saturating_add(1);
            }
        }
        if self.point == 0 {
            if let Some(p) = self.v_corr.response(self.step.freq_hz, c.period_s) {
                self.j_est = p.mass_inertia(c.inertia_guess);
            }
        }
    }

    /// The next frequency: settled here when its travel fits ahead; else after a
    /// reversal here when it fits behind, or at the turn point (the validated window
    /// holds the longest travel between the turn points); the stop after the last.
    fn next_point(&mut self) {
        self.point += 1;
        if self.point >= self.s.points {
            self.stop(None);
            return;
        }
        let c = self.s.c;
        self.step = Step::of(&self.s, self.point);
        self.amp_mnm = self.amplitude(self.step.freq_hz);
        self.osc.set_freq(self.step.freq_hz, c.period_s);
        let (pos, stop) = (self.pos_mm, self.stop_mm());
        if self.room(pos) >= self.leg_mm(0.0) {
            self.begin_point(0.0);
        } else if self.room_behind(pos) - 2.0 * stop >= self.leg_mm(c.reverse_settle_s) {
            self.reverse();
        } else {
            self.stage = Stage::ToTurn;
        }
    }

    /// Ramp to the travel's other direction.
    fn reverse(&mut self) {
        let c = self.s.c;
        self.ramp
            .go(-self.dir * c.bias_mm_s, c.accel_mm_s2, c.accel_mm_s2);
        self.stage = Stage::Reverse;
    }

    /// Settle at the current frequency, at least `min_s` (after a start or a reversal).
    fn begin_point(&mut self, min_s: f32) {
        let t = self.s.c.period_s;
        self.osc.set_freq(self.step.freq_hz, t);
        self.stage = Stage::Settle {
            left: self.step.settle_after(min_s, t),
        };
    }

    /// The setpoint is at rest and the axis has stayed so ([`RestWatch`]).
    fn is_stopped(&mut self, m: &AxisSample) -> bool {
        self.rest
            .stopped(&self.ramp, m.vel_mm_s, self.k, self.s.c.period_s)
    }
}
