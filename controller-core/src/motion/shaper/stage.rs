//! The shaper as the machine runs it: between the planner's executor and the servo
//! (issue 24, item 4). [`ShaperStage`] holds the validated shapers of the three axes and
//! their history in the machine's memory (`MachineMemory::shaper`, a static on the board:
//! 9 KiB of history are never moved through the stack), and [`ShaperStage::shape`] turns
//! each period's planner sample into the shaped one the servo follows.
//!
//! - **Off** (zero bytes, [`ShaperStage::NONE`]: the board's default): the sample passes
//!   untouched, bit for bit, for one flag test per period.
//! - **Run**: [`ShaperStage::prime`] fills the history with the program's start, so a
//!   machine at rest stays exactly at rest; a program ends only when the shaped reference
//!   has drained ([`ShaperStage::settled`]), at the programmed end bit for bit. Holds and
//!   aborts are the planner's decelerations, so they are shaped too.
//! - **Path tolerance**: [`ShaperStage::planner_config`] counts the shaper's contour
//!   deviation `B` inside the planner's tolerance `ε` (module [`super::bound`]): blends
//!   within `ε − B`, and when `B` would take more than half of `ε`, the shaped axes'
//!   accelerations are lowered until it takes half.

use super::block::{AxisShapers, InputShaper, ShaperState};
use super::bound::DeviationBound;
use super::BOARD_SHAPER_HISTORY;
use crate::config::ConfigError;
use crate::motion::planner::{PathSample, PlannerConfig};
use crate::motion::trajectory::RefSample;
use crate::Vec3;

/// Why a planner configuration cannot be shaped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapedPlannerError {
    /// A path tolerance of 0 leaves no room for the shaper's deviation.
    NoTolerance,
}

impl ShapedPlannerError {
    pub const fn message(self) -> &'static str {
        match self {
            Self::NoTolerance => {
                "planner.tolerance_mm must be > 0 with input shaping (the shaper's contour deviation is counted inside it)"
            }
        }
    }
}

/// The shapers of a running machine and their history (see the module docs). Zero bytes
/// are a valid stage, switched off (the board's zero-filled static: `active` false, and
/// nothing else is read while it is).
#[derive(Clone, Copy, Debug)]
pub struct ShaperStage {
    active: bool,
    shaper: InputShaper<f32, BOARD_SHAPER_HISTORY>,
    state: ShaperState<f32, BOARD_SHAPER_HISTORY>,
    /// The shapers as configured (what [`Self::shapers`] answers).
    config: AxisShapers,
}

impl ShaperStage {
    /// No shaping: the planner's samples pass untouched.
    pub const NONE: Self = Self {
        active: false,
        shaper: InputShaper::ZERO,
        state: ShaperState::ZERO,
        config: AxisShapers::NONE,
    };

    /// Take `cfg` for a control period `period_s` (validated whole: on an error nothing
    /// changes). No shaper on any axis switches the stage off. The history is refilled at
    /// the next [`Self::prime`]: change shapers only while no program runs.
    // (never inlined: its f64 design is not added to the frame of the machine's
    // construction on the board's boot stack)
    #[inline(never)]
    pub fn configure(&mut self, cfg: &AxisShapers, period_s: f32) -> Result<(), ConfigError> {
        if *cfg == AxisShapers::NONE {
            self.active = false;
            self.config = AxisShapers::NONE;
            return Ok(());
        }
        self.shaper = InputShaper::new(cfg, period_s)?;
        self.config = *cfg;
        self.active = true;
        Ok(())
    }

    /// The shapers configured ([`AxisShapers::NONE`] when off: zero bytes are not a
    /// configuration).
    pub fn shapers(&self) -> &AxisShapers {
        if self.active {
            &self.config
        } else {
            &AxisShapers::NONE
        }
    }

    /// Shaping is on.
    pub fn active(&self) -> bool {
        self.active
    }

    /// The validated shapers (their taps, delay and window).
    pub fn shaper(&self) -> Option<&InputShaper<f32, BOARD_SHAPER_HISTORY>> {
        self.active.then_some(&self.shaper)
    }

    /// The contour deviation bound's moments (zero when off).
    pub fn bound(&self) -> DeviationBound {
        if self.active {
            self.shaper.bound()
        } else {
            DeviationBound::default()
        }
    }

    /// A program starts at rest at `start_mm`: the history holds it.
    pub fn prime(&mut self, start_mm: [f32; 3]) {
        if self.active {
            let s = RefSample {
                pos: Vec3::from_array(start_mm),
                vel: Vec3::zero(),
                acc: Vec3::zero(),
            };
            self.shaper.restart(&mut self.state, &s);
        }
    }

    /// Shape this period's planner sample in place: position, velocity and acceleration;
    /// its tag, mode, tangent and path speed stay the executor's (what it executes).
    #[inline]
    pub fn shape(&mut self, sample: &mut PathSample) {
        if self.active {
            let input = RefSample {
                pos: sample.pos_mm,
                vel: sample.vel_mm_s,
                acc: sample.acc_mm_s2,
            };
            let out = self.shaper.process(&mut self.state, &input);
            sample.pos_mm = out.pos;
            sample.vel_mm_s = out.vel;
            sample.acc_mm_s2 = out.acc;
        }
    }

    /// The shaped reference has caught up with the planner's (always when off): a
    /// program's end waits for it.
    pub fn settled(&self) -> bool {
        !self.active || self.state.is_settled()
    }

    /// `pc` with the shaper's deviation counted inside its path tolerance (module docs);
    /// `pc` itself when off.
    pub fn planner_config(&self, pc: &PlannerConfig) -> Result<PlannerConfig, ShapedPlannerError> {
        shaped_planner_config(&self.bound(), pc)
    }
}

impl Default for ShaperStage {
    fn default() -> Self {
        Self::NONE
    }
}

/// `pc` with the deviation bound `b` counted inside its path tolerance `ε`: the shaped
/// axes' accelerations scaled down until `B ≤ ε/2`, then blends within `ε − B`
/// ([`DeviationBound::blend_tolerance_mm`]). Unchanged when nothing is shaped.
pub fn shaped_planner_config(
    b: &DeviationBound,
    pc: &PlannerConfig,
) -> Result<PlannerConfig, ShapedPlannerError> {
    let dev = b.deviation_bound_axes_mm(pc.acc_max_mm_s2);
    if dev <= 0.0 {
        return Ok(*pc);
    }
    if !(pc.tolerance_mm > 0.0) {
        return Err(ShapedPlannerError::NoTolerance);
    }
    let mut out = *pc;
    let half = 0.5 * pc.tolerance_mm;
    if dev > half {
        // (B is linear in the shaped axes' accelerations: one scale brings it to ε/2)
        let k = half / dev;
        for (a, m) in out.acc_max_mm_s2.iter_mut().zip(b.second_moment_s2) {
            if m > 0.0 {
                *a *= k;
            }
        }
    }
    // (≥ ε/2 up to rounding: the deviation now takes at most half)
    out.tolerance_mm = pc.tolerance_mm - b.deviation_bound_axes_mm(out.acc_max_mm_s2).min(half);
    Ok(out)
}
