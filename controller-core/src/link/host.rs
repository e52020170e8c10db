//! The host end of the link: handshake, command sender, real-time requests, telemetry
//! accounting and heartbeats behind a few calls.
//!
//! The host tool owns one [`HostLink`] per connection. It calls [`HostLink::poll`] often
//! (every few ms, and after every send) with an `emit` callback that encodes and writes
//! each frame; it feeds every decoded device frame to [`HostLink::on_frame`]; it queues
//! commands with [`HostLink::send`] while [`HostLink::can_send`] and real-time requests
//! with [`HostLink::request`]. Errors latch: once the link has failed (mismatch, no answer,
//! lost), every call reports the same error until a new `HostLink` (new session id) is
//! made. Real-time requests still go out in that state, so the user can always stop.

use super::command::{AckOutcome, CommandConfig, CommandError, CommandSender, SenderStats};
use super::envelope::{RealtimeRequest, Refusal, RefusedFrame, ToDevice, ToHost};
use super::handshake::{self, ProtocolMismatch, Role, Version};
use super::realtime::{RealtimeConfig, RealtimeSender, RealtimeUnanswered};
use super::seq::Seq;
use super::telemetry::{Arrival, TelemetryReceiver, TelemetryStats};
use super::watchdog::{Watchdog, WatchdogConfig};
use super::LinkConfigError;

/// Host link settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct HostLinkConfig {
    /// Command channel retransmission.
    pub command: CommandConfig,
    /// Real-time request repetition.
    pub realtime: RealtimeConfig,
    /// Watchdog on the device's frames; also sets the heartbeat interval (a quarter).
    /// Use the same timeout as the device.
    pub watchdog: WatchdogConfig,
    /// Time between Hello attempts while handshaking (ms, ≥ 1).
    pub hello_retry_ms: u32,
    /// Hello attempts before giving up with [`LinkError::NoAnswer`] (≥ 1).
    pub hello_attempts: u8,
}

/// Hello every 100 ms, 20 attempts (2 s: covers a board that is still booting).
pub const DEFAULT_HOST_LINK_CONFIG: HostLinkConfig = HostLinkConfig {
    command: super::command::DEFAULT_COMMAND_CONFIG,
    realtime: super::realtime::DEFAULT_REALTIME_CONFIG,
    watchdog: super::watchdog::DEFAULT_WATCHDOG_CONFIG,
    hello_retry_ms: 100,
    hello_attempts: 20,
};

/// Why the host link cannot go on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkError {
    /// The handshake has not completed yet: commands wait.
    NotReady,
    /// Window or device credits used up: poll and retry.
    WouldBlock,
    /// The device was built from another protocol version or message schema.
    ProtocolMismatch(ProtocolMismatch),
    /// No Hello answer after all attempts: nothing (or not our firmware) is listening.
    NoAnswer,
    /// A command was not acknowledged after all retries.
    RetriesExhausted {
        /// The command.
        seq: Seq,
    },
    /// A real-time request was not answered after all repetitions.
    RealtimeUnanswered(RealtimeUnanswered),
    /// Nothing valid from the device for the watchdog timeout.
    LinkLost,
    /// The device refused a frame (its session ended: it restarted or its watchdog
    /// expired).
    Refused {
        /// What.
        what: RefusedFrame,
        /// Why.
        reason: Refusal,
    },
}

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotReady => write!(f, "link: handshake not complete"),
            Self::WouldBlock => write!(f, "link: command window or device queue full"),
            Self::ProtocolMismatch(m) => write!(f, "{m}"),
            Self::NoAnswer => write!(f, "link: no handshake answer from the device"),
            Self::RetriesExhausted { seq } => {
                write!(
                    f,
                    "link: command {} not acknowledged after all retries",
                    seq.0
                )
            }
            Self::RealtimeUnanswered(r) => {
                write!(
                    f,
                    "link: real-time request {:?} (id {}) not answered",
                    r.req, r.id.0
                )
            }
            Self::LinkLost => write!(
                f,
                "link lost: no frame from the device within the watchdog timeout"
            ),
            Self::Refused { what, reason } => {
                write!(f, "link: device refused {what:?}: {reason:?}")
            }
        }
    }
}

/// Host link state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HostState {
    /// Sending Hello, waiting for the answer.
    Handshaking,
    /// Session open: commands flow.
    Ready,
    /// Failed with this (latched) error.
    Failed(LinkError),
}

/// What a device frame meant.
#[derive(Clone, Debug, PartialEq)]
pub enum HostEvent<T, S> {
    /// Nothing for the application (a stale or repeated frame, a credit update).
    None,
    /// The handshake completed.
    Ready,
    /// This many commands were acknowledged.
    Acked(u16),
    /// A telemetry sample (check `arrival.is_new()` before using it).
    Telemetry {
        /// Its sequence number.
        seq: Seq,
        /// The sample.
        sample: T,
        /// In order, after a gap, late, duplicate or stale.
        arrival: Arrival,
    },
    /// A status reply.
    Status {
        /// The request id it answers.
        id: Seq,
        /// The status.
        status: S,
        /// True when it answers the outstanding request.
        answered: bool,
    },
}

/// Host counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HostStats {
    /// Command channel.
    pub command: SenderStats,
    /// Telemetry channel.
    pub telemetry: TelemetryStats,
    /// Real-time request repetitions.
    pub realtime_repeats: u32,
    /// Hello frames sent.
    pub hellos: u32,
    /// Heartbeats sent.
    pub heartbeats: u32,
}

/// The host end of the link; up to `WINDOW` commands in flight.
#[derive(Clone, Debug)]
pub struct HostLink<C, const WINDOW: usize> {
    ours: Version,
    session: u16,
    /// The control rate the device announced in its Hello answer, Hz (`None` before it).
    device_rate_hz: Option<u32>,
    config: HostLinkConfig,
    state: HostState,
    hello_sent_at_ms: Option<u32>,
    commands: CommandSender<C, WINDOW>,
    realtime: RealtimeSender,
    telemetry: TelemetryReceiver,
    watchdog: Watchdog,
    last_tx_ms: Option<u32>,
    /// End of a silence the host was told to expect ([`HostLink::expect_silence`]).
    quiet_until_ms: Option<u32>,
    stats: HostStats,
}

/// Longest silence [`HostLink::expect_silence`] accepts, ms (a settings save that erases
/// both store sectors at DS8626's worst case takes 8 s).
pub const MAX_SILENCE_MS: u32 = 60_000;

impl<C, const WINDOW: usize> HostLink<C, WINDOW> {
    /// A link for the message set with `schema_hash`, opening session `session` (use a
    /// different id for every connection, e.g. from the clock, so the device restarts its
    /// numbering).
    ///
    /// # Errors
    /// [`LinkConfigError`] naming the bad setting.
    pub fn new(
        config: &HostLinkConfig,
        schema_hash: u32,
        session: u16,
    ) -> Result<Self, LinkConfigError> {
        if config.hello_retry_ms == 0 || config.hello_retry_ms > i32::MAX as u32 {
            return Err(LinkConfigError::OutOfRange("hello_retry_ms"));
        }
        if config.hello_attempts == 0 {
            return Err(LinkConfigError::OutOfRange("hello_attempts"));
        }
        Ok(Self {
            ours: Version::current(schema_hash),
            session,
            device_rate_hz: None,
            config: *config,
            state: HostState::Handshaking,
            hello_sent_at_ms: None,
            commands: CommandSender::new(&config.command, Seq::ZERO)?,
            realtime: RealtimeSender::new(&config.realtime, Seq::ZERO)?,
            telemetry: TelemetryReceiver::new(),
            watchdog: Watchdog::new(&config.watchdog)?,
            last_tx_ms: None,
            quiet_until_ms: None,
            stats: HostStats::default(),
        })
    }

    /// The device may go silent for up to `ms` (at most [`MAX_SILENCE_MS`]) from
    /// `now_ms`: a settings save that erases a flash sector stalls the board, its UART
    /// included, for seconds (the F407 has one flash bank). Until then neither the
    /// watchdog nor unanswered retransmissions and real-time repetitions fail the link;
    /// both go on being sent. A device still silent when the window ends fails it as
    /// before (the watchdog: [`LinkError::LinkLost`]).
    pub fn expect_silence(&mut self, now_ms: u32, ms: u32) {
        self.quiet_until_ms = Some(now_ms.wrapping_add(ms.min(MAX_SILENCE_MS)));
    }

    /// Inside an expected silence at `now_ms` (the window ends itself).
    fn quiet(&mut self, now_ms: u32) -> bool {
        // the window is at most MAX_SILENCE_MS long: time left beyond it is time past
        let quiet = self.quiet_until_ms.is_some_and(|t| {
            let left = t.wrapping_sub(now_ms);
            left != 0 && left <= MAX_SILENCE_MS
        });
        if !quiet {
            self.quiet_until_ms = None;
        }
        self.realtime.hold_retries(quiet);
        self.commands.hold_retries(quiet);
        quiet
    }

    /// State.
    #[must_use]
    pub const fn state(&self) -> HostState {
        self.state
    }

    /// The device's control rate, Hz, as its Hello answer announced it: `None` until the
    /// handshake has completed.
    #[must_use]
    pub const fn device_control_rate_hz(&self) -> Option<u32> {
        self.device_rate_hz
    }

    /// Counters.
    #[must_use]
    pub fn stats(&self) -> HostStats {
        HostStats {
            command: self.commands.stats(),
            telemetry: self.telemetry.stats(),
            realtime_repeats: self.realtime.repeats(),
            ..self.stats
        }
    }

    /// Commands sent and not yet acknowledged.
    #[must_use]
    pub fn in_flight(&self) -> usize {
        self.commands.in_flight()
    }

    /// True when [`HostLink::send`] would accept a command now.
    #[must_use]
    pub fn can_send(&self) -> bool {
        self.state == HostState::Ready && self.commands.can_push()
    }

    /// Queue a command (sent by the next poll).
    ///
    /// # Errors
    /// The latched error, [`LinkError::NotReady`] or [`LinkError::WouldBlock`]; the command
    /// is handed back.
    pub fn send(&mut self, cmd: C) -> Result<Seq, (LinkError, C)> {
        match self.state {
            HostState::Failed(e) => Err((e, cmd)),
            HostState::Handshaking => Err((LinkError::NotReady, cmd)),
            HostState::Ready => self
                .commands
                .push(cmd)
                .map_err(|(_, c)| (LinkError::WouldBlock, c)),
        }
    }

    /// Queue a real-time request (sent by the next poll, in any state); returns its id.
    pub fn request(&mut self, req: RealtimeRequest) -> Seq {
        self.realtime.request(req)
    }

    /// Send everything due at `now_ms` through `emit`: Hello while handshaking, pending
    /// real-time request, commands and retransmissions, a heartbeat on an idle link.
    ///
    /// # Errors
    /// The link failed (latched): see [`LinkError`].
    pub fn poll<F: FnMut(ToDevice<&C>)>(
        &mut self,
        now_ms: u32,
        mut emit: F,
    ) -> Result<(), LinkError> {
        let mut sent = false;
        let quiet = self.quiet(now_ms);
        let rt = self.realtime.poll(now_ms, |id, req| {
            sent = true;
            emit(ToDevice::Realtime { id, req });
        });
        if let Err(e) = rt {
            self.fail(LinkError::RealtimeUnanswered(e));
        }
        match self.state {
            HostState::Failed(_) => {}
            HostState::Handshaking => {
                let due = match self.hello_sent_at_ms {
                    None => true,
                    Some(t) => now_ms.wrapping_sub(t) >= self.config.hello_retry_ms,
                };
                if due {
                    if self.stats.hellos >= u32::from(self.config.hello_attempts) {
                        self.fail(LinkError::NoAnswer);
                    } else {
                        self.hello_sent_at_ms = Some(now_ms);
                        self.stats.hellos = self.stats.hellos.saturating_add(1);
                        sent = true;
                        // (a host runs no control loop: it announces no rate)
                        emit(ToDevice::Hello(self.ours.hello(
                            Role::Host,
                            self.session,
                            0,
                        )));
                    }
                }
            }
            HostState::Ready => {
                if self.watchdog.expired(now_ms) && !quiet {
                    self.fail(LinkError::LinkLost);
                } else {
                    let polled = self.commands.poll(now_ms, |seq, cmd| {
                        sent = true;
                        emit(ToDevice::Command { seq, cmd });
                    });
                    match polled {
                        Err(CommandError::RetriesExhausted { seq }) => {
                            self.fail(LinkError::RetriesExhausted { seq });
                        }
                        Err(CommandError::WouldBlock) | Ok(()) => {
                            let idle = match self.last_tx_ms {
                                None => true,
                                Some(t) => {
                                    now_ms.wrapping_sub(t) >= self.watchdog.heartbeat_interval_ms()
                                }
                            };
                            if !sent && idle {
                                sent = true;
                                self.stats.heartbeats = self.stats.heartbeats.saturating_add(1);
                                emit(ToDevice::Heartbeat);
                            }
                        }
                    }
                }
            }
        }
        if sent {
            self.last_tx_ms = Some(now_ms);
        }
        match self.state {
            HostState::Failed(e) => Err(e),
            _ => Ok(()),
        }
    }

    /// Handle one decoded device frame received at `now_ms`.
    ///
    /// # Errors
    /// A mismatch in the device's Hello, or a refusal (both latch).
    pub fn on_frame<T, S>(
        &mut self,
        frame: ToHost<T, S>,
        now_ms: u32,
    ) -> Result<HostEvent<T, S>, LinkError> {
        self.watchdog.feed(now_ms);
        match frame {
            ToHost::Hello(hello) => {
                if hello.session != self.session {
                    // Answer to another session's Hello: not ours.
                    return Ok(HostEvent::None);
                }
                let checked = match hello.role {
                    Role::Device => handshake::check(self.ours, &hello),
                    Role::Host => Err(ProtocolMismatch {
                        ours: self.ours,
                        theirs: Version::of(&hello),
                    }),
                };
                if let Err(m) = checked {
                    self.fail(LinkError::ProtocolMismatch(m));
                    return Err(LinkError::ProtocolMismatch(m));
                }
                if self.state == HostState::Handshaking {
                    self.state = HostState::Ready;
                    self.device_rate_hz = Some(hello.control_rate_hz);
                    self.watchdog.arm(now_ms);
                    self.telemetry.resync();
                    // Heartbeat at the next poll: its ack brings the device's credits.
                    self.last_tx_ms = None;
                    return Ok(HostEvent::Ready);
                }
                Ok(HostEvent::None)
            }
            ToHost::Ack { seq, credits } => {
                if self.state != HostState::Ready {
                    return Ok(HostEvent::None);
                }
                match self.commands.on_ack(seq, credits) {
                    AckOutcome::Acked(n) if n > 0 => Ok(HostEvent::Acked(n)),
                    _ => Ok(HostEvent::None),
                }
            }
            ToHost::Nak { seq, credits, got } => {
                if self.state != HostState::Ready {
                    return Ok(HostEvent::None);
                }
                match self.commands.on_nak(seq, credits, got) {
                    AckOutcome::Acked(n) if n > 0 => Ok(HostEvent::Acked(n)),
                    _ => Ok(HostEvent::None),
                }
            }
            ToHost::Refused { what, reason } => {
                let e = LinkError::Refused { what, reason };
                match what {
                    RefusedFrame::Command(_) if self.state == HostState::Ready => self.fail(e),
                    RefusedFrame::Realtime(id) => {
                        let _ = self.realtime.on_status(id);
                    }
                    RefusedFrame::Command(_) => {}
                }
                Err(e)
            }
            ToHost::Telemetry { seq, sample } => Ok(HostEvent::Telemetry {
                seq,
                sample,
                arrival: self.telemetry.on_frame(seq),
            }),
            ToHost::Status { id, status } => Ok(HostEvent::Status {
                id,
                status,
                answered: self.realtime.on_status(id),
            }),
        }
    }

    fn fail(&mut self, e: LinkError) {
        if !matches!(self.state, HostState::Failed(_)) {
            self.state = HostState::Failed(e);
        }
    }
}
