//! # host-sim
//!
//! Runs the gantry's controller core (the same `controller-core` code the firmware runs)
//! against simulated machines described in scenario files, on a PC.
//!
//! - [`builtin`]: the built-in scenario and machine files, and loading files from disk
//!   (schema: the `gantry-scenario` crate);
//! - [`engine`]: one run in its mode (discrete: the servo step against the simulated
//!   world; continuous: the paper's setting) and number type, with figures and a trace;
//! - [`jobs`]: the one parallel runner every study uses;
//! - [`studies`]: the paper reproduction, the seed methods, the velocity estimators, the
//!   fault matrix, identification, any scenario file, the machine replay and the QEMU
//!   verdict;
//! - [`gcode`]: G-code programs → validated machine moves (before any motion), soft limits;
//!   the program's planner segments, its run on the simulated machine, the measurement
//!   against the programmed path and the report;
//! - [`sim_gantry`]: the simulated gantry the runner, `gantry --sim`, the board twin and
//!   the machine replay are built on;
//! - [`cli`]: the `gantry` command line (a session over the host link with a machine);
//! - [`twin_plant`]: the board twin's plant;
//! - [`output`]: tables, JSON, CSV and plots (bundled font: renders on a bare machine);
//! - [`bench_programs`]: the planner's generated benchmark programs;
//! - [`overrides`]: `--set KEY=VALUE` settings overrides of a run.

// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench_programs;
pub mod builtin;
pub mod cli;
pub mod closed_stdout;
pub mod comp_file;
pub mod engine;
pub mod gcode;
pub mod jobs;
pub mod output;
pub mod overrides;
pub mod sim_gantry;
pub mod studies;
pub mod twin_plant;
