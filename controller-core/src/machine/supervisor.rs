//! [`Machine`]: the servo step, the motion planner and the settings behind the link.
//!
//! Requests are queued as they arrive (the link task's side, [`Machine::submit`]) and
//! executed in order at the start of a control period ([`Machine::period`]): servo
//! commands go to the servo step of that period, segments into the planner while it has
//! room (a segment that does not fit waits, and so does everything behind it), settings
//! changes are validated whole and applied only while the outputs are off where they
//! could make the output jump. Each period the planner plans ahead and samples the
//! reference the servo follows in `Run`.
//!
//! Behind the link, [`Machine::linked_period`] first takes what the link task queued
//! (requests, real-time requests, session and link-loss events: [`super::port`]), runs
//! the period, and hands status replies and telemetry back up, all without waiting.
//!
//! The planner is reached through [`PlannerHandle`] only: on the host both of its halves
//! run in the period ([`MachinePlanner`], at most one segment planned per period); on
//! the board the planning half runs in a task below the control interrupt
//! ([`crate::motion::planner::split`]) and the period only samples the reference and
//! passes requests on, in order.

use core::ops::DerefMut;

use heapless::{Deque, String};

use super::messages::{
    FaultCode, IdentifyMsg, MachineState, ModelMsg, Outcome, ProgramEnd, ProgramProgress, Request,
    Status, Telemetry, TELEMETRY_SIGNALS, VALUE_MAX,
};
use super::port::{ControlSide, Down, PreparedSettings, Up, REQUEST_QUEUE};
use super::scope::{Scope, Signal};
use crate::axes::Axis;
use crate::link::RealtimeRequest;
use crate::motion::planner::split::{SPLIT_SPANS, SPLIT_STEPS};
use crate::motion::planner::{
    MotionPlanner, Offer, PathSample, Planner, PlannerConfig, PlannerConfigError, PlannerHandle,
    RestartError, Segment, SegmentError,
};
use crate::motion::shaper::{AxisShapers, ShaperStage};
use crate::servo::io::ServoIo;
use crate::servo::{Command, Servo, ServoConfig, ServoState};
use crate::settings::{Apply, ServoConfigError, Settings};
use crate::sysid::IdentifyStatus;
use crate::Real;

/// Segment slots of the machine's planner.
pub const MACHINE_SEGMENTS: usize = 48;
/// Spans in the planner's ring.
pub const MACHINE_SPANS: usize = 256;

/// The machine's planner with both halves in the period (host-sim, tests): 32 segments,
/// 128 spans, and between its halves as many spans and steps as the board's queues.
pub type MachinePlanner = MotionPlanner<MACHINE_SEGMENTS, MACHINE_SPANS, SPLIT_SPANS, SPLIT_STEPS>;

/// The planning half alone, for a task of its own (the board:
/// [`crate::motion::planner::SplitPlanner`]).
pub type MachineTaskPlanner = Planner<MACHINE_SEGMENTS, MACHINE_SPANS>;

/// The machine's large parts: its planner (40 KiB when both halves are in it; on the
/// board only the executor's half, [`crate::motion::planner::SplitExecutor`]) and the
/// scope's buffer (8 KiB). They live where the caller puts them (a `Box` on the host, a
/// static on the board, built from a constant such as [`Self::BLANK`]) and are never
/// copied through the stack, which on the board could not hold them.
pub struct MachineMemory<M = MachinePlanner> {
    pub planner: M,
    pub scope: Scope,
    /// The backlash and lead-screw compensation tables (6 KiB; all zeros: none).
    pub comp: crate::motion::compensation::CompTables,
    /// A table being entered over the link (2 KiB; all zeros: none under way).
    pub comp_entry: super::CompEntry,
    /// The input shapers between the planner and the servo, with their history (9 KiB;
    /// all zeros: off).
    pub shaper: ShaperStage,
    /// The machine's request queue (11.5 KiB; all zeros: empty).
    pub queue: RequestQueue,
    /// The settings change in the queue, its tree and the servo configuration the link
    /// side derived from it ([`super::port::PreparedSettings`]): at most one is queued,
    /// since a settings request goes down only once every request before it was executed,
    /// so the queue's entry holds only its class. (2.3 KiB, here rather than in the
    /// machine, which is built and moved on the boot stack, or in each of the queue's 16
    /// entries; not valid as zero bytes: a blank memory sets it to `None`.)
    pub next_settings: Option<PreparedSettings>,
    /// The settings tree the machine runs (the factory tree for a machine built from a
    /// servo configuration); set when the machine is built (here for the same reason).
    pub settings: Settings,
    /// The last frequency response's points, for the host (1.5 KiB; all zeros: none).
    /// Last: the fields the control period reads stay at the offsets they had.
    pub response: super::ResponseRecord,
}

/// The machine's request queue: [`REQUEST_QUEUE`] requests as they came or as the link
/// side resolved them (a settings tree is the largest). It lives in the machine's memory,
/// not in the machine, so that the machine stays small (6 KiB) where it is built and
/// moved: on the board's boot stack. Zero bytes are an empty queue (`heapless::Deque`'s
/// indices and flag; the board's memory is a zero-filled static).
pub struct RequestQueue(Deque<Queued, REQUEST_QUEUE>);

impl RequestQueue {
    pub const fn new() -> Self {
        Self(Deque::new())
    }

    /// No request waits.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl Default for RequestQueue {
    fn default() -> Self {
        Self::new()
    }
}

impl MachineMemory<MachinePlanner> {
    pub const BLANK: Self = Self {
        planner: MachinePlanner::BLANK,
        scope: Scope::new(),
        comp: crate::motion::compensation::CompTables::NONE,
        comp_entry: crate::machine::CompEntry::NONE,
        response: crate::machine::ResponseRecord::EMPTY,
        shaper: ShaperStage::NONE,
        queue: RequestQueue::new(),
        next_settings: None,
        settings: crate::settings::FACTORY,
    };
}

/// The control period the shapers are built for, as the settings validate them
/// (`Settings::servo_config`).
fn shaper_period_s(rate_hz: u32) -> f32 {
    1.0 / rate_hz.max(1) as f32
}

/// Why [`Machine::set_shapers`] refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShaperChangeError {
    /// The outputs are on: change shapers with the machine disarmed.
    OutputsOn,
    /// A shaper is invalid (the key is named).
    Config(crate::config::ConfigError),
    /// The shapers leave the planner no path tolerance.
    Tolerance(crate::motion::shaper::ShapedPlannerError),
}

/// What [`Machine::linked_period_seen`] shows of the link's events it takes.
#[derive(Clone, Copy, Debug)]
pub enum Seen<'a> {
    /// An event, as taken.
    Down(&'a Down),
    /// The tree of the [`Down::Apply`] just shown.
    Settings(&'a Settings),
}

/// Why a machine could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MachineError {
    Settings(ServoConfigError),
    Planner(PlannerConfigError),
    /// A split planner whose task's channels were not attached.
    PlannerDetached,
    Servo(crate::config::ConfigError),
}

/// The supervisor (see the module docs). Its large parts live where `P` points
/// ([`MachineMemory`]); `R` is the servo's number type (f32 on the board).
pub struct Machine<P, M = MachinePlanner, R = f32>
where
    P: DerefMut<Target = MachineMemory<M>>,
    M: PlannerHandle,
{
    servo: Servo<R>,
    mem: P,
    planner_cfg: PlannerConfig,
    /// It runs `settings` (false: built from a servo configuration, it takes no change).
    tree: bool,
    rate_hz: u32,
    /// The settings changed in this period (echoed to the link side).
    settings_changed: bool,
    executed: u32,
    /// Requests that left the queue (executed, refused or flushed): the link's credit.
    retired: u32,
    last: Outcome,
    /// One telemetry sample every this many periods (0: none).
    telemetry_every: u32,
    /// The signals each sample carries besides its fixed fields.
    telemetry_signals: heapless::Vec<Signal, TELEMETRY_SIGNALS>,
    last_telemetry_period: u32,
    /// A program is running (after `Run`), and its end was announced.
    program: bool,
    program_ended: bool,
    /// How the latest program ended (or that it runs) and the tag of the segment the
    /// executor is on (the status reports them: what executed).
    program_end: ProgramEnd,
    program_tag: u32,
    identify: Option<IdentifyMsg>,
    /// A servo command of the supervisor's own (stop at program end, link loss).
    pending: heapless::Vec<Command, 2>,
    sample: PathSample,
    held: bool,
    /// The input shapers' contour deviation bound in the running program (mm; 0: none),
    /// taken from a program's explicit blend tolerances (`G64 P`).
    shaper_dev_mm: f32,
    /// A settings save is writing the flash (its token): the outputs stay off, nothing
    /// queued or pending runs, until the link side's `SaveDone`.
    save_lock: Option<u32>,
    /// The answer to a `SaveLock` of this period, for the link side.
    save_echo: Option<(u32, bool)>,
}

fn text<const N: usize>(s: &str) -> String<N> {
    let mut t = String::new();
    for c in s.chars() {
        if t.push(c).is_err() {
            break;
        }
    }
    t
}

fn refused(s: &str) -> Outcome {
    Outcome::refused(s)
}

/// A request in the machine's queue: as it came, or as the link side resolved it.
#[derive(Clone, Debug, PartialEq)]
// (a queue slot holds any of them: a settings tree is 584 bytes, so the queues are
// 25 and 16 of those — 24 KiB of RAM, within the board's budget: firmware/README-firmware.md)
#[allow(clippy::large_enum_variant)]
// (a 32-bit tag, word-aligned payload: moves are word copies, as for `Down`)
#[repr(u32)]
enum Queued {
    Request(Request),
    Resolved(Outcome),
    /// The settings change in [`MachineMemory::next_settings`].
    Apply {
        class: Option<Apply>,
    },
    /// A settings save or repair (`Down::SaveLock`).
    SaveLock {
        token: u32,
        repair: bool,
    },
}

/// Why a segment was refused, without formatting (the control interrupt never formats).
fn segment_refusal(e: &SegmentError) -> &'static str {
    match e {
        SegmentError::NotFinite(_) => "segment refused: a value is not finite (program stopped)",
        SegmentError::FeedNotPositive => "segment refused: feed must be > 0 (program stopped)",
        SegmentError::NegativeTolerance => {
            "segment refused: blend tolerance must be >= 0 (program stopped)"
        }
        SegmentError::NegativeDwell => "segment refused: dwell must be >= 0 (program stopped)",
        SegmentError::ArcZeroRadius => "segment refused: arc radius too small (program stopped)",
        SegmentError::ArcRadiusMismatch { .. } => {
            "segment refused: arc end not on its circle (program stopped)"
        }
        SegmentError::ArcTooManyTurns => {
            "segment refused: arc has too many turns (program stopped)"
        }
        SegmentError::ArcCollinear => "segment refused: arc points on a line (program stopped)",
        SegmentError::ArcRadiusTooLarge => {
            "segment refused: arc radius too large (program stopped)"
        }
        SegmentError::QueueFull => "segment refused: planner queue full (program stopped)",
        SegmentError::Aborting => "segment refused: the program is aborting (program stopped)",
    }
}

impl<P, M, R> Machine<P, M, R>
where
    P: DerefMut<Target = MachineMemory<M>>,
    M: PlannerHandle,
    R: Real,
{
    /// A machine with `settings` (servo and planner) at `rate_hz`; `raw` are the encoder
    /// registers now, standing for wide counts `start_counts` (0 on a board at boot);
    /// the planner in `mem` is restarted in place, its scope disarmed, its request queue
    /// emptied.
    pub fn new(
        settings: &Settings,
        rate_hz: u32,
        raw: [u32; 3],
        start_counts: [i64; 3],
        mem: P,
    ) -> Result<Self, MachineError> {
        let cfg = settings
            .servo_config(rate_hz)
            .map_err(MachineError::Settings)?;
        // (validated with the rest of the tree by `servo_config` above)
        let pc = settings.planner_config(rate_hz);
        let shapers = settings.shaper.shapers();
        Self::build(&cfg, &pc, &shapers, *settings, true, raw, start_counts, mem)
    }

    /// A machine that runs `servo` and `planner` as given, without a settings tree: a
    /// scripted run's (`crate::sim::run::SimRun`), whose configuration is a
    /// [`ServoConfig`] of its own. Its control rate is `servo.rate_hz`. It refuses every
    /// settings change (it has no tree to change; [`Self::settings`] answers the factory
    /// tree, which is not what it runs); everything else it does as [`Self::new`]'s.
    pub fn from_config(
        servo: &ServoConfig,
        planner: &PlannerConfig,
        raw: [u32; 3],
        start_counts: [i64; 3],
        mem: P,
    ) -> Result<Self, MachineError> {
        let settings = Settings::default();
        let none = AxisShapers::NONE;
        Self::build(
            servo,
            planner,
            &none,
            settings,
            false,
            raw,
            start_counts,
            mem,
        )
    }

    /// The servo built from `cfg`, the planner in `mem` restarted with `pc` (shaped by
    /// `shapers`), the scope disarmed; `settings` is the tree the machine answers with
    /// (`tree`: it runs it).
    #[allow(clippy::too_many_arguments)]
    fn build(
        cfg: &ServoConfig,
        pc: &PlannerConfig,
        shapers: &AxisShapers,
        settings: Settings,
        tree: bool,
        raw: [u32; 3],
        start_counts: [i64; 3],
        mut mem: P,
    ) -> Result<Self, MachineError> {
        let rate_hz = cfg.rate_hz;
        let servo = Servo::new(cfg, raw, start_counts).map_err(MachineError::Servo)?;
        let pc = *pc;
        let start = servo.snapshot().pos;
        mem.shaper
            .configure(shapers, shaper_period_s(rate_hz))
            .map_err(MachineError::Servo)?;
        let shaped = mem.shaper.planner_config(&pc).map_err(|_| {
            MachineError::Planner(PlannerConfigError::NotPositive(
                "tolerance_mm (the input shapers leave no path tolerance)",
            ))
        })?;
        mem.planner.restart(&shaped, start).map_err(|e| match e {
            RestartError::Config(e) => MachineError::Planner(e),
            RestartError::Detached => MachineError::PlannerDetached,
        })?;
        mem.scope.disarm();
        // (a memory a machine ran on before may hold its requests)
        mem.queue.0.clear();
        mem.next_settings = None;
        mem.settings = settings;
        let sample = PathSample {
            pos_mm: crate::Vec3::from_array(start),
            vel_mm_s: crate::Vec3::zero(),
            acc_mm_s2: crate::Vec3::zero(),
            tangent: crate::Vec3::zero(),
            path_speed_mm_s: 0.0,
            path_acc_mm_s2: 0.0,
            feed_ratio: 0.0,
            tag: 0,
            mode: crate::motion::planner::ExecMode::Idle,
        };
        Ok(Self {
            servo,
            mem,
            planner_cfg: pc,
            tree,
            rate_hz,
            settings_changed: false,
            executed: 0,
            retired: 0,
            last: Outcome::None,
            telemetry_every: 0,
            telemetry_signals: heapless::Vec::new(),
            last_telemetry_period: 0,
            program: false,
            program_ended: false,
            program_end: ProgramEnd::None,
            program_tag: 0,
            identify: None,
            pending: heapless::Vec::new(),
            sample,
            held: false,
            shaper_dev_mm: 0.0,
            save_lock: None,
            save_echo: None,
        })
    }

    /// Room in the request queue (the credit the link advertises).
    pub fn free_slots(&self) -> u16 {
        (REQUEST_QUEUE - self.mem.queue.0.len()) as u16
    }

    /// Queue a request (the link promised room: a request beyond it is dropped and
    /// reported as refused).
    pub fn submit(&mut self, r: Request) {
        self.enqueue(Queued::Request(r));
    }

    fn enqueue(&mut self, q: Queued) {
        if self.mem.queue.0.push_back(q).is_err() {
            self.executed = self.executed.wrapping_add(1);
            self.retired = self.retired.wrapping_add(1);
            self.last = refused("request queue full (the host ignored the link's credit)");
        }
    }

    /// A servo command of the supervisor's own for the next period (the newest wins when
    /// two are already waiting).
    fn pend(&mut self, c: Command) {
        if let Err(c) = self.pending.push(c) {
            if let Some(last) = self.pending.last_mut() {
                *last = c;
            }
        }
    }

    /// A command from the machine's own panel (the arm button), for the next period.
    pub fn local(&mut self, c: Command) {
        self.pend(c);
    }

    /// Latch a board fault found outside the servo step (the crystal, the settings store)
    /// and stop driving now.
    pub fn latch_board_fault(&mut self, kind: crate::servo::faults::FaultKind) {
        self.stop_program(None, ProgramEnd::Fault(FaultCode::new(kind, None)));
        self.servo.latch_board_fault(kind);
    }

    /// A new link session: requests of the old one are dropped, numbering restarts, and a
    /// `LinkLost` fault's cause is gone (a reset can clear it).
    pub fn session_started(&mut self) {
        // (the link side cancels its save at the same event)
        self.save_lock = None;
        self.mem.comp_entry.drop_transfer();
        self.pend(Command::LinkUp);
        self.retire_queue();
        self.executed = 0;
        self.last = Outcome::None;
    }

    /// Fault injection for the fault matrix (simulator and QEMU test builds): corrupt the
    /// state of `axis`' law (`Servo::inject_corrupt_state`).
    pub fn inject_corrupt_state(&mut self, axis: usize) {
        self.servo.inject_corrupt_state(axis);
    }

    /// Requests executed (or refused) so far.
    pub fn executed(&self) -> u32 {
        self.executed
    }

    /// The outcome of the latest executed request.
    pub fn last(&self) -> &Outcome {
        &self.last
    }

    /// How the latest program ended, or that it runs.
    pub fn program_end(&self) -> ProgramEnd {
        self.program_end
    }

    /// The planner's reference of the latest period (the start, held, before a program).
    pub fn path_sample(&self) -> &PathSample {
        &self.sample
    }

    /// Swap the servo's configuration for `cfg` (`Servo::reconfigure`: only with the
    /// outputs off), for a machine without a settings tree ([`Self::from_config`]); a
    /// machine with one changes it through a settings change, which also swaps its tree.
    pub fn reconfigure(&mut self, cfg: &ServoConfig) -> Result<(), crate::servo::ReconfigureError> {
        self.servo.reconfigure(cfg)
    }

    /// `axis` must be homed again (`Servo::forget_home`).
    pub fn forget_home(&mut self, axis: crate::axes::Axis) {
        self.servo.forget_home(axis);
    }

    pub fn servo(&self) -> &Servo<R> {
        &self.servo
    }

    /// Set `axis`' backlash and lead-screw compensation
    /// ([`crate::motion::compensation`], kept in the machine's memory and applied by the
    /// servo step): refused while the outputs are on.
    pub fn set_compensation(
        &mut self,
        axis: crate::axes::Axis,
        c: crate::motion::compensation::AxisCompensation,
    ) -> Result<(), crate::servo::ReconfigureError> {
        if self.servo.state().drives() {
            return Err(crate::servo::ReconfigureError::OutputsOn);
        }
        self.mem.comp.set(axis.index(), c);
        Ok(())
    }

    /// The compensation tables in use.
    pub fn compensation(&self) -> &crate::motion::compensation::CompTables {
        &self.mem.comp
    }

    /// Shape the planner's reference with `shapers` from the next program on
    /// ([`crate::motion::shaper::ShaperStage`]): refused while the outputs are on, and
    /// when a shaper is invalid or leaves the planner no path tolerance (nothing changes
    /// then). A machine with a settings tree takes them from its `shaper.*` keys.
    pub fn set_shapers(&mut self, shapers: &AxisShapers) -> Result<(), ShaperChangeError> {
        if self.servo.state().drives() {
            return Err(ShaperChangeError::OutputsOn);
        }
        let mut next = crate::motion::shaper::ShaperStage::NONE;
        next.configure(shapers, shaper_period_s(self.rate_hz))
            .map_err(ShaperChangeError::Config)?;
        next.planner_config(&self.planner_cfg)
            .map_err(ShaperChangeError::Tolerance)?;
        self.mem
            .shaper
            .configure(shapers, shaper_period_s(self.rate_hz))
            .map_err(ShaperChangeError::Config)
    }

    /// The shapers in use.
    pub fn shaper(&self) -> &ShaperStage {
        &self.mem.shaper
    }

    /// The planner's configuration the next program runs with: the configured one with
    /// the shapers' contour deviation counted inside its tolerance.
    pub fn planner_config(
        &self,
    ) -> Result<PlannerConfig, crate::motion::shaper::ShapedPlannerError> {
        self.mem.shaper.planner_config(&self.planner_cfg)
    }

    /// The settings tree it runs (the factory tree for a machine built
    /// [`Self::from_config`], which runs no tree).
    pub fn settings(&self) -> &Settings {
        &self.mem.settings
    }

    /// The control rate, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.rate_hz
    }

    /// A real-time request, executed now (outside the queue).
    pub fn realtime(&mut self, req: RealtimeRequest) {
        match req {
            RealtimeRequest::Hold => {
                if self.program {
                    self.mem.planner.hold();
                    self.held = true;
                }
            }
            RealtimeRequest::Resume => {
                if self.program {
                    self.mem.planner.resume();
                    self.held = false;
                }
            }
            RealtimeRequest::Stop => self.stop_program(Some(Command::Stop), ProgramEnd::HostStop),
            RealtimeRequest::Status => {}
        }
    }

    /// The host ended its session cleanly: a program, a jog, homing or an identification
    /// (which need the host) come to a controlled stop; the machine stays otherwise as it
    /// is (armed and holding, homed, its settings): no `LinkLost` fault.
    pub fn session_ended(&mut self) {
        self.save_lock = None;
        let moving = matches!(
            self.servo.state(),
            ServoState::Run | ServoState::Jog | ServoState::Homing | ServoState::Identify
        );
        self.stop_program(moving.then_some(Command::Stop), ProgramEnd::HostStop);
    }

    /// The link's watchdog expired: controlled stop and a `LinkLost` fault.
    pub fn link_lost(&mut self) {
        self.save_lock = None;
        self.stop_program(Some(Command::LinkLost), ProgramEnd::LinkLost);
    }

    /// Flush the request queue (counted as retired for the link's credit).
    fn retire_queue(&mut self) {
        self.retired = self.retired.wrapping_add(self.mem.queue.0.len() as u32);
        self.mem.queue.0.clear();
    }

    /// Requests retired so far (executed, refused or flushed).
    pub fn retired(&self) -> u32 {
        self.retired
    }

    /// A settings save holds the outputs off (the link side is writing the flash).
    pub fn saving(&self) -> bool {
        self.save_lock.is_some()
    }

    /// Telemetry every `periods` control periods (0: off).
    pub fn set_telemetry_every(&mut self, periods: u32) {
        self.telemetry_every = periods;
    }

    /// One control period behind the link: the link's events, the period, the replies
    /// and telemetry (see the module docs).
    #[inline(always)]
    pub fn linked_period<IO: ServoIo<R>>(&mut self, io: &mut IO, link: &mut ControlSide<'_>) {
        self.linked_period_seen(io, link, |_| {});
    }

    /// [`Self::linked_period`], showing `seen` every event it takes from the link, as it
    /// takes it (and a [`Down::Apply`]'s tree after the event): what a recording of the
    /// machine's inputs needs (the QEMU link rig's, `super::record`). The one sequence of
    /// the period: `linked_period` is this with nothing to see.
    #[inline(always)]
    pub fn linked_period_seen<IO: ServoIo<R>>(
        &mut self,
        io: &mut IO,
        link: &mut ControlSide<'_>,
        mut seen: impl FnMut(Seen<'_>),
    ) {
        while let Some(d) = link.take() {
            seen(Seen::Down(&d));
            match d {
                Down::Request(r) => self.submit(r),
                Down::Resolved(o) => self.enqueue(Queued::Resolved(o)),
                Down::Apply { class } => match link.take_settings() {
                    Some(prepared) => {
                        seen(Seen::Settings(&prepared.settings));
                        self.mem.next_settings = Some(prepared);
                        self.enqueue(Queued::Apply { class })
                    }
                    // (cannot happen: the tree is enqueued before its event) the
                    // request still retires, refused
                    None => self.enqueue(Queued::Resolved(refused("settings change lost"))),
                },
                Down::SessionStarted => self.session_started(),
                Down::Realtime { id, req } => {
                    self.realtime(req);
                    link.send(Up::Status {
                        id,
                        status: self.status(),
                    });
                }
                Down::StatusOnly { id } => link.send(Up::Status {
                    id,
                    status: self.status(),
                }),
                Down::LinkLost => self.link_lost(),
                Down::SessionEnded => self.session_ended(),
                Down::SaveLock { token, repair } => {
                    self.enqueue(Queued::SaveLock { token, repair })
                }
                Down::SaveDone { token, outcome } => {
                    if self.save_lock == Some(token) {
                        self.save_lock = None;
                        self.executed = self.executed.wrapping_add(1);
                        self.last = outcome;
                    }
                }
            }
        }
        self.period(io);
        if self.settings_changed {
            self.settings_changed = false;
            link.echo(&self.mem.settings);
        }
        if let Some((token, locked)) = self.save_echo.take() {
            link.echo_save(token, locked);
        }
        link.publish_retired(self.retired);
        if let Some(t) = self.telemetry_due() {
            link.send(Up::Telemetry(t));
        }
    }

    /// The telemetry sample of this period, when one is due.
    pub fn telemetry_due(&mut self) -> Option<Telemetry> {
        let p = self.servo.snapshot().period;
        if self.telemetry_every == 0
            || p.wrapping_sub(self.last_telemetry_period) < self.telemetry_every
        {
            return None;
        }
        self.last_telemetry_period = p;
        Some(self.telemetry())
    }

    /// Stop the program (if one runs) for `why`, with the servo command `cmd`.
    fn stop_program(&mut self, cmd: Option<Command>, why: ProgramEnd) {
        self.retire_queue();
        self.sample.vel_mm_s = crate::Vec3::zero();
        self.sample.acc_mm_s2 = crate::Vec3::zero();
        if self.program {
            self.mem.planner.abort();
            self.program_end = why;
        }
        self.program = false;
        self.program_ended = false;
        self.held = false;
        if let Some(c) = cmd {
            self.pend(c);
        }
    }

    /// One control period: execute what is queued, plan, sample, run the servo step.
    pub fn period<IO: ServoIo<R>>(&mut self, io: &mut IO) {
        let mut cmds: heapless::Vec<Command, 4> = heapless::Vec::new();
        // during a save nothing may arm: commands wait (a lost link or a new session
        // ends the save first)
        if self.save_lock.is_none() {
            for c in self.pending.drain(..) {
                let _ = cmds.push(c);
            }
        }
        // a servo command's outcome is known after the servo step: one per period
        let mut servo_request = false;
        let mut segments = 0;
        while let Some(r) = self.mem.queue.0.front() {
            if servo_request || self.save_lock.is_some() {
                break;
            }
            if matches!(r, Queued::Request(Request::Segment(_))) {
                if segments == M::OFFERS_PER_PERIOD {
                    break;
                }
                segments += 1;
            }
            // (a streaming program's segments: the segment alone is copied, not the
            // queue entry cloned, a byte-wise copy of its other variants' layout)
            let step = match r {
                Queued::Request(Request::Segment(seg)) => {
                    let seg = *seg;
                    self.segment(&seg)
                }
                _ => {
                    let r = r.clone();
                    self.execute(&r, &mut cmds)
                }
            };
            match step {
                Step::Done(o) => {
                    self.executed = self.executed.wrapping_add(1);
                    self.last = o;
                }
                Step::Servo => servo_request = true,
                Step::Locked => {}
                Step::Wait => break,
            }
            if self.mem.queue.0.pop_front().is_some() {
                self.retired = self.retired.wrapping_add(1);
            }
        }
        // the program's clock stands still while the servo holds its start for the brakes
        let ticked = self.program && !self.servo.motion_held();
        if ticked {
            // (shaped: the servo follows the planner's reference through the shapers)
            self.sample = self.mem.planner.tick();
            self.mem.shaper.shape(&mut self.sample);
            self.servo.set_planner_reference(&self.sample);
            // the executor's place in the program, for the status
            self.program_tag = self.sample.tag;
        }
        // (the snapshot is read in place: a copy of its 200 bytes cost ~190 instructions
        // a period; only the three fields the machine acts on are taken out)
        let s = self.servo.period_with(io, &cmds, Some(&self.mem.comp));
        self.mem.scope.record(s, &self.sample);
        let (refused_now, state, fault) = (s.refused, s.state, s.fault);
        if servo_request {
            self.executed = self.executed.wrapping_add(1);
            self.last = match refused_now {
                Some((_, why)) => refused(why.message()),
                None => Outcome::Done,
            };
        }
        if self.program {
            match state {
                ServoState::Run => {
                    // (a program whose start waits for the brakes has not begun: the
                    // executor is judged once it has been ticked)
                    if ticked
                        && self.program_ended
                        && self.mem.planner.is_idle()
                        && self.mem.shaper.settled()
                        && !self.held
                        && !self.servo.motion_held()
                    {
                        self.pend(Command::Stop);
                        self.program = false;
                        self.program_ended = false;
                        self.program_end = ProgramEnd::Completed;
                    }
                }
                // a fault, a stop or a disarm ended the program
                _ => {
                    let why = match fault {
                        Some(f) => ProgramEnd::Fault(FaultCode::new(f.fault.kind, f.fault.axis)),
                        None => ProgramEnd::Stopped,
                    };
                    self.stop_program(None, why)
                }
            }
        }
        self.note_identification(state);
    }

    /// A segment of the running program, offered to the planner.
    fn segment(&mut self, seg: &Segment) -> Step {
        if !self.program {
            return Step::Done(refused("segment: no program running (send run first)"));
        }
        // an explicit tolerance (G64 P) counts the shapers' deviation as the default one
        // does: blends within P − B (0 when B takes all of it: the corner is then met
        // within B, the shapers' bound, not within P)
        let offer = match seg.blend {
            crate::motion::planner::Blend::Tolerance(p) if self.shaper_dev_mm > 0.0 => {
                let mut seg = *seg;
                seg.blend =
                    crate::motion::planner::Blend::Tolerance((p - self.shaper_dev_mm).max(0.0));
                self.mem.planner.offer(&seg)
            }
            _ => self.mem.planner.offer(seg),
        };
        match offer {
            Offer::Taken => Step::Done(Outcome::Done),
            Offer::Later => Step::Wait,
            Offer::Refused(e) => {
                // a program with a bad segment cannot go on: stop on the path
                self.stop_program(Some(Command::Stop), ProgramEnd::SegmentRefused);
                Step::Done(refused(segment_refusal(&e)))
            }
        }
    }

    fn execute(&mut self, q: &Queued, cmds: &mut heapless::Vec<Command, 4>) -> Step {
        let r = match q {
            Queued::Request(r) => r,
            Queued::Resolved(o) => return Step::Done(o.clone()),
            Queued::Apply { class } => return Step::Done(self.apply(*class)),
            Queued::SaveLock { token, repair } => return self.lock_for_save(*token, *repair, cmds),
        };
        let mut servo = |c: Command| {
            let _ = cmds.push(c);
            Step::Servo
        };
        match r {
            Request::Arm => servo(Command::Arm),
            Request::Disarm => servo(Command::Disarm),
            Request::Reset => servo(Command::Reset),
            Request::Home => servo(Command::Home),
            Request::Jog { axis, vel_mm_s } => match Axis::from_index(usize::from(*axis)) {
                Some(axis) => servo(Command::Jog {
                    axis,
                    vel_mm_s: *vel_mm_s,
                }),
                None => Step::Done(refused("jog: axis must be 0, 1 or 2")),
            },
            Request::Identify { axis, window_mm } => match Axis::from_index(usize::from(*axis)) {
                Some(axis) => {
                    self.identify = None;
                    servo(Command::Identify {
                        axis,
                        window_mm: *window_mm,
                    })
                }
                None => Step::Done(refused("identify: axis must be 0, 1 or 2")),
            },
            Request::MeasureResponse { .. }
            | Request::MeasureLoop { .. }
            | Request::ResponseRead { .. } => self.response_request(r, cmds),
            Request::Run => {
                let Some(start) = self.servo.planner_start_mm() else {
                    return Step::Done(refused("run: arm the machine first (it must be idle)"));
                };
                if self.servo.state() != ServoState::Idle {
                    return Step::Done(refused("run: a program is already running"));
                }
                let Ok(pc) = self.mem.shaper.planner_config(&self.planner_cfg) else {
                    return Step::Done(refused(
                        "run: the input shapers leave no path tolerance (planner.tolerance_mm)",
                    ));
                };
                self.shaper_dev_mm = self
                    .mem
                    .shaper
                    .bound()
                    .deviation_bound_axes_mm(pc.acc_max_mm_s2);
                // in place: a planner is 40 KiB, too much for the interrupt's stack
                match self.mem.planner.restart(&pc, start) {
                    Ok(()) => {}
                    Err(RestartError::Config(_)) => {
                        return Step::Done(refused("run: planner configuration invalid"))
                    }
                    Err(RestartError::Detached) => {
                        return Step::Done(refused("run: the planning task is not connected"))
                    }
                }
                self.mem.shaper.prime(start);
                self.program = true;
                self.program_ended = false;
                self.program_end = ProgramEnd::Running;
                self.program_tag = 0;
                self.held = false;
                servo(Command::Run)
            }
            Request::Segment(seg) => self.segment(seg),
            Request::Subscribe {
                every_periods,
                signals,
            } => {
                self.telemetry_every = *every_periods;
                self.telemetry_signals = signals.clone();
                self.last_telemetry_period = self.servo.snapshot().period;
                Step::Done(Outcome::Done)
            }
            Request::ScopeArm(cfg) => match self.mem.scope.arm(cfg.clone()) {
                Ok(()) => Step::Done(Outcome::Done),
                Err(why) => Step::Done(refused(why)),
            },
            Request::ScopeRead { offset } => match self.mem.scope.read(*offset) {
                Ok(chunk) => Step::Done(Outcome::Scope(chunk)),
                Err(why) => Step::Done(refused(why)),
            },
            Request::EndProgram => {
                if self.program {
                    self.program_ended = true;
                }
                Step::Done(Outcome::Done)
            }
            Request::CompBegin { .. }
            | Request::CompPoints { .. }
            | Request::CompCommit
            | Request::CompRead { .. } => self.comp_request(r, cmds),
            Request::FeedOverride(r) => match self.mem.planner.set_feed_override(*r) {
                Ok(()) => Step::Done(Outcome::Done),
                Err(_) => Step::Done(refused("feed override must be within 0.01-2.0")),
            },
            // resolved on the link side (machine::port): text and the key table stay
            // out of the control interrupt
            Request::SettingGet { .. }
            | Request::SettingSet { .. }
            | Request::SettingsDefaults
            | Request::SettingsSave
            | Request::AcceptIdentified { .. }
            | Request::SettingsBegin
            | Request::SettingsCommit
            | Request::SettingsAbort
            | Request::SettingsRepair => Step::Done(refused(
                "settings requests reach the machine through its link (machine::port)",
            )),
        }
    }

    /// After the servo step in `state`: the frequency response's newest point into its
    /// record, and the last model identification's outcome into the status.
    fn note_identification(&mut self, state: ServoState) {
        if state == ServoState::Identify {
            self.collect_response();
        }
        if let Some(o) = self.servo.identify_outcome() {
            if self
                .identify
                .is_none_or(|m| m.axis != o.axis.index() as u8 || !m.done)
                && state != ServoState::Identify
            {
                self.identify = Some(IdentifyMsg {
                    axis: o.axis.index() as u8,
                    done: o.status == IdentifyStatus::Done,
                    model: o.result.map(|r| ModelMsg {
                        inertia: r.model.inertia,
                        viscous: r.model.viscous,
                        coulomb_pos_mnm: r.model.coulomb_pos_mnm,
                        coulomb_neg_mnm: r.model.coulomb_neg_mnm,
                    }),
                    nrmse: o.result.map_or(0.0, |r| r.nrmse),
                    r2: o.result.map_or(0.0, |r| r.r2),
                    time_s: o.result.map_or(0.0, |r| r.machine_time_s),
                });
            }
        }
    }

    /// A request of the frequency response ([`super::ResponseRecord`]): start a
    /// measurement (a servo command, in `cmds`) or read its points.
    fn response_request(&mut self, r: &Request, cmds: &mut heapless::Vec<Command, 4>) -> Step {
        match r {
            Request::MeasureResponse { axis, window_mm } => {
                let Some(axis) = Axis::from_index(usize::from(*axis)) else {
                    return Step::Done(refused("freqresp: axis must be 0, 1 or 2"));
                };
                // (the record drops the last measurement's points when the servo's new
                // run sends its first: a refused request leaves them readable)
                let _ = cmds.push(Command::MeasureResponse {
                    axis,
                    window_mm: *window_mm,
                });
                Step::Servo
            }
            Request::MeasureLoop { axis, window_mm } => {
                let Some(axis) = Axis::from_index(usize::from(*axis)) else {
                    return Step::Done(refused("loop: axis must be 0, 1 or 2"));
                };
                let _ = cmds.push(Command::MeasureLoop {
                    axis,
                    window_mm: *window_mm,
                });
                Step::Servo
            }
            _ => Step::Done(self.mem.response.read(
                r,
                self.servo.response_outcome(),
                self.servo.state() == ServoState::Identify,
            )),
        }
    }

    /// The frequency response's latest point into the record (while identifying; out of
    /// line: inlined, it cost a streaming program's period 42 instructions of register
    /// spills, `cargo insns` machine_period_program 4 328 → 4 370).
    #[cold]
    #[inline(never)]
    fn collect_response(&mut self) {
        self.mem
            .response
            .collect(self.servo.identify_runs(), self.servo.response_point());
    }

    /// A request of the compensation transfer ([`super::CompEntry`]).
    fn comp_request(&mut self, r: &Request, cmds: &heapless::Vec<Command, 4>) -> Step {
        // a commit after a disarm whose brakes still engage waits for the outputs to go
        // off, as a save does (they do by themselves, soon)
        if matches!(r, Request::CompCommit) && (!cmds.is_empty() || self.servo.switching_off()) {
            return Step::Wait;
        }
        let on = self.servo.state().drives();
        let mem = &mut *self.mem;
        Step::Done(mem.comp_entry.execute(&mut mem.comp, r, on))
    }

    /// A save's turn: lock the outputs off while the link side writes the flash, or refuse
    /// while they are on. Waits a period when a command of this one could still arm.
    fn lock_for_save(
        &mut self,
        token: u32,
        repair: bool,
        cmds: &heapless::Vec<Command, 4>,
    ) -> Step {
        // (a disarm whose brakes still engage: the outputs go off by themselves soon)
        if !cmds.is_empty() || self.servo.switching_off() {
            return Step::Wait;
        }
        if self.servo.state().drives() {
            self.save_echo = Some((token, false));
            return Step::Done(refused(if repair {
                "repair: the outputs are on; disarm first (erasing flash stalls the control loop)"
            } else {
                "save: the outputs are on; disarm first (writing flash stalls the control loop)"
            }));
        }
        self.save_lock = Some(token);
        self.save_echo = Some((token, true));
        Step::Locked
    }

    /// Swap in `next` (validated on the link side; `class` and the servo configuration
    /// derived from it, both in [`MachineMemory::next_settings`]) at this period boundary,
    /// if the servo takes it now.
    fn apply(&mut self, class: Option<Apply>) -> Outcome {
        let Some(PreparedSettings {
            settings: next,
            servo,
        }) = self.mem.next_settings.take()
        else {
            // (cannot happen: the tree is in the memory before its request is queued)
            return refused("settings change lost");
        };
        let Some(cfg) = servo else {
            return refused("rejected: the settings give no servo configuration");
        };
        if !self.tree {
            return refused("rejected: this machine runs a fixed servo configuration");
        }
        match class {
            None => {
                self.take(next);
                Outcome::Done
            }
            // (live changes with the outputs on are not taken yet: the servo swaps
            // configurations only with the outputs off)
            Some(_) => match self.servo.reconfigure(&cfg) {
                Ok(()) => {
                    self.take(next);
                    Outcome::Done
                }
                Err(crate::servo::ReconfigureError::OutputsOn) => {
                    refused("this change needs the outputs off: disarm first")
                }
                Err(crate::servo::ReconfigureError::Config(_)) => {
                    refused("rejected: the servo refuses the configuration")
                }
            },
        }
    }

    /// The new settings; the planner's take effect with the next program.
    fn take(&mut self, next: Settings) {
        // (validated with the tree on the link side; taken only with the outputs off,
        // the keys' apply class, so no program runs through the change)
        let _ = self
            .mem
            .shaper
            .configure(&next.shaper.shapers(), shaper_period_s(self.rate_hz));
        self.mem.settings = next;
        self.settings_changed = true;
        self.planner_cfg = next.planner_config(self.rate_hz);
    }

    /// The status a real-time request answers with.
    pub fn status(&self) -> Status {
        let s = self.servo.snapshot();
        let first_fault = s.fault.map(|f| {
            let mut t: String<VALUE_MAX> = text(f.fault.kind.name());
            if let Some(a) = f.fault.axis {
                let _ = t.push_str(" on ");
                let _ = t.push_str(a.name());
            }
            t
        });
        let mut fault_history = heapless::Vec::new();
        for r in self.servo.faults().history() {
            let _ = fault_history.push(FaultCode::new(r.fault.kind, r.fault.axis));
        }
        Status {
            fault_history,
            state: self.state(),
            period: s.period,
            executed: self.executed,
            last: self.last.clone(),
            fault_bits: s.fault_bits,
            first_fault,
            homed: s.homed,
            model_missing: s.model_missing,
            comp: self.mem.comp.axes_in_use(),
            pos_mm: s.pos,
            vel_mm_s: s.vel,
            planner_free: self.mem.planner.free_slots() as u16,
            queued: self.mem.queue.0.len() as u16,
            program_done: !self.program
                && self.mem.queue.0.is_empty()
                && self.pending.is_empty()
                && !self.program_end.aborted(),
            program: ProgramProgress {
                end: self.program_end,
                tag: self.program_tag,
            },
            progress: s.progress,
            identify: self.identify,
            scope: self.mem.scope.state(),
        }
    }

    /// One telemetry sample of the last period.
    pub fn telemetry(&self) -> Telemetry {
        let s = self.servo.snapshot();
        // (push, not collect: heapless' `collect` panics on overflow; the capacities match)
        let mut signals = heapless::Vec::new();
        for sig in &self.telemetry_signals {
            let _ = signals.push(sig.value(s, &self.sample));
        }
        Telemetry {
            period: s.period,
            state: self.state(),
            pos_mm: s.pos,
            reference_mm: s.reference,
            ref_vel_mm_s: self.sample.vel_mm_s.to_array(),
            ref_acc_mm_s2: self.sample.acc_mm_s2.to_array(),
            contour_mm: s.contour_norm(),
            feed_ratio: self.sample.feed_ratio,
            tag: self.sample.tag,
            signals,
        }
    }

    fn state(&self) -> MachineState {
        match self.servo.state() {
            ServoState::Disabled => MachineState::Disabled,
            ServoState::Idle => MachineState::Idle,
            ServoState::Run => MachineState::Run { held: self.held },
            ServoState::Jog => MachineState::Jog,
            ServoState::Homing => MachineState::Homing,
            ServoState::Identify => MachineState::Identify,
            ServoState::Stopping => MachineState::Stopping,
            ServoState::EncoderCheck => MachineState::EncoderCheck,
            ServoState::Fault => MachineState::Fault,
        }
    }
}

/// What executing one request did.
enum Step {
    /// Done now, with this outcome.
    Done(Outcome),
    /// A servo command: its outcome comes from this period's servo step.
    Servo,
    /// Cannot be executed yet (planner full, or its answer not back from the planning
    /// task): stays at the front of the queue.
    Wait,
    /// A save locked the outputs off: the request leaves the queue, its outcome comes
    /// with `Down::SaveDone`.
    Locked,
}
