//! Build-time configuration of the board: control rate, PWM carrier, telemetry and button
//! timing, and the servo configuration (controller-core's `presets::board`, shared with
//! the instruction-count harness so the counted period is the board's).
//!
//! The control rate can be changed at build time with the environment variable
//! `GANTRY_CONTROL_HZ` (e.g. `GANTRY_CONTROL_HZ=20000 cargo fw`); the default is 10 kHz.

use controller_core::presets::board::{self, BOARD_RATE_HZ};
use controller_core::servo::ServoConfig;

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
pub const CONTROL_RATE_HZ: u32 = parse_u32_or(option_env!("GANTRY_CONTROL_HZ"), BOARD_RATE_HZ);
const _: () = assert!(CONTROL_RATE_HZ >= 100 && CONTROL_RATE_HZ <= 50_000);

/// Servo PWM carrier frequency (TIM1), Hz.
pub const PWM_FREQUENCY_HZ: u32 = 20_000;

/// Interval between telemetry log lines, milliseconds.
pub const TELEMETRY_PERIOD_MS: u32 = 100;

/// The arm button is sampled this often, milliseconds.
pub const BUTTON_POLL_MS: u32 = 1;

/// The arm button must read pressed this long, milliseconds.
pub const ARM_BUTTON_HOLD_MS: u32 = 20;

/// Arm button hold time in button samples.
pub const ARM_BUTTON_HOLD_SAMPLES: u16 = (ARM_BUTTON_HOLD_MS / BUTTON_POLL_MS) as u16;

/// The servo configuration the board runs: the paper's DSMC on every axis with contour
/// coupling λ = 0.01, effort limit 50 = full duty, PLL 628.3 rad/s, 2 mm following
/// error, the 10 mm helix from the arm position for 15 s; encoders X/Y 32-bit, Z 16-bit,
/// 1600 counts/mm (see controller-core `presets::board`).
pub const SERVO: ServoConfig = board::servo_config(CONTROL_RATE_HZ);

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::servo::Servo;

    #[test]
    fn the_board_configuration_validates() {
        assert_eq!(SERVO.rate_hz, CONTROL_RATE_HZ);
        assert!(Servo::<f32>::new(&SERVO, [0; 3], [0; 3]).is_ok());
        assert_eq!(ARM_BUTTON_HOLD_SAMPLES, 20);
    }
}
