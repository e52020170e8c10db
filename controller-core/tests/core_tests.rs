//! controller-core's integration tests as one test binary: each file of this folder is a module
//! of it (one link and one copy of the crate's generic code instead of one per file;
//! `cargo test --test core_tests -- FILE::` runs one file's tests).

mod planner_common;
mod sysid_common;

#[path = "board_default.rs"]
mod board_default;
#[path = "frame_world.rs"]
mod frame_world;
#[path = "holding_brake.rs"]
mod holding_brake;
#[path = "index_glitch.rs"]
mod index_glitch;
#[path = "link_lossy.rs"]
mod link_lossy;
#[path = "link_segment_frames.rs"]
mod link_segment_frames;
#[path = "machine_shaper.rs"]
mod machine_shaper;
#[path = "machine_supervisor.rs"]
mod machine_supervisor;
#[path = "output_filters.rs"]
mod output_filters;
#[path = "planner_arcs.rs"]
mod planner_arcs;
#[path = "planner_corners.rs"]
mod planner_corners;
#[path = "planner_hold.rs"]
mod planner_hold;
#[path = "planner_props.rs"]
mod planner_props;
#[path = "planner_queue.rs"]
mod planner_queue;
#[path = "planner_rest_to_rest.rs"]
mod planner_rest_to_rest;
#[path = "planner_short_segments.rs"]
mod planner_short_segments;
#[path = "position_24h.rs"]
mod position_24h;
#[path = "reversed_at_rest.rs"]
mod reversed_at_rest;
#[path = "servo_modes.rs"]
mod servo_modes;
#[path = "servo_safety.rs"]
mod servo_safety;
#[path = "shaper.rs"]
mod shaper;
#[path = "sysid_safety.rs"]
mod sysid_safety;
#[path = "sysid_tuning.rs"]
mod sysid_tuning;
