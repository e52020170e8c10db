//! The release firmware closed-loop on the board twin (firmware/twin, docs/board-twin.md):
//! `gantry run` of the square and the arcs (at twice their feeds) programs over the twin's USART2, TIM1's duty
//! and the DIR pins driving the simulated gantry of `gantry --sim` (the `twin-plant`
//! helper), its counts back in the encoder timers; the same program on `gantry --sim` with
//! the same settings and telemetry rate. The twin's run completes, with its contour max
//! within 10 % of `--sim`'s and its tracking figures alike. Once a program is done its
//! twin takes faults at its pins: on the square's, the e-stop (PB12) and then an encoder
//! that sticks while X moves; on the arcs', a limit switch.
//!
//! Needs `cargo fw` (the ELF), `cargo build -p host-sim --release --bin twin-plant` and the
//! twin's Python packages (.ci/run installs them); one twin per program, in parallel.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use controller_core::machine::messages::{MachineState, Outcome, Request, Status};
use controller_core::motion::planner::Segment;
use host_sim::cli::client::Client;
use host_sim::cli::port::BoardPort;
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self, Transport, AXES};
use host_sim::gcode::report::GcodeReport;

/// Telemetry every 100 control periods (100 Hz at 10 kHz) on both machines: the contour
/// figures are taken from it. (1 kHz, `gantry`'s default, works too: every telemetry
/// byte is a UART interrupt the twin emulates: several times the wall time.)
const DECIMATION: u32 = 100;
/// Machine seconds a twin serves at most (the arcs at twice their feeds take 18).
const TWIN_SECONDS: u32 = 120;
/// How far the twin's contour max may be outside the band of `--sim`'s (below its least,
/// above its largest over the telemetry phases).
const CONTOUR_RATIO_BOUND: f64 = 0.10;
/// How far the twin's contour rms may be from `--sim`'s (an average over ~2,000 samples
/// hardly depends on their phase: 1 % over the phases of arcs_x2; the twin has read 2-3 %
/// above `--sim` in every run so far).
const CONTOUR_RMS_RATIO_BOUND: f64 = 0.06;
/// A simulated machine's clock moves in steps of 1 ms (10 periods, `SimMachine::wait`):
/// starting the program 0, 1, … 9 ms after the subscription puts its telemetry samples
/// at every phase of the 10 ms between them, in steps of 10 periods.
const SIM_PHASES_MS: u32 = DECIMATION / 10;

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
    /// The decoded defmt log (`--log-dir`'s serve.log).
    log: PathBuf,
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
        let log = dir.join("serve.log");
        Self { child, pty, log }
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

/// What a twin does once its program is done: scenarios that assert their bounds and
/// return their figures (rows of `GANTRY_TWIN_JSON`).
type After = fn(&mut Client<BoardPort>, &Served) -> Vec<serde_json::Value>;

fn on_twin(program: &Path, after: After) -> (GcodeReport, f64, Vec<serde_json::Value>) {
    let tag = program.file_stem().unwrap().to_string_lossy().to_string();
    let served = Served::start(&tag);
    let mut c = Client::connect(BoardPort::open_twin(&served.pty).unwrap()).unwrap();
    prepare(&mut c);
    cli::subscribe(&mut c, DECIMATION).unwrap();
    let before = isr_samples(&served).len();
    let t0 = Instant::now();
    let r = cli::run_program(&mut c, program, f64::from(DECIMATION) / 1e4, false, None).unwrap();
    let wall_s = t0.elapsed().as_secs_f64();
    let isr = IsrFigures::of(&isr_samples(&served)[before..]);
    // the program's own checks come first (a fault scenario needs it done)
    assert_eq!(r.status, "completed", "{tag} on the twin: {:?}", r.error);
    println!(
        "{tag} on the twin: the control interrupt (the firmware's DWT count, one cycle an \
         instruction) {:.0} cycles mean, {} the largest of {} samples ({:.1} % / {:.1} % of \
         the 10 kHz period at {} MHz), overruns {:?} over the program",
        isr.mean_cycles,
        isr.max_cycles,
        isr.samples,
        100.0 * isr.mean_cycles / PERIOD_CYCLES,
        100.0 * f64::from(isr.max_cycles) / PERIOD_CYCLES,
        SYSCLK_HZ / 1e6,
        isr.overruns,
    );
    assert!(
        isr.samples > 0,
        "{tag}: no status line in the twin's log while it ran"
    );
    assert_eq!(
        isr.overruns.0, isr.overruns.1,
        "{tag}: the control interrupt overran its deadline while the program streamed"
    );
    let mut rows = vec![serde_json::json!({
        "program": tag,
        "isr_cycles_mean": isr.mean_cycles,
        "isr_cycles_max_sampled": isr.max_cycles,
        "isr_samples": isr.samples,
        "overruns_before_after": [isr.overruns.0, isr.overruns.1],
    })];
    rows.extend(after(&mut c, &served));
    (r, wall_s, rows)
}

/// The core clock (firmware/src/board/clock.rs) and its cycles in a 10 kHz period.
const SYSCLK_HZ: f64 = 168e6;
const PERIOD_CYCLES: f64 = SYSCLK_HZ / 1e4;

/// One status line of the firmware's log (firmware/src/logger.rs, one a telemetry period):
/// `isr_cyc=LAST/MAX` (the control interrupt's DWT cycles: the last period's and the
/// largest since boot) and `overruns=N`.
#[derive(Clone, Copy, Debug)]
struct IsrSample {
    last_cycles: u32,
    overruns: u32,
}

fn isr_samples(served: &Served) -> Vec<IsrSample> {
    let text = std::fs::read_to_string(&served.log).unwrap_or_default();
    let field = |l: &str, key: &str| -> Option<String> {
        let rest = &l[l.find(key)? + key.len()..];
        Some(rest.split([' ', '/']).next()?.to_string())
    };
    text.lines()
        .filter_map(|l| {
            Some(IsrSample {
                last_cycles: field(l, "isr_cyc=")?.parse().ok()?,
                overruns: field(l, "overruns=")?.parse().ok()?,
            })
        })
        .collect()
}

/// The control interrupt over a program, from the status lines logged while it ran.
struct IsrFigures {
    samples: usize,
    mean_cycles: f64,
    max_cycles: u32,
    /// Overruns counted at the first and at the last sample.
    overruns: (u32, u32),
}

impl IsrFigures {
    fn of(s: &[IsrSample]) -> Self {
        let n = s.len().max(1) as f64;
        Self {
            samples: s.len(),
            mean_cycles: s.iter().map(|x| f64::from(x.last_cycles)).sum::<f64>() / n,
            max_cycles: s.iter().map(|x| x.last_cycles).max().unwrap_or(0),
            overruns: (
                s.first().map_or(0, |x| x.overruns),
                s.last().map_or(0, |x| x.overruns),
            ),
        }
    }
}

/// TIM1's PWM period (20 kHz, firmware/src/board/pwm.rs): the e-stop's bound.
const PWM_PERIOD_S: f64 = 1.0 / 20_000.0;
/// Control periods the firmware takes to drive the enables low after the e-stop.
const ESTOP_ENABLES_PERIODS: f64 = 2.0;
const CONTROL_PERIOD_S: f64 = 1.0 / 10_000.0;

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

/// The latest time any of the axes' enables went low at or after `t0_s` (each must).
fn enables_low_at(served: &Served, t0_s: f64) -> f64 {
    AXES.iter()
        .map(|a| output_at(served, &format!("enable.{a}"), "0", t0_s).expect("enable driven low"))
        .fold(0.0f64, f64::max)
}

/// Wait for the fault a scenario caused: its `first_fault` text.
fn fault_of(c: &mut Client<BoardPort>) -> String {
    let s = cli::wait_while(c, |s| s.state != MachineState::Fault).unwrap();
    s.first_fault.as_deref().unwrap_or("none").to_string()
}

/// Armed and holding: the e-stop input (PB12, TIM1's break) goes active. TIM1's MOE
/// clears in hardware within one PWM cycle, the firmware drives the enables low and
/// latches `estop`; a reset is refused while the input is still active and clears the
/// fault once it is released.
fn estop(c: &mut Client<BoardPort>, served: &Served) -> serde_json::Value {
    let s = cli::ready(c, false).unwrap();
    assert_eq!(s.state, MachineState::Idle, "armed before the e-stop");
    let t0 = twin_ctl(c, served, "drive B12 1");
    let fault = fault_of(c);
    let moe_after_s = output_at(served, "moe", "0", t0).expect("MOE cleared after the e-stop") - t0;
    let enables_after_s = enables_low_at(served, t0) - t0;
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
    println!(
        "e-stop on the twin: MOE cleared {:.1} µs after PB12 (bound: one PWM cycle, {:.0} µs), \
         enables low after {:.1} µs (bound {:.0} µs), fault {fault:?}, reset while active: {reset_while_active:?}",
        moe_after_s * 1e6,
        PWM_PERIOD_S * 1e6,
        enables_after_s * 1e6,
        ESTOP_ENABLES_PERIODS * CONTROL_PERIOD_S * 1e6,
    );
    assert!(moe_after_s <= PWM_PERIOD_S, "MOE after {moe_after_s} s");
    assert!(
        enables_after_s <= ESTOP_ENABLES_PERIODS * CONTROL_PERIOD_S,
        "enables after {enables_after_s} s"
    );
    assert_eq!(fault, "estop", "the fault latched");
    assert!(
        matches!(
            reset_while_active.as_str(),
            s if !s.is_empty() && !s.starts_with("Done")
        ),
        "a reset with the e-stop active is refused: {reset_while_active}"
    );
    serde_json::json!({
        "scenario": "estop",
        "moe_cleared_after_s": moe_after_s,
        "enables_low_after_s": enables_after_s,
        "fault": fault,
        "reset_while_active": reset_while_active,
    })
}

/// Periods from a stuck encoder on a moving axis to its outputs off: detected within 2
/// periods at 10 mm/s and more (docs/safety.md, the counts-due check), outputs off in
/// the period of detection, and the injection lands mid-period (one more).
const STUCK_OUTPUTS_OFF_PERIODS: f64 = 3.0;
/// Periods from a limit switch closing to the outputs off: the switch is read in the
/// next period (the plant's step sets the pin at TIM4's update), an immediate fault.
const LIMIT_OUTPUTS_OFF_PERIODS: f64 = 2.0;
/// X's speed the stuck encoder needs for its 2-period bound, mm/s.
const STUCK_MIN_SPEED_MM_S: f32 = 10.0;

/// Armed, X moving 20 mm at the rapid rate: its encoder stops counting. The firmware
/// latches `encoder_stuck on x` and drives every enable low within
/// [`STUCK_OUTPUTS_OFF_PERIODS`]; a reset (which runs the encoder check) leaves the
/// machine in fault while the encoder is still stuck.
fn stuck_encoder(c: &mut Client<BoardPort>, served: &Served) -> serde_json::Value {
    let s = cli::ready(c, false).unwrap();
    assert_eq!(s.state, MachineState::Idle, "armed before the move");
    // towards the middle of the travel, whichever side X stands on
    let dx = if s.pos_mm[0] > 0.0 { -20.0 } else { 20.0 };
    let target = [s.pos_mm[0] + dx, s.pos_mm[1], s.pos_mm[2]];
    for (what, r) in [
        ("run", Request::Run),
        ("segment", Request::Segment(Segment::rapid(target, 1))),
        ("end", Request::EndProgram),
    ] {
        assert_eq!(c.exec(r).unwrap(), Outcome::Done, "the move's {what}");
    }
    let moving = |s: &Status| s.vel_mm_s[0].abs() >= STUCK_MIN_SPEED_MM_S;
    let s = cli::wait_while(c, |s| {
        !moving(s) && !s.program_done && s.state != MachineState::Fault
    })
    .unwrap();
    assert!(moving(&s), "X moves before its encoder sticks: {s:?}");
    let speed_mm_s = s.vel_mm_s[0].abs();
    let t0 = twin_ctl(c, served, r#"inject {"encoder_stuck": {"axis": "x"}}"#);
    let fault = fault_of(c);
    let enables_after_s = enables_low_at(served, t0) - t0;
    let s = c.status().unwrap();
    let stopped_after_mm = (s.pos_mm[0] - target[0] + dx).abs();
    // the reset runs the encoder check, which a still-stuck encoder fails
    let reset = format!("{:?}", c.exec(Request::Reset).unwrap());
    let s = cli::wait_while(c, |s| s.state == MachineState::EncoderCheck).unwrap();
    println!(
        "stuck encoder on the twin: X at {speed_mm_s:.1} mm/s or more, fault {fault:?}, enables low \
         after {:.1} µs (bound {:.0} µs), X read {stopped_after_mm:.3} mm into its move; reset: {reset}, then {:?}",
        enables_after_s * 1e6,
        STUCK_OUTPUTS_OFF_PERIODS * CONTROL_PERIOD_S * 1e6,
        s.state,
    );
    assert_eq!(fault, "encoder_stuck on x", "the fault latched");
    assert!(
        enables_after_s <= STUCK_OUTPUTS_OFF_PERIODS * CONTROL_PERIOD_S,
        "enables after {enables_after_s} s"
    );
    assert_eq!(
        s.state,
        MachineState::Fault,
        "a reset while the encoder is stuck leaves the fault"
    );
    serde_json::json!({
        "scenario": "stuck_encoder",
        "speed_mm_s": speed_mm_s,
        "fault": fault,
        "enables_low_after_s": enables_after_s,
        "state_after_reset": format!("{:?}", s.state),
    })
}

/// Armed and holding: Y's high limit switch closes. The firmware latches `limit_max on
/// y` and drives every enable low within [`LIMIT_OUTPUTS_OFF_PERIODS`]; a reset is
/// refused while the switch is closed.
fn limit_switch(c: &mut Client<BoardPort>, served: &Served) -> serde_json::Value {
    let s = cli::ready(c, false).unwrap();
    assert_eq!(s.state, MachineState::Idle, "armed before the limit");
    let t0 = twin_ctl(
        c,
        served,
        r#"inject {"limit": {"axis": "y", "high": true}}"#,
    );
    let fault = fault_of(c);
    let enables_after_s = enables_low_at(served, t0) - t0;
    let reset = match c.exec(Request::Reset).unwrap() {
        Outcome::Refused(why) => why.to_string(),
        o => format!("{o:?}"),
    };
    let state = c.status().unwrap().state;
    println!(
        "limit switch on the twin: fault {fault:?}, enables low after {:.1} µs (bound {:.0} µs), \
         reset while closed: {reset:?}, then {state:?}",
        enables_after_s * 1e6,
        LIMIT_OUTPUTS_OFF_PERIODS * CONTROL_PERIOD_S * 1e6,
    );
    assert_eq!(fault, "limit_max on y", "the fault latched");
    assert!(
        enables_after_s <= LIMIT_OUTPUTS_OFF_PERIODS * CONTROL_PERIOD_S,
        "enables after {enables_after_s} s"
    );
    assert_eq!(state, MachineState::Fault, "reset with the switch closed");
    serde_json::json!({
        "scenario": "limit_switch",
        "fault": fault,
        "enables_low_after_s": enables_after_s,
        "reset_while_closed": reset,
    })
}

/// The square's twin: the e-stop, then the stuck encoder (it leaves X faulted for good).
fn estop_then_stuck_encoder(c: &mut Client<BoardPort>, served: &Served) -> Vec<serde_json::Value> {
    vec![
        estop(c, served),
        stuck_encoder(c, served),
        hardfault_while_moving(),
    ]
}

/// The outputs-off stores are the HardFault entry's first instructions (the twin's
/// `hardfault` scenario: 0.03 µs for MOE, 0.09 µs for the enables); the command lands at
/// the twin's next poll and the fault one instruction later.
const HARDFAULT_OUTPUTS_OFF_S: f64 = 2e-6;

/// A fresh twin, armed, X moving: a HardFault. MOE and every enable go low at once (the
/// naked entry's stores), the firmware stops feeding the IWDG and the chip resets, and
/// the firmware boots again with `reset cause: watchdog` (outputs off through it).
fn hardfault_while_moving() -> serde_json::Value {
    let served = Served::start("hardfault");
    let mut c = Client::connect(BoardPort::open_twin(&served.pty).unwrap()).unwrap();
    prepare(&mut c);
    let s = cli::ready(&mut c, false).unwrap();
    assert_eq!(s.state, MachineState::Idle, "armed before the move");
    let target = [s.pos_mm[0] + 20.0, s.pos_mm[1], s.pos_mm[2]];
    for (what, r) in [
        ("run", Request::Run),
        ("segment", Request::Segment(Segment::rapid(target, 1))),
        ("end", Request::EndProgram),
    ] {
        assert_eq!(c.exec(r).unwrap(), Outcome::Done, "the move's {what}");
    }
    let s = cli::wait_while(&mut c, |s| {
        s.vel_mm_s[0].abs() < STUCK_MIN_SPEED_MM_S && !s.program_done
    })
    .unwrap();
    let speed_mm_s = s.vel_mm_s[0].abs();
    assert!(
        speed_mm_s >= STUCK_MIN_SPEED_MM_S,
        "X moves before the fault: {s:?}"
    );
    let t0 = twin_ctl(&mut c, &served, "hardfault");
    // the board is silent from here on: wait for its reboot in its log
    let t_wall = Instant::now();
    let rebooted = loop {
        let log = std::fs::read(&served.log).unwrap_or_default();
        let log = String::from_utf8_lossy(&log);
        if log.contains("reset cause: watchdog") {
            break log.contains("HardFault at pc=");
        }
        assert!(
            t_wall.elapsed() < Duration::from_secs(120),
            "no reboot after the HardFault"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    let moe_after_s = output_at(&served, "moe", "0", t0).expect("MOE cleared") - t0;
    let enables_after_s = enables_low_at(&served, t0) - t0;
    // nothing is driven active again through the reset and the boot
    let log = std::fs::read_to_string(format!("{}.outputs", served.pty)).unwrap();
    let active_again: Vec<&str> = log
        .lines()
        .filter(|l| {
            let mut w = l.split(' ');
            let t: f64 = w.next().and_then(|t| t.parse().ok()).unwrap_or(0.0);
            let sig = w.next().unwrap_or("");
            let v = w.next().unwrap_or("");
            t > t0 + HARDFAULT_OUTPUTS_OFF_S
                && (sig.starts_with("enable.") || sig == "moe")
                && v == "1"
        })
        .collect();
    println!(
        "HardFault on the twin, X at {speed_mm_s:.1} mm/s: MOE off after {:.3} µs, enables low after {:.3} µs (bound {:.1} µs); the IWDG reset and a reboot logged `reset cause: watchdog`",
        moe_after_s * 1e6,
        enables_after_s * 1e6,
        HARDFAULT_OUTPUTS_OFF_S * 1e6,
    );
    assert!(rebooted, "the HardFault was logged before the reboot");
    assert!(
        moe_after_s <= HARDFAULT_OUTPUTS_OFF_S,
        "MOE after {moe_after_s} s"
    );
    assert!(
        enables_after_s <= HARDFAULT_OUTPUTS_OFF_S,
        "enables after {enables_after_s} s"
    );
    assert!(
        active_again.is_empty(),
        "outputs active after the fault: {active_again:?}"
    );
    serde_json::json!({
        "scenario": "hardfault_while_moving",
        "speed_mm_s": speed_mm_s,
        "moe_off_after_s": moe_after_s,
        "enables_low_after_s": enables_after_s,
    })
}

fn limit_only(c: &mut Client<BoardPort>, served: &Served) -> Vec<serde_json::Value> {
    vec![limit_switch(c, served)]
}

/// The program on `--sim`, started `phase_ms` after the telemetry subscription.
fn on_sim(program: &Path, phase_ms: u32) -> GcodeReport {
    let mut c = Client::connect(SimMachine::new(SimModels::Designed, DECIMATION).unwrap()).unwrap();
    prepare(&mut c);
    cli::subscribe(&mut c, DECIMATION).unwrap();
    c.sleep_ms(phase_ms).unwrap();
    cli::run_program(&mut c, program, f64::from(DECIMATION) / 1e4, false, None).unwrap()
}

/// The program on `--sim` at every telemetry phase ([`SIM_PHASES_MS`]): a contour max
/// read from samples 10 ms apart misses the peak by as much as the error moves between
/// them (arcs_x2: 10.14 to 12.10 µm over the phases), and where the twin's samples fall is
/// up to the wall clock. The twin's max is judged against this band.
struct SimBand {
    /// The run at phase 0 (segments, duration, rms).
    first: GcodeReport,
    contour_max_least_mm: f64,
    contour_max_largest_mm: f64,
}

impl SimBand {
    fn of(program: &Path) -> Self {
        let runs: Vec<GcodeReport> = (0..SIM_PHASES_MS).map(|k| on_sim(program, k)).collect();
        let maxima = runs.iter().map(|r| r.contour_max_mm);
        Self {
            contour_max_least_mm: maxima.clone().fold(f64::INFINITY, f64::min),
            contour_max_largest_mm: maxima.fold(0.0, f64::max),
            first: runs.into_iter().next().expect("at least one phase"),
        }
    }
}

/// host-sim/programs/arcs.nc with every feed doubled (F1000 → F2000 …), as
/// `arcs_x2.nc` in a temporary folder: the same arcs of every kind in half the machine time
/// (17 s instead of 34: the twin emulates the board at about 1/20 of real time, and the
/// arcs were the longest job of a CI run).
fn arcs_at_twice_the_feed() -> PathBuf {
    let text = std::fs::read_to_string(root().join("host-sim/programs/arcs.nc")).unwrap();
    let doubled: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with('(') {
                return l.to_string();
            }
            l.split(' ')
                .map(
                    |w| match w.strip_prefix('F').and_then(|f| f.parse::<f64>().ok()) {
                        Some(f) => format!("F{}", 2.0 * f),
                        None => w.to_string(),
                    },
                )
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect();
    assert!(
        doubled.iter().any(|l| l.contains("F2000")),
        "arcs.nc's feeds"
    );
    let dir = std::env::temp_dir().join(format!("gantry_twin_{}_programs", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("arcs_x2.nc");
    std::fs::write(&p, doubled.join("\n") + "\n").unwrap();
    p
}

#[test]
#[ignore = "needs `cargo fw`, the twin-plant helper and the twin's Python packages; .ci/run runs it"]
fn square_and_arcs_on_the_twin_match_the_simulated_machine() {
    let programs = [
        root().join("host-sim/programs/square.nc"),
        arcs_at_twice_the_feed(),
    ];
    // the square's twin finishes first: its fault scenarios run while the arcs go on
    let afters: [After; 2] = [estop_then_stuck_encoder, limit_only];
    let twins: Vec<_> = programs
        .iter()
        .cloned()
        .zip(afters)
        .map(|(p, after)| std::thread::spawn(move || on_twin(&p, after)))
        .collect();
    let mut rows = Vec::new();
    for (p, t) in programs.iter().zip(twins) {
        let (twin, wall_s, fault_rows) = t.join().expect("the twin's run");
        rows.extend(fault_rows);
        let band = SimBand::of(p);
        let sim = &band.first;
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        println!(
            "{name}: twin contour max {:.5} mm rms {:.5} mm, {:.3} s, {} segments ({:.0} s wall, {:.3}x real time); \
             --sim contour max {:.5} to {:.5} mm over {SIM_PHASES_MS} telemetry phases, rms {:.5} mm, {:.3} s, {} segments",
            twin.contour_max_mm, twin.contour_rms_mm, twin.duration_s, twin.segments, wall_s,
            twin.duration_s / wall_s, band.contour_max_least_mm, band.contour_max_largest_mm,
            sim.contour_rms_mm, sim.duration_s, sim.segments,
        );
        assert_eq!(
            twin.status, "completed",
            "{name} on the twin: {:?}",
            twin.error
        );
        assert!(twin.program_done, "{name}: {}", twin.program_end);
        assert_eq!(twin.segments, sim.segments, "{name}: segments executed");
        let (low, high) = (
            twin.contour_max_mm / band.contour_max_least_mm,
            twin.contour_max_mm / band.contour_max_largest_mm,
        );
        assert!(
            low >= 1.0 - CONTOUR_RATIO_BOUND && high <= 1.0 + CONTOUR_RATIO_BOUND,
            "{name}: contour max twin {} mm vs --sim {} to {} mm over the telemetry phases \
             (ratios {low:.3}, {high:.3})",
            twin.contour_max_mm,
            band.contour_max_least_mm,
            band.contour_max_largest_mm,
        );
        let rms_ratio = twin.contour_rms_mm / sim.contour_rms_mm;
        assert!(
            (rms_ratio - 1.0).abs() <= CONTOUR_RMS_RATIO_BOUND,
            "{name}: contour rms twin {} mm vs --sim {} mm (ratio {rms_ratio:.3})",
            twin.contour_rms_mm,
            sim.contour_rms_mm
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
            "sim_contour_max_band_mm": [band.contour_max_least_mm, band.contour_max_largest_mm],
            "contour_ratios_to_band": [low, high],
            "contour_rms_ratio": rms_ratio,
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
