//! The simulated machine: axis plant models, the simulated world that stands in for the
//! board's encoders, amplifiers and input pins, and the figures taken on its true state.
//! Used by host-sim and by the firmware's QEMU rig (one implementation: the same world
//! drives the same servo step in both).
//!
//! - [`plant`]: the paper's normalised axis, the [`plant::AxisDynamics`] trait and RK4;
//! - [`physical`]: the ball-screw axis with inertia, friction, load and torque limit;
//! - [`world`]: three plants behind encoders and amplifiers, implementing
//!   [`crate::servo::io::ServoIo`];
//! - [`run`]: a simulated run (servo step + world + figures, scripted commands);
//! - [`truth`]: tracking and contour figures of the true plant state.

pub mod physical;
pub mod plant;
pub mod rng;
pub mod run;
pub mod truth;
pub mod world;
