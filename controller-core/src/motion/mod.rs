//! Motion generation: the segment planner (queue, blending, look-ahead, jerk-limited
//! feed) and its per-period executor.

pub mod planner;
