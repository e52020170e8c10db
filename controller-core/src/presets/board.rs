//! The servo configuration the firmware runs on the board (firmware/src/config.rs builds
//! it at its control rate) and the instruction-count harness counts (`insns`
//! `servo_period`): one definition, so the counted period is the board's.
//!
//! Today's behaviour, kept as it was before the servo step moved into the core: the
//! paper's DSMC (Table 2) on every axis with its contour coupling λ = 0.01, outputs
//! limited to [`BOARD_EFFORT_LIMIT`] (= full PWM duty), the PLL velocity estimator at
//! [`BOARD_PLL`], a 2 mm following-error trip, and a 10 mm helix started from wherever
//! the axes are when armed, followed for 15 s and then held. The paper's gains assume the
//! paper's normalised axis (a = 10, b = 1, k = 1): a real machine's axes must be
//! identified and the laws' `plant` set before it runs.

use crate::axes::AXES;
use crate::controller::ControllerConfig;
use crate::coupling::{ContourCouplingConfig, CouplingConfig};
use crate::estimator::{CounterWidth, EstimatorBankConfig, EstimatorConfig, PllConfig};
use crate::law::smc::SmcConfig;
use crate::law::LawConfig;
use crate::motion::path::{PathConfig, PathStart};
use crate::presets::paper::{PAPER_DSMC, PAPER_LAMBDA};
use crate::servo::io::{AmplifierConfig, EncoderConfig};
use crate::servo::{PathPlan, ServoConfig};

/// Default control rate of the board, Hz (`GANTRY_CONTROL_HZ` overrides it at build time).
pub const BOARD_RATE_HZ: u32 = 10_000;

/// Encoder resolution: 2000-line encoders read ×4 on a 5 mm lead screw, 8000 counts per
/// 5 mm.
pub const BOARD_COUNTS_PER_MM: f32 = 1600.0;

/// Counter widths of the encoder timers: TIM2 (X) and TIM5 (Y) are 32-bit, TIM3 (Z)
/// 16-bit (extended in software by the servo step).
pub const BOARD_COUNTERS: [CounterWidth; AXES] = [
    CounterWidth::Bits32,
    CounterWidth::Bits32,
    CounterWidth::Bits16,
];

/// Effort at 100 % PWM duty, in the laws' units; also the laws' `u_max`.
pub const BOARD_EFFORT_LIMIT: f32 = 50.0;

/// Following-error trip level per axis, mm.
pub const BOARD_FOLLOWING_ERROR_MM: f32 = 2.0;

/// Velocity estimator: the PLL (ODrive-style tracking loop) at 628.3 rad/s (100 Hz),
/// critically damped, as host-sim uses for the 0.625 µm axis.
pub const BOARD_PLL: PllConfig = PllConfig {
    bandwidth_rad_s: 628.3,
    damping: 1.0,
};

/// The path the arm button starts: helix r = 10 mm, ω = 1 rad/s, 5 mm/s rise, placed
/// where the axes are, followed for 15 s and then held at its end point.
pub const BOARD_PATH: PathPlan = PathPlan {
    path: PathConfig::Helix {
        center: [0.0; 3],
        radius: 10.0,
        omega: 1.0,
        z_rate: 5.0,
    },
    start: PathStart::FromCurrentPosition,
    duration_s: Some(15.0),
};

/// The board's DSMC: the paper's gains, saturated at [`BOARD_EFFORT_LIMIT`].
pub const BOARD_DSMC: SmcConfig = SmcConfig {
    u_max: BOARD_EFFORT_LIMIT,
    ..PAPER_DSMC
};

const fn encoder(counter: CounterWidth) -> EncoderConfig {
    EncoderConfig {
        counts_per_mm: BOARD_COUNTS_PER_MM,
        counter,
    }
}

/// The board's servo configuration at `rate_hz` (validated by `Servo::new`, which
/// rejects rates outside 100 Hz..50 kHz and estimator tunings unstable at that rate).
pub const fn servo_config(rate_hz: u32) -> ServoConfig {
    // The servo does not quantise: TIM1's duty resolution is the board's own (drive.rs).
    let amplifier = AmplifierConfig {
        full_scale: BOARD_EFFORT_LIMIT,
        resolution_bits: 0,
    };
    ServoConfig {
        rate_hz,
        encoders: [
            encoder(BOARD_COUNTERS[0]),
            encoder(BOARD_COUNTERS[1]),
            encoder(BOARD_COUNTERS[2]),
        ],
        amplifiers: [amplifier; AXES],
        controller: ControllerConfig {
            laws: [LawConfig::Smc(BOARD_DSMC); AXES],
            coupling: CouplingConfig::Contour(ContourCouplingConfig::lambda(PAPER_LAMBDA)),
        },
        estimator: EstimatorBankConfig::uniform(EstimatorConfig::Pll(BOARD_PLL)),
        following_error_mm: [BOARD_FOLLOWING_ERROR_MM; AXES],
        path: Some(BOARD_PATH),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::servo::Servo;

    #[test]
    fn board_configuration_validates_at_the_supported_rates() {
        for rate in [1_000, BOARD_RATE_HZ, 20_000, 50_000] {
            assert!(Servo::<f32>::new(&servo_config(rate), [0; AXES], [0; AXES]).is_ok());
        }
        // the PLL at 628 rad/s is unstable below ω Ts < 0.83, i.e. under ~760 Hz
        assert!(Servo::<f32>::new(&servo_config(500), [0; AXES], [0; AXES]).is_err());
        assert!(Servo::<f32>::new(&servo_config(60_000), [0; AXES], [0; AXES]).is_err());
    }
}
