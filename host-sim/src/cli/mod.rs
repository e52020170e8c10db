//! The `gantry` command line: a session over the host link with a machine, and what each
//! subcommand does with it. The machine is `--sim` (the supervisor, planner and servo step
//! in-process against the simulated gantry, [`sim`]), `--qemu` (the firmware's QEMU
//! build in its link rig, over its emulated USART2, [`qemu`]), `--port DEV` (a board
//! over its UART, [`port`]) or `--served PTY` (one simulated machine that stays, run by
//! `gantry sim serve`, [`serve`]). What the operator reads is [`view`]; Ctrl-C is
//! [`interrupt`].
//!
//! Every subcommand speaks the link protocol ([`client`]): requests on the reliable
//! channel, status by real-time request, telemetry for the program run.

pub mod args;
pub mod client;
pub mod comp;
pub mod freqresp;
pub mod interrupt;
pub mod keys;
pub mod machine;
pub mod pendant;
pub mod port;
pub mod qemu;
pub mod scope;
pub mod serve;
pub mod sim;
pub mod trace;
pub mod transport;
pub mod tune;
pub mod view;

pub use transport::Transport;

use crate::gcode::measure::{distance, MetricSample, PathMetrics};
use crate::gcode::program::{load_program_with, segments, PlanSegment};
use crate::gcode::report::{realtime_ratio, ComputeJson, GcodeReport, LimitsJson};
use crate::gcode::{compress, ParseOptions, Program, Tool, Travel, WorkOffsets};
use crate::sim_gantry::machine_and_planner;
use anyhow::{bail, Context, Result};
use client::{expect_done, Client};
use controller_core::link::RealtimeRequest;
use controller_core::machine::messages::{
    IdentifyMsg, MachineState, Outcome, ProgramEnd, Request, Status, Telemetry,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Axis names on the command line.
pub const AXES: [&str; 3] = ["x", "y", "z"];

/// Poll interval while waiting for the machine, ms.
pub(crate) const POLL_MS: u32 = 20;
/// Longest wait for homing or an identification, ms of machine time.
const LONG_WAIT_MS: u32 = 300_000;

/// Wait (polling the status) while the machine is in a state `busy` says; its status then.
pub fn wait_while<T: Transport>(
    c: &mut Client<T>,
    busy: impl Fn(&Status) -> bool,
) -> Result<Status> {
    let t0 = c.transport.now_ms();
    let mut stopping = false;
    loop {
        let s = c.status()?;
        if !busy(&s) {
            if stopping {
                bail!(
                    "Ctrl-C: the machine stopped at x {:.3} y {:.3} z {:.3} mm, {}",
                    s.pos_mm[0],
                    s.pos_mm[1],
                    s.pos_mm[2],
                    view::state_words(&s)
                );
            }
            return Ok(s);
        }
        if interrupt::requested() && !stopping {
            c.realtime(RealtimeRequest::Stop)?;
            stopping = true;
            eprintln!("Ctrl-C: stopping (a controlled stop; Ctrl-C again quits at once)");
        }
        if c.transport.now_ms().wrapping_sub(t0) > LONG_WAIT_MS {
            bail!("the machine is still busy after {} s", LONG_WAIT_MS / 1000);
        }
        c.sleep_ms(POLL_MS)?;
    }
}

/// [`wait_while`] the machine is in `state`, with a bar at a terminal from the machine's
/// own progress (homing, identification: `Status::progress`), its position and the time
/// left at the rate so far.
pub fn wait_with_progress<T: Transport>(
    c: &mut Client<T>,
    state: MachineState,
    what: &str,
) -> Result<Status> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return wait_while(c, |s| s.state == state);
    }
    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{what} {{bar:30}} {{percent}} %, ETA {{eta}}  {{msg}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let s = wait_while(c, |s| {
        bar.set_position((s.progress.clamp(0.0, 1.0) * 1000.0) as u64);
        bar.set_message(format!(
            "X {:.3} Y {:.3} Z {:.3} mm",
            s.pos_mm[0], s.pos_mm[1], s.pos_mm[2]
        ));
        s.state == state
    });
    bar.finish_and_clear();
    s
}

/// `gantry run`'s exit status: 0 completed, 2 rejected (nothing ran), 1 anything else
/// (a fault, an abort: the program did not complete).
pub fn run_exit_code(r: &GcodeReport) -> u8 {
    match r.status.as_str() {
        "completed" if r.program_done => 0,
        "rejected" => 2,
        _ => 1,
    }
}

/// How a program ended, as `gantry run`'s JSON names it (`program_end`).
pub fn program_end_name(end: ProgramEnd) -> String {
    match end {
        ProgramEnd::None => "not_started".into(),
        ProgramEnd::Running => "running".into(),
        ProgramEnd::Completed => "completed".into(),
        ProgramEnd::Fault(code) => format!(
            "aborted_by_fault({})",
            code.kind().map_or("unknown", |k| k.name())
        ),
        ProgramEnd::HostStop => "aborted_by_host".into(),
        ProgramEnd::LinkLost => "aborted_by_link_loss".into(),
        ProgramEnd::SegmentRefused => "aborted_segment_refused".into(),
        ProgramEnd::Stopped => "aborted_stopped".into(),
    }
}

fn fault_text(s: &Status) -> String {
    s.first_fault.as_deref().unwrap_or("unknown").to_string()
}

/// Arm (when disarmed) and home (when an axis that homes is not homed yet).
pub fn ready<T: Transport>(c: &mut Client<T>, home: bool) -> Result<Status> {
    let s = c.status()?;
    if s.state == MachineState::Fault {
        bail!(
            "the machine is in fault ({}): `gantry reset` once the cause is gone",
            fault_text(&s)
        );
    }
    if s.state == MachineState::Disabled {
        expect_done("arm", c.exec(Request::Arm)?)?;
        // with `safety.arm_encoder_check` the machine checks its encoders first
        let s = wait_while(c, |s| s.state == MachineState::EncoderCheck)?;
        if s.state != MachineState::Idle {
            bail!("arming failed: {:?} ({})", s.state, fault_text(&s));
        }
    }
    if home && c.status()?.homed != 0b111 {
        expect_done("home", c.exec(Request::Home)?)?;
        let s = wait_with_progress(c, MachineState::Homing, "homing")?;
        if s.state != MachineState::Idle {
            bail!("homing failed: {:?} ({})", s.state, fault_text(&s));
        }
    }
    c.status()
}

/// The machine's travel, read from its settings.
pub fn travel<T: Transport>(c: &mut Client<T>) -> Result<Travel> {
    let mut t = [[0.0f64; 2]; 3];
    for (i, a) in AXES.iter().enumerate() {
        for (j, end) in ["min_mm", "max_mm"].iter().enumerate() {
            t[i][j] = get_f64(c, &format!("axis.{a}.travel.{end}"))?;
        }
    }
    // an unlimited end: far beyond any program
    let big = crate::gcode::MAX_WORD_MAGNITUDE;
    let t = t.map(|[lo, hi]| {
        [
            if lo.is_finite() { lo } else { -big },
            if hi.is_finite() { hi } else { big },
        ]
    });
    Travel::new(t).map_err(|e| anyhow::anyhow!("the machine's travel: {e}"))
}

/// One setting's value as text.
pub fn get<T: Transport>(c: &mut Client<T>, key: &str) -> Result<String> {
    let k = heapless::String::try_from(key).map_err(|_| anyhow::anyhow!("key too long: {key}"))?;
    match c.exec(Request::SettingGet { key: k })? {
        Outcome::Value(v) => Ok(v.to_string()),
        Outcome::Refused(why) => bail!("{why}"),
        other => bail!("unexpected answer to settings get {key}: {other:?}"),
    }
}

fn get_f64<T: Transport>(c: &mut Client<T>, key: &str) -> Result<f64> {
    let v = get(c, key)?;
    v.parse()
        .with_context(|| format!("setting {key} = {v} is not a number"))
}

/// Telemetry with the default signals every `every_periods` control periods.
pub fn subscribe<T: Transport>(c: &mut Client<T>, every_periods: u32) -> Result<()> {
    expect_done(
        "telemetry subscription",
        c.exec(Request::Subscribe {
            every_periods,
            signals: heapless::Vec::new(),
        })?,
    )?;
    Ok(())
}

/// Change one setting (value as text).
pub fn set<T: Transport>(c: &mut Client<T>, key: &str, value: &str) -> Result<()> {
    let k = heapless::String::try_from(key).map_err(|_| anyhow::anyhow!("key too long: {key}"))?;
    let v = heapless::String::try_from(value)
        .map_err(|_| anyhow::anyhow!("value too long: {value}"))?;
    expect_done(
        &format!("settings set {key}"),
        c.exec(Request::SettingSet { key: k, value: v })?,
    )?;
    Ok(())
}

/// The settings key of coordinate `axis` (0 = X) of work coordinate system `system` (0 =
/// G54): `work.g55.x_mm`.
pub fn work_key(system: usize, axis: usize) -> Option<String> {
    let cs = controller_core::settings::WorkOffsets::NAMES.get(system)?;
    Some(format!("work.{cs}.{}_mm", AXES.get(axis)?))
}

/// The machine's work coordinate systems and tool table, read from its settings: what a
/// program is interpreted with.
pub fn read_work_and_tools<T: Transport>(c: &mut Client<T>) -> Result<(WorkOffsets, Vec<Tool>)> {
    let mut work = [[0.0; 3]; crate::gcode::WORK_SYSTEMS];
    for (s, origin) in work.iter_mut().enumerate() {
        for (a, v) in origin.iter_mut().enumerate() {
            let key = work_key(s, a).context("work offset key")?;
            *v = get_f64(c, &key)
                .with_context(|| format!("reading the machine's work offsets ({key})"))?;
        }
    }
    let mut tools = Vec::new();
    for n in 1..=controller_core::settings::TOOL_COUNT {
        let key = |field: &str| format!("tool.{n}.{field}");
        tools.push(Tool {
            length_mm: get_f64(c, &key("length_mm")).with_context(|| {
                format!("reading the machine's tool table ({})", key("length_mm"))
            })?,
            diameter_mm: get_f64(c, &key("diameter_mm"))?,
        });
    }
    Ok((work, tools))
}

/// The settings a program changed with G10 (work offsets, tools) relative to what it was
/// parsed with, as `(key, value)` texts for `settings set` (the value is the `f32` the
/// machine keeps, as its shortest text).
pub fn g10_changes(program: &Program, options: &ParseOptions) -> Vec<(String, String)> {
    let text = |v: f64| (v as f32).to_string();
    let mut out: Vec<(String, String)> = program
        .work_offset_changes(options)
        .into_iter()
        .filter_map(|(s, a, v)| Some((work_key(s, a)?, text(v))))
        .collect();
    for (n, tool) in program.tool_changes(options) {
        let old = options.tools.get(n - 1).copied().unwrap_or_default();
        if tool.length_mm.to_bits() != old.length_mm.to_bits() {
            out.push((format!("tool.{n}.length_mm"), text(tool.length_mm)));
        }
        if tool.diameter_mm.to_bits() != old.diameter_mm.to_bits() {
            out.push((format!("tool.{n}.diameter_mm"), text(tool.diameter_mm)));
        }
    }
    out
}

/// A feed hold issued by the operator while a program runs: at `at_s` of machine time
/// after the start, resumed `for_s` later.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hold {
    pub at_s: f32,
    pub for_s: f32,
}

/// Issue the hold and the resume when due; `held_at` is when the hold was issued (ms).
fn operator<T: Transport>(
    c: &mut Client<T>,
    hold: Option<Hold>,
    p0: u32,
    period_s: f64,
    held_at: &mut Option<u32>,
    resumed: &mut bool,
) -> Result<()> {
    let Some(h) = hold else { return Ok(()) };
    // machine time since the program started (the machine's periods, whatever the
    // transport's clock)
    let now = (f64::from(c.last_period().wrapping_sub(p0)) * period_s * 1000.0) as u32;
    match *held_at {
        None if now as f32 >= h.at_s * 1000.0 => {
            c.realtime(RealtimeRequest::Hold)?;
            *held_at = Some(now);
        }
        Some(at) if !*resumed && (now - at) as f32 >= h.for_s * 1000.0 => {
            c.realtime(RealtimeRequest::Resume)?;
            *resumed = true;
        }
        _ => {}
    }
    Ok(())
}

/// The operator's keys during a program, read on a thread of its own so the session never
/// waits for the keyboard: `h` feed hold, `r` resume, `a` abort; single keys at a terminal
/// (while the returned guard lives), else the first character of each line.
fn keyboard() -> (std::sync::mpsc::Receiver<char>, Option<keys::SingleKeys>) {
    let (tx, rx) = std::sync::mpsc::channel();
    let single = keys::SingleKeys::start();
    if single.is_some() {
        std::thread::spawn(move || {
            use std::io::Read;
            let mut typed = [0u8; 16];
            // (a read returns each key as it comes: the terminal gives bytes one by one)
            while let Ok(n @ 1..) = std::io::stdin().read(&mut typed) {
                for b in typed.iter().take(n).filter(|b| b.is_ascii_alphabetic()) {
                    if tx.send((*b as char).to_ascii_lowercase()).is_err() {
                        return;
                    }
                }
            }
        });
    } else {
        std::thread::spawn(move || {
            for line in std::io::stdin().lines() {
                let Ok(line) = line else { break };
                if let Some(k) = line.trim().chars().next() {
                    if tx.send(k.to_ascii_lowercase()).is_err() {
                        break;
                    }
                }
            }
        });
    }
    (rx, single)
}

/// Act on the keys typed so far; `true` once the program was aborted.
fn keys<T: Transport>(
    c: &mut Client<T>,
    keys: Option<&std::sync::mpsc::Receiver<char>>,
    aborted: &mut bool,
) -> Result<()> {
    if interrupt::requested() && !*aborted {
        c.realtime(RealtimeRequest::Stop)?;
        *aborted = true;
        eprintln!("Ctrl-C: stopping on the path (a controlled stop; Ctrl-C again quits at once)");
    }
    let Some(rx) = keys else { return Ok(()) };
    while let Ok(k) = rx.try_recv() {
        match k {
            'h' => {
                c.realtime(RealtimeRequest::Hold)?;
                eprintln!("feed hold (r resumes, a aborts)");
            }
            'r' => {
                c.realtime(RealtimeRequest::Resume)?;
                eprintln!("resumed");
            }
            'a' => {
                c.realtime(RealtimeRequest::Stop)?;
                *aborted = true;
                eprintln!("aborted: stopping on the path");
            }
            _ => eprintln!("keys: h hold, r resume, a abort (then Enter)"),
        }
    }
    Ok(())
}

/// `gantry run FILE`: parse, check against the machine's travel, stream, follow. The
/// report has the keys of `cargo sim gcode`; measured from telemetry (actual and
/// reference positions, the planner's reference velocity and acceleration, at the
/// telemetry rate), so jerk is the telemetry-rate estimate.
pub fn run_program<T: Transport>(
    c: &mut Client<T>,
    path: &Path,
    telemetry_period_s: f64,
    progress: bool,
    hold: Option<Hold>,
) -> Result<GcodeReport> {
    run_program_with(c, path, telemetry_period_s, progress, hold, None)
}

/// [`run_program`] with the operator's keys (`h` hold, `r` resume, `a` abort) from
/// `buttons` instead of the terminal (a GUI's).
pub fn run_program_with<T: Transport>(
    c: &mut Client<T>,
    path: &Path,
    telemetry_period_s: f64,
    progress: bool,
    hold: Option<Hold>,
    buttons: Option<&std::sync::mpsc::Receiver<char>>,
) -> Result<GcodeReport> {
    let (limits, tol) = machine_limits(c)?;
    // the machine's control period (the telemetry's period numbers count it)
    let (run, _) = c.while_busy(|| machine_and_planner(None))??;
    let period_s = 1.0 / f64::from(run.servo.rate_hz);
    let name = path.display().to_string();
    let Loaded {
        program,
        opts,
        segs,
        compression,
        parse_s,
        compress_s,
    } = match load_on_machine(c, path, tol)? {
        Ok(loaded) => loaded,
        Err(e) => return Ok(GcodeReport::rejected(&name, &e, limits, tol)),
    };
    expect_done("run", c.exec(Request::Run)?)?;
    c.take_telemetry();
    let started = Instant::now();
    // the program's time is the machine's: its period count
    let p0 = c.status()?.period;
    // an operator at a terminal: hold, resume and abort from the keyboard (single keys
    // while `_single` lives)
    let terminal = match buttons {
        Some(_) => None,
        None => progress.then(keyboard),
    };
    let (typed, _single) = match (buttons, &terminal) {
        (Some(rx), _) => (Some(rx), None),
        (None, Some((rx, single))) => (Some(rx), single.as_ref()),
        (None, None) => (None, None),
    };
    let bar = progress.then(|| run_progress_bar(segs.len(), _single.is_some()));
    let mut aborted = false;
    let mut follow = Follow {
        metrics: c.while_busy(|| {
            PathMetrics::new(&program, &segs, limits, tol, 1.5 * telemetry_period_s)
        })?,
        bar,
        tags: segs.iter().map(|g| g.seg.tag).collect(),
        period_s,
    };
    let (mut held_at, mut resumed) = (None, false);
    for seg in &segs {
        // wait for room here, not in `send`: a feed hold stops the planner taking
        // segments, and the resume must still get through
        while !c.can_send() && !aborted {
            c.pump()?;
            operator(c, hold, p0, period_s, &mut held_at, &mut resumed)?;
            keys(c, typed, &mut aborted)?;
            c.transport.wait()?;
        }
        if aborted {
            break;
        }
        c.send(Request::Segment(seg.seg))?;
        c.pump()?;
        operator(c, hold, p0, period_s, &mut held_at, &mut resumed)?;
        keys(c, typed, &mut aborted)?;
        follow.account(c.take_telemetry());
    }
    if !aborted {
        c.send(Request::EndProgram)?;
    }
    let end = loop {
        operator(c, hold, p0, period_s, &mut held_at, &mut resumed)?;
        keys(c, typed, &mut aborted)?;
        let s = c.status()?;
        follow.account(c.take_telemetry());
        if let Outcome::Refused(why) = &s.last {
            bail!("{name}: the machine refused a segment: {why}");
        }
        let waiting = hold.is_some() && !resumed && !aborted;
        // over: at rest after its end or after an abort (the machine says which), or in
        // fault
        if s.state == MachineState::Fault
            || (s.state == MachineState::Idle
                && !waiting
                && (s.program_done || s.program.end.aborted()))
        {
            break s;
        }
        c.sleep_ms(POLL_MS)?;
    };
    if let Some(b) = follow.bar.take() {
        b.finish_and_clear();
    }
    let duration_s = f64::from(end.period.wrapping_sub(p0)) * period_s;
    let compute_s = started.elapsed().as_secs_f64();
    let run = RunEnd {
        end,
        duration_s,
        compute_s,
        compute: ComputeJson {
            parse_s,
            compress_s,
            run_s: compute_s,
        },
        compression,
    };
    let metrics = follow.metrics;
    let mut report = c.while_busy(|| run_report(&program, &segs, metrics, &run, limits))?;
    write_back_g10(c, &name, &program, &opts, &mut report)?;
    Ok(report)
}

/// A program run followed from its telemetry as it comes: the figures (no sample kept: a
/// long program runs for hours), every sample in Run (a jerk only between consecutive
/// ones), and the progress bar.
struct Follow<'p> {
    metrics: PathMetrics<'p>,
    bar: Option<ProgressBar>,
    /// The segments' tags: the bar follows the machine's executor (the telemetry's segment
    /// tag), not what was sent (a short program is sent at once and runs for seconds).
    tags: Vec<u32>,
    /// The machine's control period, s (the telemetry's period numbers count it).
    period_s: f64,
}

impl Follow<'_> {
    /// The telemetry that arrived: the bar at the latest sample, the samples in Run into
    /// the figures.
    fn account(&mut self, samples: Vec<Telemetry>) {
        if let (Some(b), Some(t)) = (&self.bar, samples.last()) {
            b.set_position(self.tags.partition_point(|g| *g < t.tag) as u64);
            b.set_message(format!(
                "X {:.3} Y {:.3} Z {:.3} mm",
                t.pos_mm[0], t.pos_mm[1], t.pos_mm[2]
            ));
        }
        for t in samples
            .iter()
            .filter(|t| matches!(t.state, MachineState::Run { .. }))
        {
            let sample = MetricSample {
                t_s: f64::from(t.period) * self.period_s,
                tag: t.tag as usize,
                planned_mm: t.reference_mm.map(f64::from),
                vel_mm_s: t.ref_vel_mm_s.map(f64::from),
                acc_mm_s2: t.ref_acc_mm_s2.map(f64::from),
                actual_mm: t.pos_mm.map(f64::from),
                along_mm: 0.0,
            };
            // (no plot trace: `gantry run` draws none)
            self.metrics.add(&sample, true, false);
        }
    }
}

/// The machine's planner limits and its configured tolerance (G64 without P), mm, from
/// its settings.
fn machine_limits<T: Transport>(c: &mut Client<T>) -> Result<(LimitsJson, f64)> {
    let mut limits = LimitsJson {
        vel: [0.0; 3],
        acc: [0.0; 3],
        jerk: [0.0; 3],
    };
    for (i, a) in AXES.iter().enumerate() {
        limits.vel[i] = get_f64(c, &format!("axis.{a}.planner.vel_max_mm_s"))?;
        limits.acc[i] = get_f64(c, &format!("axis.{a}.planner.acc_max_mm_s2"))?;
        limits.jerk[i] = get_f64(c, &format!("axis.{a}.planner.jerk_max_mm_s3"))?;
    }
    let tol = get_f64(c, "planner.tolerance_mm")?;
    Ok((limits, tol))
}

/// A program loaded for the machine: parsed where its planner starts, in its context,
/// and as the planner's segments.
struct Loaded {
    program: Program,
    /// The machine context it was parsed in (its G10 changes are relative to it).
    opts: ParseOptions,
    segs: Vec<PlanSegment>,
    compression: compress::Stats,
    parse_s: f64,
    compress_s: f64,
}

/// Parse `path` in the machine's context (its work offsets and tool table), check it
/// against its travel before any motion (also when the machine is not ready), make the
/// machine ready (homed, armed) and parse it again from where its planner starts; the
/// parser's error when the program is rejected.
fn load_on_machine<T: Transport>(
    c: &mut Client<T>,
    path: &Path,
    tol: f64,
) -> Result<Result<Loaded, crate::gcode::Error>> {
    let travel = travel(c)?;
    // the machine's work offsets and tool table: the program's coordinates are relative
    // to them, its G10 changes them
    let (work_offsets_mm, tools) = read_work_and_tools(c)?;
    let options = |start_mm: [f64; 3]| ParseOptions {
        start_mm,
        work_offsets_mm,
        tools: tools.clone(),
        ..ParseOptions::default()
    };
    let s = c.status()?;
    // rejected before any motion (also when the machine is not ready)
    let here = s.pos_mm.map(f64::from);
    if let Err(e) = c.while_busy(|| load_program_with(path, &options(here), &travel))? {
        return Ok(Err(e));
    }
    let s = ready(c, true)?;
    let start = planner_start_mm(c, &s)?;
    let opts = options(start);
    let parse_started = Instant::now();
    let program = match c.while_busy(|| load_program_with(path, &opts, &travel))? {
        Ok(p) => p,
        Err(e) => return Ok(Err(e)),
    };
    let parse_s = parse_started.elapsed().as_secs_f64();
    let compress_started = Instant::now();
    let (segs, compression) = c.while_busy(|| segments(&program, tol))?;
    let compress_s = compress_started.elapsed().as_secs_f64();
    Ok(Ok(Loaded {
        program,
        opts,
        segs,
        compression,
        parse_s,
        compress_s,
    }))
}

/// The progress bar of `gantry run` over `segments` (the keys' hint: single keys, or
/// keys and Enter).
fn run_progress_bar(segments: usize, single_keys: bool) -> ProgressBar {
    let enter = if single_keys { "" } else { " + Enter" };
    let b = ProgressBar::new(segments as u64);
    b.set_style(
        ProgressStyle::with_template(&format!(
            "{{bar:30}} {{pos}}/{{len}} segments run, ETA {{eta}}  {{msg}}  (h/r/a{enter}: hold/resume/abort)",
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    b
}

/// How a program run on the machine ended: its last status, machine and compute time,
/// and the host's compute times and compression.
struct RunEnd {
    end: Status,
    duration_s: f64,
    compute_s: f64,
    compute: ComputeJson,
    compression: compress::Stats,
}

/// The report of a program run on the machine: the figures of `metrics`, and what
/// executed from the machine's status.
fn run_report(
    program: &Program,
    segs: &[PlanSegment],
    metrics: PathMetrics,
    run: &RunEnd,
    limits: LimitsJson,
) -> GcodeReport {
    let RunEnd {
        end,
        duration_s,
        compute_s,
        ..
    } = run;
    let (duration_s, compute_s) = (*duration_s, *compute_s);
    let fault = (end.state == MachineState::Fault).then(|| fault_text(end));
    let realtime = realtime_ratio(duration_s, compute_s);
    // what executed, from the machine's status: every segment when it completed, else
    // those before the one its executor was on when it stopped
    let completed = end.program.end == ProgramEnd::Completed;
    let executed = if completed {
        segs.len()
    } else {
        segs.iter()
            .take_while(|g| g.seg.tag < end.program.tag)
            .count()
    };
    let length = |g: &PlanSegment| -> f64 {
        program
            .moves
            .get(g.moves.clone())
            .map_or(0.0, |m| m.iter().map(distance::length).sum())
    };
    let mut report = metrics.report(program, executed, duration_s, limits, fault, realtime);
    report.segments_planned = segs.len();
    if !completed {
        report.path_length_mm = segs.iter().take(executed).map(length).sum();
    }
    report.program_done = end.program_done;
    report.program_end = program_end_name(end.program.end);
    report.compression = run.compression;
    report.compute = run.compute;
    if !completed && report.status == "completed" {
        report.status = "aborted".into();
    }
    report
}

/// A completed program's G10 changes written back to the machine (into `report`), or
/// word that they were not.
fn write_back_g10<T: Transport>(
    c: &mut Client<T>,
    name: &str,
    program: &Program,
    opts: &ParseOptions,
    report: &mut GcodeReport,
) -> Result<()> {
    // LinuxCNC keeps a program's G10 changes: written back (set, not saved) once it
    // completed; a program that stopped early leaves the machine's offsets as they were
    let changes = g10_changes(program, opts);
    if report.status == "completed" {
        for (key, value) in &changes {
            set(c, key, value).with_context(|| {
                format!("{name} completed, but writing its G10 change {key} = {value} failed")
            })?;
        }
        report.settings_written = changes;
    } else if !changes.is_empty() {
        eprintln!(
            "{name}: {}: its G10 changes were not written to the machine",
            report.status
        );
    }
    Ok(())
}

/// Where the machine's planner starts a program: the reference the servo holds at rest (the
/// latest telemetry sample's, as `cargo sim gcode` takes `planner_start_mm`), not the
/// measured position, which differs by the hold error (6 µm after homing the simulated
/// gantry: the program's first move would start off the path the planner runs). The
/// measured position when no telemetry at rest arrives within a poll.
fn planner_start_mm<T: Transport>(c: &mut Client<T>, s: &Status) -> Result<[f64; 3]> {
    c.take_telemetry();
    c.sleep_ms(POLL_MS)?;
    let at_rest =
        c.take_telemetry().into_iter().rev().find(|t| {
            t.state == MachineState::Idle && t.reference_mm.iter().all(|x| x.is_finite())
        });
    Ok(at_rest.map_or(s.pos_mm, |t| t.reference_mm).map(f64::from))
}

/// Jog `axis` (0 = X) at `vel_mm_s` (0 stops); the machine stops the axis by itself when
/// no jog request came for its jog timeout, so a held key or button repeats it.
pub fn jog<T: Transport>(c: &mut Client<T>, axis: usize, vel_mm_s: f32) -> Result<()> {
    expect_done(
        "jog",
        c.exec(Request::Jog {
            axis: axis as u8,
            vel_mm_s,
        })?,
    )?;
    Ok(())
}

/// Move to `target_mm` at the rapid rate (a one-segment program: the planner's limits and
/// the soft limits apply as for any program).
pub fn move_to<T: Transport>(c: &mut Client<T>, target_mm: [f32; 3]) -> Result<Status> {
    // outside the machine's travel: refused before anything moves
    if let Err(v) = travel(c)?.check_point(target_mm.map(f64::from)) {
        bail!("move: {v}");
    }
    expect_done("move (run)", c.exec(Request::Run)?)?;
    let seg = controller_core::motion::planner::Segment::rapid(target_mm, 0);
    expect_done("move", c.exec(Request::Segment(seg))?)?;
    expect_done("move (end)", c.exec(Request::EndProgram)?)?;
    let s = wait_while(c, |s| {
        !((s.program_done || s.program.end.aborted()) && s.state == MachineState::Idle)
            && s.state != MachineState::Fault
    })?;
    if s.state == MachineState::Fault {
        bail!("move: the machine stopped on a fault ({})", fault_text(&s));
    }
    if !s.program_done {
        bail!(
            "move: the machine did not complete it ({})",
            program_end_name(s.program.end)
        );
    }
    Ok(s)
}

/// `gantry log`: the session's telemetry for `seconds` of machine time into a CSV file
/// (header `period,state,x_mm,y_mm,z_mm,ref_x_mm,ref_y_mm,ref_z_mm,ref_vx_mm_s,…,
/// contour_mm,feed_ratio,tag`, then the names of the subscribed `signals`, one column
/// each); the number of samples. Gaps (lost frames) are counted by the link and left out.
pub fn log_telemetry<T: Transport>(
    c: &mut Client<T>,
    out: &Path,
    seconds: f32,
    signals: &[String],
) -> Result<usize> {
    if !(seconds > 0.0 && seconds <= 3600.0) {
        bail!("log: --seconds must be within (0, 3600], got {seconds}");
    }
    let mut w =
        csv::Writer::from_path(out).with_context(|| format!("cannot write {}", out.display()))?;
    let mut head: Vec<String> = [
        "period",
        "state",
        "x_mm",
        "y_mm",
        "z_mm",
        "ref_x_mm",
        "ref_y_mm",
        "ref_z_mm",
        "ref_vx_mm_s",
        "ref_vy_mm_s",
        "ref_vz_mm_s",
        "ref_ax_mm_s2",
        "ref_ay_mm_s2",
        "ref_az_mm_s2",
        "contour_mm",
        "feed_ratio",
        "tag",
    ]
    .map(String::from)
    .to_vec();
    head.extend(signals.iter().cloned());
    w.write_record(&head)?;
    let (run, _) = machine_and_planner(None)?;
    let periods = (f64::from(seconds) * f64::from(run.servo.rate_hz)) as u32;
    c.take_telemetry();
    let p0 = c.status()?.period;
    let mut n = 0usize;
    loop {
        c.pump()?;
        for t in c.take_telemetry() {
            let mut row = vec![t.period.to_string(), format!("{:?}", t.state)];
            for v in t
                .pos_mm
                .iter()
                .chain(&t.reference_mm)
                .chain(&t.ref_vel_mm_s)
                .chain(&t.ref_acc_mm_s2)
                .chain([&t.contour_mm, &t.feed_ratio])
            {
                row.push(v.to_string());
            }
            row.push(t.tag.to_string());
            row.extend(
                (0..signals.len())
                    .map(|i| t.signals.get(i).map_or(String::new(), |v| v.to_string())),
            );
            w.write_record(&row)?;
            n += 1;
        }
        if c.last_period().wrapping_sub(p0) >= periods {
            break;
        }
        c.transport.wait()?;
    }
    w.flush()?;
    Ok(n)
}

/// `gantry identify` result of one axis (keys are public interface).
#[derive(Clone, Debug, Serialize)]
pub struct IdentifyJson {
    pub axis: String,
    pub status: String,
    #[serde(rename = "J")]
    pub j: Option<f32>,
    #[serde(rename = "B")]
    pub b: Option<f32>,
    pub f_pos: Option<f32>,
    pub f_neg: Option<f32>,
    pub nrmse: f32,
    pub r2: f32,
    pub machine_time_s: f32,
    pub accepted: bool,
}

/// `gantry identify --axis A [--accept]`: home, identify, report; store when accepted.
///
/// A machine whose axes have no model cannot arm, hence cannot home: then
/// `window_half_mm` is required, the user's confirmation that the axis may move that far
/// either side of where it stands; the identification then runs from Disabled.
pub fn identify<T: Transport>(
    c: &mut Client<T>,
    axes: &[usize],
    accept: bool,
    window_half_mm: Option<f32>,
) -> Result<Vec<IdentifyJson>> {
    let mut out = Vec::new();
    for &i in axes {
        let window_mm = driven_window(c, i, window_half_mm, "identify")?;
        expect_done(
            &format!("identify {}", AXES[i]),
            c.exec(Request::Identify {
                axis: i as u8,
                window_mm,
            })?,
        )?;
        let s = wait_with_progress(
            c,
            MachineState::Identify,
            &format!("identifying {}", AXES[i]),
        )?;
        let m: Option<IdentifyMsg> = s.identify.filter(|m| usize::from(m.axis) == i);
        let done = m.is_some_and(|m| m.done);
        let mut accepted = false;
        if done && accept {
            // the model changes the law: only with the outputs off
            if c.status()?.state != MachineState::Disabled {
                expect_done("disarm", c.exec(Request::Disarm)?)?;
                wait_while(c, |s| s.state == MachineState::Stopping)?;
            }
            expect_done(
                "accept",
                c.exec(Request::AcceptIdentified { axis: i as u8 })?,
            )?;
            accepted = true;
        }
        let model = m.and_then(|m| m.model);
        out.push(IdentifyJson {
            axis: AXES[i].into(),
            status: if done {
                "done".into()
            } else {
                format!("failed ({:?}, {})", s.state, fault_text(&s))
            },
            j: model.map(|m| m.inertia),
            b: model.map(|m| m.viscous),
            f_pos: model.map(|m| m.coulomb_pos_mnm),
            f_neg: model.map(|m| m.coulomb_neg_mnm),
            nrmse: m.map_or(0.0, |m| m.nrmse),
            r2: m.map_or(0.0, |m| m.r2),
            machine_time_s: m.map_or(0.0, |m| m.time_s),
            accepted,
        });
        if !done {
            break;
        }
    }
    Ok(out)
}

/// Where axis `i` may move while it is driven alone (`gantry identify`, `gantry
/// freqresp`; `what` names the command in errors). A machine whose axes have no model
/// cannot arm, hence cannot home: then `window_half_mm` is required, the user's
/// confirmation that the axis may move that far either side of where it stands, and the
/// run starts from Disabled. Homed, the axis is moved to the middle of its travel first
/// (`None`: the machine's own travel limits the run).
pub fn driven_window<T: Transport>(
    c: &mut Client<T>,
    i: usize,
    window_half_mm: Option<f32>,
    what: &str,
) -> Result<Option<[f32; 2]>> {
    let s = c.status()?;
    if s.model_missing != 0 || s.homed & (1 << i) == 0 && window_half_mm.is_some() {
        let Some(w) = window_half_mm else {
            bail!(
                "axis {} cannot be homed before it has a model (nothing can arm): give \
                 --window-mm W to {what} it within ±W mm of where it stands",
                AXES[i]
            );
        };
        if !(w.is_finite() && w > 0.0) {
            bail!("--window-mm must be a positive number of mm (the half-width of the travel `gantry {what}` may use), got {w}");
        }
        if s.state == MachineState::Idle {
            expect_done("disarm", c.exec(Request::Disarm)?)?;
        }
        let at = c.status()?.pos_mm[i];
        return Ok(Some([at - w, at + w]));
    }
    // homed: around the middle of the travel, where it has room
    let s = ready(c, true)?;
    let key = |end: &str| format!("axis.{}.travel.{end}", AXES[i]);
    let (lo, hi) = (get_f64(c, &key("min_mm"))?, get_f64(c, &key("max_mm"))?);
    if lo.is_finite() && hi.is_finite() {
        let mut target = s.pos_mm;
        target[i] = (0.5 * (lo + hi)) as f32;
        move_to(c, target)?;
    }
    Ok(None)
}

/// Every setting the machine has (a key whose value is absent, e.g. the model of an axis
/// that has none, is left out), as `key → text`, in the order of the settings keys.
pub fn read_settings<T: Transport>(c: &mut Client<T>) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for k in controller_core::settings::keys::keys() {
        if let Ok(v) = get(c, k.name) {
            out.push((k.name.to_string(), v));
        }
    }
    Ok(out)
}

/// `gantry settings export`: the settings as a TOML table of dotted keys (numbers and
/// booleans as TOML values, choices as strings).
pub fn export_toml(settings: &[(String, String)]) -> String {
    let mut t = toml::Table::new();
    for (k, v) in settings {
        let value = if let Ok(b) = v.parse::<bool>() {
            toml::Value::Boolean(b)
        } else if let Ok(i) = v.parse::<i64>() {
            toml::Value::Integer(i)
        } else if let Ok(f) = v.parse::<f64>() {
            toml::Value::Float(f)
        } else {
            toml::Value::String(v.clone())
        };
        t.insert(k.clone(), value);
    }
    let mut s = String::from(
        "# gantry settings (gantry settings export); import with gantry settings import\n",
    );
    s.push_str(&toml::to_string(&t).unwrap_or_default());
    s
}

/// The `key → text` pairs of a settings file: a table of dotted keys, nested tables
/// flattened (`[axis.x] following_error_mm = 0.8` is `axis.x.following_error_mm`).
pub fn parse_settings_toml(name: &str, text: &str) -> Result<Vec<(String, String)>> {
    let table: toml::Table = text
        .parse()
        .with_context(|| format!("{name}: not a TOML table"))?;
    let mut out = Vec::new();
    fn walk(
        prefix: &str,
        t: &toml::Table,
        out: &mut Vec<(String, String)>,
        name: &str,
    ) -> Result<()> {
        for (k, v) in t {
            let key = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match v {
                toml::Value::Table(inner) => walk(&key, inner, out, name)?,
                toml::Value::String(s) => out.push((key, s.clone())),
                toml::Value::Integer(i) => out.push((key, i.to_string())),
                toml::Value::Float(f) => out.push((key, f.to_string())),
                toml::Value::Boolean(b) => out.push((key, b.to_string())),
                other => bail!("{name}: {key}: {} is not a setting value", other.type_str()),
            }
        }
        Ok(())
    }
    walk("", &table, &mut out, name)?;
    Ok(out)
}

/// The changes of `gantry settings set`: `KEY VALUE`, or any number of `KEY=VALUE`.
pub fn parse_set_args(args: &[String]) -> Result<Vec<(String, String)>> {
    if let [key, value] = args {
        if !key.contains('=') {
            return Ok(vec![(key.clone(), value.clone())]);
        }
    }
    args.iter()
        .map(|a| match a.split_once('=') {
            Some((k, v)) if !k.is_empty() => Ok((k.trim().to_string(), v.trim().to_string())),
            _ => bail!("settings set: expected KEY VALUE or KEY=VALUE ..., got `{a}`"),
        })
        .collect()
}

/// Apply `changes` (key, value text) as one transaction: `SettingsBegin`, a `SettingSet`
/// each (type and range checked by the machine's link side as they come), `SettingsCommit`
/// (the tree validated whole and swapped in at a period boundary). All or nothing: on a
/// refusal the transaction is aborted and the machine's settings are as before; the error
/// is the machine's, naming the key and why.
pub fn apply_settings<T: Transport>(c: &mut Client<T>, changes: &[(String, String)]) -> Result<()> {
    expect_done("settings begin", c.exec(Request::SettingsBegin)?)?;
    for (k, v) in changes {
        let sent = heapless::String::try_from(k.as_str())
            .map_err(|_| anyhow::anyhow!("key too long: {k}"))
            .and_then(|key| {
                let value = heapless::String::try_from(v.as_str())
                    .map_err(|_| anyhow::anyhow!("{k}: value too long: {v}"))?;
                Ok(Request::SettingSet { key, value })
            });
        let outcome = match sent {
            Ok(r) => c.exec(r)?,
            Err(e) => {
                expect_done("settings abort", c.exec(Request::SettingsAbort)?)?;
                return Err(e);
            }
        };
        match outcome {
            Outcome::Done => {}
            Outcome::Refused(why) => {
                expect_done("settings abort", c.exec(Request::SettingsAbort)?)?;
                bail!("{why}");
            }
            other => {
                expect_done("settings abort", c.exec(Request::SettingsAbort)?)?;
                bail!("unexpected answer to settings set {k}: {other:?}");
            }
        }
    }
    match c.exec(Request::SettingsCommit)? {
        Outcome::Done => Ok(()),
        Outcome::Refused(why) => bail!("{why}"),
        other => bail!("unexpected answer to settings commit: {other:?}"),
    }
}

/// `gantry settings import FILE`: every value of the file is checked against the
/// machine's current settings first, together (types, ranges, the whole tree at the
/// machine's rate), so a bad file is reported before anything is sent; then the changed
/// keys are applied as one transaction ([`apply_settings`]), which the machine checks
/// again and takes all or nothing. Returns the keys changed.
pub fn import_settings<T: Transport>(
    c: &mut Client<T>,
    changes: &[(String, String)],
    rate_hz: u32,
) -> Result<Vec<String>> {
    use controller_core::settings::{keys::find, FACTORY};
    // the machine's tree, rebuilt from its values
    let current = read_settings(c)?;
    let mut tree = FACTORY;
    let parsed: Vec<(&str, controller_core::settings::Value)> = current
        .iter()
        .map(|(k, v)| {
            Ok((
                k.as_str(),
                find(k)
                    .map_err(|e| anyhow::anyhow!("{e}"))?
                    .parse(v)
                    .map_err(|e| anyhow::anyhow!("{e}"))?,
            ))
        })
        .collect::<Result<_>>()?;
    tree.set_all(&parsed, rate_hz)
        .map_err(|e| anyhow::anyhow!("the machine's own settings do not validate: {e}"))?;
    let before = tree;
    for (k, v) in changes {
        tree.stage_text(k, v)
            .map_err(|e| anyhow::anyhow!("import rejected, nothing changed: {e}"))?;
    }
    tree.validate_change(&before, rate_hz)
        .map_err(|e| anyhow::anyhow!("import rejected, nothing changed: {e}"))?;
    let changed: Vec<(String, String)> = changes
        .iter()
        .filter(|(k, _)| {
            let old = before.get(k).ok().map(|x| x.to_string());
            let new = tree.get(k).ok().map(|x| x.to_string());
            old != new
        })
        .cloned()
        .collect();
    if !changed.is_empty() {
        apply_settings(c, &changed)
            .map_err(|e| anyhow::anyhow!("import rejected by the machine, nothing changed: {e}"))?;
    }
    Ok(changed.into_iter().map(|(k, _)| k).collect())
}
