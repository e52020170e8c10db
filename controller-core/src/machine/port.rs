//! The hand-off between the link and the machine: on the board the link runs in its own
//! task and the machine in the control interrupt, so everything between them goes
//! through two lock-free single-producer, single-consumer queues ([`Channels`]): link
//! events down ([`Down`]), status replies and telemetry up ([`Up`]). The control
//! interrupt takes what is queued at the start of a period ([`Machine::linked_period`])
//! and never waits for the link; the link task never touches the machine.
//!
//! The link's credit (free request slots) is computed on the link side from two counters
//! — requests it passed down, requests the machine has retired (executed, refused or
//! flushed) — so the host never has more requests in flight than the machine's queue
//! holds, whichever side runs when.
//!
//! `gantry --sim` uses the very same queues in one thread (split per call).
//!
//! [`Machine::linked_period`]: super::Machine::linked_period

use core::sync::atomic::{AtomicU32, Ordering};

use heapless::spsc::{Consumer, Producer, Queue};

use super::messages::{Request, Status, Telemetry};
use super::REQUEST_QUEUE;
use crate::link::{RealtimeRequest, Seq};

/// What the link hands the machine.
#[derive(Clone, Debug, PartialEq)]
pub enum Down {
    /// A request of the reliable channel, for the machine's queue.
    Request(Request),
    /// A new session: the old one's queued requests are dropped.
    SessionStarted,
    /// A real-time request: act at once, then answer with [`Up::Status`] and `id`.
    Realtime { id: Seq, req: RealtimeRequest },
    /// Answer with [`Up::Status`] and `id` only.
    StatusOnly { id: Seq },
    /// The link's watchdog expired: controlled stop and a `LinkLost` fault.
    LinkLost,
}

/// What the machine hands the link.
#[derive(Clone, Debug, PartialEq)]
pub enum Up {
    Status { id: Seq, status: Status },
    Telemetry(Telemetry),
}

/// Capacity of the down queue: the request queue's credit, plus room for real-time
/// requests and session events (a real-time request that finds it full is dropped; the
/// host repeats it).
pub const DOWN_QUEUE: usize = REQUEST_QUEUE + 8;
/// Capacity of the up queue (status replies and telemetry samples between two runs of
/// the link task; when full, telemetry is dropped and counted as a gap by the host).
pub const UP_QUEUE: usize = 8;

/// The two queues and the credit counters.
pub struct Channels {
    down: Queue<Down, { DOWN_QUEUE + 1 }>,
    up: Queue<Up, { UP_QUEUE + 1 }>,
    /// Requests passed down (link side writes).
    sent: AtomicU32,
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
            sent: AtomicU32::new(0),
            retired: AtomicU32::new(0),
        }
    }

    /// The link's end and the control interrupt's end.
    pub fn split(&mut self) -> (LinkSide<'_>, ControlSide<'_>) {
        let (down_tx, down_rx) = self.down.split();
        let (up_tx, up_rx) = self.up.split();
        (
            LinkSide {
                down: down_tx,
                up: up_rx,
                sent: &self.sent,
                retired: &self.retired,
            },
            ControlSide {
                down: down_rx,
                up: up_tx,
                retired: &self.retired,
                dropped_up: 0,
            },
        )
    }
}

/// What the link's endpoint needs of the machine.
pub trait MachinePort {
    /// Requests the machine can still take (the credit the link advertises).
    fn free_slots(&self) -> u16;
    /// Hand an event down (a request only within the credit).
    fn down(&mut self, d: Down);
    /// The next reply or telemetry sample, if any.
    fn up(&mut self) -> Option<Up>;
}

/// The link task's end of [`Channels`].
pub struct LinkSide<'a> {
    down: Producer<'a, Down>,
    up: Consumer<'a, Up>,
    sent: &'a AtomicU32,
    retired: &'a AtomicU32,
}

impl MachinePort for LinkSide<'_> {
    fn free_slots(&self) -> u16 {
        let in_flight = self
            .sent
            .load(Ordering::Relaxed)
            .wrapping_sub(self.retired.load(Ordering::Acquire));
        (REQUEST_QUEUE as u32).saturating_sub(in_flight) as u16
    }

    fn down(&mut self, d: Down) {
        let is_request = matches!(d, Down::Request(_));
        // a full queue can only drop real-time traffic (requests stay within the
        // credit): the host repeats what it does not get an answer to
        if self.down.enqueue(d).is_ok() && is_request {
            let n = self.sent.load(Ordering::Relaxed).wrapping_add(1);
            self.sent.store(n, Ordering::Release);
        }
    }

    fn up(&mut self) -> Option<Up> {
        self.up.dequeue()
    }
}

/// The control interrupt's end of [`Channels`].
pub struct ControlSide<'a> {
    down: Consumer<'a, Down>,
    up: Producer<'a, Up>,
    retired: &'a AtomicU32,
    dropped_up: u32,
}

impl ControlSide<'_> {
    /// The next event from the link.
    pub fn take(&mut self) -> Option<Down> {
        self.down.dequeue()
    }

    /// Hand a reply or sample up; dropped (and counted) when the link task lags.
    pub fn send(&mut self, u: Up) {
        if self.up.enqueue(u).is_err() {
            self.dropped_up = self.dropped_up.wrapping_add(1);
        }
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
