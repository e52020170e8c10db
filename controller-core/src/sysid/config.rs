//! Configuration of one axis' identification ([`IdentifyConfig`]), validated once into
//! [`crate::settings::Settings`] by [`super::identifier::Identifier::new`].

use crate::config::{non_negative, positive, ConfigError};
use crate::Real;

/// Largest number of friction-pass speeds (each is run in both directions).
pub const MAX_PASS_SPEEDS: usize = 8;

/// What identification of one axis may do. Lengths mm, speeds mm/s, torques mN·m (the
/// axis' effort unit), times s. The defaults ([`IDENTIFY_DEFAULTS`]) suit the gantry's
/// ball-screw axes; only the window, the cap, the start and the period must be set per
/// machine.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct IdentifyConfig {
    /// Control period, s.
    pub period_s: f32,
    /// Travel window (machine coordinates, mm): the axis must never leave it. Known after
    /// homing, or confirmed by the user on an unhomed axis.
    pub window_min_mm: f32,
    pub window_max_mm: f32,
    /// Distance kept from each end of the window by the planned motion, mm. The start
    /// position must be at least this far inside.
    pub edge_margin_mm: f32,
    /// Hard limit on the commanded effort, mN·m.
    pub torque_cap_mnm: f32,
    /// Rough inertia the velocity loop is tuned for until the first reversal gives an
    /// estimate, mN·m/(mm/s²). The loop is stable from 0.2× to 5× this value (tested over
    /// a 20× range with the guess at the range's geometric middle).
    pub inertia_guess: f32,
    /// Crossover of the identification's velocity loop at the assumed inertia, rad/s.
    pub velocity_bandwidth_rad_s: f32,
    /// Abort (zero effort) above this |velocity|, mm/s; must exceed the fastest pass.
    pub velocity_limit_mm_s: f32,
    /// Largest planned acceleration, mm/s².
    pub accel_max_mm_s2: f32,
    /// Fraction of the cap the planned motion (friction + acceleration) may use; the rest
    /// is left to the velocity loop's feedback.
    pub torque_fraction: f32,
    /// Friction passes: `pass_speed_count` speeds evenly spaced from min to max, each run
    /// once forward and once backward, mm/s.
    pub pass_speed_min_mm_s: f32,
    pub pass_speed_max_mm_s: f32,
    pub pass_speed_count: u8,
    /// Time after a ramp before the steady part of a pass is recorded, s.
    pub settle_s: f32,
    /// Recorded steady part of each pass (shorter when the window ends first), s.
    pub steady_s: f32,
    /// Plateau after each acceleration of the inertia phase, s: the window endpoints sit
    /// at its end, where the acceleration (hence the estimator's lag) has died out.
    pub plateau_s: f32,
    /// Validation move: velocity `V sin(2π f t)` for `validation_cycles` periods.
    pub validation_freq_hz: f32,
    pub validation_cycles: u8,
    /// Integration window of the validation's effort comparison, s.
    pub validation_window_s: f32,
    /// Whole identification must end within this machine time, s.
    pub time_budget_s: f32,
}

/// Defaults for the gantry's axes (reasoning in docs/identification.md): a ±50 mm
/// window at 10 kHz, 0.5 N·m cap; five speeds 20..160 mm/s (20 mm/s is 10× the
/// Stribeck velocity, so the unmodelled Stribeck excess is below 1 % of the Coulomb
/// level, and 160 mm/s fits one pass with 0.1 s of steady motion in 90 mm).
pub const IDENTIFY_DEFAULTS: IdentifyConfig = IdentifyConfig {
    period_s: 1e-4,
    window_min_mm: -50.0,
    window_max_mm: 50.0,
    edge_margin_mm: 5.0,
    torque_cap_mnm: 500.0,
    // geometric middle of 0.02..0.4 mN·m/(mm/s²), the range of ball-screw axes the
    // gantry's motors drive (presets::gantry: X 0.064, Y 0.18, Z 0.041)
    inertia_guess: 0.09,
    velocity_bandwidth_rad_s: 150.0,
    velocity_limit_mm_s: 250.0,
    accel_max_mm_s2: 5000.0,
    torque_fraction: 0.8,
    pass_speed_min_mm_s: 20.0,
    pass_speed_max_mm_s: 160.0,
    pass_speed_count: 5,
    settle_s: 0.04,
    steady_s: 0.15,
    plateau_s: 0.03,
    validation_freq_hz: 2.0,
    validation_cycles: 2,
    validation_window_s: 0.01,
    time_budget_s: 10.0,
};

/// Why a configuration (or the start position) was rejected; every variant names the
/// field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IdentifyConfigError {
    /// A single field is not finite / not positive / negative.
    Param(ConfigError),
    /// `lower` must be strictly below `upper`.
    NotBelow {
        lower: &'static str,
        upper: &'static str,
    },
    /// The named field is outside `[min, max]`.
    OutOfRange {
        name: &'static str,
        min: f32,
        max: f32,
    },
    /// The window (minus both margins) is too short for the named motion.
    WindowTooShort {
        name: &'static str,
        needed_mm: f32,
        usable_mm: f32,
    },
    /// The start position is not inside the window by at least the edge margin.
    StartOutsideWindow {
        start_mm: f32,
        min_mm: f32,
        max_mm: f32,
    },
}

impl From<ConfigError> for IdentifyConfigError {
    fn from(e: ConfigError) -> Self {
        Self::Param(e)
    }
}

impl core::fmt::Display for IdentifyConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Param(e) => write!(f, "identify: {e}"),
            Self::NotBelow { lower, upper } => {
                write!(f, "identify: `{lower}` must be below `{upper}`")
            }
            Self::OutOfRange { name, min, max } => {
                write!(f, "identify: `{name}` must be within [{min}, {max}]")
            }
            Self::WindowTooShort {
                name,
                needed_mm,
                usable_mm,
            } => write!(
                f,
                "identify: `{name}` needs {needed_mm} mm of travel, the window leaves {usable_mm} mm"
            ),
            Self::StartOutsideWindow {
                start_mm,
                min_mm,
                max_mm,
            } => write!(
                f,
                "identify: start position {start_mm} mm must be within [{min_mm}, {max_mm}] mm"
            ),
        }
    }
}

/// Largest `velocity_bandwidth_rad_s * period_s`: 0.2, i.e. 30 samples per cycle of the
/// crossover, where the sampled PI loop still behaves like its continuous design.
pub const MAX_LOOP_BANDWIDTH_PERIODS: f32 = 0.2;

/// Largest control period accepted, s (100 Hz): below that rate the passes' windows
/// hold too few samples.
pub const MAX_PERIOD_S: f32 = 0.01;

/// Validated configuration with derived quantities.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ValidIdentifyConfig {
    pub(crate) c: IdentifyConfig,
    /// Turn points: the planned motion stays within `[turn_min, turn_max]`.
    pub(crate) turn_min_mm: f32,
    pub(crate) turn_max_mm: f32,
    pub(crate) speeds_mm_s: [f32; MAX_PASS_SPEEDS],
    pub(crate) n_speeds: usize,
    /// `(sin, cos)` of the validation move's phase step `2π f Ts`.
    pub(crate) validation_step: (f32, f32),
}

fn ordered(
    lo: f32,
    hi: f32,
    lower: &'static str,
    upper: &'static str,
) -> Result<(), IdentifyConfigError> {
    if lo < hi {
        Ok(())
    } else {
        Err(IdentifyConfigError::NotBelow { lower, upper })
    }
}

fn in_range(v: f32, name: &'static str, min: f32, max: f32) -> Result<f32, IdentifyConfigError> {
    if v >= min && v <= max {
        Ok(v)
    } else {
        Err(IdentifyConfigError::OutOfRange { name, min, max })
    }
}

impl ValidIdentifyConfig {
    pub(crate) fn new(c: &IdentifyConfig, start_mm: f32) -> Result<Self, IdentifyConfigError> {
        let period = positive(c.period_s, "period_s")?;
        in_range(period, "period_s", 0.0, MAX_PERIOD_S)?;
        let wmin = crate::config::finite(c.window_min_mm, "window_min_mm")?;
        let wmax = crate::config::finite(c.window_max_mm, "window_max_mm")?;
        ordered(wmin, wmax, "window_min_mm", "window_max_mm")?;
        let margin = non_negative(c.edge_margin_mm, "edge_margin_mm")?;
        let (turn_min, turn_max) = (wmin + margin, wmax - margin);
        ordered(
            turn_min,
            turn_max,
            "window_min_mm + edge_margin_mm",
            "window_max_mm - edge_margin_mm",
        )?;
        positive(c.torque_cap_mnm, "torque_cap_mnm")?;
        positive(c.inertia_guess, "inertia_guess")?;
        let w = positive(c.velocity_bandwidth_rad_s, "velocity_bandwidth_rad_s")?;
        in_range(
            w * period,
            "velocity_bandwidth_rad_s * period_s",
            0.0,
            MAX_LOOP_BANDWIDTH_PERIODS,
        )?;
        let a = positive(c.accel_max_mm_s2, "accel_max_mm_s2")?;
        in_range(
            positive(c.torque_fraction, "torque_fraction")?,
            "torque_fraction",
            0.0,
            1.0,
        )?;
        let vmin = positive(c.pass_speed_min_mm_s, "pass_speed_min_mm_s")?;
        let vmax = positive(c.pass_speed_max_mm_s, "pass_speed_max_mm_s")?;
        ordered(vmin, vmax, "pass_speed_min_mm_s", "pass_speed_max_mm_s")?;
        let n = in_range(
            c.pass_speed_count as f32,
            "pass_speed_count",
            2.0,
            MAX_PASS_SPEEDS as f32,
        )? as usize;
        let vlim = positive(c.velocity_limit_mm_s, "velocity_limit_mm_s")?;
        // the loop overshoots its setpoint a little; 10 % above the fastest pass
        ordered(
            1.1 * vmax,
            vlim,
            "1.1 * pass_speed_max_mm_s",
            "velocity_limit_mm_s",
        )?;
        let settle = positive(c.settle_s, "settle_s")?;
        let steady = positive(c.steady_s, "steady_s")?;
        positive(c.plateau_s, "plateau_s")?;
        let f_val = positive(c.validation_freq_hz, "validation_freq_hz")?;
        in_range(f_val * period, "validation_freq_hz * period_s", 0.0, 0.01)?;
        in_range(c.validation_cycles as f32, "validation_cycles", 1.0, 20.0)?;
        let vw = positive(c.validation_window_s, "validation_window_s")?;
        ordered(2.0 * period, vw, "2 * period_s", "validation_window_s")?;
        positive(c.time_budget_s, "time_budget_s")?;
        // the fastest pass: accelerate and brake at the planned acceleration, settle and
        // record at least half its steady time
        let usable = turn_max - turn_min;
        let needed = vmax * vmax / a + vmax * (settle + 0.5 * steady);
        if !(needed <= usable) {
            return Err(IdentifyConfigError::WindowTooShort {
                name: "pass_speed_max_mm_s",
                needed_mm: needed,
                usable_mm: usable,
            });
        }
        let start = crate::config::finite(start_mm, "start_pos_mm")?;
        if !(start >= turn_min && start <= turn_max) {
            return Err(IdentifyConfigError::StartOutsideWindow {
                start_mm: start,
                min_mm: turn_min,
                max_mm: turn_max,
            });
        }
        let mut speeds = [0.0; MAX_PASS_SPEEDS];
        for (i, s) in speeds.iter_mut().take(n).enumerate() {
            *s = vmin + (vmax - vmin) * i as f32 / (n - 1) as f32;
        }
        // the crate's f32 sin/cos (libm's works in f64, soft float on the M4; named
        // explicitly so a std build does not pick std's and differ from the board); the step is
        // at most 0.063 rad (validation_freq_hz * period_s <= 0.01)
        let phase_step = 2.0 * core::f32::consts::PI * f_val * period;
        let (step_sin, step_cos) = <f32 as Real>::sin_cos(phase_step);
        Ok(Self {
            c: *c,
            turn_min_mm: turn_min,
            turn_max_mm: turn_max,
            speeds_mm_s: speeds,
            n_speeds: n,
            validation_step: (step_sin, step_cos),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_speeds_evenly_spaced() {
        let s = ValidIdentifyConfig::new(&IDENTIFY_DEFAULTS, 0.0).unwrap();
        assert_eq!(s.n_speeds, 5);
        assert_eq!(&s.speeds_mm_s[..5], &[20.0, 55.0, 90.0, 125.0, 160.0]);
        assert_eq!((s.turn_min_mm, s.turn_max_mm), (-45.0, 45.0));
    }

    #[test]
    fn errors_name_the_field() {
        let d = IDENTIFY_DEFAULTS;
        let e = |c: IdentifyConfig| ValidIdentifyConfig::new(&c, 0.0).unwrap_err();
        assert_eq!(
            e(IdentifyConfig {
                torque_cap_mnm: 0.0,
                ..d
            }),
            IdentifyConfigError::Param(ConfigError::NotPositive("torque_cap_mnm"))
        );
        assert_eq!(
            e(IdentifyConfig {
                window_min_mm: 60.0,
                ..d
            }),
            IdentifyConfigError::NotBelow {
                lower: "window_min_mm",
                upper: "window_max_mm"
            }
        );
        assert_eq!(
            e(IdentifyConfig {
                pass_speed_count: 1,
                ..d
            }),
            IdentifyConfigError::OutOfRange {
                name: "pass_speed_count",
                min: 2.0,
                max: MAX_PASS_SPEEDS as f32
            }
        );
        assert_eq!(
            e(IdentifyConfig {
                velocity_limit_mm_s: 170.0,
                ..d
            }),
            IdentifyConfigError::NotBelow {
                lower: "1.1 * pass_speed_max_mm_s",
                upper: "velocity_limit_mm_s"
            }
        );
        assert_eq!(
            e(IdentifyConfig {
                inertia_guess: f32::NAN,
                ..d
            }),
            IdentifyConfigError::Param(ConfigError::NotFinite("inertia_guess"))
        );
        match e(IdentifyConfig {
            window_min_mm: -10.0,
            window_max_mm: 10.0,
            ..d
        }) {
            IdentifyConfigError::WindowTooShort {
                name: "pass_speed_max_mm_s",
                usable_mm,
                ..
            } => assert_eq!(usable_mm, 10.0),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn start_must_be_inside_the_margins() {
        assert_eq!(
            ValidIdentifyConfig::new(&IDENTIFY_DEFAULTS, 46.0),
            Err(IdentifyConfigError::StartOutsideWindow {
                start_mm: 46.0,
                min_mm: -45.0,
                max_mm: 45.0
            })
        );
        assert!(ValidIdentifyConfig::new(&IDENTIFY_DEFAULTS, -45.0).is_ok());
        assert_eq!(
            ValidIdentifyConfig::new(&IDENTIFY_DEFAULTS, f32::NAN),
            Err(IdentifyConfigError::Param(ConfigError::NotFinite(
                "start_pos_mm"
            )))
        );
    }
}
