//! The release firmware closed-loop on the board twin (firmware/twin, docs/board-twin.md):
//! `gantry run` of the square and the arcs programs over the twin's USART2, TIM1's duty
//! and the DIR pins driving the simulated gantry of `gantry --sim` (the `twin-plant`
//! helper), its counts back in the encoder timers; the same program on `gantry --sim` with
//! the same settings and telemetry rate. The twin's run completes, with its contour max
//! within 10 % of `--sim`'s and its tracking figures alike.
//!
//! Needs `cargo fw` (the ELF), `cargo build -p host-sim --release --bin twin-plant` and the
//! twin's Python packages (.ci/run installs them); one twin per program, in parallel.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use controller_core::machine::messages::{MachineState, Outcome, Request};
use host_sim::cli::client::Client;
use host_sim::cli::port::BoardPort;
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self, Transport, AXES};
use host_sim::studies::gcode::GcodeReport;

/// Telemetry every 100 control periods (100 Hz at 10 kHz) on both machines: the contour
/// figures are taken from it. (1 kHz, `gantry`'s default, works too: every telemetry
/// byte is a UART interrupt the twin emulates: several times the wall time.)
const DECIMATION: u32 = 100;
/// Machine seconds a twin serves at most (the arcs take 35).
const TWIN_SECONDS: u32 = 120;
/// How far the twin's contour max may be from `--sim`'s.
const CONTOUR_RATIO_BOUND: f64 = 0.10;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The settings both machines run: the designed axis models entered (a fresh board has
/// none and refuses to arm), homing off (the axes count as homed where they are armed:
/// the twin's run stays short).
fn prepare<T: Transport>(c: &mut Client<T>) {
    for a in AXES {
        cli::set(c, &format!("axis.{a}.model.known"), "true").unwrap();
        cli::set(c, &format!("axis.{a}.homing.enabled"), "false").unwrap();
    }
}

/// `firmware/twin/run --serve`, stopped (SIGTERM) when dropped.
struct Served {
    child: Child,
    pty: String,
}

impl Served {
    fn start(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("gantry_twin_{}_{tag}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pty = dir.join("tty").display().to_string();
        let child = Command::new(root().join("firmware/twin/run"))
            .args([
                "--serve",
                &pty,
                "--seconds",
                &TWIN_SECONDS.to_string(),
                "--log-dir",
            ])
            .arg(&dir)
            .stdout(Stdio::null())
            .spawn()
            .expect("firmware/twin/run");
        let clock = format!("{pty}.clock");
        let t0 = Instant::now();
        while !Path::new(&clock).exists() {
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "the twin did not come up"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        Self { child, pty }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .arg(self.child.id().to_string())
            .status();
        let _ = self.child.wait();
    }
}

fn on_twin(program: &Path, then_estop: bool) -> (GcodeReport, f64, Option<Estop>) {
    let tag = program.file_stem().unwrap().to_string_lossy().to_string();
    let served = Served::start(&tag);
    let mut c = Client::connect(BoardPort::open_twin(&served.pty).unwrap()).unwrap();
    prepare(&mut c);
    cli::subscribe(&mut c, DECIMATION).unwrap();
    let t0 = Instant::now();
    let r = cli::run_program(&mut c, program, f64::from(DECIMATION) / 1e4, false, None).unwrap();
    let wall_s = t0.elapsed().as_secs_f64();
    let estop = then_estop.then(|| estop(&mut c, &served));
    (r, wall_s, estop)
}

/// TIM1's PWM period (20 kHz, firmware/src/board/pwm.rs): the e-stop's bound.
const PWM_PERIOD_S: f64 = 1.0 / 20_000.0;
/// Control periods the firmware takes to drive the enables low after the e-stop.
const ESTOP_ENABLES_PERIODS: f64 = 2.0;
const CONTROL_PERIOD_S: f64 = 1.0 / 10_000.0;

/// The e-stop test's figures.
#[derive(Debug)]
struct Estop {
    moe_after_s: f64,
    enables_after_s: f64,
    fault: String,
    reset_while_active: String,
}

/// Append a command to the twin's `PTY.ctl` and wait (pumping the link) until it landed:
/// its machine time.
fn twin_ctl(c: &mut Client<BoardPort>, served: &Served, line: &str) -> f64 {
    use std::io::Write;
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(format!("{}.ctl", served.pty))
        .unwrap();
    writeln!(f, "{line}").unwrap();
    drop(f);
    for _ in 0..1000 {
        let done = std::fs::read_to_string(format!("{}.ctl.done", served.pty)).unwrap_or_default();
        if let Some(l) = done
            .lines()
            .find(|l| l.ends_with(line) || l.contains("error:"))
        {
            assert!(!l.contains("error:"), "the twin refused {line}: {l}");
            return l.split(' ').next().unwrap().parse().unwrap();
        }
        c.sleep_ms(5).unwrap();
    }
    panic!("the twin never took {line}");
}

/// The first change of `signal` to `value` at or after `t0_s` in the twin's output log.
fn output_at(served: &Served, signal: &str, value: &str, t0_s: f64) -> Option<f64> {
    let log = std::fs::read_to_string(format!("{}.outputs", served.pty)).unwrap();
    log.lines().find_map(|l| {
        let mut w = l.split(' ');
        let t: f64 = w.next()?.parse().ok()?;
        (w.next()? == signal && w.next()? == value && t >= t0_s).then_some(t)
    })
}

/// Armed and holding: the e-stop input (PB12, TIM1's break) goes active. TIM1's MOE
/// clears in hardware within one PWM cycle, the firmware drives the enables low and
/// latches `estop`; a reset is refused while the input is still active and clears the
/// fault once it is released.
fn estop(c: &mut Client<BoardPort>, served: &Served) -> Estop {
    let s = cli::ready(c, false).unwrap();
    assert_eq!(s.state, MachineState::Idle, "armed before the e-stop");
    let t0 = twin_ctl(c, served, "drive B12 1");
    let s = cli::wait_while(c, |s| s.state != MachineState::Fault).unwrap();
    let fault = s.first_fault.as_deref().unwrap_or("none").to_string();
    let moe = output_at(served, "moe", "0", t0).expect("MOE cleared after the e-stop");
    let enables = AXES
        .iter()
        .map(|a| output_at(served, &format!("enable.{a}"), "0", t0).expect("enable driven low"))
        .fold(0.0f64, f64::max);
    let reset_while_active = match c.exec(Request::Reset).unwrap() {
        Outcome::Refused(why) => why.to_string(),
        o => format!("{o:?}"),
    };
    assert_eq!(
        c.status().unwrap().state,
        MachineState::Fault,
        "reset with the e-stop active"
    );
    twin_ctl(c, served, "drive B12 0");
    assert_eq!(
        c.exec(Request::Reset).unwrap(),
        Outcome::Done,
        "reset once released"
    );
    let s = c.status().unwrap();
    assert_eq!(
        s.state,
        MachineState::Disabled,
        "after the reset: disarmed, not armed"
    );
    Estop {
        moe_after_s: moe - t0,
        enables_after_s: enables - t0,
        fault,
        reset_while_active,
    }
}

fn on_sim(program: &Path) -> GcodeReport {
    let mut c = Client::connect(SimMachine::new(SimModels::Designed, DECIMATION).unwrap()).unwrap();
    prepare(&mut c);
    cli::run_program(&mut c, program, f64::from(DECIMATION) / 1e4, false, None).unwrap()
}

#[test]
#[ignore = "needs `cargo fw`, the twin-plant helper and the twin's Python packages; .ci/run runs it"]
fn square_and_arcs_on_the_twin_match_the_simulated_machine() {
    let programs = ["square", "arcs"].map(|p| root().join(format!("host-sim/programs/{p}.nc")));
    // the square's twin finishes first: the e-stop runs on it while the arcs go on
    let twins: Vec<_> = programs
        .iter()
        .cloned()
        .enumerate()
        .map(|(i, p)| std::thread::spawn(move || on_twin(&p, i == 0)))
        .collect();
    let mut rows = Vec::new();
    for (p, t) in programs.iter().zip(twins) {
        let (twin, wall_s, estop) = t.join().expect("the twin's run");
        if let Some(e) = estop {
            println!(
                "e-stop on the twin: MOE cleared {:.1} µs after PB12 (bound: one PWM cycle, {:.0} µs), \
                 enables low after {:.1} µs (bound {:.0} µs), fault {:?}, reset while active: {:?}",
                e.moe_after_s * 1e6,
                PWM_PERIOD_S * 1e6,
                e.enables_after_s * 1e6,
                ESTOP_ENABLES_PERIODS * CONTROL_PERIOD_S * 1e6,
                e.fault,
                e.reset_while_active
            );
            assert!(
                e.moe_after_s <= PWM_PERIOD_S,
                "MOE after {} s",
                e.moe_after_s
            );
            assert!(
                e.enables_after_s <= ESTOP_ENABLES_PERIODS * CONTROL_PERIOD_S,
                "enables after {} s",
                e.enables_after_s
            );
            assert_eq!(e.fault, "estop", "the fault latched");
            assert!(
                !e.reset_while_active.is_empty(),
                "a reset with the e-stop active is refused"
            );
            rows.push(serde_json::json!({
                "scenario": "estop",
                "moe_cleared_after_s": e.moe_after_s,
                "enables_low_after_s": e.enables_after_s,
                "fault": e.fault,
                "reset_while_active": e.reset_while_active,
            }));
        }
        let sim = on_sim(p);
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        println!(
            "{name}: twin contour max {:.5} mm rms {:.5} mm, {:.3} s, {} segments ({:.0} s wall, {:.3}x real time); \
             --sim contour max {:.5} mm rms {:.5} mm, {:.3} s, {} segments",
            twin.contour_max_mm, twin.contour_rms_mm, twin.duration_s, twin.segments, wall_s,
            twin.duration_s / wall_s, sim.contour_max_mm, sim.contour_rms_mm, sim.duration_s, sim.segments,
        );
        assert_eq!(
            twin.status, "completed",
            "{name} on the twin: {:?}",
            twin.error
        );
        assert!(twin.program_done, "{name}: {}", twin.program_end);
        assert_eq!(twin.segments, sim.segments, "{name}: segments executed");
        let ratio = twin.contour_max_mm / sim.contour_max_mm;
        assert!(
            (ratio - 1.0).abs() <= CONTOUR_RATIO_BOUND,
            "{name}: contour max twin {} mm vs --sim {} mm (ratio {ratio:.3})",
            twin.contour_max_mm,
            sim.contour_max_mm
        );
        // the same program at the same feeds: the durations agree within a few periods of
        // telemetry
        assert!(
            (twin.duration_s - sim.duration_s).abs() <= 0.05,
            "{name}: duration twin {} s vs --sim {} s",
            twin.duration_s,
            sim.duration_s
        );
        rows.push(serde_json::json!({
            "program": name,
            "twin_contour_max_mm": twin.contour_max_mm,
            "sim_contour_max_mm": sim.contour_max_mm,
            "contour_ratio": ratio,
            "twin_contour_rms_mm": twin.contour_rms_mm,
            "sim_contour_rms_mm": sim.contour_rms_mm,
            "twin_duration_s": twin.duration_s,
            "sim_duration_s": sim.duration_s,
            "twin_wall_s": wall_s,
        }));
    }
    if let Ok(out) = std::env::var("GANTRY_TWIN_JSON") {
        std::fs::write(out, serde_json::to_string_pretty(&rows).unwrap()).unwrap();
    }
}
