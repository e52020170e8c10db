//! Reliable command channel: sequence numbers, cumulative acks, retransmission, a window,
//! and credit flow control.
//!
//! Scheme: Go-Back-N with cumulative acks and negative acks, as Klipper does host → MCU.
//!
//! - The host's [`CommandSender`] numbers commands and keeps every unacknowledged one (up
//!   to `WINDOW`). When the oldest one has waited `retransmit_timeout_ms` for its ack, or
//!   when a negative ack shows that a frame was lost, it goes back: everything
//!   unacknowledged is sent again, oldest first. Only the oldest command's retransmissions
//!   count as retries (the others were dropped because of it); after `max_retries` of them
//!   it gives up with [`CommandError::RetriesExhausted`] and the link counts as lost.
//! - The device's [`CommandReceiver`] accepts only the next expected number. A duplicate
//!   (already accepted) is re-acked and not executed again. A frame from beyond the
//!   expected one (an earlier frame was lost or overtaken) is dropped and answered with a
//!   negative ack naming it, so the host goes back after one round trip instead of a
//!   timeout. One negative ack per round: further frames beyond the gap get plain acks
//!   until the host's go-back shows (a number at or before the last one nak'ed arrives),
//!   so a burst of out-of-order frames causes one go-back, not a burst of them. Dropping
//!   instead of buffering out-of-order frames keeps the device free of any per-frame
//!   buffer.
//! - Every ack carries the device queue's free slots after the acked command, the
//!   *credits*: the sender keeps at most `min(WINDOW, credits)` commands in flight, so the
//!   device never receives a command it has no room for (grbl's `Bf:` turned into flow
//!   control). The device refuses (does not accept) a command that finds its queue full,
//!   so a stale credit figure costs a retransmission but never a lost or duplicated
//!   command.
//!
//! Sequence numbers are [`Seq`] (u16, wrapping); `WINDOW` must stay below 32768.
//! Time is the caller's monotonic millisecond counter (`u32`, wrapping).

use heapless::Deque;

use super::seq::Seq;
use super::LinkConfigError;

/// Retransmission settings of the command channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct CommandConfig {
    /// Time without an ack after which a command is sent again (ms). Must exceed the
    /// round trip: a 263-byte frame takes 2.9 ms each way at 921,600 baud, plus the link
    /// task latency and the host's serial driver (USB-serial adapters buffer 1-16 ms).
    pub retransmit_timeout_ms: u32,
    /// Retransmissions of one command before giving up (≥ 1).
    pub max_retries: u8,
}

/// 50 ms: above a USB-serial round trip (≤ 20 ms) with margin; 10 retries (0.5 s of
/// silence) before the link is declared dead, still well inside a typical 1 s watchdog
/// window on the device so both sides conclude the same.
pub const DEFAULT_COMMAND_CONFIG: CommandConfig = CommandConfig {
    retransmit_timeout_ms: 50,
    max_retries: 10,
};

impl CommandConfig {
    /// Check the settings.
    ///
    /// # Errors
    /// [`LinkConfigError`] naming the bad field.
    pub const fn validate(&self) -> Result<(), LinkConfigError> {
        if self.retransmit_timeout_ms == 0 || self.retransmit_timeout_ms > i32::MAX as u32 {
            return Err(LinkConfigError::OutOfRange("retransmit_timeout_ms"));
        }
        if self.max_retries == 0 {
            return Err(LinkConfigError::OutOfRange("max_retries"));
        }
        Ok(())
    }
}

/// Why the sender cannot go on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandError {
    /// The window or the device's credits are used up: wait for acks.
    WouldBlock,
    /// Command `seq` was retransmitted `max_retries` times without an ack.
    RetriesExhausted {
        /// The oldest unacknowledged command.
        seq: Seq,
    },
}

impl core::fmt::Display for CommandError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::WouldBlock => write!(f, "command window or device credits used up"),
            Self::RetriesExhausted { seq } => {
                write!(f, "command {} not acknowledged after all retries", seq.0)
            }
        }
    }
}

/// What an ack did to the sender.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AckOutcome {
    /// Acknowledged this many commands (0 for a repeated ack, which still updates credits).
    Acked(u16),
    /// Older than an ack already seen (reordered or duplicated on the wire): ignored.
    Stale,
    /// Acknowledges a number never sent: ignored (a device from another session).
    Bogus,
}

/// Sender counters (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SenderStats {
    /// Commands accepted by [`CommandSender::push`].
    pub pushed: u32,
    /// First transmissions.
    pub sent: u32,
    /// Retransmissions.
    pub retransmitted: u32,
    /// Commands acknowledged.
    pub acked: u32,
    /// Stale acks ignored.
    pub stale_acks: u32,
    /// Bogus acks ignored.
    pub bogus_acks: u32,
}

#[derive(Clone, Debug)]
struct Pending<C> {
    seq: Seq,
    cmd: C,
    /// Time of the last transmission, `None` before the first.
    sent_at_ms: Option<u32>,
    /// Retransmissions while this was the oldest unacknowledged command.
    retries: u8,
}

/// Host side of the command channel; keeps up to `WINDOW` unacknowledged commands.
#[derive(Clone, Debug)]
pub struct CommandSender<C, const WINDOW: usize> {
    config: CommandConfig,
    pending: Deque<Pending<C>, WINDOW>,
    next_seq: Seq,
    last_ack: Seq,
    credits: u16,
    /// A negative ack asked for a go-back at the next poll.
    go_back: bool,
    /// Retransmissions go on without counting towards `max_retries` (the host expects
    /// the device to be silent: [`super::host::HostLink::expect_silence`]).
    retries_held: bool,
    stats: SenderStats,
}

impl<C, const WINDOW: usize> CommandSender<C, WINDOW> {
    /// A sender whose first command is number `first`. It has no credits until the
    /// device's first ack (the device answers a heartbeat with one).
    ///
    /// # Errors
    /// [`LinkConfigError`] for a bad config or `WINDOW` above 32767 (`WINDOW` = 0 does
    /// not compile).
    pub fn new(config: &CommandConfig, first: Seq) -> Result<Self, LinkConfigError> {
        config.validate()?;
        if WINDOW > i16::MAX as usize {
            return Err(LinkConfigError::OutOfRange("WINDOW"));
        }
        Ok(Self {
            config: *config,
            pending: Deque::new(),
            next_seq: first,
            last_ack: first.prev(),
            credits: 0,
            go_back: false,
            retries_held: false,
            stats: SenderStats::default(),
        })
    }

    /// While `held`, unacknowledged commands are retransmitted at their timeout but never
    /// given up.
    pub fn hold_retries(&mut self, held: bool) {
        self.retries_held = held;
    }

    /// Counters.
    #[must_use]
    pub const fn stats(&self) -> SenderStats {
        self.stats
    }

    /// Commands sent and not yet acknowledged.
    #[must_use]
    pub fn in_flight(&self) -> usize {
        self.pending.len()
    }

    /// Credits from the newest ack (free device queue slots after the acked command).
    #[must_use]
    pub const fn credits(&self) -> u16 {
        self.credits
    }

    /// Number the next pushed command gets.
    #[must_use]
    pub const fn next_seq(&self) -> Seq {
        self.next_seq
    }

    /// True when [`CommandSender::push`] would accept a command now.
    #[must_use]
    pub fn can_push(&self) -> bool {
        let n = self.pending.len();
        n < WINDOW && n < usize::from(self.credits)
    }

    /// Queue `cmd` for transmission (sent by the next [`CommandSender::poll`]).
    ///
    /// # Errors
    /// [`CommandError::WouldBlock`] when the window or the credits are used up; the
    /// command is handed back unchanged in that case.
    pub fn push(&mut self, cmd: C) -> Result<Seq, (CommandError, C)> {
        if !self.can_push() {
            return Err((CommandError::WouldBlock, cmd));
        }
        let seq = self.next_seq;
        let entry = Pending {
            seq,
            cmd,
            sent_at_ms: None,
            retries: 0,
        };
        match self.pending.push_back(entry) {
            Ok(()) => {
                self.next_seq = seq.next();
                self.stats.pushed = self.stats.pushed.saturating_add(1);
                Ok(seq)
            }
            Err(entry) => Err((CommandError::WouldBlock, entry.cmd)),
        }
    }

    /// Send what is due at `now_ms` through `emit(seq, cmd)`: first transmissions, and
    /// after a timeout of the oldest command or a negative ack, every sent command again
    /// (oldest first, so the receiver sees them in order).
    ///
    /// # Errors
    /// [`CommandError::RetriesExhausted`] when the oldest command would need more than
    /// `max_retries` retransmissions; nothing is sent then.
    pub fn poll<F: FnMut(Seq, &C)>(
        &mut self,
        now_ms: u32,
        mut emit: F,
    ) -> Result<(), CommandError> {
        let timed_out = match self.pending.front() {
            Some(Pending {
                sent_at_ms: Some(t),
                ..
            }) => now_ms.wrapping_sub(*t) >= self.config.retransmit_timeout_ms,
            _ => false,
        };
        let go_back = timed_out || self.go_back;
        self.go_back = false;
        if go_back && !self.retries_held {
            if let Some(head) = self.pending.front_mut() {
                if head.retries >= self.config.max_retries {
                    return Err(CommandError::RetriesExhausted { seq: head.seq });
                }
                head.retries = head.retries.saturating_add(1);
            }
        }
        for p in self.pending.iter_mut() {
            match p.sent_at_ms {
                None => self.stats.sent = self.stats.sent.saturating_add(1),
                Some(_) if go_back => {
                    self.stats.retransmitted = self.stats.retransmitted.saturating_add(1);
                }
                Some(_) => continue,
            }
            p.sent_at_ms = Some(now_ms);
            emit(p.seq, &p.cmd);
        }
        Ok(())
    }

    /// Handle a negative ack: the device accepted up to `seq` (with `credits`, as an ack)
    /// and dropped command `got` as out of order. Asks for a go-back at the next poll when
    /// `got` is still unacknowledged (the device sends one negative ack per gap).
    pub fn on_nak(&mut self, seq: Seq, credits: u16, got: Seq) -> AckOutcome {
        let outcome = self.on_ack(seq, credits);
        if self
            .pending
            .iter()
            .any(|p| p.seq == got && p.sent_at_ms.is_some())
        {
            self.go_back = true;
        }
        outcome
    }

    /// Handle an ack from the device (cumulative up to `seq`, `credits` free slots).
    pub fn on_ack(&mut self, seq: Seq, credits: u16) -> AckOutcome {
        let advance = seq.diff(self.last_ack);
        if advance < 0 {
            self.stats.stale_acks = self.stats.stale_acks.saturating_add(1);
            return AckOutcome::Stale;
        }
        // `advance` ≥ 0 here, and at most WINDOW ≤ 32767 commands are in flight.
        let advance = advance.unsigned_abs();
        if usize::from(advance) > self.pending.len() {
            self.stats.bogus_acks = self.stats.bogus_acks.saturating_add(1);
            return AckOutcome::Bogus;
        }
        for _ in 0..advance {
            let _ = self.pending.pop_front();
        }
        self.last_ack = seq;
        self.credits = credits;
        self.stats.acked = self.stats.acked.saturating_add(u32::from(advance));
        AckOutcome::Acked(advance)
    }
}

/// What the receiver decided about one command frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Receipt {
    /// The next command in order: execute (push into the queue) and send `ack`.
    Accept(Ack),
    /// Already accepted earlier (a retransmission): do not execute, send `ack`.
    Duplicate(Ack),
    /// Beyond the expected number (an earlier frame was lost): drop, send a negative ack
    /// (`ack` plus the number received) so the sender goes back at once.
    OutOfOrder(Ack),
    /// Beyond the expected number, after a negative ack for this gap was already sent:
    /// drop, send `ack` (plain).
    Ahead(Ack),
    /// The next command but the queue is full (the sender ignored the credits): drop,
    /// send `ack` (with 0 credits).
    QueueFull(Ack),
}

impl Receipt {
    /// The ack to send back, whatever the decision.
    #[must_use]
    pub const fn ack(&self) -> Ack {
        match self {
            Self::Accept(a)
            | Self::Duplicate(a)
            | Self::OutOfOrder(a)
            | Self::Ahead(a)
            | Self::QueueFull(a) => *a,
        }
    }
}

/// Contents of an ack frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ack {
    /// Last command accepted in order.
    pub seq: Seq,
    /// Free command queue slots after it.
    pub credits: u16,
}

/// Receiver counters (saturating).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReceiverStats {
    /// Commands accepted.
    pub accepted: u32,
    /// Duplicates re-acked.
    pub duplicates: u32,
    /// Out-of-order frames dropped.
    pub out_of_order: u32,
    /// Frames dropped for a full queue.
    pub queue_full: u32,
}

/// Device side of the command channel. Holds no frames (see the module doc), so it needs
/// no window parameter.
#[derive(Clone, Copy, Debug)]
pub struct CommandReceiver {
    expected: Seq,
    /// The out-of-order frame last answered with a negative ack, for this `expected`.
    naked: Option<Seq>,
    stats: ReceiverStats,
}

impl CommandReceiver {
    /// A receiver expecting command number `first` next.
    #[must_use]
    pub const fn new(first: Seq) -> Self {
        Self {
            expected: first,
            naked: None,
            stats: ReceiverStats {
                accepted: 0,
                duplicates: 0,
                out_of_order: 0,
                queue_full: 0,
            },
        }
    }

    /// Counters.
    #[must_use]
    pub const fn stats(&self) -> ReceiverStats {
        self.stats
    }

    /// The number expected next.
    #[must_use]
    pub const fn expected(&self) -> Seq {
        self.expected
    }

    /// The current cumulative ack with `free_slots` credits.
    #[must_use]
    pub const fn ack(&self, free_slots: u16) -> Ack {
        Ack {
            seq: self.expected.prev(),
            credits: free_slots,
        }
    }

    /// Decide about command `seq`; `free_slots` is the command queue's free room now.
    pub fn on_command(&mut self, seq: Seq, free_slots: u16) -> Receipt {
        let d = seq.diff(self.expected);
        if d < 0 {
            self.stats.duplicates = self.stats.duplicates.saturating_add(1);
            Receipt::Duplicate(self.ack(free_slots))
        } else if d > 0 {
            self.stats.out_of_order = self.stats.out_of_order.saturating_add(1);
            // Nak once per go-back round: again only when the sender has gone back, i.e.
            // a number at or before the last nak'ed one arrives.
            match self.naked {
                Some(n) if seq.is_after(n) => Receipt::Ahead(self.ack(free_slots)),
                _ => {
                    self.naked = Some(seq);
                    Receipt::OutOfOrder(self.ack(free_slots))
                }
            }
        } else if free_slots == 0 {
            self.stats.queue_full = self.stats.queue_full.saturating_add(1);
            Receipt::QueueFull(self.ack(0))
        } else {
            self.expected = seq.next();
            self.naked = None;
            self.stats.accepted = self.stats.accepted.saturating_add(1);
            Receipt::Accept(self.ack(free_slots - 1))
        }
    }
}

#[cfg(test)]
mod tests;
