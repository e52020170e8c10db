//! The link side's half of the settings requests: everything that reads or writes text
//! or walks the key table (parsing a value, checking its range, naming a field in an
//! error, the change's class) happens here, in the link task, never in the control
//! interrupt. The control interrupt only receives a whole, validated tree with the servo
//! configuration derived from it (by the link side, [`super::PreparedSettings`]) to swap in
//! at a period boundary ([`super::Down::Apply`]), or an outcome already decided here
//! ([`super::Down::Resolved`]), each in its place among the other requests.
//!
//! A settings request reads the settings the machine runs; so it is resolved only once
//! every request before it was executed (a barrier), with the settings the machine
//! echoed back after its last change ([`SettingsAgent::machine_took`]).
//!
//! Transactions (`gantry settings import`, `settings set` of several keys): between
//! [`Request::SettingsBegin`] and [`Request::SettingsCommit`] the changes go into a
//! candidate tree here, each checked for its type and range; the commit validates the
//! candidate whole ([`Settings::validate_change`], the servo configuration built from it)
//! and hands it down as one tree, which the machine swaps in at a period boundary or
//! refuses whole. A refusal at any step changes nothing on the machine.

use core::fmt::Write;

use heapless::String;

use super::messages::{IdentifyMsg, Outcome, Request, TEXT_MAX, VALUE_MAX};
use crate::plant::AxisModel;
use crate::settings::{Apply, Settings, FACTORY};

/// What a settings request turned into.
#[derive(Clone, Debug, PartialEq)]
// (a value on its way into a queue slot of the same size: boxing is not possible here)
#[allow(clippy::large_enum_variant)]
pub enum Resolution {
    /// Decided here (a value read, or a refusal that names the field and why).
    Outcome(Outcome),
    /// Swap in these settings (validated whole; `class`: `None` when no servo parameter
    /// changes).
    Apply {
        settings: Settings,
        class: Option<Apply>,
    },
}

/// The link side's copy of the machine's settings, and the last identification result
/// the machine reported.
#[derive(Clone, Debug)]
pub struct SettingsAgent {
    shadow: Settings,
    rate_hz: u32,
    identify: Option<IdentifyMsg>,
    txn: Option<Transaction>,
}

/// An open settings transaction.
#[derive(Clone, Debug)]
struct Transaction {
    /// The machine's settings when it began, and the tree its changes build.
    base: Settings,
    candidate: Settings,
    /// A change was refused: the commit is too.
    refused: bool,
}

fn refused<E: core::fmt::Display>(e: E) -> Resolution {
    let mut t: String<TEXT_MAX> = String::new();
    // (a message longer than the field is cut: still names the key first)
    let _ = write!(t, "{e}");
    Resolution::Outcome(Outcome::Refused(t))
}

fn refused_text(s: &str) -> Resolution {
    let mut t: String<TEXT_MAX> = String::new();
    for c in s.chars() {
        if t.push(c).is_err() {
            break;
        }
    }
    Resolution::Outcome(Outcome::Refused(t))
}

impl SettingsAgent {
    /// The agent of a machine that runs `settings` at `rate_hz`.
    pub fn new(settings: &Settings, rate_hz: u32) -> Self {
        Self {
            shadow: *settings,
            rate_hz,
            identify: None,
            txn: None,
        }
    }

    /// A new session, or the link was lost: an open transaction is dropped.
    pub fn session_ended(&mut self) {
        self.txn = None;
    }

    /// A settings transaction is open.
    pub fn in_transaction(&self) -> bool {
        self.txn.is_some()
    }

    /// The machine took `settings` (it echoes every change it applied).
    pub fn machine_took(&mut self, settings: &Settings) {
        self.shadow = *settings;
    }

    /// The machine's control rate, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.rate_hz
    }

    /// The settings the machine runs, as far as the link side knows.
    pub fn settings(&self) -> &Settings {
        &self.shadow
    }

    /// The machine reported an identification result (in a status reply).
    pub fn identified(&mut self, m: Option<IdentifyMsg>) {
        if m.is_some() {
            self.identify = m;
        }
    }

    /// Whether `r` is resolved here.
    pub fn handles(r: &Request) -> bool {
        matches!(
            r,
            Request::SettingGet { .. }
                | Request::SettingSet { .. }
                | Request::SettingsDefaults
                | Request::AcceptIdentified { .. }
                | Request::SettingsBegin
                | Request::SettingsCommit
                | Request::SettingsAbort
        )
    }

    /// Resolve a settings request (see [`Self::handles`]); any other request is refused.
    /// Never inlined: its copies of the tree are on the link task's stack only while it
    /// runs, not under the rest of the link side's flush (the control interrupt preempts
    /// that task, and both share the board's one stack).
    #[inline(never)]
    pub fn resolve(&mut self, r: &Request) -> Resolution {
        if let Some(t) = self.txn.as_mut() {
            match r {
                Request::SettingSet { key, value } => {
                    return match t.candidate.stage_text(key, value) {
                        Ok(()) => Resolution::Outcome(Outcome::Done),
                        Err(e) => {
                            t.refused = true;
                            refused(e)
                        }
                    };
                }
                Request::SettingsDefaults => {
                    t.candidate = FACTORY;
                    return Resolution::Outcome(Outcome::Done);
                }
                Request::AcceptIdentified { .. } => {
                    return refused_text(
                        "accept: a settings transaction is open (commit or abort it first)",
                    )
                }
                _ => {}
            }
        }
        match r {
            Request::SettingsBegin => {
                self.txn = Some(Transaction {
                    base: self.shadow,
                    candidate: self.shadow,
                    refused: false,
                });
                Resolution::Outcome(Outcome::Done)
            }
            Request::SettingsAbort => {
                self.txn = None;
                Resolution::Outcome(Outcome::Done)
            }
            Request::SettingsCommit => match self.txn.take() {
                None => refused_text("commit: no settings transaction is open (begin first)"),
                Some(t) if t.refused => refused_text(
                    "commit refused: a change of the transaction was refused; nothing changed",
                ),
                // (only this agent changes the settings, and not while a transaction is
                // open: a defensive check)
                Some(t) if t.base != self.shadow => refused_text(
                    "commit refused: the settings changed since begin; nothing changed",
                ),
                Some(t) => match t.candidate.validate_change(&t.base, self.rate_hz) {
                    Ok(()) => Resolution::Apply {
                        settings: t.candidate,
                        class: self.shadow.change_class(&t.candidate),
                    },
                    Err(e) => refused(e),
                },
            },
            Request::SettingGet { key } => match self.shadow.get(key) {
                Ok(v) => {
                    let mut t: String<VALUE_MAX> = String::new();
                    let _ = write!(t, "{v}");
                    Resolution::Outcome(Outcome::Value(t))
                }
                Err(e) => refused(e),
            },
            Request::SettingSet { key, value } => {
                let mut next = self.shadow;
                match next.set_text(key, value, self.rate_hz) {
                    Ok(()) => self.apply(next),
                    Err(e) => refused(e),
                }
            }
            Request::SettingsDefaults => self.apply(FACTORY),
            Request::AcceptIdentified { axis } => {
                let i = usize::from(*axis);
                let model = self
                    .identify
                    .filter(|m| usize::from(m.axis) == i && m.done)
                    .and_then(|m| m.model);
                let Some(m) = model else {
                    return refused_text(
                        "accept: no finished identification of that axis (run identify first)",
                    );
                };
                let mut next = self.shadow;
                match next.axis.get_mut(i) {
                    Some(a) => {
                        a.model = Some(AxisModel {
                            inertia: m.inertia,
                            viscous: m.viscous,
                            coulomb_pos_mnm: m.coulomb_pos_mnm,
                            coulomb_neg_mnm: m.coulomb_neg_mnm,
                        })
                    }
                    None => return refused_text("accept: axis must be 0, 1 or 2"),
                }
                self.apply(next)
            }
            _ => refused_text("not a settings request"),
        }
    }

    /// `next` as a whole tree for the machine, if it validates.
    fn apply(&self, next: Settings) -> Resolution {
        if let Err(e) = next.validate(self.rate_hz) {
            return refused(e);
        }
        Resolution::Apply {
            settings: next,
            class: self.shadow.change_class(&next),
        }
    }
}
