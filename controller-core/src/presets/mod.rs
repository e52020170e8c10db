//! Named parameter sets, each with its source: the reference paper's plant and gains
//! ([`paper`]) and the physical 3-axis gantry with the law tunings derived from its axis
//! models ([`gantry`]); the servo configuration the firmware runs on the board
//! ([`board`]). Presets are values only; scenario files and settings choose which laws
//! run where.

pub mod board;
pub mod gantry;
pub mod paper;
