//! The identification state machine of one axis, run once per control period.
//!
//! Phases (equations and reasoning in docs/identification.md):
//!
//! 1. **Friction passes.** The velocity loop holds `pass_speed_count` speeds, each once
//!    forward and once backward, reversing before the window's turn points. The motion is
//!    cut into contiguous *integration windows*: the steady part of each pass, and the
//!    transition (reversal) between two steady parts.
//! 2. **Inertia.** In one direction at a time the speed alternates between a low and a
//!    high plateau with the strongest acceleration the cap allows; each ramp plus the
//!    following plateau is a window. Staying in one direction keeps the friction on one
//!    Coulomb level (no reversal, no Stribeck region), and accelerating and decelerating
//!    windows at the same mean speed make the friction cancel from the inertia estimate.
//! 3. **Validation.** A sinusoidal velocity move, not used for fitting; the model's
//!    prediction of the mean effort of each short window is compared with the applied
//!    effort: NRMSE and R².
//!
//! Every window gives one row of the integrated equation of motion, divided by the
//! window length `T`:
//!
//! ```text
//! J (v(t2) - v(t1))/T + B (x(t2) - x(t1))/T + f+ T+/T + f- T-/T = (1/T) ∫ u dt
//! ```
//!
//! so the velocity is never differentiated (only its two end values enter, at plateaus
//! where the estimator does not lag), the mean velocity comes from positions (counts,
//! exact), and the effort enters as its integral. Phase 1's rows (all of them) give a
//! first model that tunes phase 2; the final model is the least-squares fit of the steady
//! rows of phase 1 and the rows of phase 2. Reversal windows are left out of the final fit
//! because they cross the Stribeck region, which the model does not contain.
//!
//! Per period the work is bounded and small: a few running sums, the PI loop, the
//! planner's comparisons; at a window's end one row is added to 4×4 normal equations;
//! at a phase's end one 4×4 solve (see [`super::lsq`]). No allocation, no panics; the
//! output is finite and within `±torque_cap_mnm` whatever the input.

use super::config::{IdentifyConfig, IdentifyConfigError, ValidIdentifyConfig};
use super::lsq::{LsError, LsSolution, NormalEquations};
use super::velocity_loop::{Ramp, VelocityLoop, STOPPED_MM_S, STOP_HOLD_S};
use crate::plant::AxisModel;
use crate::Real;

/// What the board measures of one axis in one period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisSample {
    /// Position from the encoder counts, mm.
    pub pos_mm: f32,
    /// Velocity estimate (PLL / Kalman of [`crate::estimator`]), mm/s.
    pub vel_mm_s: f32,
    /// Effort applied over the period that just ended: what the identifier commanded last
    /// period after any clamp the caller applied, mN·m.
    pub effort_applied_mnm: f32,
    /// Any fault the servo's safety state machine holds (watchdog, amplifier, limit switch, estop...).
    pub fault: bool,
}

impl AxisSample {
    /// The identifications' rules for stopping the effort at once, on this sample and the
    /// effort `effort_mnm` it is checked with: the caller's fault flag, a non-finite
    /// value, the position outside `[window_min_mm, window_max_mm]`, the speed above
    /// `velocity_limit_mm_s` (`limits` in that order).
    pub(crate) fn abort_reason(&self, effort_mnm: f32, limits: [f32; 3]) -> Option<AbortReason> {
        let [lo, hi, vlim] = limits;
        if self.fault {
            Some(AbortReason::Fault)
        } else if !(self.pos_mm.is_finite() && self.vel_mm_s.is_finite() && effort_mnm.is_finite())
        {
            Some(AbortReason::NonFiniteInput)
        } else if !(self.pos_mm >= lo && self.pos_mm <= hi) {
            Some(AbortReason::LeftWindow)
        } else if !(self.vel_mm_s.abs() <= vlim) {
            Some(AbortReason::VelocityLimit)
        } else {
            None
        }
    }
}

/// Which part of the procedure is running.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentifyPhase {
    FrictionPasses,
    Inertia,
    Validation,
    /// A frequency-response measurement ([`super::frequency`]) under way.
    FrequencyResponse,
    /// Braking to rest after an abort reason that allows a controlled stop.
    Stopping,
    Done,
    Aborted,
}

/// Which fit failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitStage {
    /// The first model from all rows of the friction passes.
    FrictionPasses,
    /// The final model (steady rows + inertia rows).
    Final,
}

/// Why identification stopped early.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AbortReason {
    /// The caller's fault flag (zero effort at once).
    Fault,
    /// A non-finite position, velocity or effort (zero effort at once).
    NonFiniteInput,
    /// The measured position is outside the window (zero effort at once).
    LeftWindow,
    /// |velocity| above `velocity_limit_mm_s` (zero effort at once).
    VelocityLimit,
    /// The predicted stopping point lies outside the window (braked to rest with the
    /// whole cap first).
    WouldLeaveWindow,
    /// `time_budget_s` exceeded (braked to rest first).
    TimeBudget,
    /// A least-squares solve failed: not enough excitation or collinear data.
    FitFailed { stage: FitStage, error: LsError },
    /// The fit gave a model that cannot be physical (inertia <= 0, f+ < f-, not finite).
    ImplausibleModel { stage: FitStage },
    /// Friction leaves no torque for accelerating within the cap.
    NoTorqueMargin,
    /// The window is too short for the inertia or validation move.
    WindowTooShort,
    /// The effort has been at the cap for [`SATURATION_LIMIT_S`]: the axis does not
    /// follow (blocked, friction above the cap, or an encoder or amplifier fault, in
    /// which case the window check could not see a runaway). Zero effort at once.
    Saturated,
}

/// Overall state for the caller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentifyStatus {
    Running,
    /// Braking to rest; becomes `Aborted` with the same reason once stopped.
    Stopping(AbortReason),
    /// Finished; [`Identifier::result`] holds the model.
    Done,
    Aborted(AbortReason),
}

/// The command of one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyOutput {
    /// Effort to apply this period, finite and within `±torque_cap_mnm`, mN·m.
    pub effort_mnm: f32,
    pub phase: IdentifyPhase,
    /// Fraction of the procedure done, 0..=1.
    pub progress: f32,
    pub status: IdentifyStatus,
}

/// Quality of one identified parameter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ParamDiagnostic {
    /// Value fitted (before the viscous term's clamp at zero).
    pub value: f32,
    /// One-sigma standard error from the fit's residuals (same unit as the value).
    pub std_error: f32,
    /// Windows (rows) that excite the parameter.
    pub rows: u32,
    /// Control periods in those windows.
    pub samples: u32,
}

/// Figures of the final least-squares fit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FitDiagnostics {
    pub inertia: ParamDiagnostic,
    pub viscous: ParamDiagnostic,
    pub coulomb_pos: ParamDiagnostic,
    pub coulomb_neg: ParamDiagnostic,
    /// Duration-weighted RMS of the windows' mean-effort residuals, mN·m.
    pub residual_rms_mnm: f32,
    /// Windows in the fit.
    pub rows: u32,
    /// Smallest equilibrated Cholesky pivot (1 = orthogonal data, see [`super::lsq`]).
    pub min_pivot: f32,
}

/// Everything identification found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyResult {
    /// The identified model (constant load folded into the Coulomb terms).
    pub model: AxisModel,
    /// Validation: RMS of (measured - predicted) window-mean effort over the range
    /// (max - min) of the measured values.
    pub nrmse: f32,
    /// Validation: `1 - SS_res/SS_tot` of the window-mean efforts.
    pub r2: f32,
    /// Validation windows compared.
    pub validation_windows: u32,
    pub fit: FitDiagnostics,
    /// The first model, from the friction passes alone (tuned the inertia phase).
    pub passes_model: AxisModel,
    /// Machine time from start to rest at the end, s.
    pub machine_time_s: f32,
}

/// Weight-1 window duration: rows are weighted by their duration over 0.1 s (inverse
/// variance weighting of a mean over `T` of white noise).
const ROW_WEIGHT_REF_S: f32 = 0.1;
/// Braking gives up (and zeroes the effort) after this long, s.
const BRAKE_TIMEOUT_S: f32 = 1.0;
/// A steady window shorter than this fraction of `steady_s` is not used as a friction row.
const MIN_STEADY_FRACTION: f32 = 0.5;
/// Velocity error (mm/s, plus [`SETTLE_TOL_FRACTION`] of the speed) the loop must stay
/// within for `settle_s` before a steady window starts. A window that starts while the
/// axis still accelerates at `A` begins with the estimator's lag `2A/ω_pll` in its
/// velocity, which the window's inertia term turns into an effort error `J·lag/T`;
/// within 0.5 mm/s at a crossover of ~150 rad/s the acceleration left is below ~75 mm/s²,
/// i.e. a lag below 0.25 mm/s on the 100 Hz PLL. The PLL's noise is ~0.05 mm/s.
const SETTLE_TOL_MM_S: f32 = 0.5;
/// See [`SETTLE_TOL_MM_S`].
const SETTLE_TOL_FRACTION: f32 = 0.01;
/// A pass whose loop has not settled after this many `settle_s` records anyway (the
/// integrated rows stay valid, only less accurate).
const SETTLE_TIMEOUT_FACTOR: f32 = 6.0;
/// Longest time the effort may stay at the cap, s. Planned motion uses at most
/// `torque_fraction` of the cap; the loop saturates only briefly (a ramp planned with a
/// too small inertia guess: tens of milliseconds).
pub const SATURATION_LIMIT_S: f32 = 0.5;
/// A clipped pass speed must exceed the one before by this factor, else the passes end
/// (a repeated speed adds no information on the viscous slope).
const MIN_SPEED_STEP: f32 = 1.1;
/// Reaction allowance in the stopping distance: the loop lags its setpoint by about
/// `1/ω` while braking; `3/ω` covers a loop three times slower than designed.
const REACTION_BANDWIDTHS: f32 = 3.0;
/// The rough inertia from one reversal is trusted for the velocity loop only within this
/// factor of the guess.
const ROUGH_J_RANGE: f32 = 25.0;
/// Most halvings of the inertia phase's high speed when its cycle does not fit.
const MAX_SPEED_REDUCTIONS: u32 = 12;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RowKind {
    /// Not used (starts from rest, partial windows, reversals of phase 2).
    Discard,
    /// A reversal of phase 1 (first model only).
    Transition,
    /// The steady part of a pass.
    Steady,
    /// One ramp + plateau of phase 2.
    Inertia,
    /// A validation window.
    Validation,
}

/// Running integrals of one window.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Window {
    kind: RowKind,
    n: u32,
    n_pos: u32,
    n_neg: u32,
    /// Σ u with Neumaier compensation (long windows hold thousands of samples).
    u_sum: f32,
    u_comp: f32,
    v0: f32,
    p0: f32,
}

/// One row: `x = [Δv/T, Δx/T, T+/T, T-/T]`, `y` = mean effort.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Row {
    x: [f32; 4],
    y: f32,
    w: f32,
    n: u32,
    n_pos: u32,
    n_neg: u32,
}

impl Window {
    fn open(kind: RowKind, v: f32, p: f32) -> Self {
        Self {
            kind,
            n: 0,
            n_pos: 0,
            n_neg: 0,
            u_sum: 0.0,
            u_comp: 0.0,
            v0: v,
            p0: p,
        }
    }

    fn add(&mut self, u: f32, v: f32) {
        let t = self.u_sum + u;
        if self.u_sum.abs() >= u.abs() {
            self.u_comp += (self.u_sum - t) + u;
        } else {
            self.u_comp += (u - t) + self.u_sum;
        }
        self.u_sum = t;
        self.n = self.n.saturating_add(1);
        if v > 0.0 {
            self.n_pos = self.n_pos.saturating_add(1);
        } else if v < 0.0 {
            self.n_neg = self.n_neg.saturating_add(1);
        }
    }

    fn row(&self, v: f32, p: f32, period_s: f32) -> Option<Row> {
        if self.n == 0 {
            return None;
        }
        let n = self.n as f32;
        let t = n * period_s;
        Some(Row {
            x: [
                (v - self.v0) / t,
                (p - self.p0) / t,
                self.n_pos as f32 / n,
                self.n_neg as f32 / n,
            ],
            y: (self.u_sum + self.u_comp) / n,
            w: t / ROW_WEIGHT_REF_S,
            n: self.n,
            n_pos: self.n_pos,
            n_neg: self.n_neg,
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PassSub {
    Ramp,
    Settle,
    Steady,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Stage {
    /// Pass `pass` (speed index `pass / 2`) in direction `dir` (±1).
    Passes {
        pass: usize,
        dir: f32,
        sub: PassSub,
    },
    Approach {
        dir: f32,
        leg: u8,
    },
    Cycle {
        dir: f32,
        leg: u8,
        up: bool,
    },
    ValidationStop,
    /// The validation move `dir · amp · sin(ωt)`; `(sin, cos)` of the current phase.
    Validation {
        dir: f32,
        amp_mm_s: f32,
        sin: f32,
        cos: f32,
    },
    FinalStop,
    Braking(AbortReason),
    Finished,
}

/// Running statistics of the validation (Welford for the measured mean and variance).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct ValidationStats {
    n: u32,
    mean: f32,
    m2: f32,
    ss_res: f32,
    y_min: f32,
    y_max: f32,
}

impl ValidationStats {
    fn add(&mut self, y: f32, y_hat: f32) {
        if !(y.is_finite() && y_hat.is_finite()) {
            return;
        }
        if self.n == 0 {
            self.y_min = y;
            self.y_max = y;
        }
        self.n = self.n.saturating_add(1);
        let d = y - self.mean;
        self.mean += d / self.n as f32;
        self.m2 += d * (y - self.mean);
        self.ss_res += (y - y_hat) * (y - y_hat);
        self.y_min = self.y_min.min(y);
        self.y_max = self.y_max.max(y);
    }

    /// (NRMSE, R²); zeros when nothing was compared.
    fn figures(&self) -> (f32, f32) {
        if self.n == 0 {
            return (0.0, 0.0);
        }
        let rmse = libm::sqrtf(self.ss_res / self.n as f32);
        let nrmse = rmse.div_or(self.y_max - self.y_min, 0.0);
        let r2 = 1.0 - self.ss_res.div_or(self.m2, 1.0);
        (nrmse.finite_or_zero(), r2.finite_or_zero())
    }
}

/// Counts for the per-parameter diagnostics of the final fit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct RowCounts {
    rows: [u32; 4],
    samples: [u32; 4],
}

impl RowCounts {
    fn add(&mut self, r: &Row, inertia: bool) {
        let mut bump = |i: usize, n: u32| {
            if n > 0 {
                self.rows[i] = self.rows[i].saturating_add(1);
                self.samples[i] = self.samples[i].saturating_add(n);
            }
        };
        bump(0, if inertia { r.n } else { 0 });
        bump(1, r.n);
        bump(2, r.n_pos);
        bump(3, r.n_neg);
    }
}

/// Identification of one axis (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Identifier {
    s: ValidIdentifyConfig,
    /// Periods since start.
    k: u32,
    stage: Stage,
    status: IdentifyStatus,
    progress: f32,
    vloop: VelocityLoop,
    ramp: Ramp,
    /// Inertia the loop and the feed-forward use.
    j_loop: f32,
    /// Planned acceleration of the current phase (speeding up).
    a_plan: f32,
    /// Planned deceleration (slowing down, helped by friction once a model exists); the
    /// stopping distance uses it.
    a_brake: f32,
    /// Fastest pass speed that fits the window at `a_plan`/`a_brake`
    /// ([`Self::fitting_speed`], cached: it takes a square root).
    v_fit: f32,
    /// Period at which the current hold (settle/plateau) started.
    hold_since: Option<u32>,
    /// Period at which the current pass' steady window started.
    steady_since: u32,
    /// Period at which braking or the validation move started.
    stage_since: u32,
    /// Period since which the effort has been at the cap.
    saturated_since: Option<u32>,
    /// Period since which the velocity has stayed within the settle tolerance (passes)
    /// or below [`STOPPED_MM_S`] (stops).
    within_since: Option<u32>,
    win: Window,
    /// Phase 1, all rows.
    ne_passes: NormalEquations<4>,
    /// Final fit: steady rows + inertia rows.
    ne_final: NormalEquations<4>,
    counts: RowCounts,
    /// Last steady mean effort per direction (+, -) and its speed.
    steady_mean: [Option<(f32, f32)>; 2],
    last_transition: Option<Row>,
    /// Phase 2 speeds.
    v_lo: f32,
    v_hi: f32,
    a_inertia: f32,
    model_ff: Option<AxisModel>,
    passes_model: Option<AxisModel>,
    final_model: Option<AxisModel>,
    val: ValidationStats,
    result: Option<IdentifyResult>,
}

impl Identifier {
    /// Validate `cfg` and prepare to start from rest at `start_pos_mm`, which must lie
    /// inside the window by at least the edge margin.
    pub fn new(cfg: &IdentifyConfig, start_pos_mm: f32) -> Result<Self, IdentifyConfigError> {
        let s = ValidIdentifyConfig::new(cfg, start_pos_mm)?;
        let c = &s.c;
        let mut id = Self {
            s,
            k: 0,
            stage: Stage::Passes {
                pass: 0,
                dir: 1.0,
                sub: PassSub::Ramp,
            },
            status: IdentifyStatus::Running,
            progress: 0.0,
            vloop: VelocityLoop::new(
                c.inertia_guess,
                c.velocity_bandwidth_rad_s,
                c.torque_cap_mnm,
                c.period_s,
            ),
            ramp: Ramp::at_rest(),
            j_loop: c.inertia_guess,
            // half the planned torque for accelerating until the friction is known
            a_plan: (0.5 * c.torque_fraction * c.torque_cap_mnm / c.inertia_guess)
                .min(c.accel_max_mm_s2),
            a_brake: 0.0,
            v_fit: 0.0,
            hold_since: None,
            steady_since: 0,
            stage_since: 0,
            saturated_since: None,
            within_since: None,
            win: Window::open(RowKind::Discard, 0.0, start_pos_mm),
            ne_passes: NormalEquations::new(),
            ne_final: NormalEquations::new(),
            counts: RowCounts::default(),
            steady_mean: [None; 2],
            last_transition: None,
            v_lo: 0.0,
            v_hi: 0.0,
            a_inertia: 0.0,
            model_ff: None,
            passes_model: None,
            final_model: None,
            val: ValidationStats::default(),
            result: None,
        };
        id.a_brake = id.a_plan;
        id.v_fit = id.fitting_speed();
        id.start_pass(0, 1.0, start_pos_mm);
        Ok(id)
    }

    /// The result, once [`IdentifyStatus::Done`].
    pub fn result(&self) -> Option<&IdentifyResult> {
        self.result.as_ref()
    }

    pub fn status(&self) -> IdentifyStatus {
        self.status
    }

    /// Machine time since start, s.
    pub fn machine_time_s(&self) -> f32 {
        self.k as f32 * self.s.c.period_s
    }

    /// The model of the friction passes, once phase 1 is over.
    pub fn passes_model(&self) -> Option<AxisModel> {
        self.passes_model
    }

    fn dt(&self) -> f32 {
        self.s.c.period_s
    }

    fn elapsed_since(&self, k0: u32) -> f32 {
        self.k.saturating_sub(k0) as f32 * self.dt()
    }

    fn phase(&self) -> IdentifyPhase {
        match self.stage {
            Stage::Passes { .. } => IdentifyPhase::FrictionPasses,
            Stage::Approach { .. } | Stage::Cycle { .. } => IdentifyPhase::Inertia,
            Stage::ValidationStop | Stage::Validation { .. } | Stage::FinalStop => {
                IdentifyPhase::Validation
            }
            Stage::Braking(_) => IdentifyPhase::Stopping,
            Stage::Finished => match self.status {
                IdentifyStatus::Done => IdentifyPhase::Done,
                _ => IdentifyPhase::Aborted,
            },
        }
    }

    fn output(&self, effort_mnm: f32) -> IdentifyOutput {
        IdentifyOutput {
            effort_mnm: effort_mnm
                .finite_or_zero()
                .clamp_sym(self.s.c.torque_cap_mnm),
            phase: self.phase(),
            progress: self.progress.finite_or_zero().clamp(0.0, 1.0),
            status: self.status,
        }
    }

    /// Stop at once with zero effort.
    fn give_up(&mut self, reason: AbortReason) -> IdentifyOutput {
        self.stage = Stage::Finished;
        self.status = IdentifyStatus::Aborted(reason);
        self.output(0.0)
    }

    /// Controlled stop. A predicted window exit is urgent: the setpoint drops to zero at
    /// once and the loop brakes with the whole cap. Otherwise the setpoint ramps from the
    /// measured velocity to rest at the planned deceleration.
    fn brake(&mut self, reason: AbortReason, vel_mm_s: f32) {
        if matches!(self.stage, Stage::Braking(_) | Stage::Finished) {
            return;
        }
        self.stage = Stage::Braking(reason);
        self.status = IdentifyStatus::Stopping(reason);
        self.stage_since = self.k;
        self.within_since = None;
        if reason == AbortReason::WouldLeaveWindow {
            self.ramp = Ramp::at_rest();
        } else {
            self.ramp.v_mm_s = vel_mm_s;
            self.ramp.go(0.0, self.a_plan, self.a_brake);
        }
        self.win = Window::open(RowKind::Discard, vel_mm_s, 0.0);
    }

    /// One control period: take this period's measurement, return this period's effort.
    pub fn step(&mut self, m: &AxisSample) -> IdentifyOutput {
        if matches!(self.stage, Stage::Finished) {
            return self.output(0.0);
        }
        self.k = self.k.saturating_add(1);
        let c = self.s.c;
        let limits = [c.window_min_mm, c.window_max_mm, c.velocity_limit_mm_s];
        if let Some(r) = m.abort_reason(m.effort_applied_mnm, limits) {
            return self.give_up(r);
        }
        self.win.add(m.effort_applied_mnm, m.vel_mm_s);
        if !matches!(self.stage, Stage::Braking(_)) {
            if self.machine_time_s() > c.time_budget_s {
                self.brake(AbortReason::TimeBudget, m.vel_mm_s);
            } else {
                let stop = m.pos_mm + m.vel_mm_s.sign() * self.stop_distance(m.vel_mm_s);
                if !(stop >= c.window_min_mm && stop <= c.window_max_mm) {
                    self.brake(AbortReason::WouldLeaveWindow, m.vel_mm_s);
                }
            }
        }
        self.advance(m);
        if matches!(self.stage, Stage::Finished) {
            return self.output(0.0);
        }
        let ff = self.j_loop * self.ramp.a_mm_s2 + self.friction_ff(self.ramp.v_mm_s);
        let u = self.vloop.step(self.ramp.v_mm_s, m.vel_mm_s, ff);
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

    /// Distance to stop from `v` at the planned deceleration, plus the loop's lag, mm.
    fn stop_distance(&self, v: f32) -> f32 {
        let v = v.abs();
        let a = self.a_brake.max(1.0);
        v * v / (2.0 * a) + v * self.reaction_s()
    }

    /// Reaction allowance of the stopping distance, s.
    fn reaction_s(&self) -> f32 {
        REACTION_BANDWIDTHS / self.s.c.velocity_bandwidth_rad_s + 2.0 * self.dt()
    }

    /// Room to the turn point in direction `dir` (mm, negative beyond it).
    fn room(&self, dir: f32, pos: f32) -> f32 {
        if dir > 0.0 {
            self.s.turn_max_mm - pos
        } else {
            pos - self.s.turn_min_mm
        }
    }

    /// The motion in direction `dir` must end now to stop before the turn point.
    fn must_turn(&self, dir: f32, m: &AxisSample) -> bool {
        let v_sp = if self.ramp.v_mm_s * dir > 0.0 {
            self.ramp.v_mm_s.abs()
        } else {
            0.0
        };
        let v_meas = if m.vel_mm_s * dir > 0.0 {
            m.vel_mm_s.abs()
        } else {
            0.0
        };
        self.room(dir, m.pos_mm) <= self.stop_distance(v_sp.max(v_meas))
    }

    fn friction_ff(&self, v_sp: f32) -> f32 {
        if let Some(model) = &self.model_ff {
            return model.friction_mnm(v_sp);
        }
        let idx = if v_sp > 0.0 {
            0
        } else if v_sp < 0.0 {
            1
        } else {
            return 0.0;
        };
        match self.steady_mean[idx] {
            Some((u, _)) => u,
            None => 0.0,
        }
    }

    fn more_room_dir(&self, pos: f32) -> f32 {
        if self.room(1.0, pos) >= self.room(-1.0, pos) {
            1.0
        } else {
            -1.0
        }
    }

    fn advance(&mut self, m: &AxisSample) {
        match self.stage {
            Stage::Passes { pass, dir, sub } => self.advance_passes(pass, dir, sub, m),
            Stage::Approach { dir, leg } => self.advance_approach(dir, leg, m),
            Stage::Cycle { dir, leg, up } => self.advance_cycle(dir, leg, up, m),
            Stage::ValidationStop => self.advance_validation_stop(m),
            Stage::Validation {
                dir,
                amp_mm_s,
                sin,
                cos,
            } => self.advance_validation(dir, amp_mm_s, (sin, cos), m),
            Stage::FinalStop => {
                self.ramp.step(self.dt());
                if self.is_stopped(m) {
                    self.finish();
                }
            }
            Stage::Braking(reason) => {
                self.ramp.step(self.dt());
                if self.is_stopped(m) || self.elapsed_since(self.stage_since) > BRAKE_TIMEOUT_S {
                    self.stage = Stage::Finished;
                    self.status = IdentifyStatus::Aborted(reason);
                }
            }
            Stage::Finished => {}
        }
    }

    /// The setpoint is at rest and the axis has stayed below [`STOPPED_MM_S`] for
    /// [`STOP_HOLD_S`].
    fn is_stopped(&mut self, m: &AxisSample) -> bool {
        if !(self.ramp.reached() && self.ramp.v_mm_s == 0.0 && m.vel_mm_s.abs() < STOPPED_MM_S) {
            self.within_since = None;
            return false;
        }
        let since = *self.within_since.get_or_insert(self.k);
        self.elapsed_since(since) >= STOP_HOLD_S
    }

    // ---------------------------------------------------------------- phase 1

    /// Start pass `pass`. The first pass of a new speed continues in the direction of
    /// the pass before when the room ahead holds a whole pass (a small speed change
    /// instead of a reversal: half the ramp time on a weak axis), else it goes towards
    /// the farther turn point. The second pass of a speed comes back over the same
    /// ground, so it has at least the room the first one used. `prev_dir` is the
    /// direction of the pass before. Speeds are clipped to what fits in the window
    /// ([`Self::fitting_speed`]); once that adds no new speed the passes end.
    fn start_pass(&mut self, pass: usize, prev_dir: f32, pos: f32) {
        let speed = self.pass_speed(pass);
        if pass.is_multiple_of(2)
            && pass >= 2
            && speed <= self.pass_speed(pass - 2) * MIN_SPEED_STEP
        {
            return self.finish_passes_at(pos);
        }
        let dir = if pass % 2 == 1 {
            -prev_dir
        } else if pass > 0 && self.room(prev_dir, pos) >= self.pass_distance(speed) {
            prev_dir
        } else {
            self.more_room_dir(pos)
        };
        self.ramp.go(dir * speed, self.a_plan, self.a_brake);
        self.hold_since = None;
        self.stage = Stage::Passes {
            pass,
            dir,
            sub: PassSub::Ramp,
        };
        self.progress = 0.5 * pass as f32 / (2 * self.s.n_speeds) as f32;
    }

    /// Speed of pass `pass`: the configured speed, clipped to the fastest whose whole
    /// pass (from rest, settle, steady, stop) fits between the turn points.
    fn pass_speed(&self, pass: usize) -> f32 {
        let v = self
            .s
            .speeds_mm_s
            .get(pass / 2)
            .copied()
            .unwrap_or(self.s.c.pass_speed_min_mm_s);
        v.min(self.v_fit)
    }

    /// Largest `v` with `pass_distance(v) <= usable length` (positive root of the
    /// quadratic).
    fn fitting_speed(&self) -> f32 {
        let c = &self.s.c;
        let qa = 0.5 / self.a_plan.max(1.0) + 0.5 / self.a_brake.max(1.0);
        let qb = c.settle_s + c.steady_s + self.reaction_s();
        let usable = self.s.turn_max_mm - self.s.turn_min_mm;
        (-qb + libm::sqrtf(qb * qb + 4.0 * qa * usable)).div_or(2.0 * qa, usable)
    }

    /// Distance a pass at speed `v` needs: ramp from rest (an upper bound of the ramp
    /// from the speed before), settle, steady, stop.
    fn pass_distance(&self, v: f32) -> f32 {
        let c = &self.s.c;
        v * v / (2.0 * self.a_plan.max(1.0)) + v * (c.settle_s + c.steady_s) + self.stop_distance(v)
    }

    /// Whether the pass after `pass` (in direction `dir`, now at `pos`) has room for a
    /// whole pass in a direction it would take. If not, the current pass keeps
    /// recording its steady window until it has (or until the turn point): a longer
    /// steady window costs only its time, a truncated next pass would be wasted.
    fn next_pass_fits(&self, pass: usize, dir: f32, pos: f32) -> bool {
        let next = pass + 1;
        if next >= 2 * self.s.n_speeds {
            return true;
        }
        let need = self.pass_distance(self.pass_speed(next));
        let back = self.room(-dir, pos) >= need;
        if next % 2 == 1 {
            back
        } else {
            back || self.room(dir, pos) >= need
        }
    }

    fn advance_passes(&mut self, pass: usize, dir: f32, sub: PassSub, m: &AxisSample) {
        self.ramp.step(self.dt());
        if self.must_turn(dir, m) {
            self.end_pass(pass, dir, sub, m);
            return;
        }
        match sub {
            PassSub::Ramp => {
                if self.ramp.reached() {
                    self.hold_since = Some(self.k);
                    self.within_since = None;
                    self.stage = Stage::Passes {
                        pass,
                        dir,
                        sub: PassSub::Settle,
                    };
                }
            }
            PassSub::Settle => {
                let tol = SETTLE_TOL_MM_S + SETTLE_TOL_FRACTION * self.ramp.v_mm_s.abs();
                if (m.vel_mm_s - self.ramp.v_mm_s).abs() > tol {
                    self.within_since = None;
                } else if self.within_since.is_none() {
                    self.within_since = Some(self.k);
                }
                let settled = self
                    .within_since
                    .is_some_and(|k0| self.elapsed_since(k0) >= self.s.c.settle_s);
                let since = self.hold_since.unwrap_or(self.k);
                let timeout =
                    self.elapsed_since(since) >= SETTLE_TIMEOUT_FACTOR * self.s.c.settle_s;
                if settled || timeout {
                    if let Some(r) = self.win.row(m.vel_mm_s, m.pos_mm, self.dt()) {
                        if self.win.kind == RowKind::Transition {
                            self.ne_passes.add_row(&r.x, r.y, r.w);
                            self.last_transition = Some(r);
                        }
                    }
                    self.win = Window::open(RowKind::Steady, m.vel_mm_s, m.pos_mm);
                    self.steady_since = self.k;
                    self.stage = Stage::Passes {
                        pass,
                        dir,
                        sub: PassSub::Steady,
                    };
                }
            }
            PassSub::Steady => {
                let t = self.elapsed_since(self.steady_since);
                // waiting for room is bounded by the time the pass needs to cross the
                // window (an axis that does not follow never gets there)
                let usable = self.s.turn_max_mm - self.s.turn_min_mm;
                let wait_max = usable.div_or(self.ramp.v_mm_s.abs(), 0.0);
                if t >= self.s.c.steady_s
                    && (self.next_pass_fits(pass, dir, m.pos_mm)
                        || t >= self.s.c.steady_s + wait_max)
                {
                    self.end_pass(pass, dir, sub, m);
                }
            }
        }
    }

    fn end_pass(&mut self, pass: usize, dir: f32, sub: PassSub, m: &AxisSample) {
        if sub == PassSub::Steady {
            let long_enough =
                self.elapsed_since(self.steady_since) >= MIN_STEADY_FRACTION * self.s.c.steady_s;
            match self.win.row(m.vel_mm_s, m.pos_mm, self.dt()) {
                Some(r) if long_enough => {
                    self.steady_row(&r, pass, dir);
                    self.win = Window::open(RowKind::Transition, m.vel_mm_s, m.pos_mm);
                }
                // too short: the window continues as part of the next transition
                _ => self.win.kind = RowKind::Transition,
            }
        }
        let next = pass + 1;
        if next >= 2 * self.s.n_speeds {
            self.finish_passes(m);
        } else {
            self.start_pass(next, dir, m.pos_mm);
        }
    }

    fn steady_row(&mut self, r: &Row, pass: usize, dir: f32) {
        self.ne_passes.add_row(&r.x, r.y, r.w);
        if self.ne_final.add_row(&r.x, r.y, r.w) {
            self.counts.add(r, false);
        }
        let idx = if dir > 0.0 { 0 } else { 1 };
        let speed = self.pass_speed(pass);
        if let Some(slot) = self.steady_mean.get_mut(idx) {
            *slot = Some((r.y, speed));
        }
        // From the second speed on (both directions run at two speeds, reversals in
        // between) the rows so far determine all four parameters: the interim fit tunes
        // the loop, the friction feed-forward and the planned acceleration. Before that,
        // a rough inertia from the last reversal, with the friction during the reversal
        // taken as the steady effort of each direction (it ignores the viscous part's
        // change, up to ~40 % low on a heavily damped axis: enough for the loop's gain).
        // (not after the last pass: the passes' fit follows in the same period)
        let interim = if pass >= 3 && pass + 1 < 2 * self.s.n_speeds {
            self.fit(&self.ne_passes, FitStage::FrictionPasses).ok()
        } else {
            None
        };
        let guess = self.s.c.inertia_guess;
        let plausible = |j: f32| j > guess / ROUGH_J_RANGE && j < guess * ROUGH_J_RANGE;
        match interim {
            Some(model) if plausible(model.inertia) => {
                self.model_ff = Some(model);
                self.j_loop = model.inertia;
                self.vloop.retune(model.inertia);
            }
            _ => {
                if let (Some(tr), Some((up, _)), Some((un, _))) = (
                    self.last_transition,
                    self.steady_mean[0],
                    self.steady_mean[1],
                ) {
                    let j = (tr.y - tr.x[2] * up - tr.x[3] * un).div_or(tr.x[0], 0.0);
                    if tr.x[0].abs() > 1.0 && plausible(j) {
                        self.j_loop = j;
                        self.vloop.retune(j);
                    }
                }
            }
        }
        self.last_transition = None;
        self.plan_pass_accel(pass);
    }

    /// Acceleration for the next pass: what the cap leaves after the friction at the next
    /// speed, from the interim model when there is one, else the measured steady effort
    /// scaled by the speed ratio (an upper bound: as if all friction were viscous).
    fn plan_pass_accel(&mut self, pass: usize) {
        let c = self.s.c;
        let next_speed = self.pass_speed(pass + 1);
        let mut friction: f32 = 0.0;
        if let Some(model) = &self.model_ff {
            friction = model
                .friction_mnm(next_speed)
                .abs()
                .max(model.friction_mnm(-next_speed).abs());
        } else {
            for (u, v) in self.steady_mean.iter().flatten() {
                let scale = next_speed.div_or(*v, 1.0).max(1.0);
                friction = friction.max(u.abs() * scale);
            }
        }
        let a = (c.torque_fraction * c.torque_cap_mnm - friction).div_or(self.j_loop, 0.0);
        // never below 5 % of the configured maximum: a pass that cannot accelerate
        // faster still gives valid (integrated-form) rows
        self.a_plan = a.max(0.05 * c.accel_max_mm_s2).min(c.accel_max_mm_s2);
        self.a_brake = self.braking_accel();
        self.v_fit = self.fitting_speed();
    }

    /// Deceleration towards rest: the planned torque plus the smaller Coulomb level that
    /// opposes the motion (only once a model exists; a load that pulls in the direction
    /// of motion makes its level negative and the term zero).
    fn braking_accel(&self) -> f32 {
        let c = &self.s.c;
        let help = match &self.model_ff {
            Some(m) => m.coulomb_pos_mnm.min(-m.coulomb_neg_mnm).max(0.0),
            None => return self.a_plan,
        };
        (c.torque_fraction * c.torque_cap_mnm + help)
            .div_or(self.j_loop, 0.0)
            .max(self.a_plan)
            .min(c.accel_max_mm_s2)
    }

    /// Fit a model to `ne` (parameters only: the quality figures of the final fit are
    /// computed at the end, in a period of their own, to keep each period's work small).
    fn fit(&self, ne: &NormalEquations<4>, stage: FitStage) -> Result<AxisModel, AbortReason> {
        let ([j, b, fp, fneg], _) = ne
            .solve_params()
            .map_err(|error| AbortReason::FitFailed { stage, error })?;
        let model = AxisModel {
            inertia: j,
            // a (physically impossible) negative viscous term is noise around a small
            // true value: clamp, the diagnostic keeps the fitted value
            viscous: b.max(0.0),
            coulomb_pos_mnm: fp,
            coulomb_neg_mnm: fneg,
        };
        if model.validate().is_err() {
            return Err(AbortReason::ImplausibleModel { stage });
        }
        Ok(model)
    }

    fn finish_passes(&mut self, m: &AxisSample) {
        self.finish_passes_at(m.pos_mm);
    }

    fn finish_passes_at(&mut self, pos: f32) {
        self.win.kind = RowKind::Discard;
        let vel = self.ramp.v_mm_s;
        let model = match self.fit(&self.ne_passes, FitStage::FrictionPasses) {
            Ok(model) => model,
            Err(reason) => return self.brake(reason, vel),
        };
        self.passes_model = Some(model);
        self.model_ff = Some(model);
        self.j_loop = model.inertia;
        self.vloop.retune(model.inertia);
        self.a_brake = self.braking_accel();
        if let Err(reason) = self.plan_inertia(&model) {
            return self.brake(reason, vel);
        }
        let dir = self.more_room_dir(pos);
        self.start_approach(dir, 0);
    }

    // ---------------------------------------------------------------- phase 2

    /// Speeds and acceleration of the inertia phase: the strongest acceleration the cap
    /// leaves after the friction at the high speed, and a high speed low enough that one
    /// up-and-down cycle takes at most half the usable length.
    fn plan_inertia(&mut self, model: &AxisModel) -> Result<(), AbortReason> {
        let c = self.s.c;
        let usable = self.s.turn_max_mm - self.s.turn_min_mm;
        let v_lo = c.pass_speed_min_mm_s;
        let mut v_hi = c.pass_speed_max_mm_s;
        for _ in 0..MAX_SPEED_REDUCTIONS {
            let friction = model
                .friction_mnm(v_hi)
                .abs()
                .max(model.friction_mnm(-v_hi).abs());
            let a = (c.torque_fraction * c.torque_cap_mnm - friction)
                .div_or(model.inertia, 0.0)
                .min(c.accel_max_mm_s2);
            if a > 0.0 {
                let cycle = (v_hi * v_hi - v_lo * v_lo) / a + (v_hi + v_lo) * c.plateau_s;
                if cycle <= 0.5 * usable {
                    self.v_lo = v_lo;
                    self.v_hi = v_hi;
                    self.a_inertia = a;
                    return Ok(());
                }
            }
            v_hi = v_lo + 0.7 * (v_hi - v_lo);
            if v_hi < 1.5 * v_lo {
                break;
            }
        }
        let friction = model
            .friction_mnm(v_lo)
            .abs()
            .max(model.friction_mnm(-v_lo).abs());
        if c.torque_fraction * c.torque_cap_mnm <= friction {
            Err(AbortReason::NoTorqueMargin)
        } else {
            Err(AbortReason::WindowTooShort)
        }
    }

    fn cycle_distance(&self) -> f32 {
        (self.v_hi * self.v_hi - self.v_lo * self.v_lo) / self.a_inertia
            + (self.v_hi + self.v_lo) * self.s.c.plateau_s
    }

    fn start_approach(&mut self, dir: f32, leg: u8) {
        self.win.kind = RowKind::Discard;
        // the reversal into this leg brakes at the deceleration its stopping distance
        // was planned with
        self.ramp.go(dir * self.v_lo, self.a_plan, self.a_brake);
        self.hold_since = None;
        self.stage = Stage::Approach { dir, leg };
        self.progress = 0.5 + 0.15 * leg as f32;
    }

    /// True once the ramp has reached its target and the plateau has lasted `plateau_s`.
    fn plateau_done(&mut self) -> bool {
        if !self.ramp.reached() {
            return false;
        }
        let since = *self.hold_since.get_or_insert(self.k);
        self.elapsed_since(since) >= self.s.c.plateau_s
    }

    fn advance_approach(&mut self, dir: f32, leg: u8, m: &AxisSample) {
        self.ramp.step(self.dt());
        if self.plateau_done() {
            // symmetric ramps from here: accelerating and decelerating windows at the
            // same mean speed (module docs)
            self.a_plan = self.a_inertia;
            self.a_brake = self.a_inertia;
            self.win = Window::open(RowKind::Inertia, m.vel_mm_s, m.pos_mm);
            self.next_cycle(dir, leg, m);
        }
    }

    /// Start an up-and-down cycle if it fits before the turn point, else the next leg.
    fn next_cycle(&mut self, dir: f32, leg: u8, m: &AxisSample) {
        let need = self.cycle_distance() + self.stop_distance(self.v_lo);
        if self.room(dir, m.pos_mm) >= need {
            self.ramp
                .go(dir * self.v_hi, self.a_inertia, self.a_inertia);
            self.hold_since = None;
            self.stage = Stage::Cycle { dir, leg, up: true };
        } else {
            self.next_leg(dir, leg, m);
        }
    }

    fn next_leg(&mut self, dir: f32, leg: u8, m: &AxisSample) {
        if leg == 0 {
            self.start_approach(-dir, 1);
        } else {
            self.finish_inertia(m);
        }
    }

    fn advance_cycle(&mut self, dir: f32, leg: u8, up: bool, m: &AxisSample) {
        self.ramp.step(self.dt());
        if self.must_turn(dir, m) {
            self.next_leg(dir, leg, m);
            return;
        }
        if !self.plateau_done() {
            return;
        }
        if let Some(r) = self.win.row(m.vel_mm_s, m.pos_mm, self.dt()) {
            if self.ne_final.add_row(&r.x, r.y, r.w) {
                self.counts.add(&r, true);
            }
        }
        self.win = Window::open(RowKind::Inertia, m.vel_mm_s, m.pos_mm);
        if up {
            self.ramp
                .go(dir * self.v_lo, self.a_inertia, self.a_inertia);
            self.hold_since = None;
            self.stage = Stage::Cycle {
                dir,
                leg,
                up: false,
            };
        } else {
            self.next_cycle(dir, leg, m);
        }
    }

    fn finish_inertia(&mut self, m: &AxisSample) {
        self.win = Window::open(RowKind::Discard, m.vel_mm_s, m.pos_mm);
        match self.fit(&self.ne_final, FitStage::Final) {
            Ok(model) => {
                self.final_model = Some(model);
                self.model_ff = Some(model);
                self.j_loop = model.inertia;
                self.vloop.retune(model.inertia);
            }
            Err(reason) => return self.brake(reason, m.vel_mm_s),
        }
        self.a_brake = self.braking_accel();
        self.ramp.go(0.0, self.a_plan, self.a_brake);
        self.hold_since = None;
        self.stage = Stage::ValidationStop;
        self.progress = 0.8;
    }

    // ---------------------------------------------------------------- phase 3

    fn advance_validation_stop(&mut self, m: &AxisSample) {
        self.ramp.step(self.dt());
        if !self.ramp.reached() {
            return;
        }
        let since = *self.hold_since.get_or_insert(self.k);
        if self.elapsed_since(since) < self.s.c.settle_s {
            return;
        }
        let c = self.s.c;
        let w = 2.0 * core::f32::consts::PI * c.validation_freq_hz;
        let dir = self.more_room_dir(m.pos_mm);
        // the move goes 2V/ω out and back; keep its stopping allowance inside the room
        let room = self.room(dir, m.pos_mm) - self.stop_distance(self.v_hi);
        let amp = self.v_hi.min(self.a_inertia / w).min(0.5 * room * w);
        if !(amp >= 0.5 * self.v_lo) {
            return self.brake(AbortReason::WindowTooShort, m.vel_mm_s);
        }
        self.win = Window::open(RowKind::Validation, m.vel_mm_s, m.pos_mm);
        self.stage_since = self.k;
        self.stage = Stage::Validation {
            dir,
            amp_mm_s: amp,
            sin: 0.0,
            cos: 1.0,
        };
    }

    fn advance_validation(&mut self, dir: f32, amp: f32, (sn, cs): (f32, f32), m: &AxisSample) {
        let c = self.s.c;
        let t = self.elapsed_since(self.stage_since);
        let duration = c.validation_cycles as f32 / c.validation_freq_hz;
        let w = 2.0 * core::f32::consts::PI * c.validation_freq_hz;
        if self.win.n as f32 * self.dt() >= c.validation_window_s - 0.5 * self.dt() {
            if let (Some(r), Some(model)) = (
                self.win.row(m.vel_mm_s, m.pos_mm, self.dt()),
                self.final_model,
            ) {
                let predicted = model.inertia * r.x[0]
                    + model.viscous * r.x[1]
                    + model.coulomb_pos_mnm * r.x[2]
                    + model.coulomb_neg_mnm * r.x[3];
                self.val.add(r.y, predicted);
            }
            self.win = Window::open(RowKind::Validation, m.vel_mm_s, m.pos_mm);
        }
        if t >= duration {
            self.win.kind = RowKind::Discard;
            self.ramp = Ramp::at_rest();
            self.within_since = None;
            self.stage = Stage::FinalStop;
            self.progress = 0.98;
            return;
        }
        // setpoint at this period's phase, then rotate the phase by ω·Ts: two products
        // instead of a sin/cos per period (libm's sincosf costs ~2000 instructions on the
        // M4); the first-order renormalisation keeps sin² + cos² = 1 to rounding.
        self.ramp.v_mm_s = dir * amp * sn;
        self.ramp.target_mm_s = self.ramp.v_mm_s;
        self.ramp.a_mm_s2 = dir * amp * w * cs;
        let (ds, dc) = self.s.validation_step;
        let (s1, c1) = (sn * dc + cs * ds, cs * dc - sn * ds);
        let k = 1.5 - 0.5 * (s1 * s1 + c1 * c1);
        self.stage = Stage::Validation {
            dir,
            amp_mm_s: amp,
            sin: (s1 * k).finite_or_zero(),
            cos: (c1 * k).finite_or_zero(),
        };
        self.progress = 0.8 + 0.18 * t / duration;
    }

    /// Done: the final fit's quality figures (the same factorisation as the fit, plus
    /// residual and standard errors) and the result.
    fn finish(&mut self) {
        let (nrmse, r2) = self.val.figures();
        let stats: Option<LsSolution<4>> = self.ne_final.solve().ok();
        if let (Some(model), Some(passes_model)) = (self.final_model, self.passes_model) {
            let diag = |i: usize| ParamDiagnostic {
                value: stats.map_or(0.0, |s| s.theta[i]),
                std_error: stats.map_or(0.0, |s| s.std_error[i]),
                rows: self.counts.rows[i],
                samples: self.counts.samples[i],
            };
            self.result = Some(IdentifyResult {
                model,
                nrmse,
                r2,
                validation_windows: self.val.n,
                fit: FitDiagnostics {
                    inertia: diag(0),
                    viscous: diag(1),
                    coulomb_pos: diag(2),
                    coulomb_neg: diag(3),
                    residual_rms_mnm: stats.map_or(0.0, |s| s.residual_rms),
                    rows: self.ne_final.rows(),
                    min_pivot: stats.map_or(0.0, |s| s.min_pivot),
                },
                passes_model,
                machine_time_s: self.machine_time_s(),
            });
            self.status = IdentifyStatus::Done;
        } else {
            self.status = IdentifyStatus::Aborted(AbortReason::FitFailed {
                stage: FitStage::Final,
                error: LsError::TooFewRows,
            });
        }
        self.progress = 1.0;
        self.stage = Stage::Finished;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sysid::config::IDENTIFY_DEFAULTS;

    fn id() -> Identifier {
        Identifier::new(&IDENTIFY_DEFAULTS, 0.0).unwrap()
    }

    #[test]
    fn fit_reports_too_few_and_degenerate_rows() {
        let id = id();
        let mut ne = NormalEquations::<4>::new();
        assert_eq!(
            id.fit(&ne, FitStage::FrictionPasses).unwrap_err(),
            AbortReason::FitFailed {
                stage: FitStage::FrictionPasses,
                error: LsError::TooFewRows
            }
        );
        // passes in one direction only: f- has no data
        for v in [20.0, 55.0, 90.0, 125.0] {
            ne.add_row(&[0.0, v, 1.0, 0.0], 40.0 + 0.25 * v, 1.0);
        }
        ne.add_row(&[2000.0, 60.0, 1.0, 0.0], 183.0, 1.0);
        assert_eq!(
            id.fit(&ne, FitStage::Final).unwrap_err(),
            AbortReason::FitFailed {
                stage: FitStage::Final,
                error: LsError::Unexcited { index: 3 }
            }
        );
    }

    #[test]
    fn fit_rejects_an_implausible_model_and_clamps_negative_viscous() {
        let id = id();
        let rows = |j: f32, b: f32| {
            let mut ne = NormalEquations::<4>::new();
            for (x, w) in [
                ([0.0, 20.0, 1.0, 0.0], 1.0),
                ([0.0, 120.0, 1.0, 0.0], 1.0),
                ([0.0, -20.0, 0.0, 1.0], 1.0),
                ([0.0, -120.0, 0.0, 1.0], 1.0),
                ([2000.0, 70.0, 1.0, 0.0], 1.0),
                ([-2000.0, 70.0, 1.0, 0.0], 1.0),
            ] {
                let y = j * x[0] + b * x[1] + 40.0 * x[2] - 30.0 * x[3];
                ne.add_row(&x, y, w);
            }
            ne
        };
        assert_eq!(
            id.fit(&rows(-0.1, 0.25), FitStage::Final).unwrap_err(),
            AbortReason::ImplausibleModel {
                stage: FitStage::Final
            }
        );
        let ne = rows(0.1, -0.01);
        let m = id.fit(&ne, FitStage::Final).unwrap();
        assert_eq!(m.viscous, 0.0);
        let theta = ne.solve().unwrap().theta;
        assert!((theta[1] + 0.01).abs() < 1e-4, "{theta:?}");
        assert!((m.inertia - 0.1).abs() < 1e-5);
    }

    #[test]
    fn window_rows_are_the_integrated_equation() {
        // 1000 samples at 1e-4 s: v 10 -> 30 mm/s, 2 mm travelled, all forward, u = 50
        let mut w = Window::open(RowKind::Steady, 10.0, 1.0);
        for _ in 0..1000 {
            w.add(50.0, 20.0);
        }
        let r = w.row(30.0, 3.0, 1e-4).unwrap();
        assert!((r.x[0] - 200.0).abs() < 1e-3, "{r:?}"); // Δv/T = 20/0.1
        assert!((r.x[1] - 20.0).abs() < 1e-4); // Δx/T
        assert_eq!((r.x[2], r.x[3], r.n), (1.0, 0.0, 1000));
        assert!((r.y - 50.0).abs() < 1e-4);
        assert!((r.w - 1.0).abs() < 1e-6);
        assert_eq!(
            Window::open(RowKind::Discard, 0.0, 0.0).row(0.0, 0.0, 1e-4),
            None
        );
    }

    #[test]
    fn validation_figures() {
        let mut v = ValidationStats::default();
        assert_eq!(v.figures(), (0.0, 0.0));
        for (y, p) in [(0.0, 1.0), (10.0, 9.0), (20.0, 21.0), (30.0, 29.0)] {
            v.add(y, p);
        }
        v.add(f32::NAN, 0.0); // ignored
        let (nrmse, r2) = v.figures();
        // residuals ±1: RMSE 1 over the range 30; SS_tot = 500
        assert!((nrmse - 1.0 / 30.0).abs() < 1e-6, "{nrmse}");
        assert!((r2 - (1.0 - 4.0 / 500.0)).abs() < 1e-6, "{r2}");
    }
}
