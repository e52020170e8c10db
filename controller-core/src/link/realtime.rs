//! Real-time requests (hold, resume, stop, status): outside the command queue and window.
//!
//! grbl's single-byte `!`, `~`, `?` rebuilt as frames: still CRC-checked, but they bypass
//! the command sequence and credits, and the device executes them on arrival. Each request
//! carries an id (its own [`Seq`] numbering); the device's status reply echoes the id and
//! is the request's acknowledgement. The host repeats an unanswered request after a
//! timeout; the device executes a request only when its id is newer than the last one it
//! executed, so a repeated or late-arriving old request (a `Hold` overtaken by a
//! `Resume`) never acts twice or out of order. It still gets a status reply.
//!
//! One request is outstanding at a time on the host: a new request replaces an unanswered
//! one (a `Stop` need not wait behind a lost `Hold`).

use super::envelope::RealtimeRequest;
use super::seq::Seq;
use super::LinkConfigError;

/// Host settings for real-time requests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct RealtimeConfig {
    /// Time without a status reply after which the request is sent again (ms).
    pub retry_timeout_ms: u32,
    /// Repetitions before giving up (≥ 1).
    pub max_retries: u8,
}

/// Same timing as the command channel: 50 ms, 10 repetitions.
pub const DEFAULT_REALTIME_CONFIG: RealtimeConfig = RealtimeConfig {
    retry_timeout_ms: 50,
    max_retries: 10,
};

impl RealtimeConfig {
    /// Check the settings.
    ///
    /// # Errors
    /// [`LinkConfigError`] naming the bad field.
    pub const fn validate(&self) -> Result<(), LinkConfigError> {
        if self.retry_timeout_ms == 0 || self.retry_timeout_ms > i32::MAX as u32 {
            return Err(LinkConfigError::OutOfRange("realtime.retry_timeout_ms"));
        }
        if self.max_retries == 0 {
            return Err(LinkConfigError::OutOfRange("realtime.max_retries"));
        }
        Ok(())
    }
}

/// A real-time request was not answered after all repetitions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RealtimeUnanswered {
    /// Request id.
    pub id: Seq,
    /// The request.
    pub req: RealtimeRequest,
}

#[derive(Clone, Copy, Debug)]
struct Outstanding {
    id: Seq,
    req: RealtimeRequest,
    sent_at_ms: Option<u32>,
    retries: u8,
}

/// Host side: numbers requests and repeats the unanswered one.
#[derive(Clone, Copy, Debug)]
pub struct RealtimeSender {
    config: RealtimeConfig,
    next_id: Seq,
    outstanding: Option<Outstanding>,
    repeats: u32,
    /// Repetitions go on without counting towards `max_retries` (the host expects the
    /// device to be silent: [`super::host::HostLink::expect_silence`]).
    retries_held: bool,
}

impl RealtimeSender {
    /// A sender whose first request gets id `first`.
    ///
    /// # Errors
    /// [`LinkConfigError`] for a bad config.
    pub const fn new(config: &RealtimeConfig, first: Seq) -> Result<Self, LinkConfigError> {
        if let Err(e) = config.validate() {
            return Err(e);
        }
        Ok(Self {
            config: *config,
            next_id: first,
            outstanding: None,
            repeats: 0,
            retries_held: false,
        })
    }

    /// While `held`, a request is repeated at its timeout but never given up.
    pub fn hold_retries(&mut self, held: bool) {
        self.retries_held = held;
    }

    /// Queue `req` (sent by the next [`RealtimeSender::poll`]); replaces an unanswered one.
    pub fn request(&mut self, req: RealtimeRequest) -> Seq {
        let id = self.next_id;
        self.next_id = id.next();
        self.outstanding = Some(Outstanding {
            id,
            req,
            sent_at_ms: None,
            retries: 0,
        });
        id
    }

    /// The unanswered request, if any.
    #[must_use]
    pub fn outstanding(&self) -> Option<(Seq, RealtimeRequest)> {
        self.outstanding.map(|o| (o.id, o.req))
    }

    /// Repetitions so far.
    #[must_use]
    pub const fn repeats(&self) -> u32 {
        self.repeats
    }

    /// Send the request if it is new or its timeout ran out.
    ///
    /// # Errors
    /// [`RealtimeUnanswered`] after `max_retries` repetitions; the request is dropped.
    pub fn poll<F: FnMut(Seq, RealtimeRequest)>(
        &mut self,
        now_ms: u32,
        mut emit: F,
    ) -> Result<(), RealtimeUnanswered> {
        let Some(o) = self.outstanding.as_mut() else {
            return Ok(());
        };
        match o.sent_at_ms {
            None => {}
            Some(t) if now_ms.wrapping_sub(t) >= self.config.retry_timeout_ms => {
                if self.retries_held {
                    // repeated, not counted
                } else if o.retries >= self.config.max_retries {
                    let e = RealtimeUnanswered {
                        id: o.id,
                        req: o.req,
                    };
                    self.outstanding = None;
                    return Err(e);
                } else {
                    o.retries = o.retries.saturating_add(1);
                }
                self.repeats = self.repeats.saturating_add(1);
            }
            Some(_) => return Ok(()),
        }
        o.sent_at_ms = Some(now_ms);
        emit(o.id, o.req);
        Ok(())
    }

    /// A status reply for request `id` arrived; true when it answers the outstanding one.
    pub fn on_status(&mut self, id: Seq) -> bool {
        match self.outstanding {
            Some(o) if o.id == id => {
                self.outstanding = None;
                true
            }
            _ => false,
        }
    }
}

/// What the device does with a real-time request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RealtimeVerdict {
    /// New request: execute it, then reply with the status.
    Execute,
    /// Repeated or older than the last executed one: only reply with the status.
    ReplyOnly,
}

/// Device side: executes each request id at most once, never an older one after a newer.
#[derive(Clone, Copy, Debug, Default)]
pub struct RealtimeReceiver {
    last_executed: Option<Seq>,
}

impl RealtimeReceiver {
    /// Nothing executed yet.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            last_executed: None,
        }
    }

    /// Forget the history (new session: the host restarts its ids).
    pub fn reset(&mut self) {
        self.last_executed = None;
    }

    /// Decide about request `id`.
    pub fn on_request(&mut self, id: Seq) -> RealtimeVerdict {
        match self.last_executed {
            Some(last) if !id.is_after(last) => RealtimeVerdict::ReplyOnly,
            _ => {
                self.last_executed = Some(id);
                RealtimeVerdict::Execute
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_repeats_until_answered_then_stops() {
        let mut s = RealtimeSender::new(&DEFAULT_REALTIME_CONFIG, Seq(0)).unwrap();
        let id = s.request(RealtimeRequest::Hold);
        let mut sent = 0;
        s.poll(0, |_, _| sent += 1).unwrap();
        s.poll(49, |_, _| sent += 1).unwrap();
        assert_eq!(sent, 1);
        s.poll(50, |_, _| sent += 1).unwrap();
        assert_eq!(sent, 2);
        assert!(!s.on_status(Seq(id.0.wrapping_add(7))));
        assert!(s.on_status(id));
        s.poll(1000, |_, _| sent += 1).unwrap();
        assert_eq!((sent, s.repeats()), (2, 1));
    }

    #[test]
    fn host_gives_up_after_max_retries() {
        let cfg = RealtimeConfig {
            retry_timeout_ms: 10,
            max_retries: 3,
        };
        let mut s = RealtimeSender::new(&cfg, Seq(0)).unwrap();
        s.request(RealtimeRequest::Stop);
        let mut sent = 0;
        let mut t = 0;
        let err = loop {
            if let Err(e) = s.poll(t, |_, _| sent += 1) {
                break e;
            }
            t += 10;
        };
        assert_eq!(err.req, RealtimeRequest::Stop);
        assert_eq!(sent, 4); // first send + 3 repetitions
        assert_eq!(s.outstanding(), None);
    }

    #[test]
    fn a_newer_request_replaces_the_unanswered_one() {
        let mut s = RealtimeSender::new(&DEFAULT_REALTIME_CONFIG, Seq(65535)).unwrap();
        s.request(RealtimeRequest::Hold);
        let stop = s.request(RealtimeRequest::Stop);
        assert_eq!(stop, Seq(0));
        assert_eq!(s.outstanding(), Some((Seq(0), RealtimeRequest::Stop)));
    }

    #[test]
    fn device_executes_each_id_once_and_never_an_older_one() {
        let mut r = RealtimeReceiver::new();
        assert_eq!(r.on_request(Seq(65535)), RealtimeVerdict::Execute);
        assert_eq!(r.on_request(Seq(65535)), RealtimeVerdict::ReplyOnly);
        assert_eq!(r.on_request(Seq(1)), RealtimeVerdict::Execute); // across the wrap
        assert_eq!(r.on_request(Seq(0)), RealtimeVerdict::ReplyOnly); // late, older
        r.reset();
        assert_eq!(r.on_request(Seq(0)), RealtimeVerdict::Execute);
    }

    #[test]
    fn bad_config_is_rejected_by_name() {
        let cfg = RealtimeConfig {
            retry_timeout_ms: 0,
            max_retries: 3,
        };
        assert_eq!(
            RealtimeSender::new(&cfg, Seq(0)).err(),
            Some(LinkConfigError::OutOfRange("realtime.retry_timeout_ms"))
        );
    }
}
