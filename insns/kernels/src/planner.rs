//! Planner kernels: the planner in a steady state on a CAM-like contour (a circle of
//! radius 60 mm cut into 0.15 mm G1 segments at 25 mm/s, G64 with the gantry's 0.01 mm
//! tolerance), the queue full and the machine moving.
//!
//! - `planner_sample`: one period's reference, the executor's [`MotionPlanner::sample`]
//!   (what the control interrupt runs before the servo step);
//! - `planner_segment`: one segment added with its look-ahead: [`MotionPlanner::push`]
//!   then one [`MotionPlanner::plan`] (the planner task's work for a new segment; the
//!   same `plan` also runs once per period to top up the step buffer).

use controller_core::motion::planner::{MotionPlanner, Segment, GANTRY_PLANNER};

/// The kernels' planner: 16 segment slots, 64 spans, 32 in the executor's channel, 16
/// steps (smaller than host-sim's 64/256/128/32 so that both kernels fit the emulated
/// 128 KiB of RAM; the per-call work does not depend on the capacities).
pub type KernelPlanner = MotionPlanner<16, 64, 32, 16>;

/// Segments per full circle: 2π·60 mm / 0.15 mm.
const SEGMENTS_PER_TURN: u32 = 2513;
const RADIUS_MM: f32 = 60.0;
const FEED_MM_S: f32 = 25.0;
/// Periods run before counting: the machine is at feed.
const WARMUP_PERIODS: u32 = 3000;

/// The planner on the circle, with the next segment's index.
pub struct PlannerState {
    mp: KernelPlanner,
    next: u32,
}

fn segment(k: u32) -> Segment {
    let th =
        2.0 * core::f32::consts::PI * (k % SEGMENTS_PER_TURN) as f32 / SEGMENTS_PER_TURN as f32;
    let (s, c) = (libm::sinf(th), libm::cosf(th));
    Segment::line([RADIUS_MM * c, RADIUS_MM * s, 0.0], FEED_MM_S, k)
}

impl PlannerState {
    fn new() -> Option<Self> {
        let mut mp = KernelPlanner::new(&GANTRY_PLANNER, [RADIUS_MM, 0.0, 0.0]).ok()?;
        let mut next = 1;
        for _ in 0..WARMUP_PERIODS {
            while mp.free_slots() > 1 {
                mp.push(&segment(next)).ok()?;
                next += 1;
            }
            mp.tick();
        }
        Some(Self { mp, next })
    }

    /// Setup of `planner_sample`: moving at feed, the step buffer topped up.
    pub fn setup_sample() -> Option<Self> {
        let mut s = Self::new()?;
        s.mp.plan();
        let v = s.mp.sample().path_speed_mm_s;
        s.mp.plan();
        (v > 0.5 * FEED_MM_S).then_some(s)
    }

    /// Setup of `planner_segment`: moving at feed with exactly one free slot.
    pub fn setup_segment() -> Option<Self> {
        let s = Self::new()?;
        (s.mp.free_slots() == 1).then_some(s)
    }

    /// One period's reference; returns the X position.
    #[inline(never)]
    pub fn sample(&mut self) -> f32 {
        self.mp.sample().pos_mm.x
    }

    /// One segment pushed and planned; returns the free slots.
    #[inline(never)]
    pub fn add_segment(&mut self) -> usize {
        let _ = self.mp.push(&segment(self.next));
        self.next += 1;
        self.mp.plan();
        self.mp.free_slots()
    }
}
