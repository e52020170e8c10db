//! The session with the machine, on a thread of its own: it owns the link's [`Client`],
//! runs the window's commands one at a time with the same functions the `gantry` command
//! line runs (`ready`, `run_program_with`, `identify`, `scope::arm` and `read`, …), and keeps the
//! link serviced between them. The window never touches the link: it sends [`Command`]s,
//! reads [`Event`]s and the tapped status and telemetry, all through channels that never
//! block the session. A window that stalls (a slow frame, a dragged window) therefore
//! cannot stop the machine's heartbeat; only the session thread's own death can, and then
//! the machine's link watchdog stops it.
//!
//! Stopping is out of band: [`Operator::stop`] is the controlled stop Ctrl-C gives the
//! command line (the running command stops the machine on its path), and a running
//! program's hold, resume and abort go to its key channel, as `gantry run`'s keys do.

use anyhow::{anyhow, Result};
use controller_core::machine::messages::{MachineState, Request, Status, Telemetry};
use controller_core::machine::scope::{ScopeConfig, Signal};
use host_sim::cli::client::{expect_done, Client, Tapped};
use host_sim::cli::machine::{AnyTransport, MachineArgs};
use host_sim::cli::{self, interrupt, IdentifyJson, AXES};
use host_sim::gcode::program::load_program_with;
use host_sim::gcode::{Move, ParseOptions};
use std::path::PathBuf;
use std::sync::mpsc::{channel, Receiver, Sender, TryRecvError};
use std::time::{Duration, Instant};

/// How often the idle session reads the machine's status (the read-out's fault list,
/// homed axes, settings state come from it; position comes with every telemetry sample).
const STATUS_EVERY: Duration = Duration::from_millis(100);

/// The window is woken for new telemetry at most this often (60 frames/s: more would
/// draw frames no screen shows).
const FRAME_MIN: Duration = Duration::from_millis(16);

/// The signals every telemetry sample carries besides its fixed fields, by default: the
/// three axes' efforts (the law's output, N·m at the motor) and the contour error.
pub const DEFAULT_SIGNALS: [&str; 3] = ["effort.x", "effort.y", "effort.z"];

/// What the window asks of the machine.
#[derive(Clone, Debug)]
pub enum Command {
    Arm,
    Disarm,
    /// Reset a latched fault (refused by the machine while its cause is present).
    Reset,
    Home,
    /// Jog an axis at a speed (0 stops); the machine stops it by itself when no jog
    /// request came for its jog timeout, so a held button resends it.
    Jog {
        axis: usize,
        vel_mm_s: f32,
    },
    /// Move one axis by `step_mm` at the rapid rate (a one-segment program).
    Step {
        axis: usize,
        step_mm: f32,
    },
    /// Parse a program with the machine's offsets and travel, for its tool path.
    Load(PathBuf),
    /// Run a program (homing and arming first, as `gantry run` does).
    Run(PathBuf),
    /// Read every setting.
    ReadSettings,
    /// Change settings, one transaction (all or nothing).
    SetSettings(Vec<(String, String)>),
    /// Save the settings to the machine's flash.
    SaveSettings,
    /// Identify one axis; `window_mm` for an axis that has no model yet (its half-width
    /// of travel around where it stands).
    Identify {
        axis: usize,
        window_mm: Option<f32>,
        accept: bool,
    },
    /// Tune one axis (`gantry tune`): identify, measure, shape, verify; `window_mm` for
    /// an axis that has no model yet.
    Tune {
        axis: usize,
        window_mm: Option<f32>,
        shaper: host_sim::cli::tune::ShaperChoice,
    },
    /// Store the last identification's model of `axis` in the settings (not saved to
    /// flash): disarm first (a model changes the law), as `gantry identify --accept` does.
    Accept {
        axis: usize,
    },
    /// Choose the telemetry's signals (up to four names, `gantry scope --signals` names).
    Signals(Vec<String>),
    /// A scope capture (`gantry scope`'s), `timeout_s` of machine time; `run`: a program
    /// to run while the scope waits (`gantry scope --run`, homing and arming first).
    Scope {
        config: ScopeConfig,
        names: Vec<String>,
        timeout_s: f32,
        run: Option<PathBuf>,
    },
}

impl Command {
    /// What the window calls it while it runs.
    pub fn what(&self) -> String {
        match self {
            Self::Arm => "arm".into(),
            Self::Disarm => "disarm".into(),
            Self::Reset => "reset".into(),
            Self::Home => "home".into(),
            Self::Jog { axis, .. } => format!("jog {}", axis_name(*axis)),
            Self::Step { axis, step_mm } => format!("step {} {step_mm:+} mm", axis_name(*axis)),
            Self::Load(p) => format!("load {}", p.display()),
            Self::Run(p) => format!("run {}", p.display()),
            Self::ReadSettings => "read settings".into(),
            Self::SetSettings(_) => "settings set".into(),
            Self::SaveSettings => "settings save".into(),
            Self::Identify { axis, .. } => format!("identify {}", axis_name(*axis)),
            Self::Tune { axis, .. } => format!("tune {}", axis_name(*axis)),
            Self::Accept { axis } => format!("accept {}", axis_name(*axis)),
            Self::Signals(_) => "telemetry signals".into(),
            Self::Scope { .. } => "scope".into(),
        }
    }
}

fn axis_name(i: usize) -> &'static str {
    AXES.get(i).copied().unwrap_or("?")
}

/// A program as the window draws it.
#[derive(Clone, Debug)]
pub struct LoadedProgram {
    pub path: PathBuf,
    pub moves: Vec<Move>,
    /// Extent `[[min, max]; 3]` (machine mm).
    pub bounds_mm: [[f64; 2]; 3],
    /// Lines of the file.
    pub lines: usize,
}

/// What the session tells the window.
#[derive(Debug)]
pub enum Event {
    /// Connected: the machine's control rate and telemetry decimation.
    Connected {
        rate_hz: u32,
        decimation: u32,
    },
    /// A command started.
    Started(String),
    /// A command ended: what it was, and its result in words.
    Finished {
        what: String,
        result: Result<String, String>,
    },
    Program(Box<LoadedProgram>),
    /// A program's run ended: its report (the keys of `gantry run --json`).
    RunReport(Box<host_sim::gcode::report::GcodeReport>),
    Settings(Vec<(String, String)>),
    Identified(Vec<IdentifyJson>),
    /// A tuning ended (`gantry tune --json`'s keys).
    Tuned(Box<host_sim::cli::tune::TuneReport>),
    /// The telemetry's signal names, in their order in each sample.
    Signals(Vec<String>),
    Scope(Box<cli::scope::Capture>),
    /// The session ended (the link failed, or the machine went away).
    Lost(String),
}

/// The window's end of the session.
pub struct Session {
    pub commands: Sender<Command>,
    pub events: Receiver<Event>,
    pub tapped: Receiver<Tapped>,
    pub operator: Operator,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// Out-of-band operator actions, taken while a command runs.
#[derive(Clone)]
pub struct Operator {
    keys: Sender<char>,
}

impl Operator {
    /// A controlled stop of whatever moves (program, jog, homing, identification).
    pub fn stop(&self) {
        interrupt::request();
        let _ = self.keys.send('a');
    }
    /// Feed hold of the running program.
    pub fn hold(&self) {
        let _ = self.keys.send('h');
    }
    /// Resume the held program.
    pub fn resume(&self) {
        let _ = self.keys.send('r');
    }
}

impl Session {
    /// Connect to the machine `args` names on a thread of its own; `wake` is called
    /// whenever something arrived (the window repaints).
    pub fn start(args: MachineArgs, wake: impl Fn() + Send + Sync + 'static) -> Self {
        let (commands, cmd_rx) = channel();
        let (ev_tx, events) = channel();
        let (tap_tx, tapped) = channel();
        let (keys, key_rx) = channel();
        let thread = std::thread::Builder::new()
            .name("gantry-session".into())
            .spawn(move || {
                let wake = Waker::start(wake);
                let result = connect(&args).and_then(|mut c| {
                    serve(&mut c, &args, tap_tx, &cmd_rx, &key_rx, &ev_tx, &wake)
                });
                if let Err(e) = result {
                    let _ = ev_tx.send(Event::Lost(format!("{e:#}")));
                }
                wake.wake();
            })
            .expect("spawning the session thread"); // allow-panic: host GUI start-up
        Self {
            commands,
            events,
            tapped,
            operator: Operator { keys },
            thread: Some(thread),
        }
    }

    /// Send a command (after those queued).
    pub fn send(&self, c: Command) {
        let _ = self.commands.send(c);
    }
}

impl Drop for Session {
    /// The session ends with a goodbye (the machine stays as the window left it) once
    /// the command running has ended; a running program is stopped first.
    fn drop(&mut self) {
        // (dropping the command sender ends the session loop)
        let (dead, _) = channel();
        self.commands = dead;
        if let Some(t) = self.thread.take() {
            if !t.is_finished() {
                self.operator.stop();
            }
            let _ = t.join();
        }
    }
}

/// Wakes the window from the session without ever waiting for it: the window's wake
/// call (egui's `request_repaint`) takes the window's context lock, which a frame holds
/// while it is tessellated, hundreds of milliseconds on a loaded machine with software
/// OpenGL, longer than the machine's link watchdog. A thread of its own makes that call;
/// the session only leaves a note for it (a one-slot channel, never full for long).
struct Waker(std::sync::mpsc::SyncSender<()>);

impl Waker {
    fn start(wake: impl Fn() + Send + 'static) -> Self {
        let (tx, rx) = std::sync::mpsc::sync_channel::<()>(1);
        let spawned = std::thread::Builder::new()
            .name("gantry-wake".into())
            .spawn(move || {
                for () in rx {
                    wake();
                }
            });
        if spawned.is_err() {
            // (no waker: the window still repaints on its own timer)
            let (dead, _) = std::sync::mpsc::sync_channel(1);
            return Self(dead);
        }
        Self(tx)
    }

    /// Ask for a repaint; returns at once.
    fn wake(&self) {
        let _ = self.0.try_send(());
    }
}

fn connect(args: &MachineArgs) -> Result<Client<AnyTransport>> {
    args.open()
}

/// The session loop: commands as they come, the link serviced between them.
fn serve(
    c: &mut Client<AnyTransport>,
    args: &MachineArgs,
    tap: Sender<Tapped>,
    commands: &Receiver<Command>,
    keys: &Receiver<char>,
    events: &Sender<Event>,
    wake: &Waker,
) -> Result<()> {
    let rate_hz = c.control_rate_hz();
    let decimation = args.decimation(rate_hz);
    let mut signals: Vec<String> = DEFAULT_SIGNALS.iter().map(|s| s.to_string()).collect();
    subscribe(c, decimation, &signals)?;
    c.tap(tap);
    let _ = events.send(Event::Connected {
        rate_hz,
        decimation,
    });
    let _ = events.send(Event::Signals(signals.clone()));
    wake.wake();
    let mut last_status = Instant::now() - STATUS_EVERY;
    let mut scope: Option<PendingScope> = None;
    let mut last_wake = Instant::now();
    loop {
        match commands.try_recv() {
            Ok(cmd) => {
                interrupt::clear();
                while keys.try_recv().is_ok() {}
                let what = cmd.what();
                let _ = events.send(Event::Started(what.clone()));
                wake.wake();
                let result = execute(c, cmd, decimation, keys, events, &mut signals, &mut scope);
                // a link that failed ends the session; a refused command does not
                let result = match result {
                    Err(e) if is_link_failure(&e) => return Err(e),
                    r => r.map_err(|e| format!("{e:#}")),
                };
                interrupt::clear();
                let _ = events.send(Event::Finished { what, result });
                wake.wake();
                continue;
            }
            Err(TryRecvError::Disconnected) => break,
            Err(TryRecvError::Empty) => {}
        }
        c.pump()?;
        if last_status.elapsed() >= STATUS_EVERY {
            let st = c.status()?;
            last_status = Instant::now();
            if let Some(p) = scope.take() {
                scope = p.check(c, &st, events)?;
            }
        }
        // (the tap has them: the client's own copy is dropped)
        if !c.take_telemetry().is_empty() && last_wake.elapsed() >= FRAME_MIN {
            wake.wake();
            last_wake = Instant::now();
        }
        c.transport.wait()?;
    }
    c.goodbye()
}

/// A link failure (as opposed to a refusal): the session cannot go on.
fn is_link_failure(e: &anyhow::Error) -> bool {
    let t = format!("{e:#}");
    t.contains("link failed") || t.contains("serial port") || t.contains("no session")
}

/// Telemetry every `decimation` periods with `names` as its signals.
fn subscribe(c: &mut Client<AnyTransport>, decimation: u32, names: &[String]) -> Result<()> {
    let mut signals = heapless::Vec::new();
    for n in names {
        let s = Signal::from_name(n).ok_or_else(|| anyhow!("no signal named `{n}`"))?;
        signals
            .push(s)
            .map_err(|_| anyhow!("at most 4 telemetry signals, got {}", names.len()))?;
    }
    expect_done(
        "telemetry subscription",
        c.exec(Request::Subscribe {
            every_periods: decimation,
            signals,
        })?,
    )?;
    Ok(())
}

fn execute(
    c: &mut Client<AnyTransport>,
    cmd: Command,
    decimation: u32,
    keys: &Receiver<char>,
    events: &Sender<Event>,
    signals: &mut Vec<String>,
    scope: &mut Option<PendingScope>,
) -> Result<String> {
    let done = |c: &mut Client<AnyTransport>, what: &str, r: Request| -> Result<String> {
        expect_done(what, c.exec(r)?)?;
        Ok(format!("{what}: done"))
    };
    match cmd {
        Command::Arm => {
            let s = c.status()?;
            if s.state != MachineState::Disabled {
                return Ok(format!(
                    "already armed ({})",
                    host_sim::cli::view::state_words(&s)
                ));
            }
            done(c, "arm", Request::Arm)?;
            let s = cli::wait_while(c, |s| s.state == MachineState::EncoderCheck)?;
            Ok(format!("armed: {}", host_sim::cli::view::state_words(&s)))
        }
        Command::Disarm => done(c, "disarm", Request::Disarm),
        Command::Reset => done(c, "reset", Request::Reset),
        Command::Home => {
            cli::ready(c, false)?;
            expect_done("home", c.exec(Request::Home)?)?;
            let s = cli::wait_while(c, |s| s.state == MachineState::Homing)?;
            Ok(at("homed", &s))
        }
        Command::Jog { axis, vel_mm_s } => {
            cli::jog(c, axis, vel_mm_s)?;
            Ok(String::new())
        }
        Command::Step { axis, step_mm } => {
            let s = c.status()?;
            let mut target = s.pos_mm;
            target[axis.min(2)] += step_mm;
            let s = cli::move_to(c, target)?;
            Ok(at("moved", &s))
        }
        Command::Load(path) => {
            let travel = cli::travel(c)?;
            let (work_offsets_mm, tools) = cli::read_work_and_tools(c)?;
            let s = c.status()?;
            let options = ParseOptions {
                start_mm: s.pos_mm.map(f64::from),
                work_offsets_mm,
                tools,
                ..ParseOptions::default()
            };
            let p = c.while_busy(|| load_program_with(&path, &options, &travel))?;
            let p = p.map_err(|e| anyhow!("{e}"))?;
            let lines = std::fs::read_to_string(&path)
                .map(|t| t.lines().count())
                .unwrap_or(0);
            let summary = format!("{}: {} moves", path.display(), p.moves.len());
            let _ = events.send(Event::Program(Box::new(LoadedProgram {
                path,
                moves: p.moves,
                bounds_mm: p.bounds_mm,
                lines,
            })));
            Ok(summary)
        }
        Command::Run(path) => {
            let period_s = f64::from(decimation) / f64::from(c.control_rate_hz());
            let r = cli::run_program_with(c, &path, period_s, false, None, Some(keys))?;
            let text = format!(
                "{}: {} ({}), contour max {:.4} mm",
                path.display(),
                r.status,
                r.program_end,
                r.contour_max_mm
            );
            let _ = events.send(Event::RunReport(Box::new(r)));
            Ok(text)
        }
        Command::ReadSettings => {
            let all = cli::read_settings(c)?;
            let n = all.len();
            let _ = events.send(Event::Settings(all));
            Ok(format!("{n} settings read"))
        }
        Command::SetSettings(changes) => {
            cli::apply_settings(c, &changes)?;
            let all = cli::read_settings(c)?;
            let _ = events.send(Event::Settings(all));
            Ok(format!("{} setting(s) changed (not saved)", changes.len()))
        }
        Command::SaveSettings => {
            expect_done("settings save", c.exec(Request::SettingsSave)?)?;
            Ok("settings saved to the machine's flash".into())
        }
        Command::Identify {
            axis,
            window_mm,
            accept,
        } => {
            let r = cli::identify(c, &[axis], accept, window_mm)?;
            let text = r
                .iter()
                .map(|j| format!("{}: {}", j.axis, j.status))
                .collect::<Vec<_>>()
                .join(", ");
            let _ = events.send(Event::Identified(r));
            Ok(text)
        }
        Command::Tune {
            axis,
            window_mm,
            shaper,
        } => {
            let o = cli::tune::TuneOptions {
                axis,
                window_half_mm: window_mm,
                bandwidth_rad_s: None,
                shaper,
                dry_run: false,
                telemetry_period_s: f64::from(decimation) / f64::from(c.control_rate_hz()),
            };
            // (the stop's program is written beside the other temporary files)
            let out = std::env::temp_dir().join(format!("gantry-gui-tune-{}", std::process::id()));
            let r = cli::tune::tune(c, &o, &out)?;
            let text = format!("tune {}: {}", axis_name(axis), r.outcome);
            let _ = events.send(Event::Tuned(Box::new(r)));
            let all = cli::read_settings(c)?;
            let _ = events.send(Event::Settings(all));
            Ok(text)
        }
        Command::Accept { axis } => {
            // the model changes the law: only with the outputs off
            if c.status()?.state != MachineState::Disabled {
                expect_done("disarm", c.exec(Request::Disarm)?)?;
                cli::wait_while(c, |s| s.state == MachineState::Stopping)?;
            }
            expect_done(
                "accept",
                c.exec(Request::AcceptIdentified { axis: axis as u8 })?,
            )?;
            let all = cli::read_settings(c)?;
            let _ = events.send(Event::Settings(all));
            Ok(format!(
                "axis {}: the identified model is in the settings (not saved: Settings, Save to flash, keeps it)",
                axis_name(axis)
            ))
        }
        Command::Signals(names) => {
            subscribe(c, decimation, &names)?;
            *signals = names;
            let _ = events.send(Event::Signals(signals.clone()));
            Ok(format!("telemetry signals: {}", signals.join(", ")))
        }
        Command::Scope {
            config,
            names,
            timeout_s,
            run,
        } => {
            // armed, then the session goes on: the capture is read when the machine's
            // status says it is done, and meanwhile the operator can jog, run or stop
            // (what usually triggers it); `gantry scope --run`'s program runs here
            cli::scope::arm(c, config)?;
            if !(timeout_s > 0.0 && timeout_s <= 3600.0) {
                anyhow::bail!("the scope's timeout must be within (0, 3600] s, got {timeout_s}");
            }
            let armed_at = c.status()?.period;
            *scope = Some(PendingScope {
                names,
                armed_at,
                timeout_periods: (f64::from(timeout_s) * f64::from(c.control_rate_hz())) as u32,
            });
            if let Some(path) = &run {
                let period_s = f64::from(decimation) / f64::from(c.control_rate_hz());
                let r = cli::run_program_with(c, path, period_s, false, None, Some(keys))?;
                let text = format!("{}: {} ({})", path.display(), r.status, r.program_end);
                let _ = events.send(Event::RunReport(Box::new(r)));
                return Ok(format!("scope armed; {text}"));
            }
            Ok("scope armed: waiting for its trigger".into())
        }
    }
}

/// A scope capture armed and not read yet.
#[derive(Debug)]
pub struct PendingScope {
    names: Vec<String>,
    /// The machine's period when it was armed.
    armed_at: u32,
    timeout_periods: u32,
}

impl PendingScope {
    /// Read the capture once the machine says it is done (then `None`); say why it ended
    /// when the scope was disarmed or timed out; else keep waiting.
    fn check(
        self,
        c: &mut Client<AnyTransport>,
        st: &Status,
        events: &Sender<Event>,
    ) -> Result<Option<Self>> {
        use controller_core::machine::scope::ScopeState;
        let ended = |why: String| {
            let _ = events.send(Event::Finished {
                what: "scope".into(),
                result: Err(why),
            });
        };
        match st.scope {
            ScopeState::Done => {
                let rate_hz = c.control_rate_hz();
                let cap = cli::scope::read(c, self.names, rate_hz)?;
                let n = cap.rows.len();
                let _ = events.send(Event::Scope(Box::new(cap)));
                let _ = events.send(Event::Finished {
                    what: "scope".into(),
                    result: Ok(format!("scope: {n} samples read")),
                });
                Ok(None)
            }
            ScopeState::Off => {
                ended("the scope was disarmed".into());
                Ok(None)
            }
            _ if st.period.wrapping_sub(self.armed_at) > self.timeout_periods => {
                let what = if st.scope == ScopeState::Waiting {
                    "trigger"
                } else {
                    "complete"
                };
                ended(format!(
                    "the scope did not {what} within {:.1} s of machine time",
                    f64::from(self.timeout_periods) / f64::from(c.control_rate_hz())
                ));
                Ok(None)
            }
            _ => Ok(Some(self)),
        }
    }
}

fn at(what: &str, s: &Status) -> String {
    format!(
        "{what}: X {:.3} Y {:.3} Z {:.3} mm",
        s.pos_mm[0], s.pos_mm[1], s.pos_mm[2]
    )
}

/// The newest telemetry sample's time, s of machine time.
pub fn sample_time_s(t: &Telemetry, rate_hz: u32) -> f64 {
    f64::from(t.period) / f64::from(rate_hz.max(1))
}
