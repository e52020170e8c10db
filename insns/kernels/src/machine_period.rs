//! The core's whole control period as the board's control interrupt runs it:
//! [`Machine::linked_period`] on the board's machine (firmware `machine_slot`: the
//! supervisor with the planner's executor half, [`SplitExecutor`], the planning half
//! [`SplitPlanner`] run as the `plan` task after every period), behind the link's queues
//! ([`Channels`]):
//!
//! - `machine_period_program`: a period of a streaming program at feed (0.15 mm chords of
//!   a 60 mm circle at 25 mm/s, [`Program::Chords`]) in which a segment request arrives
//!   from the link (as one does after every segment the machine retires) and a telemetry
//!   sample is due (1 kHz, `gantry`'s default): the link's queue taken, the supervisor's
//!   request queue and program, the executor's sample, the servo step, the scope, the
//!   credit and the telemetry sample sent up;
//! - `machine_period_shaped`: `machine_period_program` with the board's set of input
//!   shapers on (settings `shaper.*`: MZV on X at 90 Hz, ZV on Y at 35 Hz, ZVD on Z at
//!   55 Hz, 8 taps): the planner's sample shaped before the servo follows it;
//! - `machine_period_idle`: the same machine after boot, outputs off, nothing queued, no
//!   sample due.
//!
//! The machine is the one of the firmware's QEMU link rig and `gantry --sim`: factory
//! settings with the designed axis models (a fresh board refuses to arm without them),
//! against the simulated gantry (host-sim/scenarios/gcode.toml, build.rs's [`LINK_RUN`]),
//! with homing off (as the board twin's closed-loop test sets it: the axes count as homed
//! where they are armed). The uncounted setup runs it closed-loop on that world, as a
//! host streams a program over the link, until the program is at feed; the counted period
//! then reads what the world's sensors would give for it (recorded in the setup: they
//! depend on the previous periods' outputs only) from [`ReplayIo`], so the count holds
//! none of the world's physics.

use controller_core::axes::AXES;
use controller_core::machine::messages::{MachineState, ProgramEnd, Request, Status};
use controller_core::machine::scope::Scope;
use controller_core::machine::{
    Channels, ControlSide, Down, LinkSide, LinkState, Machine, MachineMemory, MachinePort,
    MachineTaskPlanner, Up, MACHINE_SEGMENTS, MACHINE_SPANS,
};
use controller_core::motion::planner::{PlannerChannels, SplitExecutor, SplitPlanner};
use controller_core::servo::io::{Inputs, ServoIo};
use controller_core::sim::gantry::{designed_settings, gantry_world, GantryOptions};
use controller_core::sim::run::RunConfig;
use controller_core::sim::world::World;

use crate::plan_task::Program;

include!(concat!(env!("OUT_DIR"), "/link_run.rs"));

/// The control interrupt's half of the planner (firmware `machine_slot`).
type Executor = SplitExecutor<'static>;
/// The machine as the firmware holds it.
type KernelMachine = Machine<&'static mut MachineMemory<Executor>, Executor>;
/// The planning half, the firmware's `plan` task.
type PlanTask = SplitPlanner<'static, MACHINE_SEGMENTS, MACHINE_SPANS>;

/// Telemetry every this many periods: `gantry`'s default 1 kHz at the machine's 10 kHz.
pub const TELEMETRY_EVERY: u32 = 10;
/// Periods the setup runs the program at most before it must be at feed.
const PROGRAM_PERIODS: u32 = 3000;
/// Periods the setup waits at most for the arm (the encoder check, the brakes).
const ARM_PERIODS: u32 = 3000;
/// Periods the idle machine runs after boot before its counted period.
const IDLE_PERIODS: u32 = 50;

// The board's statics (firmware `machine_slot`), and the link task's side. Each setup
// takes them anew (blank, as at boot); the kernel state a previous setup built on them
// is not used again.
static mut MEMORY: MachineMemory<Executor> = MachineMemory {
    planner: SplitExecutor::DETACHED,
    scope: Scope::new(),
    comp: controller_core::motion::compensation::CompTables::NONE,
    comp_entry: controller_core::machine::CompEntry::NONE,
    response: controller_core::machine::ResponseRecord::EMPTY,
    shaper: controller_core::motion::shaper::ShaperStage::NONE,
    queue: controller_core::machine::RequestQueue::new(),
    next_settings: None,
    settings: controller_core::settings::FACTORY,
};
static mut PLANNER: MachineTaskPlanner = MachineTaskPlanner::BLANK;
static mut PLANNER_CHANNELS: PlannerChannels = PlannerChannels::new();
static mut CHANNELS: Channels = Channels::new();
static mut MACHINE: Option<KernelMachine> = None;
static mut LINK_STATE: Option<LinkState> = None;
static mut WORLD: Option<World> = None;

/// The counted period's IO: what the world's sensors read for that period (recorded in
/// the setup), the writes kept (in the kernel's state, so they stay).
pub struct ReplayIo {
    inputs: Inputs,
    counters: [u32; AXES],
    index: [Option<u32>; AXES],
    /// The last efforts written (0 after a switch-off), the brake outputs.
    pub effort: [f32; AXES],
    pub outputs_on: bool,
    pub brakes: [bool; AXES],
}

impl ReplayIo {
    /// The reads `world` gives for its next period, in the servo step's order (the index
    /// captures are taken with the inputs).
    fn record(world: &mut World) -> Self {
        let inputs = ServoIo::<f32>::read_inputs(world);
        let counters = ServoIo::<f32>::read_counters(world);
        let index = ServoIo::<f32>::read_index(world);
        Self {
            inputs,
            counters,
            index,
            effort: [0.0; AXES],
            outputs_on: false,
            brakes: [false; AXES],
        }
    }
}

impl ServoIo<f32> for ReplayIo {
    fn read_inputs(&mut self) -> Inputs {
        self.inputs
    }

    fn read_counters(&mut self) -> [u32; AXES] {
        self.counters
    }

    fn read_index(&mut self) -> [Option<u32>; AXES] {
        self.index
    }

    fn write_outputs(&mut self, effort: &[f32; AXES]) {
        self.effort = *effort;
        self.outputs_on = true;
    }

    fn disable_outputs(&mut self) {
        self.effort = [0.0; AXES];
        self.outputs_on = false;
    }

    fn write_brakes(&mut self, released: [bool; AXES]) {
        self.brakes = released;
    }
}

/// The machine in the setup: closed-loop on the world, the planning task after every
/// period, and a host on the link's side.
struct Rig {
    machine: &'static mut KernelMachine,
    world: &'static mut World,
    plan: PlanTask,
    control: ControlSide<'static>,
    link: LinkSide<'static, 'static>,
    /// The period of the last telemetry sample the host got.
    last_telemetry: Option<u32>,
    /// The last status reply.
    status: Option<Status>,
}

impl Rig {
    /// The link rig's machine at boot, built as the firmware builds it (`shaped`: with
    /// the board's set of input shapers in its settings).
    fn boot(shaped: bool) -> Option<Self> {
        let run: RunConfig = postcard::from_bytes(LINK_RUN).ok()?;
        let mut settings = designed_settings();
        for a in &mut settings.axis {
            a.homing.enabled = false;
        }
        if shaped {
            use controller_core::motion::shaper::ShaperKind;
            for (sh, (kind, freq_hz)) in [
                &mut settings.shaper.x,
                &mut settings.shaper.y,
                &mut settings.shaper.z,
            ]
            .into_iter()
            .zip([
                (ShaperKind::Mzv, 90.0),
                (ShaperKind::Zv, 35.0),
                (ShaperKind::Zvd, 55.0),
            ]) {
                sh.kind = Some(kind);
                sh.freq_hz = freq_hz;
            }
        }
        let rate_hz = run.servo.rate_hz;
        // the link rig's world (no index pulses; no switches, homing being off)
        let options = GantryOptions {
            index_pulses: false,
            board_amplifier: false,
        };
        let world = gantry_world(&run.world, &settings, rate_hz, options).ok()?;
        // SAFETY: the emulator (or a host test) runs one setup at a time and calls
        // nothing concurrently; every reference to these statics handed out by an
        // earlier setup belongs to a kernel state that is not used again.
        let (memory, planner, planner_channels, channels, slot, link_state, world) = unsafe {
            let pc = &mut *core::ptr::addr_of_mut!(PLANNER_CHANNELS);
            *pc = PlannerChannels::new();
            let c = &mut *core::ptr::addr_of_mut!(CHANNELS);
            *c = Channels::new();
            let w = &mut *core::ptr::addr_of_mut!(WORLD);
            (
                &mut *core::ptr::addr_of_mut!(MEMORY),
                &mut *core::ptr::addr_of_mut!(PLANNER),
                pc,
                c,
                &mut *core::ptr::addr_of_mut!(MACHINE),
                &mut *core::ptr::addr_of_mut!(LINK_STATE),
                w.insert(world),
            )
        };
        // as at boot (firmware `blank_static`), then firmware `machine_slot::build`
        planner.blank();
        memory.scope.blank();
        let (executor_ends, planner_ends) = planner_channels.split();
        memory.planner.attach(executor_ends);
        let plan = SplitPlanner::new(planner, planner_ends);
        *slot = None;
        let machine = slot.insert(
            Machine::new(
                &settings,
                rate_hz,
                world.counter_registers(),
                world.counts(),
                memory,
            )
            .ok()?,
        );
        let (ends, control) = channels.split();
        let link = LinkSide::new(ends, link_state.insert(LinkState::new(&settings, rate_hz)));
        let mut rig = Self {
            machine,
            world,
            plan,
            control,
            link,
            last_telemetry: None,
            status: None,
        };
        // a host connects and subscribes to telemetry (`gantry`'s default rate)
        rig.link.down(Down::SessionStarted);
        rig.request(Request::Subscribe {
            every_periods: TELEMETRY_EVERY,
            signals: heapless::Vec::new(),
        })?;
        Some(rig)
    }

    /// One control period (the interrupt: the machine's period; the world advances),
    /// then the planning task and the link task (everything sent up taken).
    fn period(&mut self) {
        self.machine
            .linked_period(&mut *self.world, &mut self.control);
        self.world.advance();
        self.plan.run();
        while let Some(u) = self.link.up() {
            match u {
                Up::Telemetry(t) => self.last_telemetry = Some(t.period),
                Up::Status { status, .. } => self.status = Some(status),
            }
        }
        self.link.poll();
    }

    /// Send `r` when there is credit and run periods until the machine retired it.
    fn request(&mut self, r: Request) -> Option<()> {
        for _ in 0..100 {
            if self.link.free_slots() > 0 {
                break;
            }
            self.period();
        }
        if self.link.free_slots() == 0 {
            return None;
        }
        let done = self.machine.retired().wrapping_add(1);
        self.link.down(Down::Request(r));
        for _ in 0..100 {
            self.period();
            if self.machine.retired() == done {
                return Some(());
            }
        }
        None
    }

    /// Run periods until the machine's state is `want` (at most `n`).
    fn until_state(&mut self, want: MachineState, n: u32) -> Option<()> {
        for _ in 0..n {
            if self.machine.status().state == want {
                return Some(());
            }
            self.period();
        }
        None
    }

    /// The counted period's state: the machine and its link end, the world's reads
    /// for that period.
    fn into_kernel(self) -> MachinePeriod {
        MachinePeriod {
            io: ReplayIo::record(self.world),
            machine: self.machine,
            control: self.control,
        }
    }
}

/// A host streaming [`Program::Chords`] from where the machine was armed.
struct Stream {
    start_mm: [f32; 3],
    next: u32,
}

impl Stream {
    /// Send segments while the link has credit.
    fn top_up(&mut self, rig: &mut Rig) {
        while rig.link.free_slots() > 0 {
            self.send(rig);
        }
    }

    fn send(&mut self, rig: &mut Rig) {
        let seg = Program::Chords.segment_from(self.next, self.start_mm);
        rig.link.down(Down::Request(Request::Segment(seg)));
        self.next += 1;
    }
}

/// State of the `machine_period_*` kernels: the board's machine, its end of the link's
/// queues (holding what arrives in the counted period), the replayed IO.
pub struct MachinePeriod {
    machine: &'static mut KernelMachine,
    control: ControlSide<'static>,
    io: ReplayIo,
}

impl MachinePeriod {
    /// Arm, start the program, stream it until it is at feed with the planner's and the
    /// machine's queues full; then hold the next segment back until a telemetry sample
    /// is due, send it, and stop before that period. `None` unless the machine runs the
    /// program at feed then.
    pub fn setup_program() -> Option<Self> {
        Self::setup_streaming(false)
    }

    /// [`Self::setup_program`] with the board's set of input shapers on.
    pub fn setup_shaped() -> Option<Self> {
        Self::setup_streaming(true)
    }

    fn setup_streaming(shaped: bool) -> Option<Self> {
        let mut rig = Rig::boot(shaped)?;
        rig.request(Request::Arm)?;
        rig.until_state(MachineState::Idle, ARM_PERIODS)?;
        let start_mm = rig.machine.servo().planner_start_mm()?;
        rig.request(Request::Run)?;
        let mut stream = Stream { start_mm, next: 1 };
        // (shaped, the path's acceleration is lowered to keep the shapers' deviation in
        // the tolerance, and the reference comes one delay later: longer to reach feed)
        let periods = if shaped {
            2 * PROGRAM_PERIODS
        } else {
            PROGRAM_PERIODS
        };
        for _ in 0..periods {
            stream.top_up(&mut rig);
            rig.period();
        }
        // the next segment waits for credit and for the period before a sample
        let mut sent = false;
        for _ in 0..4 * TELEMETRY_EVERY * 100 {
            let next = rig.machine.servo().snapshot().period.wrapping_add(1);
            let due = rig
                .last_telemetry
                .is_some_and(|p| next.wrapping_sub(p) >= TELEMETRY_EVERY);
            if due && rig.link.free_slots() > 0 {
                stream.send(&mut rig);
                sent = true;
                break;
            }
            rig.period();
        }
        let status = rig.machine.status();
        let t = rig.machine.telemetry();
        let speed = libm::sqrtf(t.ref_vel_mm_s.iter().map(|v| v * v).sum::<f32>());
        let at_feed = status.state == (MachineState::Run { held: false })
            && status.program.end == ProgramEnd::Running
            && status.first_fault.is_none()
            && (0.98..=1.02).contains(&t.feed_ratio)
            && (24.0..=26.0).contains(&speed)
            // the program streams: the planner full, requests waiting behind it
            && status.planner_free <= 1
            && usize::from(status.queued) + 1 >= controller_core::machine::REQUEST_QUEUE;
        (sent && at_feed).then(|| rig.into_kernel())
    }

    /// The machine after boot, disarmed (outputs off), with a host connected and
    /// subscribed, nothing queued; the counted period sends no sample.
    pub fn setup_idle() -> Option<Self> {
        let mut rig = Rig::boot(false)?;
        for _ in 0..IDLE_PERIODS {
            rig.period();
        }
        // a period with no telemetry sample due next
        for _ in 0..TELEMETRY_EVERY {
            let next = rig.machine.servo().snapshot().period.wrapping_add(1);
            if rig
                .last_telemetry
                .is_some_and(|p| next.wrapping_sub(p) < TELEMETRY_EVERY)
            {
                break;
            }
            rig.period();
        }
        let status = rig.machine.status();
        let idle = status.state == MachineState::Disabled
            && status.queued == 0
            && status.first_fault.is_none()
            && !rig.machine.servo().snapshot().outputs_on;
        idle.then(|| rig.into_kernel())
    }

    /// One control period behind the link; returns the X effort written.
    #[inline(never)]
    pub fn step(&mut self) -> f32 {
        self.machine.linked_period(&mut self.io, &mut self.control);
        self.io.effort[0]
    }
}
