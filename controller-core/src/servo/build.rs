//! Building the servo from a [`ServoConfig`] ([`Servo::new`]: every block validated,
//! nothing built when one is rejected) and swapping in a new configuration with the
//! outputs off ([`Servo::reconfigure`]: what carries over, and when).

use super::brake::Brakes;
use super::checks::{EncoderChecks, ARM_CHECK_SPEED_MM_S, ARM_CHECK_WRONG_COUNTS};
use super::config::{ReconfigureError, ServoConfig, MAX_RATE_HZ, MIN_RATE_HZ};
use super::faults::FaultLog;
use super::identify::Identification;
use super::index_check::IndexCheck;
use super::manual::ManualState;
use super::monitor::Monitor;
use super::snapshot::Snapshot;
use super::state::ServoState;
use super::step::Servo;
use super::stop::StopState;
use crate::axes::AXES;
use crate::config::ConfigError;
use crate::controller::{ControlOutput, Controller3};
use crate::estimator::{EstimatorBank, EstimatorTiming, WideCounter};
use crate::filter::OutputFilters;
use crate::motion::compensation::CompState;
use crate::motion::feedforward::FeedForward;
use crate::motion::path::PathStart;
use crate::motion::reference::{Clock, ReferenceMode};
use crate::{Real, Vec3};

impl<R: Real> Servo<R> {
    /// Validates `cfg` (every block rejects its bad parameters; nothing is built then).
    /// `raw` are the encoder registers now, which stand for wide counts `start_counts`
    /// (0 on a board at boot; the simulated machine's absolute counts).
    pub fn new(
        cfg: &ServoConfig,
        raw: [u32; AXES],
        start_counts: [i64; AXES],
    ) -> Result<Self, ConfigError> {
        Self::build(cfg, raw, start_counts)
    }

    /// Validates `cfg` exactly as [`Servo::new`] does, without keeping a servo. The link
    /// task validates every settings change with it, preempted by the control interrupt:
    /// with [`Servo::build`] inlined here the compiler drops the stores of the servo
    /// nobody reads, and the frame holds the validation's values only (0.8 KiB on the
    /// board's ELF, against `Servo::new`'s 3.9 KiB plus the 4.2 KiB servo it returns in
    /// its caller's frame).
    #[inline(never)]
    pub fn check(cfg: &ServoConfig) -> Result<(), ConfigError> {
        Self::build(cfg, [0; AXES], [0; AXES]).map(|_| ())
    }

    /// [`Servo::new`]'s body, inlined into it, [`Servo::check`] and
    /// [`Servo::reconfigure`] (whose new servo is then built in its own frame, not
    /// returned through a second copy).
    #[inline(always)]
    fn build(
        cfg: &ServoConfig,
        raw: [u32; AXES],
        start_counts: [i64; AXES],
    ) -> Result<Self, ConfigError> {
        if !(MIN_RATE_HZ..=MAX_RATE_HZ).contains(&cfg.rate_hz) {
            return Err(ConfigError::OutOfRange("rate_hz (100..=50000)"));
        }
        let period_s = 1.0 / f64::from(cfg.rate_hz);
        let mut count_len = [0.0; AXES];
        let mut timing = [EstimatorTiming {
            period_s: period_s as f32,
            count_size: 0.0,
        }; AXES];
        let mut full_scale = Vec3::zero();
        let mut counts_per_mm = [0.0; AXES];
        for i in 0..AXES {
            count_len[i] = cfg.encoders[i].count_len()?;
            counts_per_mm[i] = cfg.encoders[i].counts_per_mm;
            timing[i].count_size = count_len[i] as f32;
            full_scale[i] = R::from_f32(cfg.amplifiers[i].checked_full_scale()?);
        }
        let path = match &cfg.path {
            Some(p) => {
                let duration = match p.duration_s {
                    Some(d) if d >= 0.0 && d.is_finite() => {
                        Some(libm::round(d / period_s).min(f64::from(u32::MAX)) as u32)
                    }
                    Some(_) => return Err(ConfigError::Negative("path.duration_s")),
                    None => None,
                };
                Some((p.path.build()?.cast(), duration))
            }
            None => None,
        };
        cfg.travel.validate()?;
        super::brake::validate_all(&cfg.brakes)?;
        cfg.homing.validate()?;
        cfg.jog.validate()?;
        for (i, a) in cfg.homing.axes.iter().enumerate() {
            if a.enabled && !cfg.travel.axes[i].contains(a.home_mm()) {
                return Err(ConfigError::OutOfRange(
                    "homing: switch_pos_mm -/+ pulloff_mm must lie inside the travel",
                ));
            }
        }
        let path_start = cfg.path.map_or(PathStart::Absolute, |p| p.start);
        let s = &cfg.safety;
        let positive = |v: f32, n| crate::config::positive(v, n);
        // (`from_fn`, not `[0, 1, 2].map`: its indices are provably in range, so no panic
        // path reaches the control interrupt, which rebuilds the servo on a settings change)
        let counters = core::array::from_fn(|i| {
            let mut c = WideCounter::new(cfg.encoders[i].counter, raw[i], start_counts[i]);
            c.set_inverted(cfg.encoders[i].invert);
            c
        });
        let motor_inverted = super::commands::axis_mask(cfg.amplifiers.map(|a| a.invert));
        let model_missing = super::commands::axis_mask(core::array::from_fn(|i| {
            cfg.controller.laws[i].is_model_based() && !cfg.model_known[i]
        }));
        let mut snapshot = Snapshot::boot();
        snapshot.model_missing = model_missing;
        snapshot.homed = super::commands::axis_mask(cfg.homing.axes.map(|a| !a.enabled));
        Ok(Self {
            period_s,
            clock: Clock::new(cfg.rate_hz),
            dt: R::from_f64(period_s),
            counters,
            count_len: count_len.map(R::from_f64),
            count_len_f32: count_len.map(|l| l as f32),
            counts_per_mm,
            full_scale,
            motor_inverted,
            estimators: EstimatorBank::new(&cfg.estimator, &timing, count_len, start_counts)?,
            controller: Controller3::new(&cfg.controller)?,
            monitor: Monitor::new(
                s,
                counts_per_mm,
                full_scale.to_array().map(Real::to_f32),
                period_s,
            )?,
            index: IndexCheck::new(
                core::array::from_fn(|i| cfg.encoders[i].index_period_counts),
                s.encoder_noise_counts,
                s.index_max_correction_counts,
            )?,
            faults: FaultLog::new(),
            state: ServoState::Disabled,
            path,
            path_start,
            motion: ReferenceMode::Hold(Vec3::zero()),
            comp: CompState::NONE,
            ff: FeedForward::new(&cfg.feedforward)?,
            ff_effort: Vec3::zero(),
            filters: OutputFilters::new(&cfg.filters, period_s as f32)?,
            filtered: cfg.filters.iter().any(|f| !f.is_empty()),
            travel: cfg.travel,
            manual: ManualState {
                homing: cfg.homing,
                jog: cfg.jog,
                jog_timeout_periods: super::monitor::periods(cfg.jog.timeout_s, period_s),
                homed: 0,
                no_homing: super::commands::axis_mask(cfg.homing.axes.map(|a| !a.enabled)),
            },
            ident: Identification {
                cfg: cfg.identify,
                run: None,
                outcome: None,
                outcome_kind: super::identify::IdentifyKind::Model,
                response_points: 0,
                runs: 0,
            },
            link_down: false,
            stopping: StopState {
                then: ServoState::Fault,
                rest_periods: 0,
                settle_periods: super::monitor::periods(
                    positive(s.stop_settle_s, "safety.stop_settle_s")?,
                    period_s,
                ),
                estop_controlled: match s.estop_category {
                    0 => false,
                    1 => true,
                    _ => return Err(ConfigError::OutOfRange("safety.estop_category (0 or 1)")),
                },
                estop_periods: super::monitor::periods(
                    positive(s.estop_stop_time_s, "safety.estop_stop_time_s")?,
                    period_s,
                ),
                estop_left: None,
                timeout_periods: super::monitor::periods(
                    positive(s.stop_timeout_s, "safety.stop_timeout_s")?,
                    period_s,
                ),
                decel: s.axes.map(|a| a.stop_decel_mm_s2),
                braking: false,
            },
            checks: EncoderChecks {
                check: None,
                periods: super::monitor::periods(
                    positive(s.encoder_check_time_s, "safety.encoder_check_time_s")?,
                    period_s,
                ),
                counts: i64::from(s.encoder_check_counts.max(1)),
                effort: s.axes.map(|a| a.stuck_effort_change),
                arm: None,
                arm_on: s.arm_encoder_check,
                arm_step: core::array::from_fn(|i| {
                    (f64::from(ARM_CHECK_SPEED_MM_S)
                        * f64::from(cfg.encoders[i].counts_per_mm)
                        * period_s) as f32
                }),
                arm_wrong: s.encoder_noise_counts + ARM_CHECK_WRONG_COUNTS,
            },
            applied: Vec3::zero(),
            brakes: Brakes::new(&cfg.brakes, period_s),
            out: ControlOutput::default(),
            snapshot,
        })
    }

    /// Swap in a new configuration at this period boundary (settings changed by the
    /// user): only while the outputs are off, since new gains or a new model could jump
    /// the output. The encoder counters, the homed axes and their origins, the latched
    /// faults and the period count carry over; `cfg` is validated whole first and
    /// nothing changes when it is rejected. Never inlined: the control interrupt calls
    /// it on a settings change only, and its new servo must not sit in the interrupt's
    /// frame every period.
    #[inline(never)]
    pub fn reconfigure(&mut self, cfg: &ServoConfig) -> Result<(), ReconfigureError> {
        if self.state.drives() {
            return Err(ReconfigureError::OutputsOn);
        }
        let counts = self.counters.map(|c| c.count());
        let mut next = Self::build(cfg, [0; AXES], counts).map_err(ReconfigureError::Config)?;
        // the counters' register history, so that the next reading extends them as before
        // (in the direction the new settings give)
        let same_direction = core::array::from_fn::<_, AXES, _>(|i| {
            self.counters[i].inverted() == next.counters[i].inverted()
        });
        next.counters = core::array::from_fn(|i| {
            let mut c = self.counters[i];
            c.set_inverted(next.counters[i].inverted());
            c
        });
        if next.counts_per_mm == self.counts_per_mm
            && next.manual.homing == self.manual.homing
            && same_direction.iter().all(|s| *s)
            && next.motor_inverted == self.motor_inverted
        {
            // the same encoders and switches: the origins still hold
            next.manual.homed = self.manual.homed;
        }
        if next.counts_per_mm == self.counts_per_mm && same_direction.iter().all(|s| *s) {
            // the same count frame: the index references still hold
            next.index.carry_over(&self.index);
        }
        next.faults = self.faults;
        // the offsets applied stay (the tables are the machine's, not the configuration's)
        next.comp = self.comp;
        next.link_down = self.link_down;
        next.state = self.state;
        next.ident.outcome = self.ident.outcome;
        next.ident.outcome_kind = self.ident.outcome_kind;
        next.ident.response_points = self.ident.response_points;
        // (a new configuration is not a new run: a record of its points keeps them)
        next.ident.runs = self.ident.runs;
        let mut snap = self.snapshot;
        snap.model_missing = next.snapshot.model_missing;
        next.snapshot = snap;
        next.publish_faults();
        *self = next;
        Ok(())
    }
}
