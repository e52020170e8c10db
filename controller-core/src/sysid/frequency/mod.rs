//! Frequency response of an axis from the machine: a stepped sine measures the response
//! from the motor's effort to the encoder's position, `H(jω)` (mm per mN·m), at each
//! frequency of a log-spaced grid, and [`find_modes`] finds its resonances and
//! anti-resonances (frequency, damping, height over the rigid-body line): what a notch
//! filter is placed from. Method, defaults and measured accuracy: docs/identification.md,
//! "Frequency response".
//!
//! Why a stepped sine (and not a multisine or a chirp): each frequency is settled and
//! then measured over a whole number of its cycles, so one sin/cos correlation (one
//! DFT bin, a few sums per period, no sample storage) gives its response without leakage,
//! each frequency gets the amplitude it needs, and a light mode's ringing dies out before
//! it is measured. A multisine measures all at once but needs its crest factor in the
//! torque cap and a period's worth of samples (or an FFT) per block; on a 10 kHz
//! interrupt with a few KiB to spare the sums win.
//!
//! **Friction.** An axis at rest sticks: a small sine sees the static friction's
//! stiffness, a larger one a describing-function damping that depends on its amplitude
//! (Coulomb friction `F` on a motion of velocity amplitude `V` damps like a viscous
//! `4F/(πV)`, tens of times the frame's own damping at the amplitudes a backlash allows).
//! So the sine rides on a constant travel speed, far above the Stribeck region and above
//! the sine's own velocity amplitude: the motion never reverses during a measurement, the
//! friction is a constant force that has no component at the sine's frequency, and what is
//! measured is the linear response about the travel (the viscous friction stays, as it
//! does in any motion). The axis travels back and forth inside its window, reversing
//! between two frequencies. The position enters as its steps (the travel's ramp has no
//! component at a whole number of cycles); the travel speed is chosen so that the counts'
//! boundaries fall evenly over the sine's phases ([`ResponseMeasurement::new`]).
//!
//! **Amplitude.** The sine's effort is `Ĵ 2πf v` (a rigid body's velocity amplitude `v`),
//! `Ĵ` the inertia the lowest frequency measures: the velocity amplitude (what the
//! friction and the backlash care about) stays the same over the grid, and the position
//! amplitude falls only as `1/f`.
//!
//! - [`config`]: [`ResponseConfig`], validated once;
//! - [`excitation`]: the grid, each frequency's schedule, the phase-continuous sine;
//! - [`estimate`]: the correlation and the response at one frequency (zero-order-hold
//!   corrected), [`FrequencyResponse`];
//! - [`measure`]: [`ResponseMeasurement`], the per-period state machine with its safety
//!   rules (those of the model identification);
//! - [`loop_measure`]: [`LoopMeasurement`], the same stepped sine added to the laws'
//!   effort while they hold the axis on a travelling reference: the open loop `L(jω)`
//!   the output filters are accepted on;
//! - [`modes`]: [`find_modes`], the rigid-body line, resonances and anti-resonances.

pub mod config;
pub mod estimate;
mod excitation;
pub mod loop_measure;
pub mod measure;
pub mod modes;

pub use config::{ResponseConfig, ResponseConfigError, MAX_POINTS, RESPONSE_DEFAULTS};
pub use estimate::{FrequencyResponse, ResponsePoint};
pub use loop_measure::{LoopMeasurement, LoopReference, LOOP_DEFAULTS};
pub use measure::{ResponseMeasurement, ResponseOutput};
pub use modes::{find_modes, Mode, ModeConfig, ModeError, ModeReport, RigidBody, MODE_DEFAULTS};

#[cfg(test)]
mod loop_tests;
#[cfg(test)]
mod tests;
