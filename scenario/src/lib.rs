//! # gantry-scenario
//!
//! The one schema of the simulator's input files: a **scenario** describes the machine
//! (per axis: plant model, encoder, amplifier, following-error limit, initial state; the
//! control rate), the path, the controller per axis (explicit gains, or tuned from the
//! axis model), the velocity estimators, and the figures to take. host-sim runs every
//! built-in study from such files (`host-sim/scenarios/`), `host-sim run FILE` runs any of
//! them, and the firmware's QEMU build reads its scenarios from the same files (through
//! its build script), so there is no second copy to keep in step.
//!
//! A file may hold several runs: `[[case]]` and `[[variant]]` tables override parts of the
//! base scenario, and every case runs with every variant it allows (see [`file`]). Tables
//! keyed `x`, `y`, `z` may take their common part from an `all` key.
//!
//! - [`file`]: reading files (size cap, includes, cases and variants, `all` merging), with
//!   errors that name the file, the run and the key;
//! - [`schema`]: the file's types;
//! - [`machine`]: the machine's values checked as the settings check them (and the
//!   physical ranges of those no setting holds);
//! - [`resolve`]: turning one run into the core's configurations (servo, world, figures).

// `!(x <= cap)` is deliberate: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod file;
pub mod machine;
pub mod resolve;
pub mod schema;

pub use file::{load, load_str, ScenarioError, MAX_FILE_BYTES};
pub use resolve::{Resolved, MAX_SIM_STEPS};
pub use schema::{Mode, Numeric, Scenario};
