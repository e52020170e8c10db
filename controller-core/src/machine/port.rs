//! The hand-off between the link and the machine: on the board the link runs in its own
//! task and the machine in the control interrupt, so everything between them goes
//! through two lock-free single-producer, single-consumer queues ([`Channels`]): link
//! events down ([`Down`]), status replies and telemetry up ([`Up`]). The control
//! interrupt takes what is queued at the start of a period ([`Machine::linked_period`])
//! and never waits for the link; the link task never touches the machine.
//!
//! The link's credit (free request slots) is computed on the link side from two counters
//! — requests it accepted, requests the machine has retired (executed, refused or
//! flushed) — so the host never has more requests in flight than the machine's queue
//! holds, whichever side runs when.
//!
//! Settings requests are resolved on the link side ([`SettingsAgent`]): the text, the
//! key table and the error messages stay out of the control interrupt, which gets a
//! validated tree with the servo configuration derived from it ([`PreparedSettings`],
//! [`Down::Apply`]) or a decided outcome ([`Down::Resolved`]) in the request's place. Such a request waits (and everything behind it) until the requests
//! before it were executed, so that it reads the settings the machine runs; the machine
//! echoes each tree it took back up (a queue of its own).
//!
//! A settings save ([`Request::SettingsSave`]) is the one request the link side carries
//! out itself, because it owns the flash and the control interrupt must never wait on
//! it: once everything before it was executed, it goes down as [`Down::SaveLock`]; the
//! machine, with its outputs off, locks them off and says so ([`Echo::Save`]); the link
//! task writes the flash ([`LinkSide::save_due`]) and hands the result down
//! ([`LinkSide::save_finished`], [`Down::SaveDone`]), which releases the lock. A new
//! session or a lost link cancels a save on both sides. A repair
//! ([`Request::SettingsRepair`]: erase the store, write the settings) takes the same path;
//! [`LinkSide::save_due`] says which ([`SaveJob`]).
//!
//! `gantry --sim` uses the very same queues in one thread (split per call).
//!
//! [`Machine::linked_period`]: super::Machine::linked_period

use core::sync::atomic::{AtomicU32, Ordering};

use heapless::spsc::{Consumer, Producer, Queue};

use heapless::Deque;

use super::messages::{Outcome, Request, Status, Telemetry};
use super::settings_agent::{Resolution, SettingsAgent};
use crate::link::{RealtimeRequest, Seq};
use crate::servo::ServoConfig;
use crate::settings::{Apply, Settings};

/// What the link hands the machine. No variant holds a settings tree (628 bytes): a
/// change's tree waits in a queue of its own ([`Down::Apply`]), so that the control
/// interrupt, which takes every event by value, copies 120 bytes per event, not 632
/// (the segments of a streaming program: `cargo insns`' `machine_period_program`).
#[derive(Clone, Debug, PartialEq)]
// (recorded and replayed by `super::record`)
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
// (a 32-bit tag: the payload then starts word-aligned and a move is a word copy; with a
// byte tag sharing a word with it, each move was a byte-wise copy, 5 instructions a byte)
#[repr(u32)]
pub enum Down {
    /// A request of the reliable channel, for the machine's queue.
    Request(Request),
    /// A request already decided on the link side (a settings value read, a refusal):
    /// the machine records the outcome in the request's place.
    Resolved(Outcome),
    /// A settings change validated on the link side: swap it in at a period boundary
    /// (only with the outputs off when `class` is not `None`), in the request's place.
    /// Its tree is the next in the settings queue ([`ControlSide::take_settings`]),
    /// enqueued before this event.
    Apply { class: Option<Apply> },
    /// A new session: the old one's queued requests are dropped.
    SessionStarted,
    /// A real-time request: act at once, then answer with [`Up::Status`] and `id`.
    Realtime { id: Seq, req: RealtimeRequest },
    /// Answer with [`Up::Status`] and `id` only.
    StatusOnly { id: Seq },
    /// The link's watchdog expired: controlled stop and a `LinkLost` fault.
    LinkLost,
    /// A settings save reached the front, everything before it executed: with the
    /// outputs off, hold them off until [`Down::SaveDone`] with the same `token`, and
    /// answer with [`Echo::Save`] (in the request's place).
    SaveLock { token: u32, repair: bool },
    /// The link side finished the save `token` (written or failed: `outcome`, the
    /// request's outcome); the outputs may be armed again.
    SaveDone { token: u32, outcome: Outcome },
    /// The host ended its session cleanly: what needs it stops (a controlled stop of a
    /// program, a jog, homing, an identification), no `LinkLost` fault; the rest stays.
    SessionEnded,
}

/// A settings change as the link side hands it down: the validated tree and the servo
/// configuration derived from it here, outside the control interrupt, which only swaps
/// the prepared value in at the period the change's request executes ([`Down::Apply`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedSettings {
    pub settings: Settings,
    /// `None` when the tree gives no servo configuration (the machine refuses the change).
    pub servo: Option<ServoConfig>,
}

impl PreparedSettings {
    /// `settings` with the servo configuration it gives at `rate_hz`.
    pub fn new(settings: Settings, rate_hz: u32) -> Self {
        Self {
            servo: settings.servo_config(rate_hz).ok(),
            settings,
        }
    }
}

/// What the machine reports back to the link side about settings (a queue of its own).
#[derive(Clone, Debug, PartialEq)]
// (a queue slot holds either)
#[allow(clippy::large_enum_variant)]
pub enum Echo {
    /// The machine took these settings.
    Took(Settings),
    /// The save `token`: `locked` (outputs off and held off: write the flash now), or
    /// refused (the outputs are on; the refusal is the request's outcome).
    Save { token: u32, locked: bool },
}

/// What the link task writes to flash when a save is due ([`LinkSide::save_due`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SaveJob {
    /// The settings the machine runs.
    pub settings: Settings,
    /// Erase the store first ([`Request::SettingsRepair`]), rather than append a record.
    pub repair: bool,
}

/// Where the link side's save is.
#[derive(Clone, Debug, PartialEq)]
enum SavePhase {
    Idle,
    /// [`Down::SaveLock`] sent, waiting for the machine's [`Echo::Save`].
    Locking(u32),
    /// The machine holds the outputs off: the flash may be written.
    Ready(u32),
    /// Written (or failed): [`Down::SaveDone`] waits for room in the down queue.
    Reply {
        token: u32,
        outcome: Outcome,
    },
}

/// What the machine hands the link.
#[derive(Clone, Debug, PartialEq)]
// (a queue slot holds either: 9 slots of 280 bytes)
#[allow(clippy::large_enum_variant)]
pub enum Up {
    Status { id: Seq, status: Status },
    Telemetry(Telemetry),
}

/// Requests waiting to be executed in the machine's queue, at most: the link's credit
/// (the host never has more in flight than [`super::Machine::free_slots`] says), which
/// this side computes and the machine's queue is sized by.
pub const REQUEST_QUEUE: usize = 16;

/// Capacity of the down queue: the request queue's credit, plus room for real-time
/// requests and session events (a real-time request that finds it full is dropped; the
/// host repeats it).
pub const DOWN_QUEUE: usize = REQUEST_QUEUE + 8;
/// Capacity of the up queue (status replies and telemetry samples between two runs of
/// the link task; when full, telemetry is dropped and counted as a gap by the host).
pub const UP_QUEUE: usize = 8;

/// Settings trees the machine took and save answers, on their way back to the link side.
const ECHO_QUEUE: usize = 4;

/// Settings trees on their way down ([`Down::Apply`]): one at a time, since a settings
/// request goes down only once every request before it was executed.
const APPLY_QUEUE: usize = 1;

/// The queues and the credit counter.
pub struct Channels {
    down: Queue<Down, { DOWN_QUEUE + 1 }>,
    up: Queue<Up, { UP_QUEUE + 1 }>,
    echo: Queue<Echo, { ECHO_QUEUE + 1 }>,
    applies: Queue<PreparedSettings, { APPLY_QUEUE + 1 }>,
    /// Requests retired by the machine (control side writes).
    retired: AtomicU32,
}

impl Default for Channels {
    fn default() -> Self {
        Self::new()
    }
}

impl Channels {
    pub const fn new() -> Self {
        Self {
            down: Queue::new(),
            up: Queue::new(),
            echo: Queue::new(),
            applies: Queue::new(),
            retired: AtomicU32::new(0),
        }
    }

    /// The link's end and the control interrupt's end.
    pub fn split(&mut self) -> (LinkEnds<'_>, ControlSide<'_>) {
        let (down_tx, down_rx) = self.down.split();
        let (up_tx, up_rx) = self.up.split();
        let (echo_tx, echo_rx) = self.echo.split();
        let (apply_tx, apply_rx) = self.applies.split();
        (
            LinkEnds {
                down: down_tx,
                up: up_rx,
                echo: echo_rx,
                applies: apply_tx,
                retired: &self.retired,
            },
            ControlSide {
                down: down_rx,
                up: up_tx,
                echo: echo_tx,
                applies: apply_rx,
                retired: &self.retired,
                dropped_up: 0,
            },
        )
    }
}

/// The link's ends of [`Channels`], before the link side's state joins them
/// ([`LinkSide::new`]).
pub struct LinkEnds<'a> {
    down: Producer<'a, Down>,
    up: Consumer<'a, Up>,
    echo: Consumer<'a, Echo>,
    applies: Producer<'a, PreparedSettings>,
    retired: &'a AtomicU32,
}

impl LinkEnds<'_> {
    /// Hand `d` down as it was recorded: a replay of a recorded session
    /// ([`super::record`]); the link side's own logic is not involved. `false` when the
    /// queue is full.
    pub fn replay_down(&mut self, d: Down) -> bool {
        self.down.enqueue(d).is_ok()
    }

    /// Hand a recorded [`Down::Apply`]'s tree down (before or after its event, within
    /// the same period), prepared as the link side prepares it for a machine at
    /// `rate_hz`. `false` when the queue is full.
    pub fn replay_settings(&mut self, s: Settings, rate_hz: u32) -> bool {
        self.applies
            .enqueue(PreparedSettings::new(s, rate_hz))
            .is_ok()
    }
}

/// What the link's endpoint needs of the machine.
pub trait MachinePort {
    /// Requests the machine can still take (the credit the link advertises).
    fn free_slots(&self) -> u16;
    /// Hand an event down (a request only within the credit).
    fn down(&mut self, d: Down);
    /// Called every link task run: pass down what waited.
    fn poll(&mut self) {}
    /// The next reply or telemetry sample, if any.
    fn up(&mut self) -> Option<Up>;
}

/// Link-side state that outlives a split of [`Channels`] (`gantry --sim` splits them
/// anew for every call; the firmware once).
pub struct LinkState {
    agent: SettingsAgent,
    /// Requests accepted from the host, waiting to go down in order.
    held: Deque<Request, REQUEST_QUEUE>,
    /// Requests accepted (held or passed down) and requests dropped unsent (a new
    /// session): the credit is `REQUEST_QUEUE - (accepted - dropped - retired)`.
    accepted: u32,
    dropped: u32,
    /// Requests passed down.
    passed: u32,
    save: SavePhase,
    save_token: u32,
    /// The save under way is a repair.
    save_repair: bool,
}

impl LinkState {
    /// The link side of a machine that runs `settings` at `rate_hz`.
    pub fn new(settings: &Settings, rate_hz: u32) -> Self {
        Self {
            agent: SettingsAgent::new(settings, rate_hz),
            held: Deque::new(),
            accepted: 0,
            dropped: 0,
            passed: 0,
            save: SavePhase::Idle,
            save_token: 0,
            save_repair: false,
        }
    }

    /// The settings the machine runs, as the link side knows them.
    pub fn settings(&self) -> &Settings {
        self.agent.settings()
    }

    /// The machine's control rate, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.agent.rate_hz()
    }
}

/// The link task's end of [`Channels`], with its state.
pub struct LinkSide<'a, 's> {
    ends: LinkEnds<'a>,
    state: &'s mut LinkState,
}

impl<'a, 's> LinkSide<'a, 's> {
    pub fn new(ends: LinkEnds<'a>, state: &'s mut LinkState) -> Self {
        Self { ends, state }
    }

    /// The ends back (the state stays where it is).
    pub fn into_ends(self) -> LinkEnds<'a> {
        self.ends
    }

    /// The machine's control rate, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.state.rate_hz()
    }

    /// What to write to flash now, when a save (or a repair) is due: the machine holds
    /// its outputs off until [`Self::save_finished`].
    pub fn save_due(&self) -> Option<SaveJob> {
        matches!(self.state.save, SavePhase::Ready(_)).then(|| SaveJob {
            settings: *self.state.agent.settings(),
            repair: self.state.save_repair,
        })
    }

    /// The save [`Self::save_due`] asked for is over (`outcome`: done, or why not); the
    /// machine releases its lock.
    pub fn save_finished(&mut self, outcome: Outcome) {
        if let SavePhase::Ready(token) = self.state.save {
            self.state.save = SavePhase::Reply { token, outcome };
            self.flush();
        }
    }

    /// Pass held requests down in order while the machine's queue has room; a settings
    /// request only once everything before it was executed (it is resolved then); nothing
    /// while a save is under way.
    /// Enqueue `tree` with the servo configuration derived from it here, in the link
    /// task: the control interrupt only swaps it in. Never inlined, for the stack, as
    /// [`SettingsAgent::resolve`].
    #[inline(never)]
    fn hand_down(&mut self, tree: Settings) {
        let prepared = PreparedSettings::new(tree, self.state.rate_hz());
        let _ = self.ends.applies.enqueue(prepared);
    }

    fn flush(&mut self) {
        let retired = self.ends.retired.load(Ordering::Acquire);
        // (after `retired`: every tree the retired requests applied is in the queue)
        while let Some(e) = self.ends.echo.dequeue() {
            match e {
                Echo::Took(s) => self.state.agent.machine_took(&s),
                Echo::Save { token, locked } => {
                    // (a stale answer, of a save a new session cancelled, is ignored)
                    if self.state.save == SavePhase::Locking(token) {
                        self.state.save = if locked {
                            SavePhase::Ready(token)
                        } else {
                            SavePhase::Idle
                        };
                    }
                }
            }
        }
        if let SavePhase::Reply { token, outcome } = &self.state.save {
            let done = Down::SaveDone {
                token: *token,
                outcome: outcome.clone(),
            };
            if self.ends.down.enqueue(done).is_ok() {
                self.state.save = SavePhase::Idle;
            }
        }
        while let Some(r) = self.state.held.front() {
            if self.state.save != SavePhase::Idle {
                break;
            }
            let mut lock = None;
            let mut tree = None;
            let d = if matches!(r, Request::SettingsSave | Request::SettingsRepair) {
                if self.state.passed != retired {
                    break;
                }
                let token = self.state.save_token.wrapping_add(1);
                let repair = matches!(r, Request::SettingsRepair);
                lock = Some((token, repair));
                Down::SaveLock { token, repair }
            } else if SettingsAgent::handles(r) {
                if self.state.passed != retired {
                    break;
                }
                match self.state.agent.resolve(r) {
                    Resolution::Outcome(o) => Down::Resolved(o),
                    Resolution::Apply { settings, class } => {
                        tree = Some(settings);
                        Down::Apply { class }
                    }
                }
            } else {
                Down::Request(r.clone())
            };
            // (the tree first, and only with room for both: the machine takes it at its
            // event; a full queue leaves the request held, resolved again next time)
            if !self.ends.down.ready() || (tree.is_some() && !self.ends.applies.ready()) {
                break;
            }
            if let Some(t) = tree {
                self.hand_down(t);
            }
            let _ = self.ends.down.enqueue(d);
            if let Some((token, repair)) = lock {
                self.state.save_token = token;
                self.state.save_repair = repair;
                self.state.save = SavePhase::Locking(token);
            }
            self.state.held.pop_front();
            self.state.passed = self.state.passed.wrapping_add(1);
        }
    }
}

impl MachinePort for LinkSide<'_, '_> {
    fn free_slots(&self) -> u16 {
        let in_flight = self
            .state
            .accepted
            .wrapping_sub(self.state.dropped)
            .wrapping_sub(self.ends.retired.load(Ordering::Acquire));
        (REQUEST_QUEUE as u32).saturating_sub(in_flight) as u16
    }

    fn down(&mut self, d: Down) {
        match d {
            Down::Request(r) => {
                // within the credit there is room (a request beyond it is the host's
                // error: dropped, and the host's retransmission finds it refused)
                if self.state.held.push_back(r).is_ok() {
                    self.state.accepted = self.state.accepted.wrapping_add(1);
                }
            }
            d @ (Down::SessionStarted | Down::SessionEnded) => {
                // the old (or ended) session's requests that never went down are dropped
                // here, those queued in the machine there
                let n = self.state.held.len() as u32;
                self.state.held.clear();
                self.state.dropped = self.state.dropped.wrapping_add(n);
                // (the machine drops its lock at the same event)
                self.state.save = SavePhase::Idle;
                self.state.agent.session_ended();
                let _ = self.ends.down.enqueue(d);
            }
            Down::LinkLost => {
                self.state.save = SavePhase::Idle;
                self.state.agent.session_ended();
                let _ = self.ends.down.enqueue(Down::LinkLost);
            }
            // real-time traffic skips the queue; a full queue drops it (the host repeats
            // what it gets no answer to)
            other => {
                let _ = self.ends.down.enqueue(other);
            }
        }
        self.flush();
    }

    fn poll(&mut self) {
        self.flush();
    }

    fn up(&mut self) -> Option<Up> {
        let u = self.ends.up.dequeue()?;
        if let Up::Status { status, .. } = &u {
            self.state.agent.identified(status.identify);
        }
        Some(u)
    }
}

/// The control interrupt's end of [`Channels`].
pub struct ControlSide<'a> {
    down: Consumer<'a, Down>,
    up: Producer<'a, Up>,
    echo: Producer<'a, Echo>,
    applies: Consumer<'a, PreparedSettings>,
    retired: &'a AtomicU32,
    dropped_up: u32,
}

impl ControlSide<'_> {
    /// The next event from the link.
    pub fn take(&mut self) -> Option<Down> {
        self.down.dequeue()
    }

    /// The prepared tree of the [`Down::Apply`] just taken (`None` only if the link side
    /// broke the order it enqueues them in).
    pub fn take_settings(&mut self) -> Option<PreparedSettings> {
        self.applies.dequeue()
    }

    /// Hand a reply or sample up; dropped (and counted) when the link task lags.
    pub fn send(&mut self, u: Up) {
        if self.up.enqueue(u).is_err() {
            self.dropped_up = self.dropped_up.wrapping_add(1);
        }
    }

    /// The machine took `settings` (echoed to the link side before the request that
    /// applied them is published as retired).
    pub fn echo(&mut self, settings: &Settings) {
        // (room: at most one per retired request the link side has not seen, and it
        // passes no settings request down before it saw them all)
        let _ = self.echo.enqueue(Echo::Took(*settings));
    }

    /// The answer to [`Down::SaveLock`] `token` (see [`Echo::Save`]).
    pub fn echo_save(&mut self, token: u32, locked: bool) {
        // (room: a save goes down only after the link side saw every earlier echo)
        let _ = self.echo.enqueue(Echo::Save { token, locked });
    }

    /// Publish how many requests the machine has retired in total.
    pub fn publish_retired(&mut self, retired: u32) {
        self.retired.store(retired, Ordering::Release);
    }

    /// Replies and samples dropped because the up queue was full.
    pub fn dropped_up(&self) -> u32 {
        self.dropped_up
    }
}
