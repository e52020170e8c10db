//! The planner across two tasks, as the board runs it: the planning half
//! ([`SplitPlanner`]: segments, look-ahead, spans, steps) in a task below the control
//! interrupt, the executor ([`SplitExecutor`]: one step and one span evaluation per
//! period) in the interrupt. They meet only through the lock-free SPSC queues of
//! [`PlannerChannels`]; neither ever waits for the other.
//!
//! * Interrupt → task: [`PlanCommand`]s in request order (a program's restart, its
//!   segments, hold, resume, abort, feed override) and the executor's status every
//!   period.
//! * Task → interrupt: spans and steps (see [`super`]), and a [`PlanReport`] after every
//!   run of the task (commands taken, the last segment's result, free slots, state).
//!
//! A segment's result is known once the task ran: [`SplitExecutor::offer`] sends it and
//! answers [`Offer::Later`] until the report carries its ticket, so a refused segment is
//! refused in request order, exactly as when both halves run in one period. With the
//! task run after every control period that is one segment per period (10,000/s at 10
//! kHz, more than the 921,600-baud link carries).
//!
//! A restart begins a new program *run*: the executor restarts at once (it is small), the
//! planner when the task takes the command; every span and step carries its run, and the
//! executor drops those of an earlier run still in the queues.

use heapless::spsc::{Consumer, Producer, Queue};
use heapless::Deque;

use super::config::{PlannerConfig, PlannerConfigError, ValidPlannerConfig};
use super::executor::{ExecMode, Executor, ExecutorStatus, PathSample, Step};
use super::handle::{Offer, PlannerHandle, RestartError};
use super::planner::{check_feed_override, Planner, PlannerState};
use super::segment::{Segment, SegmentError};
use super::span::Span;

/// Spans between the halves (as the single-thread [`crate::machine::MachinePlanner`]).
pub const SPLIT_SPANS: usize = 64;
/// Steps buffered between the halves: the task may be late this many periods before the
/// executor underruns (and stops on the path by itself); also the latency of a hold.
pub const SPLIT_STEPS: usize = 32;
/// Commands in flight to the task (a segment at a time, plus real-time ones).
pub const SPLIT_COMMANDS: usize = 8;
/// Reports and executor statuses in flight (each side keeps the newest).
const SPLIT_REPORTS: usize = 4;
/// Commands the interrupt keeps when the command queue is full (the task is not
/// running): sent first the next period; the newest replaces the last when full.
const BACKLOG: usize = 4;

/// What the control interrupt asks of the planning task, in request order.
#[derive(Clone, Copy, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // (a queue slot of 8: the largest is a segment)
pub enum PlanCommand {
    /// A new program run at rest at `start_mm`.
    Restart {
        cfg: PlannerConfig,
        start_mm: [f32; 3],
        run: u16,
    },
    /// Queue a segment; its result comes back with `ticket`.
    Push {
        ticket: u32,
        seg: Segment,
    },
    Hold,
    Resume,
    Abort,
    /// Validated by the interrupt already.
    FeedOverride(f32),
}

/// The planning task's news, after each of its runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanReport {
    /// Program run the planner follows.
    pub run: u16,
    /// Commands taken so far (all kinds, wrapping).
    pub taken: u32,
    /// The last segment taken, and its result.
    pub push_ticket: u32,
    pub push_result: Result<(), SegmentError>,
    pub free_slots: u16,
    pub state: PlannerState,
}

impl PlanReport {
    const NONE: Self = Self {
        run: 0,
        taken: 0,
        push_ticket: 0,
        push_result: Ok(()),
        free_slots: 0,
        state: PlannerState::Idle,
    };
}

/// The queues between the halves (a static on the board: 10 KiB, built from
/// [`PlannerChannels::new`]).
pub struct PlannerChannels {
    spans: Queue<Span, { SPLIT_SPANS + 1 }>,
    steps: Queue<Step, { SPLIT_STEPS + 1 }>,
    commands: Queue<PlanCommand, { SPLIT_COMMANDS + 1 }>,
    reports: Queue<PlanReport, { SPLIT_REPORTS + 1 }>,
    statuses: Queue<ExecutorStatus, { SPLIT_REPORTS + 1 }>,
}

impl Default for PlannerChannels {
    fn default() -> Self {
        Self::new()
    }
}

impl PlannerChannels {
    pub const fn new() -> Self {
        Self {
            spans: Queue::new(),
            steps: Queue::new(),
            commands: Queue::new(),
            reports: Queue::new(),
            statuses: Queue::new(),
        }
    }

    /// The interrupt's ends and the task's ends.
    pub fn split(&mut self) -> (ExecutorEnds<'_>, PlannerEnds<'_>) {
        let (span_tx, span_rx) = self.spans.split();
        let (step_tx, step_rx) = self.steps.split();
        let (cmd_tx, cmd_rx) = self.commands.split();
        let (rep_tx, rep_rx) = self.reports.split();
        let (st_tx, st_rx) = self.statuses.split();
        (
            ExecutorEnds {
                spans: span_rx,
                steps: step_rx,
                commands: cmd_tx,
                reports: rep_rx,
                statuses: st_tx,
            },
            PlannerEnds {
                spans: span_tx,
                steps: step_tx,
                commands: cmd_rx,
                reports: rep_tx,
                statuses: st_rx,
            },
        )
    }
}

/// The control interrupt's ends of [`PlannerChannels`].
pub struct ExecutorEnds<'a> {
    spans: Consumer<'a, Span>,
    steps: Consumer<'a, Step>,
    commands: Producer<'a, PlanCommand>,
    reports: Consumer<'a, PlanReport>,
    statuses: Producer<'a, ExecutorStatus>,
}

/// The planning task's ends of [`PlannerChannels`].
pub struct PlannerEnds<'a> {
    spans: Producer<'a, Span>,
    steps: Producer<'a, Step>,
    commands: Consumer<'a, PlanCommand>,
    reports: Producer<'a, PlanReport>,
    statuses: Consumer<'a, ExecutorStatus>,
}

/// The control interrupt's half (see the module docs): the executor, its ends of the
/// channels, and what it knows of the task. Until [`SplitExecutor::attach`]ed it holds
/// the reference where the program would start and refuses to start one.
pub struct SplitExecutor<'a> {
    ends: Option<ExecutorEnds<'a>>,
    executor: Executor,
    run: u16,
    /// Commands sent (all kinds, wrapping): compared with the report's `taken`.
    sent: u32,
    next_ticket: u32,
    /// A segment sent whose result has not come back.
    outstanding: Option<u32>,
    report: PlanReport,
    backlog: Deque<PlanCommand, BACKLOG>,
}

impl<'a> SplitExecutor<'a> {
    /// Not connected to a task yet: a constant, so that a static can hold one.
    pub const DETACHED: Self = Self {
        ends: None,
        executor: Executor::new(0.0, [0.0; 3]),
        run: 0,
        sent: 0,
        next_ticket: 1,
        outstanding: None,
        report: PlanReport::NONE,
        backlog: Deque::new(),
    };

    /// Connect to the task's channels (before the machine restarts it).
    pub fn attach(&mut self, ends: ExecutorEnds<'a>) {
        *self = Self::DETACHED;
        self.ends = Some(ends);
    }

    /// The newest report (the task's view; `run` tells whether it is of this program).
    pub fn report(&self) -> &PlanReport {
        &self.report
    }

    /// Send `c` after what waits in the backlog; keep it there if the queue is full.
    fn send(&mut self, c: PlanCommand) {
        self.flush();
        let Some(ends) = self.ends.as_mut() else {
            return;
        };
        self.sent = self.sent.wrapping_add(1);
        if self.backlog.is_empty() {
            if let Err(c) = ends.commands.enqueue(c) {
                let _ = self.backlog.push_back(c);
            }
            return;
        }
        if let Err(c) = self.backlog.push_back(c) {
            // (the task has not run for BACKLOG + SPLIT_COMMANDS commands: the newest
            // real-time request wins; the one it replaces is counted as taken never)
            if let Some(last) = self.backlog.back_mut() {
                *last = c;
            }
            self.sent = self.sent.wrapping_sub(1);
        }
    }

    fn flush(&mut self) {
        let Some(ends) = self.ends.as_mut() else {
            return;
        };
        while let Some(c) = self.backlog.pop_front() {
            if let Err(c) = ends.commands.enqueue(c) {
                let _ = self.backlog.push_front(c);
                return;
            }
        }
    }

    /// The report is of this program run.
    fn current(&self) -> bool {
        self.report.run == self.run
    }
}

/// The planning half in a task of its own: the segment is planned by the task, so the
/// period may offer one while resolving the previous one.
impl PlannerHandle for SplitExecutor<'_> {
    const OFFERS_PER_PERIOD: usize = 2;

    fn restart(&mut self, cfg: &PlannerConfig, start_mm: [f32; 3]) -> Result<(), RestartError> {
        if self.ends.is_none() {
            return Err(RestartError::Detached);
        }
        let set = ValidPlannerConfig::new(cfg).map_err(RestartError::Config)?;
        if start_mm.iter().any(|x| !x.is_finite()) {
            return Err(RestartError::Config(PlannerConfigError::NotFinite(
                "start_mm",
            )));
        }
        self.run = self.run.wrapping_add(1);
        self.executor = Executor::for_run(set.period_s, start_mm, self.run);
        self.outstanding = None;
        // (what an earlier run still had to say is void: the restart replaces it)
        self.sent = self.sent.wrapping_sub(self.backlog.len() as u32);
        self.backlog.clear();
        self.send(PlanCommand::Restart {
            cfg: *cfg,
            start_mm,
            run: self.run,
        });
        Ok(())
    }

    fn offer(&mut self, seg: &Segment) -> Offer {
        if let Some(t) = self.outstanding {
            if self.current() && self.report.push_ticket == t {
                self.outstanding = None;
                return match self.report.push_result {
                    Ok(()) => Offer::Taken,
                    Err(e) => Offer::Refused(e),
                };
            }
            return Offer::Later;
        }
        if !self.current() || self.report.free_slots == 0 || !self.backlog.is_empty() {
            return Offer::Later;
        }
        let Some(ends) = self.ends.as_mut() else {
            return Offer::Later;
        };
        let ticket = self.next_ticket;
        if ends
            .commands
            .enqueue(PlanCommand::Push { ticket, seg: *seg })
            .is_err()
        {
            return Offer::Later;
        }
        self.sent = self.sent.wrapping_add(1);
        self.next_ticket = ticket.wrapping_add(1);
        self.outstanding = Some(ticket);
        Offer::Later
    }

    fn hold(&mut self) {
        self.send(PlanCommand::Hold);
    }

    fn resume(&mut self) {
        self.send(PlanCommand::Resume);
    }

    fn abort(&mut self) {
        self.send(PlanCommand::Abort);
    }

    fn set_feed_override(&mut self, ratio: f32) -> Result<(), PlannerConfigError> {
        check_feed_override(ratio)?;
        self.send(PlanCommand::FeedOverride(ratio));
        Ok(())
    }

    fn free_slots(&self) -> usize {
        if !self.current() {
            return 0;
        }
        usize::from(self.report.free_slots).saturating_sub(usize::from(self.outstanding.is_some()))
    }

    fn tick(&mut self) -> PathSample {
        self.flush();
        let Some(ends) = self.ends.as_mut() else {
            return self
                .executor
                .sample(&mut Deque::<Span, 1>::new(), &mut Deque::<Step, 1>::new());
        };
        for _ in 0..SPLIT_REPORTS + 1 {
            match ends.reports.dequeue() {
                Some(r) => self.report = r,
                None => break,
            }
        }
        let sample = self.executor.sample(&mut ends.spans, &mut ends.steps);
        // (full: the task has not run since; it finds the newest of the ones it has)
        let _ = ends.statuses.enqueue(self.executor.status());
        sample
    }

    fn is_idle(&self) -> bool {
        let steps_left = self.ends.as_ref().is_some_and(|e| e.steps.ready());
        self.executor.mode() == ExecMode::Idle
            && !steps_left
            && self.backlog.is_empty()
            && self.current()
            && self.report.taken == self.sent
            && matches!(self.report.state, PlannerState::Idle | PlannerState::Held)
    }
}

/// The planning task's half (see the module docs): the planner and its ends of the
/// channels. [`SplitPlanner::run`] once after every control period.
pub struct SplitPlanner<'a, const N: usize, const S: usize> {
    planner: &'a mut Planner<N, S>,
    ends: PlannerEnds<'a>,
    taken: u32,
    push_ticket: u32,
    push_result: Result<(), SegmentError>,
    status: Option<ExecutorStatus>,
}

impl<'a, const N: usize, const S: usize> SplitPlanner<'a, N, S> {
    /// The task's half on `planner` (restarted by the first command; a static on the
    /// board, built from `Planner::BLANK`).
    pub fn new(planner: &'a mut Planner<N, S>, ends: PlannerEnds<'a>) -> Self {
        Self {
            planner,
            ends,
            taken: 0,
            push_ticket: 0,
            push_result: Ok(()),
            status: None,
        }
    }

    pub fn planner(&self) -> &Planner<N, S> {
        self.planner
    }

    /// One run: the commands that came (in order), the executor's newest status, then
    /// plan ahead (spans and steps while there is room), and report. Bounded: at most
    /// [`SPLIT_COMMANDS`] commands, each at most one segment's look-ahead.
    pub fn run(&mut self) {
        for _ in 0..SPLIT_COMMANDS {
            let Some(c) = self.ends.commands.dequeue() else {
                break;
            };
            self.take(c);
        }
        for _ in 0..SPLIT_REPORTS + 1 {
            match self.ends.statuses.dequeue() {
                Some(st) => self.status = Some(st),
                None => break,
            }
        }
        if let Some(st) = self.status {
            self.planner.sync(&st);
        }
        self.planner
            .produce(&mut self.ends.spans, &mut self.ends.steps, SPLIT_STEPS);
        let st = self.planner.status();
        // (full: the interrupt has not run since; it takes the newest it finds)
        let _ = self.ends.reports.enqueue(PlanReport {
            run: self.planner.run_id(),
            taken: self.taken,
            push_ticket: self.push_ticket,
            push_result: self.push_result,
            free_slots: u16::try_from(st.free_slots).unwrap_or(u16::MAX),
            state: st.state,
        });
    }

    fn take(&mut self, c: PlanCommand) {
        self.taken = self.taken.wrapping_add(1);
        match c {
            PlanCommand::Restart { cfg, start_mm, run } => {
                // (validated by the interrupt; an error leaves the old planner, whose
                // run the executor no longer follows)
                let _ = self.planner.restart_run(&cfg, start_mm, run);
                self.status = None;
            }
            PlanCommand::Push { ticket, seg } => {
                self.push_ticket = ticket;
                self.push_result = self.planner.push(&seg);
            }
            PlanCommand::Hold => self.planner.hold(),
            PlanCommand::Resume => self.planner.resume(),
            PlanCommand::Abort => self.planner.abort(),
            PlanCommand::FeedOverride(r) => {
                let _ = self.planner.set_feed_override(r);
            }
        }
    }
}
