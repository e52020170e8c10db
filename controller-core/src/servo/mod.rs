//! The per-period servo step: the one control sequence the board's control interrupt, the
//! simulator's discrete mode and the firmware's QEMU rig all run, with its safety state
//! machine (states, fault detection, stops, reset rules). The machine's supervisor
//! ([`crate::machine`]) sits above it and is the only layer called a supervisor.
//!
//! [`Servo::period`] (in [`step`]), in order:
//!
//! 1. sample the inputs; e-stop and amplifier faults latch in any state, limit switches
//!    while the outputs are on; apply the period's commands ([`modes`]); if the outputs
//!    may not be driven, switch them off *before anything else*;
//! 2. read the encoder counters and extend them to wide counts
//!    ([`crate::estimator::WideCounter`]: the signed difference of successive readings
//!    modulo the counter width, so a wrap can be neither lost nor double counted);
//! 3. sample the reference ([`crate::motion::reference::Motion`]: hold, path, controlled
//!    stop, jog, homing, the planner's sample);
//! 4. positions from counts and velocity estimates ([`crate::estimator::EstimatorBank`]);
//! 5. while enabled: the encoder checks ([`monitor`]); evaluate the 3-axis controller and
//!    check its outputs and states are finite; saturate to the amplifiers' range; check
//!    following error and speed; write the outputs, or switch them off on an immediate
//!    fault, or start a controlled stop; commit every controller and estimator state with
//!    the output actually applied;
//! 6. the holding brakes' commands ([`brake`]: released only on an axis driven now and in
//!    the previous period, engaged at the end of a controlled stop), written out once;
//!    then publish the telemetry [`Snapshot`](snapshot::Snapshot) (plain copies).
//!
//! States ([`ServoState`], [`state`]): `Disabled` (boot; outputs off) → arm → `Idle`
//! (holding the position it armed at: arming never starts motion) → `Run` (a path or the
//! planner's program), `Jog`, `Homing` or `Identify` (the model identification, or the
//! frequency response of `Command::MeasureResponse`), each back to `Idle` (a stop command
//! ends the motion with a controlled stop). A fault of the immediate category goes
//! straight to `Fault` (outputs off in that period); a controlled one goes through
//! `Stopping`. `Fault` → reset → `Disabled` only once every cause is gone; an encoder fault
//! first runs the encoder check (`EncoderCheck`): the axis must follow a small effort in
//! both directions, or the reset is refused. Which command is valid when:
//! [`modes::check`]; the transitions: [`modes`]; the encoder checks' state: `checks`, their
//! periods: `encoder_check`; the controlled stop's state: `stop`; homing's and jogging's:
//! `manual` (their periods: `manual_period`); identification's: [`identify`] (its periods:
//! `identify_period`).
//!
//! Holding brakes ([`brake`]): motion commanded while a brake still opens is accepted and
//! held at rest until it is open ([`Servo::motion_held`]); a controlled stop ends with the
//! brakes gripping before the outputs go off; an immediate one engages them in the period
//! the outputs go off.
//!
//! Coordinates: the servo works in machine coordinates, the wide encoder counts whose
//! origin homing moves ([`crate::motion::homing`], `WideCounter::rebase`); the encoder
//! checks see the steps between readings, so re-basing never looks like a jump. Soft
//! limits ([`travel`]) apply to axes that are homed (or take no part in homing).
//!
//! Configuration: [`ServoConfig`] ([`config`]), validated whole when the servo is built or
//! reconfigured.
//!
//! Nothing here allocates, blocks, formats or panics; every number that reaches an output
//! is finite and within the amplifier's range.

pub mod brake;
mod build;
mod checks;
pub mod commands;
pub mod config;
mod encoder_check;
pub mod faults;
pub mod identify;
mod identify_period;
pub mod index_check;
pub mod io;
mod manual;
mod manual_period;
pub mod modes;
pub mod monitor;
pub mod snapshot;
pub mod state;
pub mod step;
mod stop;
pub mod travel;

pub use commands::{Command, CommandRefusal};
pub use config::{PathPlan, ReconfigureError, ServoConfig, MAX_RATE_HZ, MIN_RATE_HZ};
pub use state::ServoState;
pub use step::{Servo, ARM_CHECK_SPEED_MM_S, STOPPING_FERROR_SCALE};
