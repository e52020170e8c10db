//! The board's planning task as it runs (`SplitPlanner::run`, firmware task `plan`, after
//! every control period), with its channel work, on a program in a steady state:
//!
//! - `plan_task_period`: a run with no new segment (sync with the executor's status, the
//!   step buffer topped up by one period, the report): what every period costs;
//! - `plan_task_segment`: a run that takes one new segment (a 0.15 mm chord of a 60 mm
//!   circle at 25 mm/s, the CAM case sent uncompressed) and plans it;
//! - `plan_task_arc`: a run that takes one arc through a point (a compressed primitive:
//!   a 30° arc of a 25.4 mm circle at 200 mm/s) and plans it.
//!
//! Between runs the executor's side runs as the control interrupt does (`offer`, `tick`).
//! The planner is 8 segments and 32 spans (the emulated RAM holds every kernel's state
//! at once); a run's work does not grow with the capacities (the look-ahead's queries
//! are logarithmic in them).

use controller_core::motion::planner::{
    Offer, Planner, PlannerChannels, PlannerHandle, Segment, SplitExecutor, SplitPlanner,
    GANTRY_PLANNER,
};

type TaskPlanner = Planner<8, 32>;

/// What the kernel's program sends (also the program the `machine_period_program`
/// kernel streams, [`crate::machine_period`]).
#[derive(Clone, Copy)]
pub enum Program {
    /// 0.15 mm chords of a 60 mm circle at 25 mm/s.
    Chords,
    /// 30° arcs through a point of a 25.4 mm circle at 200 mm/s.
    Arcs,
}

const CHORD_RADIUS_MM: f32 = 60.0;
const CHORDS_PER_TURN: u32 = 2513;
const CHORD_FEED_MM_S: f32 = 25.0;
const ARC_RADIUS_MM: f32 = 25.4;
const ARCS_PER_TURN: u32 = 12;
const ARC_FEED_MM_S: f32 = 200.0;
/// Periods run before counting: the machine is at feed.
const WARMUP_PERIODS: u32 = 4000;

impl Program {
    /// Where the program starts (segment `k` ends at the `k`-th point of its circle).
    pub fn start(self) -> [f32; 3] {
        match self {
            Program::Chords => [CHORD_RADIUS_MM, 0.0, 0.0],
            Program::Arcs => [ARC_RADIUS_MM, 0.0, 0.0],
        }
    }

    /// Segment `k` (tag `k`, from 1) of the program started at [`Self::start`].
    pub fn segment(self, k: u32) -> Segment {
        self.segment_by(k, None)
    }

    /// Segment `k` of the program started at `start_mm` instead (its circle moved there).
    pub fn segment_from(self, k: u32, start_mm: [f32; 3]) -> Segment {
        let o = self.start();
        self.segment_by(k, Some([0, 1, 2].map(|i| start_mm[i] - o[i])))
    }

    /// Segment `k`, its points moved by `by` mm.
    fn segment_by(self, k: u32, by: Option<[f32; 3]>) -> Segment {
        let shift = |p: [f32; 3]| match by {
            Some(d) => [0, 1, 2].map(|i| p[i] + d[i]),
            None => p,
        };
        let at = |r: f32, n: u32, k: f32| {
            let th = 2.0 * core::f32::consts::PI * k / n as f32;
            shift([r * libm::cosf(th), r * libm::sinf(th), 0.0])
        };
        match self {
            Program::Chords => {
                let p = at(
                    CHORD_RADIUS_MM,
                    CHORDS_PER_TURN,
                    (k % CHORDS_PER_TURN) as f32,
                );
                Segment::line(p, CHORD_FEED_MM_S, k)
            }
            Program::Arcs => {
                let k = k % ARCS_PER_TURN;
                let via = at(ARC_RADIUS_MM, ARCS_PER_TURN, k as f32 - 0.5);
                let end = at(ARC_RADIUS_MM, ARCS_PER_TURN, k as f32);
                Segment::arc_through(via, end, ARC_FEED_MM_S, k)
            }
        }
    }
}

static mut CHANNELS: PlannerChannels = PlannerChannels::new();
static mut PLANNER: TaskPlanner = TaskPlanner::BLANK;

/// Both halves of the board's planner over their channels.
pub struct PlanTask {
    task: SplitPlanner<'static, 8, 32>,
    exec: SplitExecutor<'static>,
    program: Program,
    next: u32,
    /// A segment offered whose result is not back yet.
    pending: bool,
}

impl PlanTask {
    /// The program running at feed; the task's next run takes a segment when `offered`.
    fn new(program: Program, offered: bool) -> Option<Self> {
        // SAFETY: the emulator builds one kernel state at a time and calls nothing
        // concurrently; each setup takes the statics anew (the state it replaces is not
        // used again).
        let (channels, planner) = unsafe {
            let c = &mut *core::ptr::addr_of_mut!(CHANNELS);
            *c = PlannerChannels::new();
            (c, &mut *core::ptr::addr_of_mut!(PLANNER))
        };
        let (exec_ends, task_ends) = channels.split();
        let mut exec = SplitExecutor::DETACHED;
        exec.attach(exec_ends);
        let task = SplitPlanner::new(planner, task_ends);
        let mut s = Self {
            task,
            exec,
            program,
            next: 1,
            pending: false,
        };
        s.exec.restart(&GANTRY_PLANNER, program.start()).ok()?;
        for _ in 0..WARMUP_PERIODS {
            s.period(true);
        }
        // settle into "one slot free": the next offer is the counted one
        for _ in 0..64 {
            if !s.pending && s.exec.free_slots() <= 1 {
                break;
            }
            s.period(true);
        }
        if offered {
            s.offer();
            if !s.pending {
                return None;
            }
        }
        Some(s)
    }

    /// The interrupt's side of a period: offer the next segment while there is room.
    fn offer(&mut self) {
        let seg = self.program.segment(self.next);
        match self.exec.offer(&seg) {
            Offer::Taken => {
                self.pending = false;
                self.next += 1;
            }
            Offer::Later => self.pending = true,
            Offer::Refused(_) => self.pending = false,
        }
    }

    /// One control period and one task run (`keep_full`: offer segments while there is
    /// room, as a host streaming a program does).
    fn period(&mut self, keep_full: bool) {
        if keep_full && (self.pending || self.exec.free_slots() > 1) {
            self.offer();
        }
        self.exec.tick();
        self.task.run();
    }

    pub fn setup_period(program: Program) -> Option<Self> {
        let mut s = Self::new(program, false)?;
        // the buffer topped up, nothing offered: the next run only plans one period ahead
        s.exec.tick();
        (!s.pending).then_some(s)
    }

    pub fn setup_segment(program: Program) -> Option<Self> {
        let mut s = Self::new(program, true)?;
        s.exec.tick();
        Some(s)
    }

    /// One run of the planning task; returns its free slots.
    #[inline(never)]
    pub fn run(&mut self) -> usize {
        self.task.run();
        self.task.planner().free_slots()
    }
}
