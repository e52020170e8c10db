//! Build-time configuration: rates, scaling, limits and the selected laws.
//!
//! The control rate can be changed at build time with the environment variable
//! `GANTRY_CONTROL_HZ` (e.g. `GANTRY_CONTROL_HZ=20000 cargo fw`); the default is 10 kHz.

use controller_core::estimator::{EstimatorConfig, EstimatorTiming, PllConfig};
use controller_core::gantry::GantryConfig;
use controller_core::params::{LawConfig, PAPER_DSMC, PAPER_LAMBDA};

use crate::control::{LoopConfig, PathPlan};
use crate::AXES;

/// Parses a decimal `u32` at compile time (for `option_env!`); `default` if absent.
const fn parse_u32_or(s: Option<&str>, default: u32) -> u32 {
    let bytes = match s {
        Some(s) => s.as_bytes(),
        None => return default,
    };
    let mut v: u32 = 0;
    let mut i = 0;
    while i < bytes.len() {
        let d = bytes[i];
        assert!(
            d.is_ascii_digit(),
            "GANTRY_CONTROL_HZ must be a decimal number"
        );
        v = v * 10 + (d - b'0') as u32;
        i += 1;
    }
    v
}

/// Control interrupt rate, Hz (default 10 kHz; 20 kHz fits, see the README).
pub const CONTROL_RATE_HZ: u32 = parse_u32_or(option_env!("GANTRY_CONTROL_HZ"), 10_000);
const _: () = assert!(CONTROL_RATE_HZ >= 100 && CONTROL_RATE_HZ <= 50_000);

/// Control period, seconds.
pub const CONTROL_PERIOD_S: f32 = 1.0 / CONTROL_RATE_HZ as f32;

/// Servo PWM carrier frequency (TIM1), Hz.
pub const PWM_FREQUENCY_HZ: u32 = 20_000;

/// Encoder resolution: 2000-line encoder read x4 = 8000 counts/rev on a 5 mm lead screw.
pub const MM_PER_COUNT: f64 = 5.0 / 8000.0;

/// Interval between telemetry log lines, milliseconds.
pub const TELEMETRY_PERIOD_MS: u32 = 100;

/// Arm/reset button must read pressed this long, seconds.
pub const ARM_BUTTON_HOLD_S: f32 = 0.02;

/// Arm button hold time in control periods.
pub const ARM_BUTTON_HOLD_PERIODS: u16 = (ARM_BUTTON_HOLD_S * CONTROL_RATE_HZ as f32) as u16;

/// Effort that corresponds to 100 % PWM duty on the machine (the laws' `u_max`).
pub const BOARD_EFFORT_LIMIT: f32 = 50.0;

/// Following-error trip level on the machine, mm.
pub const BOARD_FOLLOWING_ERROR_LIMIT_MM: [f32; AXES] = [2.0; AXES];

/// Velocity estimator of the machine: controller-core's PLL (ODrive-style tracking loop),
/// 628 rad/s (100 Hz), critically damped, as host-sim uses for the 0.625 µm axis.
pub const BOARD_PLL: PllConfig = PllConfig {
    bandwidth_rad_s: 628.3,
    damping: 1.0,
};

/// The machine's control loop: the paper's DSMC on every axis with cross-coupling
/// λ = 0.01, saturated at [`BOARD_EFFORT_LIMIT`], following a 10 mm radius helix (one turn
/// in 2π s, 5 mm/s rise) for 15 s from wherever the axes are when armed, then holding its
/// end point. The paper's gains assume the paper's normalised axis; a real machine's axes
/// must be identified and the `plant` of the law set accordingly.
pub fn board_loop() -> LoopConfig {
    let law = LawConfig::Smc(controller_core::params::SmcConfig {
        u_max: BOARD_EFFORT_LIMIT,
        ..PAPER_DSMC
    });
    LoopConfig {
        gantry: GantryConfig::uniform(law, PAPER_LAMBDA),
        estimator: [EstimatorConfig::Pll(BOARD_PLL); AXES],
        accel_model: [None; AXES],
        rate_hz: CONTROL_RATE_HZ,
        length_per_count: MM_PER_COUNT,
        timing: EstimatorTiming {
            period_s: CONTROL_PERIOD_S,
            count_size: MM_PER_COUNT as f32,
        },
        path: PathPlan::HelixFromArmPosition {
            radius: 10.0,
            omega: 1.0,
            z_rate: 5.0,
        },
        following_error_limit: BOARD_FOLLOWING_ERROR_LIMIT_MM,
        horizon_s: None,
        path_duration_s: 15.0,
    }
}
