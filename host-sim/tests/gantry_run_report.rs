//! `gantry run`'s report comes from what the machine executed (its status), not from
//! what the host sent: a program that completed reports every segment and the programmed
//! length; one stopped by an e-stop or a lost link reports `program_done` false, why it
//! ended, fewer segments than planned, and a failing exit status.

use anyhow::Result;
use controller_core::servo::ServoState;
use controller_core::sim::world::Injection;
use host_sim::cli::client::Client;
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self, Transport};
use host_sim::gcode::report::GcodeReport;
use std::path::Path;

/// 1 kHz telemetry at 10 kHz.
const DECIMATION: u32 = 10;
const TELEMETRY_PERIOD_S: f64 = 1e-3;
/// Control periods of the program's run before the disturbance: 3 s of the square's ~10.
const RUN_PERIODS_BEFORE: u64 = 30_000;

fn square() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("programs/square.nc")
}

/// What happens to the machine once its program has run [`RUN_PERIODS_BEFORE`] periods.
#[derive(Clone, Copy, PartialEq)]
enum Disturbance {
    None,
    /// The e-stop is pressed.
    Estop,
    /// The host's bytes stop reaching the machine for this many periods (its watchdog
    /// expires after 500 ms), then the line works again so that the host hears why.
    Silence(u64),
}

struct Rig {
    inner: SimMachine,
    what: Disturbance,
    run_periods: u64,
    /// When the disturbance happened (machine periods).
    at: Option<u64>,
}

impl Rig {
    fn silent(&self) -> bool {
        match (self.what, self.at) {
            (Disturbance::Silence(n), Some(at)) => self.inner.periods() < at + n,
            _ => false,
        }
    }
}

impl Transport for Rig {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        if self.silent() {
            return Ok(());
        }
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        self.inner.recv(buf)
    }
    fn now_ms(&self) -> u32 {
        self.inner.now_ms()
    }
    fn clock_runs_alone(&self) -> bool {
        self.inner.clock_runs_alone()
    }
    fn wait(&mut self) -> Result<()> {
        self.inner.wait()?;
        if self.inner.machine().servo().state() == ServoState::Run {
            self.run_periods += 10;
        }
        if self.at.is_none() && self.run_periods >= RUN_PERIODS_BEFORE {
            self.at = Some(self.inner.periods());
            if self.what == Disturbance::Estop {
                self.inner.inject(&Injection::Estop);
            }
        }
        Ok(())
    }
}

fn run(what: Disturbance) -> GcodeReport {
    let rig = Rig {
        inner: SimMachine::new(SimModels::Designed, DECIMATION).unwrap(),
        what,
        run_periods: 0,
        at: None,
    };
    let mut c = Client::connect_session(rig, 7).unwrap();
    let r = cli::run_program(&mut c, &square(), TELEMETRY_PERIOD_S, false, None).unwrap();
    eprintln!(
        "{}: {} of {} segments, {:.6} of {:.6} mm",
        r.program_end, r.segments, r.segments_planned, r.path_length_mm, r.path_length_planned_mm
    );
    if what != Disturbance::None {
        assert!(c.transport.at.is_some(), "the disturbance never came");
    }
    r
}

#[test]
fn a_completed_program_reports_every_segment_and_the_programmed_length() {
    let r = run(Disturbance::None);
    assert_eq!(r.status, "completed");
    assert!(r.program_done);
    assert_eq!(r.program_end, "completed");
    assert_eq!(r.segments_planned, 9);
    assert_eq!(r.segments, r.segments_planned);
    // square.nc: 4 × 40 mm sides plus the moves to and from the corner
    assert!(
        r.path_length_planned_mm > 160.0,
        "{}",
        r.path_length_planned_mm
    );
    assert!(
        (r.path_length_mm - r.path_length_planned_mm).abs() <= 1e-3,
        "{} vs {}",
        r.path_length_mm,
        r.path_length_planned_mm
    );
    assert_eq!(cli::run_exit_code(&r), 0);
    let json = serde_json::to_value(&r).unwrap();
    for key in [
        "segments",
        "segments_planned",
        "path_length_mm",
        "path_length_planned_mm",
        "program_done",
        "program_end",
    ] {
        assert!(json.get(key).is_some(), "no key {key}");
    }
}

#[test]
fn an_e_stop_aborts_the_program_and_the_report_says_so() {
    let r = run(Disturbance::Estop);
    assert_eq!(r.status, "fault");
    assert!(!r.program_done);
    assert_eq!(r.program_end, "aborted_by_fault(estop)");
    assert_eq!(r.segments_planned, 9);
    assert!(r.segments < r.segments_planned, "{} segments", r.segments);
    assert!(
        r.segments >= 1,
        "3 s into the square: {} segments",
        r.segments
    );
    assert!(
        r.path_length_mm < r.path_length_planned_mm - 1.0,
        "{} vs {}",
        r.path_length_mm,
        r.path_length_planned_mm
    );
    assert_eq!(cli::run_exit_code(&r), 1);
}

#[test]
fn a_lost_link_aborts_the_program_and_the_report_says_so() {
    // 0.8 s of silence: beyond the machine's 500 ms watchdog, within the host's 1.5 s of
    // retries
    let r = run(Disturbance::Silence(8_000));
    assert_eq!(r.status, "fault");
    assert!(!r.program_done);
    assert_eq!(r.program_end, "aborted_by_link_loss");
    assert!(r.segments < r.segments_planned, "{} segments", r.segments);
    assert!(r.path_length_mm < r.path_length_planned_mm - 1.0);
    assert_eq!(cli::run_exit_code(&r), 1);
}
