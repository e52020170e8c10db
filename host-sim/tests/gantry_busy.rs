//! `Client::while_busy`: host work between requests (parsing, compressing and measuring a
//! program in `gantry run`) keeps the link serviced on a machine whose clock runs on while
//! the host computes, as a board's, the board twin's and QEMU's do. Without it, 800 ms of
//! host work is 800 ms of silence to the machine, past its 500 ms link watchdog: the
//! armed machine latches `link_lost` (what `gantry --twin run` hit under load).
//!
//! The machine here is the simulated one behind [`RunsAlone`]: the host's work advances
//! a shared host clock, and every call on the transport first runs the machine up to it.
//! The work takes its time in 100 ms steps, each after the host has waited on the
//! transport again (one whole turn of the link's pump in between), or after half a second of
//! waiting for that: at most 100 ms of machine time pass between two polls of the link,
//! however the threads are scheduled, so its 125 ms heartbeats reach the machine well
//! within the 500 ms watchdog.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;
use host_sim::cli::client::Client;
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self, Transport};

/// 1 kHz telemetry at 10 kHz.
const DECIMATION: u32 = 10;
/// The host's work: longer than the machine's 500 ms link watchdog.
const WORK_MS: u32 = 800;
const WORK_STEP_MS: u32 = 100;
/// Wall time a step of the work waits for a turn of the pump (a wait on the transport): a
/// turn takes microseconds; half a second covers a host so loaded that the pump's thread
/// is not scheduled for a while (20 ms failed one run in four at a load of 9 on 2 cores).
const PUMP_TURN_WAIT: Duration = Duration::from_millis(500);

/// The simulated machine with a clock that runs alone: `host_ms` (advanced by the host's
/// work and by its waits) is how far the machine has to run before anything else.
struct RunsAlone {
    inner: SimMachine,
    host_ms: Arc<AtomicU32>,
    /// The host's waits so far (a turn of its pump each; the work's steps wait for one).
    waits: Arc<AtomicU32>,
}

impl RunsAlone {
    fn catch_up(&mut self) -> Result<()> {
        while self.inner.now_ms() < self.host_ms.load(Ordering::SeqCst) {
            self.inner.wait()?;
        }
        Ok(())
    }
}

impl Transport for RunsAlone {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        self.catch_up()?;
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        self.catch_up()?;
        self.inner.recv(buf)
    }
    fn now_ms(&self) -> u32 {
        self.inner.now_ms()
    }
    fn wait(&mut self) -> Result<()> {
        self.host_ms.fetch_add(1, Ordering::SeqCst);
        self.catch_up()?;
        self.waits.fetch_add(1, Ordering::SeqCst);
        Ok(())
    }
    fn clock_runs_alone(&self) -> bool {
        true
    }
}

/// A session with the machine homed and armed, and the work that takes [`WORK_MS`].
fn armed() -> (Client<RunsAlone>, impl Fn() -> u32 + Send + Sync) {
    let inner = SimMachine::new(SimModels::Designed, DECIMATION).unwrap();
    let host_ms = Arc::new(AtomicU32::new(inner.now_ms()));
    let waits = Arc::new(AtomicU32::new(0));
    let t = RunsAlone {
        inner,
        host_ms: host_ms.clone(),
        waits: waits.clone(),
    };
    let mut c = Client::connect_session(t, 11).unwrap();
    cli::ready(&mut c, true).unwrap();
    assert!(c.status().unwrap().first_fault.is_none());
    let work = move || {
        let mut steps_without_a_wait = 0;
        for _ in 0..WORK_MS / WORK_STEP_MS {
            let seen = waits.load(Ordering::SeqCst);
            let t0 = Instant::now();
            while waits.load(Ordering::SeqCst) == seen && t0.elapsed() < PUMP_TURN_WAIT {
                std::thread::yield_now();
            }
            if waits.load(Ordering::SeqCst) == seen {
                steps_without_a_wait += 1;
            }
            host_ms.fetch_add(WORK_STEP_MS, Ordering::SeqCst);
        }
        steps_without_a_wait
    };
    (c, work)
}

#[test]
fn host_work_inline_is_silence_past_the_link_watchdog() {
    let (mut c, work) = armed();
    // (the work on this thread: nobody calls the transport while it runs)
    assert_eq!(work(), WORK_MS / WORK_STEP_MS);
    c.transport.catch_up().unwrap();
    let first = c.transport.inner.machine().servo().faults().first();
    assert_eq!(
        first.map(|f| f.fault.kind.name()),
        Some("link_lost"),
        "800 ms of host work with the link unserviced must trip the 500 ms watchdog"
    );
}

#[test]
fn host_work_beside_the_link_keeps_the_session() {
    let (mut c, work) = armed();
    let p0 = c.transport.inner.periods();
    let without_a_wait = c.while_busy(work).unwrap();
    assert_eq!(
        without_a_wait, 0,
        "every step of the work saw the link serviced"
    );
    // the machine ran the work's 800 ms, and nothing tripped
    assert!(c.transport.inner.periods() - p0 >= u64::from(WORK_MS) * 10);
    assert!(!c.transport.inner.machine().servo().faults().any());
    let s = c.status().unwrap();
    assert!(s.first_fault.is_none(), "{:?}", s.first_fault);
}

#[test]
fn on_the_simulated_machine_the_work_runs_here_and_the_machine_stands_still() {
    let mut c = Client::connect_session(
        SimMachine::new(SimModels::Designed, DECIMATION).unwrap(),
        12,
    )
    .unwrap();
    let p0 = c.transport.periods();
    let here = std::thread::current().id();
    let ran_on = c.while_busy(|| std::thread::current().id()).unwrap();
    assert_eq!(ran_on, here);
    assert_eq!(c.transport.periods(), p0);
}
