//! The machine: the supervisor the firmware and the simulated machine (`gantry --sim`) run
//! behind the host link. It owns the servo step, the motion planner and the settings, and
//! turns link requests into servo commands, planner segments and settings changes at a
//! period boundary ([`Machine::period`]); the link's real-time requests (hold, resume,
//! stop, status) act at once ([`Machine::realtime`]), and link loss stops the machine.
//!
//! Message types: [`messages`]. Transport: [`crate::link`].

mod endpoint;
pub mod messages;
mod supervisor;

pub use endpoint::Endpoint;
pub use supervisor::{Machine, MachineError, MachinePlanner, REQUEST_QUEUE};
