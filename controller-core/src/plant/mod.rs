//! Models of one axis, below every law, estimator, identification and simulation that
//! uses them: the models the laws and the identification work with, and the physical
//! truth a simulated axis follows.
//!
//! - [`params`]: [`PlantParams`], the normalised axis `θ'' = -a θ' - b θ + k u` a
//!   sliding-mode law's equivalent control cancels and the Kalman estimator predicts with;
//! - [`axis_model`]: [`AxisModel`], the rigid-body model with asymmetric Coulomb friction
//!   that identification produces and the tuning rules start from;
//! - [`state`]: the axis state, the [`state::AxisDynamics`] trait and RK4 over a set of
//!   axes;
//! - [`paper`]: the paper's normalised axis as a simulated plant, with a step disturbance;
//! - [`physical`]: the ball-screw axis with inertia, friction, load and torque limit;
//! - [`frame`]: what lies between an axis' motor and its tool: a compliant mode,
//!   backlash, the screw's lead error.

pub mod axis_model;
pub mod frame;
pub mod paper;
pub mod params;
pub mod physical;
pub mod state;

pub use axis_model::AxisModel;
pub use params::PlantParams;
