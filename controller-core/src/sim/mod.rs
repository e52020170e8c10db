//! The simulated machine: the world that stands in for the board's encoders, amplifiers
//! and input pins around the plant models of [`crate::plant`], and the figures taken on
//! its true state. Used by host-sim and by the firmware's QEMU rig (one implementation:
//! the same world drives the same servo step in both).
//!
//! - [`world`]: three plants behind encoders and amplifiers, implementing
//!   [`crate::servo::io::ServoIo`];
//! - [`frame_step`]: one period of an axis with a frame (motor and tool side together);
//! - [`gantry`]: the simulated gantry (designed settings, the world with its homing
//!   switches) of host-sim's `gantry --sim` and the QEMU link rig;
//! - [`run`]: a simulated run (the machine + world + figures, scripted commands);
//! - [`run_memory`]: a scripted run's machine memory without a planner;
//! - [`program`]: a program run's requests (a polyline streamed as segments);
//! - [`truth`]: tracking and contour figures of the true plant state;
//! - [`rng`]: the SplitMix64 generator every simulation and study draws from;
//! - [`random`]: random physical axes from the documented range.

pub mod frame_step;
pub mod gantry;
pub mod program;
pub mod random;
pub mod rng;
pub mod run;
pub mod run_memory;
pub mod truth;
pub mod world;
