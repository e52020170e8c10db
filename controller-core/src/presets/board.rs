//! The servo configuration the firmware runs on the board (firmware/src/config.rs builds
//! it at its control rate) and the instruction-count harness counts (`insns`
//! `servo_period`): one definition, so the counted period is the board's.
//!
//! The shipped default drives the physical gantry of [`crate::presets::gantry`] in
//! machine units (mm, mN·m): the paper's DSMC rescaled to each axis' model
//! ([`dsmc_for`]) with the paper's contour coupling at λ = 1 (the gain that matters in
//! mm; docs/seed-methods.md), efforts limited to each motor's peak torque (the
//! amplifiers' full command), the PLL at [`BOARD_PLL`], the gantry's fault thresholds and
//! its holding brake on Z ([`crate::presets::gantry::GANTRY_BRAKES`]).
//! Arming holds position; the demo helix ([`BOARD_PATH`]) runs only when a path is
//! started explicitly (firmware feature `demo-helix`, or the host link).
//!
//! A real machine's axes differ from these presets: identify them (`gantry identify`) and
//! store the result before running the model-based laws.

use crate::axes::AXES;
use crate::controller::ControllerConfig;
use crate::coupling::{ContourCouplingConfig, CouplingConfig};
use crate::estimator::{EstimatorBankConfig, EstimatorConfig, PllConfig};
use crate::law::LawConfig;
use crate::motion::jog::JogConfig;
use crate::motion::path::{PathConfig, PathStart};
use crate::presets::gantry::{
    dsmc_for, GANTRY_AMPLIFIERS, GANTRY_BRAKES, GANTRY_ENCODERS, GANTRY_HOMING, GANTRY_SAFETY,
    GANTRY_TRAVEL, GANTRY_X, GANTRY_Y, GANTRY_Z,
};
use crate::servo::monitor::SafetyConfig;
use crate::servo::{PathPlan, ServoConfig};
use crate::sysid::IDENTIFY_DEFAULTS;

/// Worst-case erase of one 128 KiB flash sector of the STM32F407 at the 8-bit
/// parallelism the HAL programs with, ms (DS8626, flash programming characteristics: 2 s
/// typical). The whole chip stalls for it (one flash bank): the firmware stretches its
/// watchdog above it, the host expects that much silence from the link around a save.
pub const FLASH_SECTOR_ERASE_MAX_MS: u32 = 4_000;

/// Default control rate of the board, Hz (`GANTRY_CONTROL_HZ` overrides it at build time).
pub const BOARD_RATE_HZ: u32 = 10_000;

/// Contour coupling gain on the physical axes (mm): λ = 1 (the paper's 0.01 was chosen for
/// its normalised units, where it is negligible).
pub const BOARD_LAMBDA: f32 = 1.0;

/// Velocity estimator: the PLL at 1000 rad/s, critically damped; of the sweep
/// 628 / 1000 / 2000 / 4000 rad/s on the physical helix it gave the lowest DSMC contour
/// error with chattering within 1.5× the exact velocity's (docs/velocity-estimation.md).
pub const BOARD_PLL: PllConfig = PllConfig {
    bandwidth_rad_s: 1000.0,
    damping: 1.0,
};

/// The demo path: helix r = 10 mm, ω = 1 rad/s (10 mm/s), 5 mm/s rise, placed where the
/// axes are, followed for 15 s and then held at its end point.
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

/// The servo configuration of the gantry as designed at `rate_hz` (validated by
/// `Servo::new`, which rejects rates outside 100 Hz..50 kHz and estimator tunings
/// unstable at that rate): the simulated gantry, the QEMU rig and the instruction counts
/// run it. Its axis models are the presets', marked known.
pub const fn servo_config(rate_hz: u32) -> ServoConfig {
    ServoConfig {
        rate_hz,
        encoders: GANTRY_ENCODERS,
        amplifiers: GANTRY_AMPLIFIERS,
        brakes: GANTRY_BRAKES,
        controller: ControllerConfig {
            laws: [
                LawConfig::Smc(dsmc_for(&GANTRY_X)),
                LawConfig::Smc(dsmc_for(&GANTRY_Y)),
                LawConfig::Smc(dsmc_for(&GANTRY_Z)),
            ],
            coupling: CouplingConfig::Contour(ContourCouplingConfig::lambda(BOARD_LAMBDA)),
        },
        estimator: EstimatorBankConfig::uniform(EstimatorConfig::Pll(BOARD_PLL)),
        safety: SafetyConfig::with_axes(GANTRY_SAFETY),
        path: Some(BOARD_PATH),
        travel: GANTRY_TRAVEL,
        homing: GANTRY_HOMING,
        jog: JogConfig::GANTRY,
        identify: IDENTIFY_DEFAULTS,
        model_known: [true; AXES],
        feedforward: [crate::motion::feedforward::FeedForwardConfig::NONE; AXES],
        filters: [crate::filter::AxisFilterConfig::NONE; AXES],
    }
}

/// What a board runs before anything was stored in its settings: [`servo_config`] with
/// every axis model unknown, so the model-based laws refuse to arm until the axes are
/// identified (or their models entered) — the presets describe the gantry we designed,
/// not the machine the board was flashed onto.
pub const fn factory_config(rate_hz: u32) -> ServoConfig {
    let mut c = servo_config(rate_hz);
    c.model_known = [false; AXES];
    c
}

const _: () = assert!(AXES == 3);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::servo::Servo;

    #[test]
    fn board_configuration_validates_at_the_supported_rates() {
        for rate in [2_000, BOARD_RATE_HZ, 20_000, 50_000] {
            let cfg = servo_config(rate);
            assert!(Servo::<f32>::new(&cfg, [0; AXES], [0; AXES]).is_ok());
            assert!(cfg.safety.check_for_machine().is_ok());
        }
        // the PLL at 1000 rad/s needs ω Ts < 0.83, i.e. a rate above ~1.2 kHz
        assert!(Servo::<f32>::new(&servo_config(1_000), [0; AXES], [0; AXES]).is_err());
        assert!(Servo::<f32>::new(&servo_config(60_000), [0; AXES], [0; AXES]).is_err());
    }
}
