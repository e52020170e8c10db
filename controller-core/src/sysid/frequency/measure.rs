//! The measurement's state machine ([`ResponseMeasurement`]), one control period at a
//! time: ramp to the travel speed, then for each frequency of the grid, from the highest
//! down, settle and measure with the sine riding on the travel, reversing before the
//! window's turn points, and a stop at the end. From the top down: the first windows,
//! short and of many cycles, ride out the holding loop's start (it learns the friction
//! there) with nothing leaking through their window, and the lowest frequencies, whose
//! two or three cycles would not, come last, when the loop knows the friction of both
//! directions. A reversal into a direction whose friction is not known yet settles as
//! long as the start. The same safety rules as the model identification
//! ([`super::super::identifier`]): zero effort at once on a fault, a non-finite input,
//! a position outside the window or a speed above the limit; a controlled stop when the
//! predicted stopping point leaves the window or the time budget is spent; zero effort
//! when the effort stays at the cap. The output is finite and within the cap whatever
//! the input.

use super::super::identifier::{AbortReason, AxisSample, IdentifyStatus};
use super::super::velocity_loop::{Ramp, RestWatch, VelocityLoop};
use super::config::{ResponseConfig, ResponseConfigError, ValidResponseConfig};
use super::estimate::{Correlator, ResponsePoint};
use super::excitation::{Oscillator, Step};
use crate::Real;

/// `1 - 1/φ` (φ the golden ratio): the fraction of a count the travel advances per period
/// (see [`ResponseMeasurement::new`]).
const GOLDEN_FRACTION: f32 = 0.381_966;
/// Braking gives up (and zeroes the effort) after this long, s.
const BRAKE_TIMEOUT_S: f32 = 1.0;
/// Longest time the effort may stay at the cap, s (the model identification's).
const SATURATION_LIMIT_S: f32 = 0.5;
/// Reaction allowance in the stopping distance, in time constants of the braking loop.
const REACTION_BANDWIDTHS: f32 = 3.0;
/// Seed of the dither's generator (any non-zero value; fixed: runs repeat exactly).
const DITHER_SEED: u32 = 0x9E37_79B9;

/// The command of one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResponseOutput {
    /// Effort to apply this period, finite and within `±torque_cap_mnm`, mN·m.
    pub effort_mnm: f32,
    /// Fraction of the grid measured, 0..=1.
    pub progress: f32,
    pub status: IdentifyStatus,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    /// Ramping to the travel speed (no sine yet).
    Start,
    /// Ramping to the other direction (the sine runs on); `flipped`: the loop's integral
    /// was set to the new direction's friction.
    Reverse {
        flipped: bool,
    },
    Settle {
        left: u32,
    },
    Measure {
        left: u32,
    },
    FinalStop,
    Braking(AbortReason),
    Finished,
}

/// A frequency-response measurement of one axis (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseMeasurement {
    s: ValidResponseConfig,
    /// Periods since start.
    k: u32,
    stage: Stage,
    status: IdentifyStatus,
    vloop: VelocityLoop,
    ramp: Ramp,
    osc: Oscillator,
    /// Travel speed (snapped), mm/s, and direction (±1).
    bias_mm_s: f32,
    dir: f32,
    /// The grid point under way and its schedule.
    point: usize,
    step: Step,
    /// The sine's effort amplitude, mN·m.
    amp_mnm: f32,
    /// Inertia the amplitude and the loop use, mN·m/(mm/s²).
    j_est: f32,
    corr: Correlator,
    /// A finished window waits for its last effort (applied in the period after).
    pending: Option<Step>,
    prev_pos_mm: f32,
    /// `(sin, cos)` of the sine in the previous period, and whether that period's effort
    /// belongs to the window.
    prev_sc: (f32, f32),
    prev_in_window: bool,
    /// Mean effort while travelling forward / backward (friction, load), mN·m.
    friction_mnm: [Option<f32>; 2],
    stage_since: u32,
    saturated_since: Option<u32>,
    rest: RestWatch,
    /// The latest measured point and its index in the grid.
    last: Option<(u8, ResponsePoint)>,
    measured: u8,
    /// The dither's generator (xorshift32).
    rng: u32,
}

impl ResponseMeasurement {
    /// Validate `cfg` and prepare to start from rest at `start_pos_mm` (inside the window
    /// by the edge margin). `count_mm` is the encoder's count length: the travel speed is
    /// moved to the nearest whose advance per period is a whole number of counts plus
    /// [`GOLDEN_FRACTION`] of one, so that the count boundaries fall evenly over the
    /// sine's phases (a whole number of counts per period would read every period at the
    /// same place between two counts: a sine smaller than a count would vanish); 0 keeps
    /// the configured speed.
    pub fn new(
        cfg: &ResponseConfig,
        start_pos_mm: f32,
        count_mm: f32,
    ) -> Result<Self, ResponseConfigError> {
        let s = ValidResponseConfig::new(cfg)?;
        let c = &s.c;
        if !(start_pos_mm >= s.turn_min_mm && start_pos_mm <= s.turn_max_mm) {
            return Err(ResponseConfigError::StartOutsideWindow);
        }
        let per_count = count_mm.div_or(c.period_s, 0.0);
        let bias = if per_count > 0.0 && per_count < c.bias_mm_s {
            let n = libm::roundf(c.bias_mm_s / per_count - GOLDEN_FRACTION).max(0.0);
            (n + GOLDEN_FRACTION) * per_count
        } else {
            c.bias_mm_s
        };
        // towards the farther turn point
        let dir = if s.turn_max_mm - start_pos_mm >= start_pos_mm - s.turn_min_mm {
            1.0
        } else {
            -1.0
        };
        let step = Step::of(&s, 0);
        let first = bias * (bias / c.accel_mm_s2 + step.duration_s(c.period_s, c.start_settle_s))
            + bias * bias / c.accel_mm_s2;
        let room = (s.turn_max_mm - start_pos_mm).max(start_pos_mm - s.turn_min_mm);
        if !(first <= room) {
            return Err(ResponseConfigError::WindowTooShort {
                needed_mm: first,
                usable_mm: room,
            });
        }
        let loop_cap = c.torque_cap_mnm * (1.0 - c.excitation_fraction);
        let mut ramp = Ramp::at_rest();
        ramp.go(dir * bias, c.accel_mm_s2, c.accel_mm_s2);
        let mut m = Self {
            s,
            k: 0,
            stage: Stage::Start,
            status: IdentifyStatus::Running,
            vloop: VelocityLoop::new(
                c.inertia_guess,
                c.loop_bandwidth_rad_s,
                loop_cap,
                c.period_s,
            ),
            ramp,
            osc: Oscillator::new(),
            bias_mm_s: bias,
            dir,
            point: 0,
            step,
            amp_mnm: 0.0,
            j_est: c.inertia_guess,
            corr: Correlator::new(1),
            pending: None,
            prev_pos_mm: start_pos_mm,
            prev_sc: (0.0, 1.0),
            prev_in_window: false,
            friction_mnm: [None; 2],
            stage_since: 0,
            saturated_since: None,
            rest: RestWatch::default(),
            last: None,
            measured: 0,
            rng: DITHER_SEED,
        };
        m.amp_mnm = m.amplitude(step.freq_hz);
        Ok(m)
    }

    /// The travel speed used (after snapping), mm/s.
    pub fn bias_mm_s(&self) -> f32 {
        self.bias_mm_s
    }

    /// The latest measured point and its index in the grid.
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

    /// The inertia measured at the lowest frequency (the guess before), mN·m/(mm/s²).
    pub fn inertia_estimate(&self) -> f32 {
        self.j_est
    }

    fn dt(&self) -> f32 {
        self.s.c.period_s
    }

    fn elapsed_since(&self, k0: u32) -> f32 {
        self.k.saturating_sub(k0) as f32 * self.dt()
    }

    /// The sine's effort amplitude at `freq_hz`: a rigid body's `Ĵ max(a, ω v, ω² x)`,
    /// within the share of the cap the sine may use.
    fn amplitude(&self, freq_hz: f32) -> f32 {
        let c = &self.s.c;
        let w = 2.0 * core::f32::consts::PI * freq_hz;
        let a = c
            .accel_amp_mm_s2
            .max(w * c.vel_amp_mm_s)
            .max(w * w * c.pos_amp_mm);
        (self.j_est * a).min(c.excitation_fraction * c.torque_cap_mnm)
    }

    /// The next dither sample, uniform in `±dither_mnm`.
    fn dither(&mut self) -> f32 {
        let mut x = self.rng;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.rng = x;
        // 24 bits: exact in f32
        let unit = (x >> 8) as f32 * (1.0 / 16_777_216.0);
        (2.0 * unit - 1.0) * self.s.c.dither_mnm
    }

    fn output(&self, effort_mnm: f32) -> ResponseOutput {
        let n = self.s.points as f32;
        ResponseOutput {
            effort_mnm: effort_mnm
                .finite_or_zero()
                .clamp_sym(self.s.c.torque_cap_mnm),
            progress: (f32::from(self.measured) / n).clamp(0.0, 1.0),
            status: self.status,
        }
    }

    fn give_up(&mut self, reason: AbortReason) -> ResponseOutput {
        self.stage = Stage::Finished;
        self.status = IdentifyStatus::Aborted(reason);
        self.output(0.0)
    }

    /// Controlled stop: a predicted window exit brakes at once (setpoint at rest), any
    /// other reason ramps down; the loop brakes at its braking bandwidth.
    fn brake(&mut self, reason: AbortReason, vel_mm_s: f32) {
        if matches!(self.stage, Stage::Braking(_) | Stage::Finished) {
            return;
        }
        let c = self.s.c;
        self.stage = Stage::Braking(reason);
        self.status = IdentifyStatus::Stopping(reason);
        self.stage_since = self.k;
        self.rest.reset();
        self.pending = None;
        self.prev_in_window = false;
        self.vloop = VelocityLoop::new(
            self.j_est,
            c.brake_bandwidth_rad_s,
            c.torque_cap_mnm,
            c.period_s,
        );
        if reason == AbortReason::WouldLeaveWindow {
            self.ramp = Ramp::at_rest();
        } else {
            self.ramp.v_mm_s = vel_mm_s;
            self.ramp.go(0.0, c.accel_mm_s2, c.accel_mm_s2);
        }
    }

    /// Distance to stop from `v` at the ramps' deceleration plus the braking loop's lag.
    fn stop_distance(&self, v: f32) -> f32 {
        let c = &self.s.c;
        let v = v.abs();
        v * v / (2.0 * c.accel_mm_s2)
            + v * (REACTION_BANDWIDTHS / c.brake_bandwidth_rad_s + 2.0 * c.period_s)
    }

    fn room(&self, dir: f32, pos: f32) -> f32 {
        if dir > 0.0 {
            self.s.turn_max_mm - pos
        } else {
            pos - self.s.turn_min_mm
        }
    }

    /// One control period: this period's measurement in, this period's effort out.
    pub fn step(&mut self, m: &AxisSample) -> ResponseOutput {
        if self.stage == Stage::Finished {
            return self.output(0.0);
        }
        self.k = self.k.saturating_add(1);
        let c = self.s.c;
        let limits = [c.window_min_mm, c.window_max_mm, c.velocity_limit_mm_s];
        if let Some(r) = m.abort_reason(m.effort_applied_mnm, limits) {
            return self.give_up(r);
        }
        if !matches!(self.stage, Stage::Braking(_)) {
            let stop = m.pos_mm + m.vel_mm_s.sign() * self.stop_distance(m.vel_mm_s);
            if self.elapsed_since(0) > c.time_budget_s {
                self.brake(AbortReason::TimeBudget, m.vel_mm_s);
            } else if !(stop >= c.window_min_mm && stop <= c.window_max_mm) {
                self.brake(AbortReason::WouldLeaveWindow, m.vel_mm_s);
            }
        }
        self.correlate(m);
        let sc = self.osc.advance();
        self.advance(m, sc);
        if self.stage == Stage::Finished {
            return self.output(0.0);
        }
        let ff = self.j_est * self.ramp.a_mm_s2;
        let mut u = self.vloop.step(self.ramp.v_mm_s, m.vel_mm_s, ff);
        let exciting = matches!(
            self.stage,
            Stage::Reverse { .. } | Stage::Settle { .. } | Stage::Measure { .. }
        );
        if exciting {
            u += self.amp_mnm * sc.0 + self.dither();
        }
        self.prev_sc = sc;
        self.prev_pos_mm = m.pos_mm;
        if u.abs() >= c.torque_cap_mnm {
            let since = *self.saturated_since.get_or_insert(self.k);
            if self.elapsed_since(since) >= SATURATION_LIMIT_S {
                return self.give_up(AbortReason::Saturated);
            }
        } else {
            self.saturated_since = None;
        }
        self.output(u)
    }

    /// The previous period's effort into the window's sums, and a finished window's
    /// point once its last effort is in.
    fn correlate(&mut self, m: &AxisSample) {
        if self.prev_in_window {
            self.corr.add_effort(m.effort_applied_mnm, self.prev_sc);
            self.prev_in_window = false;
        }
        if let Some(step) = self.pending.take() {
            self.finish_point(&step);
        }
    }

    /// The point of the window just completed: its response, the friction of the
    /// direction, the inertia (lowest frequency), the next frequency's amplitude.
    fn finish_point(&mut self, step: &Step) {
        let c = self.s.c;
        let idx = self.point.saturating_sub(1);
        if let Some(p) = self.corr.response(step.freq_hz, c.period_s) {
            self.last = Some((idx.min(usize::from(u8::MAX)) as u8, p));
            self.measured = self.measured.saturating_add(1);
            if idx == 0 {
                // the amplitude's inertia from the first (highest) frequency: above the
                // modes, the motor side's (at most the frame's share low, ~10 % on the
                // gantry: a little less amplitude than planned)
                self.j_est = p.mass_inertia(c.inertia_guess);
                self.vloop.retune(self.j_est);
            }
        }
        let d = if self.dir > 0.0 { 0 } else { 1 };
        if let Some(f) = self.friction_mnm.get_mut(d) {
            *f = Some(self.corr.mean_effort());
        }
        self.amp_mnm = self.amplitude(self.step.freq_hz);
    }

    fn advance(&mut self, m: &AxisSample, sc: (f32, f32)) {
        self.ramp.step(self.dt());
        match self.stage {
            Stage::Start => {
                if self.ramp.reached() {
                    self.begin_point(self.s.c.start_settle_s);
                }
            }
            Stage::Reverse { flipped } => {
                // the friction changes sides as the motion reverses: so does the
                // integral that carried it
                if !flipped && self.ramp.v_mm_s * self.dir <= 0.0 {
                    // (the settling after it is longer while that friction is unknown)
                    let d = if self.dir > 0.0 { 1 } else { 0 };
                    let next = match self.friction_mnm.get(d).copied().flatten() {
                        Some(f) => f,
                        None => -self.vloop.integral_mnm(),
                    };
                    self.vloop.set_integral_mnm(next);
                    self.stage = Stage::Reverse { flipped: true };
                }
                if self.ramp.reached() {
                    let settle = self.reverse_settle_s(-self.dir);
                    self.dir = -self.dir;
                    self.begin_point(settle);
                }
            }
            Stage::Settle { left } => {
                if left <= 1 {
                    self.corr = Correlator::new(self.step.measure_periods);
                    self.stage = Stage::Measure {
                        left: self.step.measure_periods,
                    };
                    self.measure(m, sc);
                } else {
                    self.stage = Stage::Settle { left: left - 1 };
                }
            }
            Stage::Measure { .. } => self.measure(m, sc),
            Stage::FinalStop => {
                if self.is_stopped(m) {
                    self.stage = Stage::Finished;
                    self.status = IdentifyStatus::Done;
                }
            }
            Stage::Braking(reason) => {
                if self.is_stopped(m) || self.elapsed_since(self.stage_since) > BRAKE_TIMEOUT_S {
                    self.stage = Stage::Finished;
                    self.status = IdentifyStatus::Aborted(reason);
                }
            }
            Stage::Finished => {}
        }
    }

    /// One period of a window: the position's step with this period's sine; at the
    /// window's end the next frequency (its point is finished next period).
    fn measure(&mut self, m: &AxisSample, sc: (f32, f32)) {
        let Stage::Measure { left } = self.stage else {
            return;
        };
        self.corr.add_step(m.pos_mm - self.prev_pos_mm, sc);
        self.prev_in_window = true;
        if left > 1 {
            self.stage = Stage::Measure { left: left - 1 };
            return;
        }
        self.pending = Some(self.step);
        self.point += 1;
        if self.point >= self.s.points {
            self.stage = Stage::FinalStop;
            self.ramp
                .go(0.0, self.s.c.accel_mm_s2, self.s.c.accel_mm_s2);
            self.rest.reset();
            return;
        }
        self.step = Step::of(&self.s, self.point);
        let c = &self.s.c;
        let need = self.bias_mm_s
            * self
                .step
                .duration_s(c.period_s, self.reverse_settle_s(-self.dir))
            + self.stop_distance(self.bias_mm_s);
        if self.room(self.dir, m.pos_mm) < need {
            self.ramp
                .go(-self.dir * self.bias_mm_s, c.accel_mm_s2, c.accel_mm_s2);
            self.stage = Stage::Reverse { flipped: false };
            self.osc.set_freq(self.step.freq_hz, c.period_s);
        } else {
            self.begin_point(0.0);
        }
    }

    /// The settling after a reversal into `dir`: the start's while that direction's
    /// friction is unknown (the loop learns it as at the start).
    fn reverse_settle_s(&self, dir: f32) -> f32 {
        let d = if dir > 0.0 { 0 } else { 1 };
        match self.friction_mnm.get(d).copied().flatten() {
            Some(_) => self.s.c.reverse_settle_s,
            None => self.s.c.start_settle_s.max(self.s.c.reverse_settle_s),
        }
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
