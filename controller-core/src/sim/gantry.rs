//! The simulated gantry every simulated machine is built on: the factory settings with the
//! designed axis models entered ([`designed_settings`]), and the physical world of a
//! machine description with limit switches where the settings' homing expects them
//! ([`gantry_world`]). host-sim's `sim_gantry` (`gantry --sim`, the twin plant, the
//! machine replay) and the firmware's QEMU link rig both build their machine from here,
//! so the machine the replay compares against is built by the same code as the rig's.

use crate::config::ConfigError;
use crate::servo::ServoConfig;
use crate::settings::{ServoConfigError, Settings, FACTORY, PLACEHOLDER_MODELS};
use crate::sim::world::{SwitchConfig, World, WorldConfig};

/// Factory settings with the designed gantry's axis models entered (`gantry --sim`'s
/// machine, and the QEMU link rig's).
pub fn designed_settings() -> Settings {
    let mut settings: Settings = FACTORY;
    for (a, m) in settings.axis.iter_mut().zip(PLACEHOLDER_MODELS) {
        a.model = Some(m);
    }
    settings
}

/// What the world keeps of the machine description besides the homing switches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GantryOptions {
    /// Keep the encoders' index pulses of the machine description (host-sim's world);
    /// without, the switches carry none (the QEMU link rig's world, as it was first
    /// built: the rig's recorded runs are replayed against it).
    pub index_pulses: bool,
    /// The amplifiers apply the duty unquantised (the board twin's plant: the board's
    /// timer is the quantisation).
    pub board_amplifier: bool,
}

/// Why the simulated gantry could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GantryError {
    /// The settings give no servo configuration at the rate.
    Settings(ServoConfigError),
    /// The world rejects the machine description.
    World(ConfigError),
}

/// The physical gantry of `wcfg` with limit switches where `settings`' homing expects
/// them, behind the sensors and actuators `settings` configure at `rate_hz`.
pub fn gantry_world(
    wcfg: &WorldConfig,
    settings: &Settings,
    rate_hz: u32,
    options: GantryOptions,
) -> Result<World, GantryError> {
    let mut wcfg = *wcfg;
    for (sw, homing) in wcfg
        .switches
        .iter_mut()
        .zip(SwitchConfig::for_homing(settings))
    {
        let index_period_counts = if options.index_pulses {
            sw.index_period_counts
        } else {
            homing.index_period_counts
        };
        *sw = SwitchConfig {
            index_period_counts,
            ..homing
        };
    }
    let mut servo_cfg: ServoConfig = settings
        .servo_config(rate_hz)
        .map_err(GantryError::Settings)?;
    if options.board_amplifier {
        for a in &mut servo_cfg.amplifiers {
            a.resolution_bits = 0;
        }
    }
    World::new(&wcfg, &servo_cfg).map_err(GantryError::World)
}
