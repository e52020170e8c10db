//! The user's settings of the machine: one typed tree ([`Settings`]),
//! the servo configuration it describes ([`Settings::servo_config`]), dotted keys to read
//! and change single values ([`keys`]), and its record in flash ([`store`], feature
//! `store`).
//!
//! The tree holds what a user of a machine sets, identifies or tunes: per axis the law and
//! its bandwidth, the identified (or entered) model, encoder and amplifier scale, limits
//! and fault thresholds, travel, homing and jog; the coupling, the velocity estimator, the
//! link watchdog and identification's torque cap and margin; and, for the host's G-code
//! interpreter, the work coordinate systems and the tool table ([`offsets`]). Everything
//! else a [`ServoConfig`](crate::servo::ServoConfig) holds is a property of the board or of
//! the firmware (counter widths, amplifier resolution, timings of the fault checks, the
//! demo path) and comes from [`crate::presets::board::factory_config`].
//!
//! The flow: the firmware loads the tree at boot ([`store::SettingsStore::load`]; a
//! corrupt or foreign record gives [`FACTORY`] and the caller latches
//! `FaultKind::SettingsCorrupt`), builds the servo configuration from it, and the link's
//! command handler edits it with [`Settings::set`] (every change validated against the
//! whole tree; nothing changes on an error), applies it with `Servo::reconfigure` while the
//! outputs are off, and saves it on request. docs/settings.md lists every key.

pub mod keys;
pub mod offsets;
pub mod servo_config;
#[cfg(feature = "store")]
pub mod store;
pub mod tree;

pub use keys::{Apply, Key, KeyError, Range, SetError, Value};
pub use offsets::{ToolSettings, ToolTable, WorkOffset, WorkOffsets, TOOL_COUNT, WORK_SYSTEMS};
pub use servo_config::{ServoConfigError, PLACEHOLDER_MODELS};
pub use tree::{
    AmplifierSettings, AxisFilterSettings, AxisSettings, CouplingKind, CouplingSettings,
    EncoderSettings, EstimatorSettings, FilterKind, FilterStageSettings, IdentifySettings,
    JogSettings, LawKind, LawSettings, LinkSettings, MotorSettings, Settings, FACTORY, NO_FILTERS,
    SETTINGS_VERSION,
};
