//! The device end of the link: handshake, command receiver, real-time requests, watchdog
//! and telemetry numbering behind one call per received frame.
//!
//! The firmware's link task owns one [`DeviceLink`]. For every decoded frame it calls
//! [`DeviceLink::on_frame`] with the command queue's free slots and sends the returned
//! reply; it acts on the returned event (push the command into the queue, execute a
//! real-time request and answer with [`ToHost::Status`]). Periodically (every link task
//! run) it calls [`DeviceLink::poll`]: that reports watchdog expiry, which the supervisor
//! turns into a controlled stop and a `LinkLost` fault, and sends credit updates when the
//! queue drains. Telemetry frames are numbered by [`DeviceLink::telemetry`].

use super::command::{Ack, CommandReceiver, Receipt, ReceiverStats};
use super::envelope::{RealtimeRequest, Refusal, RefusedFrame, ToDevice, ToHost};
use super::handshake::{self, Hello, ProtocolMismatch, Role, Version};
use super::realtime::{RealtimeReceiver, RealtimeVerdict};
use super::seq::Seq;
use super::telemetry::TelemetrySender;
use super::watchdog::{Watchdog, WatchdogConfig};
use super::LinkConfigError;

/// Device link settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct DeviceLinkConfig {
    /// Heartbeat watchdog.
    pub watchdog: WatchdogConfig,
    /// Send an unsolicited ack (credit update) when the queue has this many more free
    /// slots than last advertised (≥ 1). An update is always sent when the last advertised
    /// credit was 0, so the host is never left waiting.
    pub credit_update_step: u16,
}

/// 500 ms watchdog; a credit update every 4 freed slots (one 6-byte ack per 4 commands
/// consumed: under 1 % of the link at 1000 commands/s).
pub const DEFAULT_DEVICE_LINK_CONFIG: DeviceLinkConfig = DeviceLinkConfig {
    watchdog: super::watchdog::DEFAULT_WATCHDOG_CONFIG,
    credit_update_step: 4,
};

/// The device's session state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceSession {
    /// No handshake yet, or the session ended (watchdog).
    None,
    /// Handshake done with this session id.
    Active(u16),
    /// The last handshake did not match.
    Mismatch(ProtocolMismatch),
}

/// A frame the device sends back (type-independent; turn into [`ToHost`] with
/// [`Reply::into_frame`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reply {
    /// Handshake answer.
    Hello(Hello),
    /// Command ack / credit update.
    Ack(Ack),
    /// Negative ack: `ack`, and command `got` was dropped as out of order.
    Nak {
        /// The cumulative ack.
        ack: Ack,
        /// The dropped command.
        got: Seq,
    },
    /// Refusal.
    Refused {
        /// What was refused.
        what: RefusedFrame,
        /// Why.
        reason: Refusal,
    },
}

impl Reply {
    /// The frame to encode and send.
    #[must_use]
    pub const fn into_frame<T, S>(self) -> ToHost<T, S> {
        match self {
            Self::Hello(h) => ToHost::Hello(h),
            Self::Ack(a) => ToHost::Ack {
                seq: a.seq,
                credits: a.credits,
            },
            Self::Nak { ack, got } => ToHost::Nak {
                seq: ack.seq,
                credits: ack.credits,
                got,
            },
            Self::Refused { what, reason } => ToHost::Refused { what, reason },
        }
    }
}

/// What the application must do after a frame.
#[derive(Clone, Debug, PartialEq)]
pub enum DeviceEvent<C> {
    /// Nothing.
    None,
    /// A new session started: the host restarts command numbering. Queued commands of
    /// an earlier session are the supervisor's to keep or flush.
    SessionStarted {
        /// The session id.
        session: u16,
    },
    /// The host ended its session cleanly ([`ToDevice::Goodbye`]): the watchdog is off;
    /// stop what needs the host (a program, a jog), without a `LinkLost` fault.
    SessionEnded,
    /// The handshake did not match: report it; commands are refused.
    Mismatch(ProtocolMismatch),
    /// Push this command into the command queue (room was promised by `free_slots`).
    Command(C),
    /// Execute this real-time request now, then send [`ToHost::Status`] with `id`.
    Realtime {
        /// Request id to echo.
        id: Seq,
        /// The request.
        req: RealtimeRequest,
    },
    /// Only send [`ToHost::Status`] with `id` (a repeated or overtaken request).
    StatusOnly {
        /// Request id to echo.
        id: Seq,
    },
}

/// Outcome of one received frame.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceStep<C> {
    /// What to do.
    pub event: DeviceEvent<C>,
    /// What to send back right away (before any status reply).
    pub reply: Option<Reply>,
}

/// Outcome of [`DeviceLink::poll`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DevicePoll {
    /// The watchdog expired now: controlled stop + `LinkLost`. The session has ended;
    /// reported once.
    pub link_lost: bool,
    /// A credit update to send.
    pub reply: Option<Reply>,
}

/// The device end of the link.
#[derive(Clone, Copy, Debug)]
pub struct DeviceLink {
    ours: Version,
    /// The machine's control rate, Hz, announced in every Hello answer.
    control_rate_hz: u32,
    credit_update_step: u16,
    session: DeviceSession,
    commands: CommandReceiver,
    realtime: RealtimeReceiver,
    watchdog: Watchdog,
    telemetry: TelemetrySender,
    /// Credits in the last ack sent.
    advertised: u16,
}

impl DeviceLink {
    /// A device link for the message set with `schema_hash` (see
    /// [`super::schema::schema_hash`]), for a machine whose control loop runs at
    /// `control_rate_hz` (announced to the host in the handshake).
    ///
    /// # Errors
    /// [`LinkConfigError`] naming the bad setting (a control rate of 0 among them).
    pub fn new(
        config: &DeviceLinkConfig,
        schema_hash: u32,
        control_rate_hz: u32,
    ) -> Result<Self, LinkConfigError> {
        if config.credit_update_step == 0 {
            return Err(LinkConfigError::OutOfRange("credit_update_step"));
        }
        if control_rate_hz == 0 {
            return Err(LinkConfigError::OutOfRange("control_rate_hz"));
        }
        Ok(Self {
            ours: Version::current(schema_hash),
            control_rate_hz,
            credit_update_step: config.credit_update_step,
            session: DeviceSession::None,
            commands: CommandReceiver::new(Seq::ZERO),
            realtime: RealtimeReceiver::new(),
            watchdog: Watchdog::new(&config.watchdog)?,
            telemetry: TelemetrySender::new(Seq::ZERO),
            advertised: 0,
        })
    }

    /// Session state.
    #[must_use]
    pub const fn session(&self) -> DeviceSession {
        self.session
    }

    /// Command channel counters.
    #[must_use]
    pub const fn command_stats(&self) -> ReceiverStats {
        self.commands.stats()
    }

    /// Handle one decoded frame received at `now_ms`; `free_slots` is the command queue's
    /// free room now.
    pub fn on_frame<C>(
        &mut self,
        frame: ToDevice<C>,
        now_ms: u32,
        free_slots: u16,
    ) -> DeviceStep<C> {
        // Any valid frame proves the host is alive.
        self.watchdog.feed(now_ms);
        match frame {
            ToDevice::Hello(hello) => self.on_hello(&hello, now_ms),
            ToDevice::Heartbeat => DeviceStep {
                event: DeviceEvent::None,
                reply: match self.session {
                    DeviceSession::Active(_) => Some(self.ack(self.commands.ack(free_slots))),
                    _ => None,
                },
            },
            ToDevice::Command { seq, cmd } => self.on_command(seq, cmd, free_slots),
            ToDevice::Realtime { id, req } => self.on_realtime(id, req),
            ToDevice::Goodbye => DeviceStep {
                event: match self.session {
                    DeviceSession::Active(_) => {
                        self.session = DeviceSession::None;
                        self.watchdog.disarm();
                        DeviceEvent::SessionEnded
                    }
                    _ => DeviceEvent::None,
                },
                reply: None,
            },
        }
    }

    /// Call every link task run: watchdog and credit updates.
    pub fn poll(&mut self, now_ms: u32, free_slots: u16) -> DevicePoll {
        if matches!(self.session, DeviceSession::Active(_)) && self.watchdog.expired(now_ms) {
            self.session = DeviceSession::None;
            self.watchdog.disarm();
            return DevicePoll {
                link_lost: true,
                reply: None,
            };
        }
        let reply = match self.session {
            DeviceSession::Active(_)
                if free_slots > 0
                    && (self.advertised == 0
                        || free_slots.saturating_sub(self.advertised)
                            >= self.credit_update_step) =>
            {
                Some(self.ack(self.commands.ack(free_slots)))
            }
            _ => None,
        };
        DevicePoll {
            link_lost: false,
            reply,
        }
    }

    /// Frame for a telemetry sample, numbered; `None` without a session (no telemetry
    /// spew at a host that has not asked for it).
    pub fn telemetry<T, S>(&mut self, sample: T) -> Option<ToHost<T, S>> {
        match self.session {
            DeviceSession::Active(_) => Some(ToHost::Telemetry {
                seq: self.telemetry.next_seq(),
                sample,
            }),
            _ => None,
        }
    }

    fn ack(&mut self, ack: Ack) -> Reply {
        self.advertised = ack.credits;
        Reply::Ack(ack)
    }

    fn refusal(&self) -> Refusal {
        match self.session {
            DeviceSession::Mismatch(_) => Refusal::ProtocolMismatch,
            _ => Refusal::NoSession,
        }
    }

    fn on_hello<C>(&mut self, hello: &Hello, now_ms: u32) -> DeviceStep<C> {
        let reply = Some(Reply::Hello(self.ours.hello(
            Role::Device,
            hello.session,
            self.control_rate_hz,
        )));
        let checked = match hello.role {
            Role::Host => handshake::check(self.ours, hello),
            // Our own Hello came back: an echo or a loop, not a host.
            Role::Device => Err(ProtocolMismatch {
                ours: self.ours,
                theirs: Version::of(hello),
            }),
        };
        let event = match checked {
            Err(m) => {
                self.session = DeviceSession::Mismatch(m);
                self.watchdog.disarm();
                DeviceEvent::Mismatch(m)
            }
            Ok(()) if self.session == DeviceSession::Active(hello.session) => {
                // A repeated Hello of the running session: answer, change nothing.
                DeviceEvent::None
            }
            Ok(()) => {
                self.session = DeviceSession::Active(hello.session);
                self.commands = CommandReceiver::new(Seq::ZERO);
                self.realtime.reset();
                self.watchdog.arm(now_ms);
                // Credits are unknown to the new host: the next poll advertises them.
                self.advertised = 0;
                DeviceEvent::SessionStarted {
                    session: hello.session,
                }
            }
        };
        DeviceStep { event, reply }
    }

    fn on_command<C>(&mut self, seq: Seq, cmd: C, free_slots: u16) -> DeviceStep<C> {
        if !matches!(self.session, DeviceSession::Active(_)) {
            return DeviceStep {
                event: DeviceEvent::None,
                reply: Some(Reply::Refused {
                    what: RefusedFrame::Command(seq),
                    reason: self.refusal(),
                }),
            };
        }
        let receipt = self.commands.on_command(seq, free_slots);
        let ack = self.ack(receipt.ack());
        let reply = Some(match receipt {
            Receipt::OutOfOrder(a) => Reply::Nak { ack: a, got: seq },
            _ => ack,
        });
        let event = match receipt {
            Receipt::Accept(_) => DeviceEvent::Command(cmd),
            _ => DeviceEvent::None,
        };
        DeviceStep { event, reply }
    }

    fn on_realtime<C>(&mut self, id: Seq, req: RealtimeRequest) -> DeviceStep<C> {
        let active = matches!(self.session, DeviceSession::Active(_));
        let event = match req {
            // Stopping and holding are always safe: honoured even without a session, so
            // a host that cannot handshake (wrong version) can still stop the machine.
            RealtimeRequest::Hold | RealtimeRequest::Stop if !active => {
                DeviceEvent::Realtime { id, req }
            }
            RealtimeRequest::Status => DeviceEvent::Realtime { id, req },
            _ if !active => {
                return DeviceStep {
                    event: DeviceEvent::None,
                    reply: Some(Reply::Refused {
                        what: RefusedFrame::Realtime(id),
                        reason: self.refusal(),
                    }),
                }
            }
            _ => match self.realtime.on_request(id) {
                RealtimeVerdict::Execute => DeviceEvent::Realtime { id, req },
                RealtimeVerdict::ReplyOnly => DeviceEvent::StatusOnly { id },
            },
        };
        DeviceStep { event, reply: None }
    }
}
