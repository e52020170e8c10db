//! The machine: the supervisor the firmware and the simulated machine (`gantry --sim`) run
//! behind the host link. It owns the servo step, the motion planner and the settings, and
//! turns link requests into servo commands, planner segments and settings changes at a
//! period boundary ([`Machine::period`]); the link's real-time requests (hold, resume,
//! stop, status) act at the next period boundary, and link loss stops the machine.
//!
//! Message types: [`messages`]. The link's end: [`Endpoint`], which reaches the machine
//! only through the lock-free queues of [`port`] (on the board the link task and the
//! control interrupt). A settings save is written by the link side (`save`, feature `store`). Transport:
//! [`crate::link`].

mod comp_entry;
mod endpoint;
pub mod messages;
pub mod port;
#[cfg(feature = "serde")]
pub mod record;
mod response_record;
#[cfg(feature = "store")]
pub mod save;
pub mod scope;
mod settings_agent;
mod supervisor;

pub use comp_entry::CompEntry;
pub use endpoint::Endpoint;
pub use port::{
    Channels, ControlSide, Down, Echo, LinkEnds, LinkSide, LinkState, MachinePort,
    PreparedSettings, SaveJob, Up, REQUEST_QUEUE,
};
pub use response_record::ResponseRecord;
#[cfg(feature = "store")]
pub use save::{save_blocking, save_due_into, write_blocking};
pub use settings_agent::{Resolution, SettingsAgent};
pub use supervisor::{
    Machine, MachineError, MachineMemory, MachinePlanner, MachineTaskPlanner, RequestQueue, Seen,
    ShaperChangeError, MACHINE_SEGMENTS, MACHINE_SPANS,
};
