//! The motion planner: lines, circular arcs in any plane and helices, blended within a
//! path tolerance, with a jerk-limited feed along the path, look-ahead over the queue,
//! feed override, feed hold/resume and abort. `no_std`, no allocation, fixed capacities,
//! f32 throughout. The method, its bounds and measured figures: docs/planner.md.
//!
//! Two halves, one implementation on the board and in the simulator:
//!
//! * [`Planner`] (lower-priority task): [`Planner::push`] validates and queues segments
//!   ([`Segment`]); [`Planner::produce`] cuts the queue into polynomial [`Span`]s (septic
//!   per axis, limits per span), hands them to the executor as needed and generates one
//!   [`Step`] (span, σ, σ̇, σ̈) per control period with the look-ahead.
//! * [`Executor`] (control interrupt): [`Executor::sample`] takes one step and evaluates
//!   its span into the reference [`PathSample`] (position, velocity, acceleration,
//!   tangent, feed ratio, tag) in a bounded, loop-free amount of work. Feed hold, resume,
//!   abort and override act in the planner's look-ahead (so that every span's limits hold
//!   while stopping); the executor stops by itself only when steps run out (underrun).
//!
//! **Protocol.** Spans and steps flow planner → executor through two single-producer,
//! single-consumer queues ([`channel::Sink`]/[`channel::Source`]; `heapless::spsc` on the
//! board, lock-free). The executor publishes an [`ExecutorStatus`] (a small `Copy` value,
//! through a third queue on the board) that the planner reads with
//! [`Planner::sync`] before each `produce`: it tells which spans may be dropped and, after
//! the executor stopped on its own (underrun), the new epoch and the exact stop point from
//! which the planner restarts the profile. Steps of an old epoch are
//! dropped by the executor, so neither side ever waits for the other.
//!
//! [`MotionPlanner`] wires both halves for a single thread (host-sim, tests);
//! [`split`] runs them in two tasks (the board: [`SplitPlanner`] in a task below the
//! control interrupt, [`SplitExecutor`] in it). The supervisor drives either through
//! [`PlannerHandle`].

mod blend;
pub mod channel;
pub mod config;
mod corner;
mod executor;
pub mod fmath;
mod geometry;
pub mod handle;
mod lookahead;
mod mintree;
mod pipeline;
#[allow(clippy::module_inception)]
mod planner;
pub mod profile;
mod ring;
mod scan;
pub mod segment;
pub mod span;
pub mod split;

pub use config::{PlannerConfig, PlannerConfigError, ValidPlannerConfig, GANTRY_PLANNER};
pub use executor::{ExecMode, Executor, ExecutorStatus, PathSample, Step};
pub use handle::{Offer, PlannerHandle, RestartError};
pub use pipeline::MotionPlanner;
pub use planner::{
    check_feed_override, Planner, PlannerState, PlannerStatus, FEED_OVERRIDE_MAX, FEED_OVERRIDE_MIN,
};
pub use segment::{Blend, Feed, Motion, Plane, Segment, SegmentError, MAX_ARC_PIECES};
pub use span::{Span, SpanPoint};
pub use split::{PlannerChannels, SplitExecutor, SplitPlanner};
