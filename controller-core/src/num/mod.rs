//! Numbers: the [`crate::Real`] trait every law is written over (`f32`, the firmware's type;
//! `f64`, the host reference; saturating fixed point), with guarded division and
//! fractional powers; fast roots and trig; shared roots; three-axis vectors; RK4.

pub mod exponent;
pub mod fixed;
pub mod ode;
pub mod powers;
pub mod real;
pub mod shared_root;
pub mod vec3;
