//! The window: its state (the session, what the machine told it, each panel's own state)
//! and one frame of it. Layout: the read-out and the machine's buttons across the top,
//! jog and program on the left, the messages at the bottom, and the tabs (tool path,
//! live plots, scope, settings, identification) in the middle.

use crate::live::Live;
use crate::panels;
use crate::session::{Command, Event, LoadedProgram, Session};
use host_sim::cli::machine::MachineArgs;
use std::collections::VecDeque;
use std::path::PathBuf;

/// Messages the log at the bottom keeps.
const LOG_LINES: usize = 200;

/// The central area's tabs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Tab {
    #[default]
    Path,
    Plots,
    Scope,
    Settings,
    Identify,
    Tune,
}

impl Tab {
    pub const ALL: [Tab; 6] = [
        Tab::Path,
        Tab::Plots,
        Tab::Scope,
        Tab::Settings,
        Tab::Identify,
        Tab::Tune,
    ];
    pub fn label(self) -> &'static str {
        match self {
            Tab::Path => "Tool path",
            Tab::Plots => "Live plots",
            Tab::Scope => "Scope",
            Tab::Settings => "Settings",
            Tab::Identify => "Identification",
            Tab::Tune => "Tuning",
        }
    }
}

/// What the window was started to do by itself (CI, screenshots, benchmarks).
#[derive(Clone, Debug, Default)]
pub struct Script {
    /// Load this program at start.
    pub program: Option<PathBuf>,
    /// Home, then run the loaded program.
    pub run: bool,
    /// Write a screenshot here, then close: when the program ended (with `run`), else
    /// after `after_s` seconds.
    pub screenshot: Option<PathBuf>,
    /// Seconds after start for the screenshot (or to close) without `run`.
    pub after_s: Option<f64>,
    /// Tab to show.
    pub tab: Tab,
    /// The process' exit status: 0, or 1 when the run did not complete, the session
    /// ended or the screenshot could not be written.
    pub exit_code: std::sync::Arc<std::sync::atomic::AtomicI32>,
}

/// The window's whole state.
pub struct GantryApp {
    pub args: MachineArgs,
    pub session: Option<Session>,
    pub live: Live,
    pub program: Option<LoadedProgram>,
    /// The command running, if any.
    pub busy: Option<String>,
    pub log: VecDeque<String>,
    pub tab: Tab,
    pub lost: Option<String>,
    pub connected: bool,
    pub controls: panels::controls::Controls,
    pub path_view: panels::path::PathView,
    pub plots: panels::plots::Plots,
    pub scope: panels::scope::ScopePanel,
    pub settings: panels::settings::SettingsPanel,
    pub identify: panels::identify::IdentifyPanel,
    pub tune: panels::tune::TunePanel,
    pub script: Script,
    pub script_state: crate::script::ScriptState,
    /// Program runs that ended (with or without a report).
    pub runs_ended: u32,
    /// The last run's report.
    pub report: Option<Box<host_sim::gcode::report::GcodeReport>>,
}

impl GantryApp {
    /// A window on the machine `args` names; `wake` repaints it (eframe's context).
    pub fn new(args: MachineArgs, script: Script, wake: impl Fn() + Send + Sync + 'static) -> Self {
        let session = Session::start(args.clone(), wake);
        Self::with_session(args, script, session)
    }

    /// A window on the session already started on the machine `args` names.
    pub fn with_session(args: MachineArgs, script: Script, session: Session) -> Self {
        let mut app = Self::detached(args, script);
        app.session = Some(session);
        if let Some(p) = app.script.program.clone() {
            app.controls.program_path = p.display().to_string();
            app.send(Command::Load(p));
        }
        app
    }

    /// A window with no session (nothing is sent anywhere): the frame benchmark's, which
    /// feeds `live` and `program` itself.
    pub fn detached(args: MachineArgs, script: Script) -> Self {
        Self {
            args,
            session: None,
            live: Live::default(),
            program: None,
            busy: None,
            log: VecDeque::new(),
            tab: script.tab,
            lost: None,
            connected: false,
            controls: Default::default(),
            path_view: Default::default(),
            plots: Default::default(),
            scope: Default::default(),
            settings: Default::default(),
            identify: Default::default(),
            tune: Default::default(),
            script,
            script_state: Default::default(),
            report: None,
            runs_ended: 0,
        }
    }

    /// Queue a command for the session.
    pub fn send(&mut self, c: Command) {
        if let Command::Run(_) = &c {
            self.live.clear_trail();
        }
        match &self.session {
            Some(s) => s.send(c),
            None => self.say("no session with the machine".into()),
        }
    }

    pub fn say(&mut self, line: String) {
        if self.log.len() >= LOG_LINES {
            self.log.pop_front();
        }
        self.log.push_back(line);
    }

    /// Take what the session sent since the last frame.
    pub fn poll(&mut self) {
        let Some(s) = &self.session else { return };
        self.live.drain(&s.tapped);
        let events: Vec<Event> = s.events.try_iter().collect();
        for e in events {
            self.on_event(e);
        }
    }

    fn on_event(&mut self, e: Event) {
        match e {
            Event::Connected {
                rate_hz,
                decimation,
            } => {
                self.connected = true;
                self.live.rate_hz = rate_hz;
                self.settings.rate_hz = rate_hz;
                self.live.decimation = decimation;
                self.say(format!(
                    "connected: control at {rate_hz} Hz, telemetry at {} Hz",
                    rate_hz / decimation.max(1)
                ));
                self.send(Command::ReadSettings);
            }
            Event::Started(what) => self.busy = Some(what),
            Event::Finished { what, result } => {
                self.busy = None;
                if what.starts_with("run ") {
                    self.runs_ended += 1;
                }
                match result {
                    Ok(t) if t.is_empty() => {}
                    Ok(t) => self.say(t),
                    Err(e) => self.say(format!("{what}: {e}")),
                }
            }
            Event::Program(p) => {
                self.path_view.fit = true;
                self.program = Some(*p);
            }
            Event::RunReport(r) => self.report = Some(r),
            Event::Settings(all) => self.settings.set_values(all),
            Event::Identified(r) => self.identify.results.extend(r),
            Event::Tuned(r) => self.tune.reports.push(*r),
            Event::Signals(names) => {
                // the samples kept carry the old signals' values: not to be drawn under
                // the new names
                if names != self.live.signals {
                    self.live.history.clear();
                }
                self.live.signals = names;
            }
            Event::Scope(cap) => self.scope.capture = Some(*cap),
            Event::Lost(why) => {
                self.say(format!("session ended: {why}"));
                self.lost = Some(why);
                self.busy = None;
            }
        }
    }

    /// Start a new session after the last one ended.
    pub fn reconnect(&mut self, wake: impl Fn() + Send + Sync + 'static) {
        self.session = None;
        self.lost = None;
        self.connected = false;
        self.session = Some(Session::start(self.args.clone(), wake));
    }

    /// One frame.
    pub fn frame(&mut self, ui: &mut egui::Ui) {
        self.poll();
        crate::script::step(self, ui.ctx());
        egui::Panel::top("machine").show(ui, |ui| panels::dro::show(self, ui));
        egui::Panel::bottom("log")
            .resizable(true)
            .default_size(90.0)
            .show(ui, |ui| panels::dro::log(self, ui));
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(270.0)
            .show(ui, |ui| panels::controls::show(self, ui));
        egui::CentralPanel::default().show(ui, |ui| {
            ui.horizontal(|ui| {
                for t in Tab::ALL {
                    ui.selectable_value(&mut self.tab, t, t.label());
                }
            });
            ui.separator();
            match self.tab {
                Tab::Path => panels::path::show(self, ui),
                Tab::Plots => panels::plots::show(self, ui),
                Tab::Scope => panels::scope::show(self, ui),
                Tab::Settings => panels::settings::show(self, ui),
                Tab::Identify => panels::identify::show(self, ui),
                Tab::Tune => panels::tune::show(self, ui),
            }
        });
        // live: repaint while the machine streams (the session also wakes the window)
        if self.connected && self.lost.is_none() {
            ui.ctx()
                .request_repaint_after(std::time::Duration::from_millis(16));
        }
    }
}

impl eframe::App for GantryApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.frame(ui);
    }
}
