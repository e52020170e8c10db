//! From the settings tree to the servo configuration: the laws from each axis' model and
//! bandwidth (the tuning rules of [`crate::sysid::tuning`]), everything else copied into
//! the board's [`factory_config`], and the result validated by the servo itself.

use crate::axes::{Axis, AXES};
use crate::config::{positive, ConfigError};
use crate::coupling::{ContourCouplingConfig, CouplingConfig};
use crate::estimator::{EstimatorBankConfig, EstimatorConfig};
use crate::filter::AxisFilterConfig;
use crate::law::LawConfig;
use crate::link::LinkConfigError;
use crate::motion::planner::PlannerConfig;
use crate::motion::shaper::{shaped_planner_config, InputShaper, BOARD_SHAPER_HISTORY};
use crate::plant::AxisModel;
use crate::presets::board::factory_config;
use crate::presets::gantry::{GANTRY_X, GANTRY_Y, GANTRY_Z};
use crate::servo::monitor::AxisSafetyConfig;
use crate::servo::{Servo, ServoConfig};
use crate::sysid::tuning::{self, TuningConfig};

use super::tree::{AxisSettings, CouplingKind, LawKind, Settings};

/// The model a law is built from on an axis whose model is unknown (`model = None`): the
/// designed gantry's rigid-body models ([`crate::presets::gantry`]; Z without its gravity
/// load, as the board default's DSMC uses them). It only makes the configuration complete
/// and valid: the servo refuses to arm a model-based law on such an axis
/// (`ServoConfig::model_known` is false), so these gains never drive a machine nobody
/// identified. PID is not model-based and arms with the gains this placeholder gives.
pub const PLACEHOLDER_MODELS: [AxisModel; AXES] = [
    AxisModel::from_physical(&GANTRY_X),
    AxisModel::from_physical(&GANTRY_Y),
    AxisModel::from_physical(&GANTRY_Z),
];

/// Why a settings tree does not give a servo configuration; every variant names the part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ServoConfigError {
    /// The axis' model is not one a law can be built from.
    Model { axis: Axis, error: ConfigError },
    /// The axis' tuning (bandwidth, full scale, counts per mm) is invalid.
    Tuning { axis: Axis, error: ConfigError },
    /// The axis' feed-forward is invalid (the field is named).
    FeedForward { axis: Axis, error: ConfigError },
    /// A filter stage of the axis is invalid at the control rate (`stage`: 1-4; the field
    /// is named).
    Filter {
        axis: Axis,
        stage: u8,
        error: ConfigError,
    },
    /// The link watchdog's timeout is outside its range.
    Link(LinkConfigError),
    /// The motion planner's settings are invalid (the field is named).
    Planner(crate::motion::planner::PlannerConfigError),
    /// The planner would command the axis faster than its overspeed limit.
    PlannerSpeed { axis: Axis },
    /// An axis' input shaper is invalid, or too long for the board's history (the key is
    /// named: `shaper.y.freq_hz`, `shaper.y (zvd) longer than the shaper history …`).
    Shaper(ConfigError),
    /// The shapers leave no path tolerance for the planner's blends
    /// ([`crate::motion::shaper::ShapedPlannerError`]).
    ShaperTolerance(crate::motion::shaper::ShapedPlannerError),
    /// The servo rejected the configuration (its own validation, e.g. an estimator
    /// bandwidth unstable at the control rate, a following error below its at-rest value,
    /// a home position outside the travel).
    Servo(ConfigError),
}

impl core::fmt::Display for ServoConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Model { axis, error } => write!(f, "axis.{}.model: {error}", axis.name()),
            Self::Tuning { axis, error } => write!(f, "axis.{} tuning: {error}", axis.name()),
            Self::FeedForward { axis, error } => write!(f, "axis.{}.{error}", axis.name()),
            Self::Filter { axis, stage, error } => {
                write!(f, "axis.{}.filter.stage{stage}: {error}", axis.name())?;
                match error {
                    ConfigError::OutOfRange(name) if name.ends_with("_hz") => {
                        f.write_str(" (frequencies lie from 1/10000 to 0.45 of the control rate)")
                    }
                    _ => Ok(()),
                }
            }
            Self::Link(e) => write!(f, "{e}"),
            Self::Planner(e) => write!(f, "planner: {e:?}"),
            Self::PlannerSpeed { axis } => {
                write!(f, "planner speed above axis.{}.vel_max_mm_s", axis.name())
            }
            Self::Shaper(e) => write!(f, "{e}"),
            Self::ShaperTolerance(e) => f.write_str(e.message()),
            Self::Servo(e) => write!(f, "servo configuration: {e}"),
        }
    }
}

/// The law of one axis from its settings.
fn law(
    a: &AxisSettings,
    placeholder: &AxisModel,
    axis: Axis,
) -> Result<LawConfig, ServoConfigError> {
    let model = match &a.model {
        Some(m) => {
            m.validate()
                .map_err(|error| ServoConfigError::Model { axis, error })?;
            m
        }
        None => placeholder,
    };
    let tuning_err = |error| ServoConfigError::Tuning { axis, error };
    // guards the division below
    let counts = positive(a.encoder.counts_per_mm, "encoder.counts_per_mm").map_err(tuning_err)?;
    let t = TuningConfig {
        bandwidth_rad_s: a.law.bandwidth_rad_s,
        torque_max_mnm: a.amplifier.full_scale,
        // one count, the DSMC's singular floor; 1/1600 equals the presets' 5/8000 bit for bit
        count_mm: 1.0 / counts,
    };
    t.validate().map_err(tuning_err)?;
    Ok(match a.law.kind {
        LawKind::Pid => LawConfig::Pid(tuning::pid(model, &t)),
        LawKind::Dsmc => LawConfig::Smc(tuning::dsmc(model, &t)),
        LawKind::DobSmc => LawConfig::DobSmc(tuning::dob_smc(model, &t)),
        LawKind::AdaptiveSmc => LawConfig::AdaptiveSmc(tuning::adaptive_smc(model, &t)),
    })
}

impl AxisSettings {
    /// The axis' filter stages that are on, in order, each designed at `period_s` (so a
    /// refusal names the axis and the stage; the servo designs them again when it is
    /// built).
    pub fn filter_config(
        &self,
        axis: Axis,
        period_s: f32,
    ) -> Result<AxisFilterConfig, ServoConfigError> {
        let mut f = AxisFilterConfig::NONE;
        for (stage, s) in (1u8..).zip(self.filter.stages()) {
            if let Some(c) = s.config() {
                let error = |error| ServoConfigError::Filter { axis, stage, error };
                c.design(period_s).map_err(error)?;
                f.push(c).map_err(error)?;
            }
        }
        Ok(f)
    }
}

impl Settings {
    /// The input shapers valid at `rate_hz` and their deviation within the planner `pc`'s
    /// tolerance. Apart and never inlined: the link task validates settings on its stack,
    /// which the control interrupt preempts, and the shapers' f64 design must not add to
    /// the frame that also builds a servo.
    #[inline(never)]
    fn check_shapers(&self, pc: &PlannerConfig, rate_hz: u32) -> Result<(), ServoConfigError> {
        let shaper = InputShaper::<f32, BOARD_SHAPER_HISTORY>::new(
            &self.shaper.shapers(),
            1.0 / rate_hz.max(1) as f32,
        )
        .map_err(ServoConfigError::Shaper)?;
        shaped_planner_config(&shaper.bound(), pc).map_err(ServoConfigError::ShaperTolerance)?;
        Ok(())
    }

    /// The servo configuration these settings describe at control rate `rate_hz`: the
    /// board's [`factory_config`] (counter widths, amplifier resolution, fault-check
    /// timings, the demo path, identification's template) with every value the tree holds
    /// written over it, each axis' law tuned from its model (or the
    /// [`PLACEHOLDER_MODELS`] entry, with `model_known` false). Validated whole: by the
    /// model and tuning checks, the link watchdog's range, `check_for_machine` (every limit
    /// finite) and `Servo::new` itself, so a configuration returned here is one the servo
    /// accepts.
    ///
    /// The servo's own validation is [`Servo::check`], which keeps no servo (0.8 KiB of
    /// frame on the board, where the link task runs this preempted by the control
    /// interrupt).
    pub fn servo_config(&self, rate_hz: u32) -> Result<ServoConfig, ServoConfigError> {
        let mut c = factory_config(rate_hz);
        for (i, a) in self.axis.iter().enumerate() {
            let Some((axis, placeholder)) = Axis::from_index(i).zip(PLACEHOLDER_MODELS.get(i))
            else {
                continue;
            };
            let law = law(a, placeholder, axis)?;
            if let Some(l) = c.controller.laws.get_mut(i) {
                *l = law;
            }
            if let Some(e) = c.encoders.get_mut(i) {
                e.counts_per_mm = a.encoder.counts_per_mm;
                e.invert = a.encoder.invert;
            }
            if let Some(amp) = c.amplifiers.get_mut(i) {
                amp.full_scale = a.amplifier.full_scale;
                amp.invert = a.motor.invert;
            }
            if let Some(s) = c.safety.axes.get_mut(i) {
                *s = AxisSafetyConfig {
                    vel_max_mm_s: a.vel_max_mm_s,
                    accel_max_mm_s2: a.accel_max_mm_s2,
                    min_ferror_mm: a.min_ferror_mm,
                    ferror_mm: a.following_error_mm,
                    stuck_effort_change: a.stuck_effort_change,
                    stop_decel_mm_s2: a.stop_decel_mm_s2,
                };
            }
            if let Some(t) = c.travel.axes.get_mut(i) {
                *t = a.travel;
            }
            if let Some(h) = c.homing.axes.get_mut(i) {
                *h = a.homing;
            }
            if let Some(j) = c.jog.axes.get_mut(i) {
                *j = a.jog;
            }
            if let Some(b) = c.brakes.get_mut(i) {
                *b = a.brake;
            }
            if let Some(k) = c.model_known.get_mut(i) {
                *k = a.model.is_some();
            }
            a.feedforward
                .validate()
                .map_err(|error| ServoConfigError::FeedForward { axis, error })?;
            if let Some(ff) = c.feedforward.get_mut(i) {
                *ff = a.feedforward;
            }
            let f = a.filter_config(axis, 1.0 / rate_hz.max(1) as f32)?;
            if let Some(slot) = c.filters.get_mut(i) {
                *slot = f;
            }
        }
        c.jog.timeout_s = self.jog.timeout_s;
        c.safety.arm_encoder_check = self.safety.arm_encoder_check;
        c.controller.coupling = match self.coupling.kind {
            CouplingKind::None => CouplingConfig::None,
            CouplingKind::Contour => {
                CouplingConfig::Contour(ContourCouplingConfig::lambda(self.coupling.lambda))
            }
        };
        c.estimator = EstimatorBankConfig::uniform(EstimatorConfig::Pll(self.estimator.pll()));
        c.identify.torque_cap_mnm = self.identify.torque_cap_mnm;
        c.identify.edge_margin_mm = self.identify.edge_margin_mm;
        self.link
            .watchdog()
            .validate()
            .map_err(ServoConfigError::Link)?;
        let pc = self.planner_config(rate_hz);
        crate::motion::planner::ValidPlannerConfig::new(&pc).map_err(ServoConfigError::Planner)?;
        self.check_shapers(&pc, rate_hz)?;
        for (a, axis) in self.axis.iter().zip(Axis::ALL) {
            if !(a.planner.vel_max_mm_s <= a.vel_max_mm_s) {
                return Err(ServoConfigError::PlannerSpeed { axis });
            }
        }
        c.safety
            .check_for_machine()
            .map_err(ServoConfigError::Servo)?;
        Servo::<f32>::check(&c).map_err(ServoConfigError::Servo)?;
        Ok(c)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::presets::board::{factory_config, servo_config, BOARD_RATE_HZ};
    use crate::presets::gantry::{dsmc_for, GANTRY_AXES};
    use crate::settings::FACTORY;

    #[test]
    fn factory_settings_give_exactly_the_factory_config() {
        for rate in [2_000, BOARD_RATE_HZ, 20_000, 50_000] {
            assert_eq!(FACTORY.servo_config(rate), Ok(factory_config(rate)));
        }
    }

    #[test]
    fn entering_the_preset_models_gives_the_board_default_bit_for_bit() {
        let mut s = FACTORY;
        for (a, p) in s.axis.iter_mut().zip(&GANTRY_AXES) {
            a.model = Some(AxisModel::from_physical(p));
        }
        let c = s.servo_config(BOARD_RATE_HZ).unwrap();
        assert_eq!(c, servo_config(BOARD_RATE_HZ));
        for (l, p) in c.controller.laws.iter().zip(&GANTRY_AXES) {
            assert_eq!(*l, LawConfig::Smc(dsmc_for(p)));
        }
    }

    #[test]
    fn placeholders_are_the_models_the_board_default_is_tuned_for() {
        for (m, p) in PLACEHOLDER_MODELS.iter().zip(&GANTRY_AXES) {
            assert_eq!(*m, AxisModel::from_physical(p));
            assert_eq!(m.validate(), Ok(()));
        }
    }

    #[test]
    fn every_law_kind_builds_and_validates_on_every_axis() {
        for kind in LawKind::ALL {
            let mut s = FACTORY;
            for a in &mut s.axis {
                a.law.kind = kind;
            }
            let c = s.servo_config(BOARD_RATE_HZ).unwrap();
            for (i, l) in c.controller.laws.iter().enumerate() {
                let t = TuningConfig {
                    bandwidth_rad_s: 157.0,
                    torque_max_mnm: [1000.0, 2000.0, 1000.0][i],
                    count_mm: 1.0 / 1600.0,
                };
                let m = &PLACEHOLDER_MODELS[i];
                let expected = match kind {
                    LawKind::Pid => LawConfig::Pid(tuning::pid(m, &t)),
                    LawKind::Dsmc => LawConfig::Smc(tuning::dsmc(m, &t)),
                    LawKind::DobSmc => LawConfig::DobSmc(tuning::dob_smc(m, &t)),
                    LawKind::AdaptiveSmc => LawConfig::AdaptiveSmc(tuning::adaptive_smc(m, &t)),
                };
                assert_eq!(*l, expected);
            }
            assert_eq!(c.model_known, [false; AXES]);
        }
    }

    #[test]
    fn rejections_name_the_part() {
        let mut s = FACTORY;
        s.axis[1].model = Some(AxisModel {
            inertia: -1.0,
            ..PLACEHOLDER_MODELS[1]
        });
        assert_eq!(
            s.servo_config(BOARD_RATE_HZ),
            Err(ServoConfigError::Model {
                axis: Axis::Y,
                error: ConfigError::NotPositive("inertia")
            })
        );
        let mut s = FACTORY;
        s.axis[2].encoder.counts_per_mm = 0.0;
        assert_eq!(
            s.servo_config(BOARD_RATE_HZ),
            Err(ServoConfigError::Tuning {
                axis: Axis::Z,
                error: ConfigError::NotPositive("encoder.counts_per_mm")
            })
        );
        let mut s = FACTORY;
        s.link.watchdog_ms = 5;
        assert_eq!(
            s.servo_config(BOARD_RATE_HZ),
            Err(ServoConfigError::Link(LinkConfigError::OutOfRange(
                "watchdog.timeout_ms"
            )))
        );
        // valid alone, rejected by the servo: PLL at 5000 rad/s is unstable at 2 kHz
        let mut s = FACTORY;
        s.estimator.pll_bandwidth_rad_s = 5000.0;
        assert!(matches!(
            s.servo_config(2_000),
            Err(ServoConfigError::Servo(ConfigError::Unstable(_)))
        ));
        assert!(s.servo_config(20_000).is_ok());
    }

    #[test]
    fn a_servo_fits_the_frame_the_board_measured() {
        // `Servo::reconfigure` builds a whole servo in the control interrupt's frame (the
        // board's stack high-waters in firmware/README-firmware.md were measured with it
        // at this size): a larger servo needs them measured again
        let size = core::mem::size_of::<Servo<f32>>();
        std::println!("Servo<f32>: {size} bytes");
        assert!(size <= 4400, "Servo<f32> is {size} bytes");
    }
}
