//! The host end of a `gantry` session: the link's [`HostLink`] over a [`Transport`], with
//! the requests a command needs (execute one request and wait for its outcome, read the
//! status, collect telemetry).
//!
//! A request's outcome: the device counts the requests it executed in the session
//! ([`Status::executed`]) and keeps the last one's [`Outcome`]; the client sends one
//! request, then asks for the status until the count reaches it.
//!
//! The machine's control rate comes with the handshake ([`Client::control_rate_hz`]):
//! telemetry decimations, scope captures and period-counted timeouts are converted with
//! it, never with an assumed rate.

use super::transport::Transport;
use anyhow::{anyhow, bail, Result};
use controller_core::link::host::DEFAULT_HOST_LINK_CONFIG;
use controller_core::link::{
    encode, Arrival, Feed, FrameDecoder, HostEvent, HostLink, HostState, RealtimeRequest, ToDevice,
    ToHost, MAX_FRAME_LEN,
};
use controller_core::machine::messages::{Outcome, Request, Status, Telemetry, SCHEMA_HASH};

/// Commands in flight at most.
const WINDOW: usize = 8;
/// Repetitions of an unanswered command or status request (every 50 ms) before the link is
/// declared dead: 1.5 s, so that a noisy line (1 % of bytes corrupted loses about half
/// of the 100-byte status frames) still gets through; the device's own watchdog is fed by
/// every frame that does arrive.
const MAX_RETRIES: u8 = 30;
/// Give up waiting for the device after this much (device) time, ms.
const REPLY_TIMEOUT_MS: u32 = 5_000;
/// Silence to expect from the board after a settings save or repair, ms: each erases up
/// to both store sectors, and the whole chip, its UART included, stalls for an erase
/// (`presets::board::FLASH_SECTOR_ERASE_MAX_MS` at worst each), plus a second of margin.
pub const SAVE_SILENCE_MS: u32 =
    2 * controller_core::presets::board::FLASH_SECTOR_ERASE_MAX_MS + 1_000;

/// A connected session.
pub struct Client<T: Transport> {
    pub transport: T,
    link: HostLink<Request, WINDOW>,
    decoder: FrameDecoder,
    rx: Vec<u8>,
    sent: u32,
    status: Option<Status>,
    status_id: Option<controller_core::link::Seq>,
    /// Telemetry received since the last [`Client::take_telemetry`].
    telemetry: Vec<Telemetry>,
    pub telemetry_gaps: u32,
    /// The newest control period number seen in a status or telemetry frame.
    last_period: u32,
    /// Extra time a reply may take while a save's silence is expected, ms.
    reply_grace_ms: u32,
    /// A copy of every status and telemetry sample as it arrives ([`Client::tap`]).
    tap: Option<std::sync::mpsc::Sender<Tapped>>,
    /// The machine's control rate, Hz, from its handshake answer.
    control_rate_hz: u32,
}

/// What [`Client::tap`] copies out of a session.
#[derive(Clone, Debug)]
pub enum Tapped {
    Status(Status),
    Telemetry(Telemetry),
}

impl<T: Transport> Client<T> {
    /// Handshake with the device behind `transport` (a session id from the process id).
    pub fn connect(transport: T) -> Result<Self> {
        Self::connect_session(transport, (std::process::id() & 0xffff) as u16 | 1)
    }

    /// Handshake with session id `session` (tests: the same bytes on every run).
    pub fn connect_session(transport: T, session: u16) -> Result<Self> {
        let mut cfg = DEFAULT_HOST_LINK_CONFIG;
        cfg.realtime.max_retries = MAX_RETRIES;
        cfg.command.max_retries = MAX_RETRIES;
        let link = HostLink::new(&cfg, SCHEMA_HASH, session).map_err(|e| anyhow!("link: {e}"))?;
        let mut c = Self {
            transport,
            link,
            decoder: FrameDecoder::new(),
            rx: Vec::new(),
            sent: 0,
            status: None,
            status_id: None,
            telemetry: Vec::new(),
            telemetry_gaps: 0,
            last_period: 0,
            reply_grace_ms: 0,
            tap: None,
            control_rate_hz: 0,
        };
        while c.link.state() == HostState::Handshaking {
            c.pump()?;
            c.transport.wait()?;
        }
        if let HostState::Failed(e) = c.link.state() {
            bail!("no session with the machine: {e:?}");
        }
        c.control_rate_hz = match c.link.device_control_rate_hz() {
            Some(hz) if hz > 0 => hz,
            // (a device link refuses to start without a rate: this is not our firmware)
            _ => bail!("no session with the machine: its handshake names no control rate"),
        };
        Ok(c)
    }

    /// The machine's control rate, Hz, as it announced it in the handshake (never 0).
    pub fn control_rate_hz(&self) -> u32 {
        self.control_rate_hz
    }

    /// Handle what arrived, send what is due, then handle what arrived meanwhile.
    ///
    /// What arrived is read before the link is polled: the poll checks the watchdog
    /// against the clock now, and frames the device sent while the host was not reading
    /// (a wait whose clock reading moved far, a panel exchange, a host starved of CPU)
    /// are proof of life that the watchdog must see first. Polled first, a clock that
    /// moved past the watchdog's timeout since the last read declared the link lost with
    /// the device's frames unread in the socket.
    pub fn pump(&mut self) -> Result<()> {
        self.receive()?;
        let now = self.transport.now_ms();
        let mut frames: Vec<Vec<u8>> = Vec::new();
        let res = self.link.poll(now, |f| {
            if super::trace::on() {
                let what = match &f {
                    controller_core::link::ToDevice::Hello(_) => "hello".to_string(),
                    controller_core::link::ToDevice::Heartbeat => "heartbeat".to_string(),
                    controller_core::link::ToDevice::Command { seq, .. } => {
                        format!("command {}", seq.0)
                    }
                    controller_core::link::ToDevice::Realtime { id, req } => {
                        format!("realtime {} {req:?}", id.0)
                    }
                    controller_core::link::ToDevice::Goodbye => "goodbye".to_string(),
                };
                super::trace::line(format_args!("m{now} tx {what}"));
            }
            let mut buf = [0u8; MAX_FRAME_LEN];
            if let Ok(n) = encode(&f, &mut buf) {
                frames.push(buf[..n].to_vec());
            }
        });
        for f in frames {
            self.transport.send(&f)?;
        }
        if let Err(e) = &res {
            super::trace::line(format_args!("m{now} failed {e:?}"));
        }
        res.map_err(|e| anyhow!("link failed: {e:?}"))?;
        self.receive()
    }

    /// `work` on a thread of its own while this one keeps the link serviced (heartbeats,
    /// acknowledgements, telemetry), on a transport whose machine clock runs alone
    /// ([`Transport::clock_runs_alone`]): parsing, compressing and measuring a program can
    /// take longer than the machine's link watchdog on a board (and on the twin or QEMU,
    /// whose clocks run on while the host computes). On the simulated machine, whose
    /// clock moves only when the host waits, `work` runs here and the machine stands still.
    pub fn while_busy<R: Send>(&mut self, work: impl FnOnce() -> R + Send) -> Result<R> {
        if !self.transport.clock_runs_alone() {
            return Ok(work());
        }
        std::thread::scope(|s| {
            let job = s.spawn(work);
            while !job.is_finished() {
                self.pump()?;
                self.transport.wait()?;
            }
            job.join()
                .map_err(|_| anyhow!("the host's work beside the link panicked"))
        })
    }

    /// Handle what arrived, sending nothing (not even heartbeats: a host gone silent).
    pub fn receive(&mut self) -> Result<()> {
        let now = self.transport.now_ms();
        self.transport.recv(&mut self.rx)?;
        let bytes = std::mem::take(&mut self.rx);
        let mut rest: &[u8] = &bytes;
        loop {
            match self.decoder.feed::<ToHost<Telemetry, Status>>(rest) {
                Feed::NeedMore => break,
                Feed::Frame { result, rest: r } => {
                    rest = r;
                    let frame = match result {
                        Ok(f) => f,
                        Err(e) => {
                            if std::env::var_os("GANTRY_DEBUG_FRAMES").is_some() {
                                eprintln!("frame dropped: {e:?}");
                            }
                            continue;
                        }
                    };
                    if super::trace::on() {
                        let what = match &frame {
                            ToHost::Hello(_) => "hello".to_string(),
                            ToHost::Ack { seq, credits } => format!("ack {} {credits}", seq.0),
                            ToHost::Nak { seq, .. } => format!("nak {}", seq.0),
                            ToHost::Refused { what, reason } => {
                                format!("refused {what:?} {reason:?}")
                            }
                            ToHost::Telemetry { seq, sample } => {
                                format!("telemetry {} p{}", seq.0, sample.period)
                            }
                            ToHost::Status { id, status } => {
                                format!("status {} p{}", id.0, status.period)
                            }
                        };
                        super::trace::line(format_args!("m{now} rx {what}"));
                    }
                    match self.link.on_frame(frame, now) {
                        Ok(HostEvent::Telemetry {
                            sample, arrival, ..
                        }) => {
                            if matches!(
                                arrival,
                                Arrival::InOrder | Arrival::Gap { .. } | Arrival::Late
                            ) {
                                self.last_period = self.last_period.max(sample.period);
                                if let Some(tap) = &self.tap {
                                    let _ = tap.send(Tapped::Telemetry(sample.clone()));
                                }
                                self.telemetry.push(sample);
                            }
                        }
                        Ok(HostEvent::Status { id, status, .. }) => {
                            if Some(id) == self.status_id {
                                self.status_id = None;
                            }
                            self.last_period = self.last_period.max(status.period);
                            if let Some(tap) = &self.tap {
                                let _ = tap.send(Tapped::Status(status.clone()));
                            }
                            self.status = Some(status);
                        }
                        Ok(_) => {}
                        Err(e) => bail!("link failed: {e:?}"),
                    }
                }
            }
        }
        self.telemetry_gaps = self.link.stats().telemetry.lost;
        Ok(())
    }

    /// From now on, a copy of every status and telemetry sample to `to` as it arrives,
    /// whatever command is running (a live view beside a blocking command: `gantry gui`'s
    /// session thread).
    pub fn tap(&mut self, to: std::sync::mpsc::Sender<Tapped>) {
        self.tap = Some(to);
    }

    /// Room for a request now (window and the device's credit).
    pub fn can_send(&self) -> bool {
        self.link.can_send()
    }

    /// Queue `req` (waiting for room in the window); does not wait for its outcome.
    pub fn send(&mut self, req: Request) -> Result<()> {
        let mut req = req;
        let t0 = self.transport.now_ms();
        loop {
            match self.link.send(req) {
                Ok(_) => {
                    self.sent = self.sent.wrapping_add(1);
                    return Ok(());
                }
                Err((e, r)) => {
                    if !matches!(e, controller_core::link::LinkError::WouldBlock) {
                        bail!("link: {e:?}");
                    }
                    req = r;
                    self.pump()?;
                    self.transport.wait()?;
                    if self.transport.now_ms().wrapping_sub(t0) > REPLY_TIMEOUT_MS * 20 {
                        bail!("the machine takes no more requests");
                    }
                }
            }
        }
    }

    /// The status now (a real-time request).
    pub fn status(&mut self) -> Result<Status> {
        self.status_id = Some(self.link.request(RealtimeRequest::Status));
        self.realtime_wait()
    }

    /// A real-time request (hold, resume, stop), answered with the status.
    pub fn realtime(&mut self, req: RealtimeRequest) -> Result<Status> {
        self.status_id = Some(self.link.request(req));
        self.realtime_wait()
    }

    fn realtime_wait(&mut self) -> Result<Status> {
        let t0 = self.transport.now_ms();
        loop {
            self.pump()?;
            if self.status_id.is_none() {
                if let Some(s) = &self.status {
                    return Ok(s.clone());
                }
            }
            if self.transport.now_ms().wrapping_sub(t0) > REPLY_TIMEOUT_MS + self.reply_grace_ms {
                bail!("no status from the machine");
            }
            self.transport.wait()?;
        }
    }

    /// Send `req` and wait until the machine executed it; its outcome.
    ///
    /// A settings save or repair may stall the board for seconds (a flash erase): the link
    /// is told to expect that silence ([`HostLink::expect_silence`]) and the replies until
    /// the outcome may take that long.
    pub fn exec(&mut self, req: Request) -> Result<Outcome> {
        let stalls = matches!(req, Request::SettingsSave | Request::SettingsRepair);
        if stalls {
            self.link
                .expect_silence(self.transport.now_ms(), SAVE_SILENCE_MS);
            self.reply_grace_ms = SAVE_SILENCE_MS;
        }
        let r = self.send(req).and_then(|()| self.wait_executed());
        self.reply_grace_ms = 0;
        r
    }

    /// Wait until every request sent so far was executed; the last outcome.
    pub fn wait_executed(&mut self) -> Result<Outcome> {
        let t0 = self.transport.now_ms();
        loop {
            let s = self.status()?;
            if s.executed >= self.sent {
                return Ok(s.last);
            }
            if self.transport.now_ms().wrapping_sub(t0) > REPLY_TIMEOUT_MS * 20 {
                bail!(
                    "the machine executed {} of {} requests",
                    s.executed,
                    self.sent
                );
            }
            self.transport.wait()?;
        }
    }

    /// Wait `ms` of device time (pumping the link).
    pub fn sleep_ms(&mut self, ms: u32) -> Result<()> {
        let t0 = self.transport.now_ms();
        while self.transport.now_ms().wrapping_sub(t0) < ms {
            self.pump()?;
            self.transport.wait()?;
        }
        Ok(())
    }

    /// The newest control period number the machine reported (status or telemetry): the
    /// machine's clock as the host sees it.
    pub fn last_period(&self) -> u32 {
        self.last_period
    }

    /// End the session cleanly ([`ToDevice::Goodbye`]): the machine's link watchdog is
    /// turned off without a `LinkLost` fault, and what needed this host (a program, a jog)
    /// stops; the machine stays armed, homed and set up for the next session. Without it
    /// the watchdog ends the session 500 ms later with a `LinkLost` fault latched.
    pub fn goodbye(&mut self) -> Result<()> {
        // what arrived first (acks, a last status), so nothing the host owes is pending
        self.pump()?;
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode(&ToDevice::<&Request>::Goodbye, &mut buf)
            .map_err(|e| anyhow!("goodbye frame: {e:?}"))?;
        super::trace::line(format_args!("m{} tx goodbye", self.transport.now_ms()));
        self.transport.send(&buf[..n])
    }

    /// The transport, for a new session on the same line.
    pub fn into_transport(self) -> T {
        self.transport
    }

    /// Telemetry received since the last call.
    pub fn take_telemetry(&mut self) -> Vec<Telemetry> {
        std::mem::take(&mut self.telemetry)
    }
}

/// `Ok` for [`Outcome::Done`] and values, an error naming `what` for a refusal.
pub fn expect_done(what: &str, o: Outcome) -> Result<Outcome> {
    match o {
        Outcome::Refused(why) => bail!("{what} refused: {why}"),
        other => Ok(other),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::link::{Role, Seq, Version};

    /// A device reduced to its frames: answers the host's Hello, and whatever the test
    /// puts in `inbox`; its clock is set by the test.
    struct Scripted {
        now: u32,
        inbox: Vec<u8>,
    }

    fn frame(f: &ToHost<Telemetry, Status>) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode(f, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    impl Transport for Scripted {
        fn send(&mut self, bytes: &[u8]) -> Result<()> {
            let mut d = FrameDecoder::new();
            if let Feed::Frame {
                result: Ok(controller_core::link::ToDevice::Hello(h)),
                ..
            } = d.feed::<controller_core::link::ToDevice<Request>>(bytes)
            {
                let ours = Version::current(SCHEMA_HASH).hello(Role::Device, h.session, 10_000);
                self.inbox.extend(frame(&ToHost::Hello(ours)));
            }
            Ok(())
        }
        fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
            buf.append(&mut self.inbox);
            Ok(())
        }
        fn now_ms(&self) -> u32 {
            self.now
        }
        fn wait(&mut self) -> Result<()> {
            self.now += 1;
            Ok(())
        }
        fn clock_runs_alone(&self) -> bool {
            false
        }
    }

    #[test]
    fn a_frame_waiting_when_the_clock_has_moved_past_the_watchdog_keeps_the_link() {
        let mut c = Client::connect_session(
            Scripted {
                now: 0,
                inbox: Vec::new(),
            },
            3,
        )
        .unwrap();
        c.pump().unwrap();
        // the host did not read for a while (a panel exchange, a starved host): its clock
        // moved past the watchdog's timeout since the last frame it read, and the device's
        // ack of its heartbeat waits unread
        let t = c.transport.now + DEFAULT_HOST_LINK_CONFIG.watchdog.timeout_ms + 100;
        c.transport.now = t;
        c.transport.inbox.extend(frame(&ToHost::Ack {
            seq: Seq::ZERO,
            credits: 16,
        }));
        c.pump().unwrap();
        c.pump().unwrap();
        // and with nothing from the device for the timeout, the link is lost
        c.transport.now = t + DEFAULT_HOST_LINK_CONFIG.watchdog.timeout_ms;
        let e = c.pump().unwrap_err().to_string();
        assert!(e.contains("LinkLost"), "{e}");
    }
}
