//! `gantry`: command a machine over the host link. `--sim` runs the machine's supervisor,
//! planner and servo step in-process against the simulated physical gantry; `--qemu`
//! boots the firmware's QEMU build in its link rig and talks to it over its emulated
//! USART2 (one machine per invocation either way: it powers up at the work origin,
//! unhomed, disarmed); `--port DEV` talks to a board over its UART; `gantry sim serve PTY`
//! runs one simulated machine that stays, and `--served PTY` talks to it. See the README
//! ("The gantry CLI") and docs/link-protocol.md.

use anyhow::{bail, Context, Result};

/// Largest settings file `settings import` reads (an export is a few KiB).
const SETTINGS_FILE_MAX_BYTES: u64 = 1 << 20;
use clap::{Parser, Subcommand};
use controller_core::machine::messages::{MachineState, Request, Status};
use controller_core::machine::scope::ScopeConfig;
use host_sim::cli::client::{expect_done, Client};
use host_sim::cli::machine::MachineArgs;
use host_sim::cli::scope::Capture;
use host_sim::cli::serve::{ServeOptions, Speed};
use host_sim::cli::sim::SimModels;
use host_sim::cli::{self, view, Hold, Transport, AXES};
use host_sim::output::report::write_json;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "gantry",
    about = "Command a gantry over the host link",
    version
)]
struct Cli {
    #[command(flatten)]
    machine: MachineArgs,
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// The simulated gantry as a long-lived machine (no --sim/--qemu/--port/--served).
    Sim {
        #[command(subcommand)]
        op: SimOp,
    },
    /// The serial ports of this computer, a board's first (an ST-Link's virtual COM port,
    /// USB-UART adapters); no machine option. Example: `gantry ports`.
    Ports,
    /// Print a completion script for SHELL (bash, zsh, fish, elvish, powershell); no
    /// machine option. Example: `gantry completions bash > ~/.local/share/bash-completion/completions/gantry`.
    Completions {
        /// The shell the script is for.
        shell: clap_complete::Shell,
    },
    /// The machine's status on one screen, with units (state, position, velocity, feed,
    /// homing, faults, program). Example: `gantry --served /tmp/gantry status`.
    Status {
        /// Machine-readable: the status as JSON (keys documented in the README).
        #[arg(long)]
        json: bool,
    },
    /// A live one-line read-out (state, X Y Z mm, feed mm/min, program segment, fault),
    /// refreshed until Ctrl-C. Example: `gantry --served /tmp/gantry watch`.
    Watch {
        /// Stop after this much machine time, s.
        #[arg(long, allow_negative_numbers = true, value_parser = cli::args::duration_s)]
        seconds: Option<f32>,
        /// Read-outs per second of machine time (0.5-50).
        #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = cli::args::watch_hz)]
        hz: f32,
    },
    /// Telemetry to a CSV file for a while of machine time (one row per sample: period,
    /// state, position, reference, reference velocity and acceleration, contour, feed
    /// ratio, segment tag).
    Log {
        /// The CSV file to write, e.g. out/log.csv.
        out: PathBuf,
        /// Machine time to record, s.
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true, value_parser = cli::args::duration_s)]
        seconds: f32,
        /// Up to 4 more signals per sample, comma-separated (as `scope --signals`):
        /// columns after the fixed ones.
        #[arg(long)]
        signals: Option<String>,
    },
    /// Capture signals at the control rate with the machine's scope, to a CSV file (and
    /// OUT.png / OUT.svg beside it). Signals: pos, ref, vel, tracking, effort, sliding,
    /// ref_vel (.x .y .z), contour, feed_ratio.
    Scope {
        /// The CSV file to write (OUT.png and OUT.svg beside it), e.g. out/scope.csv.
        out: PathBuf,
        /// Up to 4 signals, comma-separated.
        #[arg(long, default_value = "pos.x,ref.x,tracking.x")]
        signals: String,
        /// Samples per signal (samples x signals <= 2048).
        #[arg(long, default_value_t = 500)]
        samples: u16,
        /// One sample every this many control periods.
        #[arg(long, default_value_t = 1)]
        every: u16,
        /// Samples kept from before the trigger.
        #[arg(long, default_value_t = 0)]
        pre: u16,
        /// now, fault, rising:SIGNAL:LEVEL or falling:SIGNAL:LEVEL.
        #[arg(long, default_value = "now")]
        trigger: String,
        /// Run this G-code program while the scope waits (homes and arms first).
        #[arg(long)]
        run: Option<PathBuf>,
        /// Give up when the capture is not complete after this much machine time, s.
        #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = cli::args::duration_s)]
        timeout_s: f32,
        /// No figure.
        #[arg(long)]
        no_plot: bool,
    },
    /// Latched faults.
    Faults {
        /// Machine-readable: `first`, `system_bits`, `axis_bits`, `history` as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Outputs on, holding.
    Arm,
    /// Outputs off.
    Disarm,
    /// Clear faults whose cause is gone.
    Reset,
    /// Arm and run the homing sequence.
    Home,
    /// Jog an axis at a speed for a time (homes first), then stop.
    Jog {
        /// x, y or z.
        axis: String,
        /// Speed, mm/s; negative toward the axis' minimum. Example: `gantry jog x -20`.
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        vel_mm_s: f32,
        /// How long to jog, s of machine time.
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true, value_parser = cli::args::duration_s)]
        seconds: f32,
    },
    /// Keyboard jog at a terminal (homes and arms first): arrows X/Y, PgUp/PgDn Z, `s`
    /// steps or continuous, `1`-`4` the step (0.01-10 mm) or speed (1-50 mm/s), `q` quits.
    /// Example: `gantry --served /tmp/gantry pendant`.
    Pendant,
    /// The operator's window (the `gantry-gui` program beside this one; `cargo gui` builds
    /// and runs it): read-out, jog pad, program with its tool path, live plots, scope,
    /// settings editor, identification. Example: `gantry --served /tmp/gantry gui`.
    Gui {
        /// Options passed on to `gantry-gui` (`gantry gui --help` lists them).
        #[arg(
            trailing_var_arg = true,
            allow_hyphen_values = true,
            value_name = "GUI OPTIONS"
        )]
        args: Vec<String>,
    },
    /// Move to a point (machine mm) at the rapid rate, homing and arming first; refused
    /// before anything moves when the point is outside the travel.
    Move {
        /// X, machine mm. Example: `gantry move -20 10 -5`.
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        x_mm: f32,
        /// Y, machine mm.
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        y_mm: f32,
        /// Z, machine mm.
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        z_mm: f32,
    },
    /// Run a G-code program (homes and arms first); prints the `cargo sim gcode` keys.
    Run {
        /// The G-code program, e.g. host-sim/programs/square.nc.
        file: PathBuf,
        /// Write the report as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Feed hold after this many seconds of machine time...
        #[arg(long, allow_negative_numbers = true, value_parser = cli::args::instant_s)]
        hold_at_s: Option<f32>,
        /// ...and resume this long after it.
        #[arg(long, default_value_t = 0.5, allow_negative_numbers = true, value_parser = cli::args::duration_s)]
        hold_for_s: f32,
    },
    /// Identify axes (x, y, z or all); --accept stores the models in the settings.
    Identify {
        /// x, y, z or all. Example: `gantry identify --axis all --window-mm 20 --accept`.
        #[arg(long)]
        axis: String,
        /// Store the identified models in the machine's settings (not saved: `settings
        /// save` keeps them for the next boot).
        #[arg(long)]
        accept: bool,
        /// Identify unhomed axes within ± this many mm of where they stand (needed while
        /// the machine has no model and so cannot arm to home).
        #[arg(long, allow_negative_numbers = true)]
        window_mm: Option<f32>,
        /// Write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Measure an axis' frequency response from effort to encoder (a stepped sine, 5-300
    /// Hz, within the identification's window and torque cap) and find its resonances and
    /// anti-resonances, as `cargo sim freqresp` does: a table, --json, Bode plots in --out.
    /// Example: `gantry --sim --machine host-sim/machines/gantry_flexible.toml freqresp y`.
    Freqresp {
        /// x, y or z.
        axis: String,
        /// Measure an unhomed axis within ± this many mm of where it stands (needed while
        /// the machine has no model and so cannot arm to home).
        #[arg(long, allow_negative_numbers = true)]
        window_mm: Option<f32>,
        /// The JSON (`cargo sim freqresp --json`'s keys) and the Bode plot.
        #[command(flatten)]
        output: host_sim::output::freqresp_plots::FreqRespOutput,
    },
    /// Tune an axis in one go: identify it (the model is accepted), measure its frequency
    /// response, take a rapid stop as the reference, set the friction feed-forward and an
    /// input shaper at the strongest resonance, measure the loop on the laws and keep the
    /// notches placed from it only on its measured margins (6 dB, 30°), take the stop
    /// again; put everything back when the stop rings more than before. Nothing is saved
    /// (`settings save`).
    /// Example: `gantry --sim --machine host-sim/machines/gantry_flexible.toml tune x`.
    Tune {
        /// x, y or z.
        axis: String,
        /// As `identify --window-mm`: needed while the machine has no model.
        #[arg(long, allow_negative_numbers = true)]
        window_mm: Option<f32>,
        /// The law's closed-loop bandwidth to set (`axis.<a>.law.bandwidth_rad_s`); the
        /// machine's when absent.
        #[arg(long, allow_negative_numbers = true)]
        bandwidth_rad_s: Option<f32>,
        /// auto (mzv, else zv: what fits the shaper's history), none, or a kind: zv, mzv,
        /// zvd, ei, 2hump_ei, 3hump_ei.
        #[arg(long, default_value = "auto")]
        shaper: String,
        /// Measure (the loop too, with the notches' prediction) and report; change no
        /// setting and run no stop.
        #[arg(long)]
        dry_run: bool,
        /// Write the report as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Where the stop's program and the loop's Bode plot (`loop_<axis>.png`, `.svg`) go.
        #[arg(long, default_value = "out/tune")]
        out: PathBuf,
    },
    /// Settings: list, get KEY, set KEY VALUE | set KEY=VALUE..., defaults, save, repair,
    /// export FILE, import FILE.
    Settings {
        #[command(subcommand)]
        op: SettingsOp,
    },
    /// Backlash and lead-screw compensation (LinuxCNC COMP_FILE and BACKLASH): load AXIS
    /// FILE, show AXIS, clear AXIS. Kept by the machine until its next boot (load it each
    /// session); applies to referenced axes.
    Comp {
        #[command(subcommand)]
        op: CompOp,
    },
}

#[derive(Subcommand)]
enum CompOp {
    /// Read a compensation file, check it, enter it on the machine (outputs off: disarm
    /// first) and read it back. Example: `gantry comp load y comp_y.txt --backlash-mm
    /// 0.02`.
    Load {
        /// x, y or z.
        axis: String,
        /// One point per line: `nominal forward reverse` (mm, nominal increasing, at most
        /// 256 points; `#` and `;` start comments).
        file: PathBuf,
        /// LinuxCNC's COMP_FILE_TYPE: 0 the columns are the positions measured at the
        /// tool, 1 they are the trims to add.
        #[arg(long, default_value_t = 0)]
        file_type: u32,
        /// Backlash added as +-half by direction, mm (0-1).
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = cli::args::finite)]
        backlash_mm: f32,
        /// Fastest change of the applied offset, mm/s.
        #[arg(long, default_value_t = controller_core::motion::compensation::DEFAULT_COMP_RATE_MM_S, allow_negative_numbers = true, value_parser = cli::args::finite)]
        rate_mm_s: f32,
        /// Its acceleration, mm/s².
        #[arg(long, default_value_t = controller_core::motion::compensation::DEFAULT_COMP_ACCEL_MM_S2, allow_negative_numbers = true, value_parser = cli::args::finite)]
        accel_mm_s2: f32,
    },
    /// The compensation an axis uses, as a COMP_FILE_TYPE 1 file (trims) or JSON.
    Show {
        /// x, y or z.
        axis: String,
        /// Machine-readable: `axis`, `backlash_mm`, `rate_mm_s`, `accel_mm_s2`, `points`
        /// (`[nominal, forward trim, reverse trim]` mm each).
        #[arg(long)]
        json: bool,
    },
    /// Remove an axis' compensation (outputs off).
    Clear {
        /// x, y or z.
        axis: String,
    },
}

#[derive(Subcommand)]
enum SimOp {
    /// Run one simulated machine behind a pseudo-terminal at PTY until Ctrl-C, in real
    /// time: `gantry --served PTY …` commands then talk to the same machine, as to a
    /// board. Example: `gantry sim serve /tmp/gantry --flash gantry.flash &` then
    /// `gantry --served /tmp/gantry home`.
    Serve {
        /// Where the pseudo-terminal appears (a symlink to its /dev/pts device), e.g.
        /// /tmp/gantry.
        pty: PathBuf,
        /// Machine time per wall time: 1 is real time, 10 ten times faster, `max` as fast
        /// as this computer runs it.
        #[arg(long, default_value = "1", allow_negative_numbers = true)]
        speed: Speed,
        /// The machine's settings flash, kept in this file: loaded at power-on as a board
        /// loads its store, written at every `settings save`.
        #[arg(long, value_name = "FILE")]
        flash: Option<PathBuf>,
        /// Start with factory settings when the flash holds none (no axis model:
        /// identify first); otherwise the designed gantry's models are entered.
        #[arg(long)]
        factory: bool,
        /// Stop after this much machine time, s (default: until Ctrl-C or SIGTERM).
        #[arg(long, allow_negative_numbers = true, value_parser = cli::args::duration_s)]
        seconds: Option<f32>,
        /// The machine's axes from a machine file instead of the rigid gantry's, e.g.
        /// host-sim/machines/gantry_flexible.toml.
        #[arg(long, value_name = "FILE")]
        machine: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum SettingsOp {
    List,
    Get {
        /// A dotted key, e.g. axis.x.following_error_mm (`settings list` shows them all).
        key: String,
    },
    /// `set KEY VALUE`, or `set KEY=VALUE KEY=VALUE ...`: several keys applied as one
    /// change, all or nothing (for keys only valid together).
    Set {
        /// KEY VALUE, or KEY=VALUE KEY=VALUE ... Example: `settings set
        /// axis.x.motor.invert true`.
        #[arg(required = true, num_args = 1.., allow_hyphen_values = true)]
        args: Vec<String>,
    },
    Defaults,
    /// Store the settings the machine runs in its flash, for the next boot (outputs off:
    /// disarm first).
    Save,
    /// Erase the machine's settings store and write the settings it runs into it (outputs
    /// off: disarm first).
    Repair,
    /// Write every setting to a TOML file (dotted keys).
    Export {
        /// The TOML file to write, e.g. machine.toml.
        file: PathBuf,
    },
    /// Apply a TOML file of settings: all checked together first, nothing changes when one
    /// is bad.
    Import {
        /// A TOML file of dotted keys, as `settings export` writes it.
        file: PathBuf,
    },
}

fn axis_index(a: &str) -> Result<usize> {
    AXES.iter()
        .position(|n| n.eq_ignore_ascii_case(a))
        .ok_or_else(|| anyhow::anyhow!("axis must be x, y or z, got `{a}`"))
}

fn main() -> ExitCode {
    host_sim::closed_stdout::exit_quietly_on_closed_stdout();
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    if let Cmd::Sim { op } = cli.command {
        if cli.machine.any() {
            bail!("`gantry sim serve` runs a machine of its own: leave out --sim, --qemu, --port, --twin and --served");
        }
        let SimOp::Serve {
            pty,
            speed,
            flash,
            factory,
            seconds,
            machine,
        } = op;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let on_signal = stop.clone();
        ctrlc::set_handler(move || on_signal.store(true, std::sync::atomic::Ordering::Relaxed))
            .context("cannot handle Ctrl-C")?;
        let opts = ServeOptions {
            pty,
            speed,
            flash,
            models: if factory {
                SimModels::Factory
            } else {
                SimModels::Designed
            },
            machine,
            seconds: seconds.map(f64::from),
        };
        host_sim::cli::serve::serve(&opts, stop)?;
        return Ok(ExitCode::SUCCESS);
    }
    if matches!(cli.command, Cmd::Ports | Cmd::Completions { .. }) && cli.machine.any() {
        bail!("`gantry ports` and `gantry completions` talk to no machine: leave out --sim, --qemu, --port, --twin and --served");
    }
    if let Cmd::Gui { args } = &cli.command {
        return gui(&cli.machine, args);
    }
    match &cli.command {
        Cmd::Ports => {
            print!("{}", host_sim::cli::port::ports_text()?);
            return Ok(ExitCode::SUCCESS);
        }
        Cmd::Completions { shell } => {
            let mut cmd = <Cli as clap::CommandFactory>::command();
            let mut script = Vec::new();
            clap_complete::generate(*shell, &mut cmd, "gantry", &mut script);
            // (through print!: a reader that went away ends gantry quietly, status 141)
            print!("{}", String::from_utf8_lossy(&script));
            return Ok(ExitCode::SUCCESS);
        }
        _ => {}
    }
    host_sim::cli::interrupt::install()?;
    cli.machine.check()?;
    let c = cli.machine.open()?;
    let decimation = cli.machine.decimation(c.control_rate_hz());
    session(c, cli.command, decimation)
}

/// `gantry gui`: the `gantry-gui` program beside this one, with the machine options given
/// to gantry and the GUI's own; it replaces this process.
fn gui(machine: &MachineArgs, args: &[String]) -> Result<ExitCode> {
    use std::os::unix::process::CommandExt;
    let exe = std::env::current_exe().context("where gantry runs from")?;
    let gui = exe.with_file_name("gantry-gui");
    if !gui.is_file() {
        bail!(
            "{} is not built: `cargo build -p gantry-gui --release` builds it (or run `cargo gui …`)",
            gui.display()
        );
    }
    let err = std::process::Command::new(&gui)
        .args(machine.to_args())
        .args(args)
        .exec();
    bail!("cannot start {}: {err}", gui.display())
}

/// What the subcommand does with the machine behind `c`; then the session ends with a
/// goodbye (a served machine or a board stays as the command left it, with no `LinkLost`
/// fault), whether the command succeeded or not.
fn session<T: Transport>(mut c: Client<T>, command: Cmd, decimation: u32) -> Result<ExitCode> {
    let done = command_on(&mut c, command, decimation);
    let bye = c.goodbye();
    let code = done?;
    bye?;
    Ok(code)
}

/// What the subcommand does with the machine behind `c`.
fn command_on<T: Transport>(c: &mut Client<T>, command: Cmd, decimation: u32) -> Result<ExitCode> {
    match command {
        Cmd::Sim { .. } | Cmd::Ports | Cmd::Completions { .. } | Cmd::Gui { .. } => {
            bail!("`gantry sim serve`, `ports`, `completions` and `gui` take no session")
        }
        Cmd::Status { json } => status(c, json)?,
        Cmd::Watch { seconds, hz } => watch(c, seconds, hz)?,
        Cmd::Log {
            out,
            seconds,
            signals,
        } => log(c, &out, seconds, signals.as_deref(), decimation)?,
        Cmd::Scope {
            out,
            signals,
            samples,
            every,
            pre,
            trigger,
            run,
            timeout_s,
            no_plot,
        } => {
            let cfg = scope_config(&signals, samples, every, pre, &trigger)?;
            let cap = scope_capture(c, cfg, &signals, run.as_deref(), timeout_s, decimation)?;
            write_scope(&out, &cap, no_plot)?;
        }
        Cmd::Faults { json } => faults(c, json)?,
        // what is wrong and what to do, from the status, before the machine's own refusal
        Cmd::Arm => arm(c)?,
        Cmd::Disarm => disarm(c)?,
        Cmd::Reset => reset(c)?,
        Cmd::Home => home(c)?,
        Cmd::Jog {
            axis,
            vel_mm_s,
            seconds,
        } => jog(c, &axis, vel_mm_s, seconds)?,
        Cmd::Pendant => host_sim::cli::pendant::pendant(c)?,
        Cmd::Move { x_mm, y_mm, z_mm } => move_to(c, [x_mm, y_mm, z_mm])?,
        Cmd::Run {
            file,
            json,
            hold_at_s,
            hold_for_s,
        } => return run_file(c, &file, json.as_deref(), hold_at_s, hold_for_s, decimation),
        Cmd::Identify {
            axis,
            accept,
            window_mm,
            json,
        } => return identify(c, &axis, accept, window_mm, json.as_deref()),
        Cmd::Tune {
            axis,
            window_mm,
            bandwidth_rad_s,
            shaper,
            dry_run,
            json,
            out,
        } => {
            let o = cli::tune::TuneOptions {
                axis: axis_index(&axis)?,
                window_half_mm: window_mm,
                bandwidth_rad_s,
                shaper: cli::tune::ShaperChoice::parse(&shaper)?,
                dry_run,
                telemetry_period_s: f64::from(decimation) / f64::from(c.control_rate_hz()),
            };
            let r = cli::tune::tune(c, &o, &out)?;
            print!("{}", cli::tune::table(&r));
            std::fs::create_dir_all(&out)?;
            let n = host_sim::output::loop_plots::tune_figures(&out, &r)?;
            if n > 0 {
                println!("the loop's Bode plot (PNG + SVG) in {}", out.display());
            }
            if let Some(j) = json {
                write_json(&j, &r)?;
            }
            return Ok(if r.applied() || dry_run {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            });
        }
        Cmd::Freqresp {
            axis,
            window_mm,
            output,
        } => return freqresp(c, &axis, window_mm, &output),
        Cmd::Settings { op } => settings(c, op)?,
        Cmd::Comp { op } => comp(c, op)?,
    }
    Ok(ExitCode::SUCCESS)
}

/// `gantry comp`.
fn comp<T: Transport>(c: &mut Client<T>, op: CompOp) -> Result<()> {
    use controller_core::motion::compensation::AxisCompensation;
    use host_sim::comp_file::{self, CompFileType};
    match op {
        CompOp::Load {
            axis,
            file,
            file_type,
            backlash_mm,
            rate_mm_s,
            accel_mm_s2,
        } => {
            let a = axis_index(&axis)?;
            let kind = CompFileType::from_number(file_type)?;
            let pts = comp_file::read(&file, kind)?;
            // (the flags first: a refusal of theirs is not the file's)
            controller_core::motion::compensation::CompBuilder::begin(
                0,
                backlash_mm,
                rate_mm_s,
                accel_mm_s2,
            )
            .map_err(|e| anyhow::anyhow!("--backlash-mm, --rate-mm-s, --accel-mm-s2: {e}"))?;
            let table = AxisCompensation::with_limits(&pts, backlash_mm, rate_mm_s, accel_mm_s2)
                .map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?;
            cli::comp::load(c, a, &table)?;
            if let Some(w) = cli::comp::deflection_warning(c, a)? {
                eprintln!("warning: {w}");
            }
            println!(
                "comp {}: {} points and a backlash of {} mm in use (read back identical; kept until the machine's next boot)",
                AXES[a],
                table.len(),
                table.backlash_mm()
            );
        }
        CompOp::Show { axis, json } => {
            let a = axis_index(&axis)?;
            let m = cli::comp::read(c, a)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&cli::comp::json(a, &m))?);
            } else {
                print!("{}", cli::comp::text(a, &m));
            }
        }
        CompOp::Clear { axis } => {
            let a = axis_index(&axis)?;
            cli::comp::clear(c, a)?;
            println!("comp {}: none", AXES[a]);
        }
    }
    Ok(())
}

/// `gantry status`: the machine's status, as text or JSON.
fn status<T: Transport>(c: &mut Client<T>, json: bool) -> Result<()> {
    let s = c.status()?;
    if json {
        println!("{}", serde_json::to_string_pretty(&status_json(&s))?);
    } else {
        print!("{}", view::status_text(&s, c.control_rate_hz()));
    }
    Ok(())
}

/// `gantry watch`: the position line, `hz` times a second of machine time, for `seconds`
/// or until Ctrl-C.
fn watch<T: Transport>(c: &mut Client<T>, seconds: Option<f32>, hz: f32) -> Result<()> {
    let every_ms = (1000.0 / hz) as u32;
    let tty = std::io::stdout().is_terminal();
    let t0 = c.transport.now_ms();
    loop {
        let s = c.status()?;
        if tty {
            print!("\r{}\x1b[K", view::dro_line(&s));
            std::io::Write::flush(&mut std::io::stdout())?;
        } else {
            println!("{}", view::dro_line(&s));
        }
        let elapsed_s = f64::from(c.transport.now_ms().wrapping_sub(t0)) / 1000.0;
        if host_sim::cli::interrupt::requested()
            || seconds.is_some_and(|limit| elapsed_s >= f64::from(limit))
        {
            break;
        }
        c.sleep_ms(every_ms)?;
    }
    if tty {
        println!();
    }
    Ok(())
}

/// `gantry log`: telemetry (with the chosen `signals` after the fixed columns) to a CSV
/// file for `seconds` of machine time.
fn log<T: Transport>(
    c: &mut Client<T>,
    out: &Path,
    seconds: f32,
    signals: Option<&str>,
    decimation: u32,
) -> Result<()> {
    let names: Vec<String> = match signals {
        Some(list) => {
            let chosen = cli::scope::parse_signals(list)?;
            expect_done(
                "telemetry subscription",
                c.exec(Request::Subscribe {
                    every_periods: decimation,
                    signals: heapless::Vec::from_slice(&chosen)
                        .map_err(|_| anyhow::anyhow!("--signals: at most 4"))?,
                })?,
            )?;
            list.split(',')
                .map(|n| n.trim().to_string())
                .filter(|n| !n.is_empty())
                .collect()
        }
        None => Vec::new(),
    };
    let n = cli::log_telemetry(c, out, seconds, &names)?;
    println!("{n} samples written to {}", out.display());
    Ok(())
}

/// The scope's configuration from `gantry scope`'s words.
fn scope_config(
    signals: &str,
    samples: u16,
    every: u16,
    pre: u16,
    trigger: &str,
) -> Result<ScopeConfig> {
    let channels = cli::scope::parse_signals(signals)?;
    let cfg = ScopeConfig {
        channels: heapless::Vec::from_slice(&channels)
            .map_err(|_| anyhow::anyhow!("--signals: at most 4"))?,
        samples,
        every_periods: every,
        pre_trigger: pre,
        trigger: cli::scope::parse_trigger(trigger)?,
    };
    Ok(cfg)
}

/// `gantry scope`: the capture of `cfg` (running the program `run` meanwhile, if any).
fn scope_capture<T: Transport>(
    c: &mut Client<T>,
    cfg: ScopeConfig,
    signals: &str,
    run: Option<&Path>,
    timeout_s: f32,
    decimation: u32,
) -> Result<Capture> {
    let names: Vec<String> = signals
        .split(',')
        .map(|n| n.trim().to_string())
        .filter(|n| !n.is_empty())
        .collect();
    let rate_hz = c.control_rate_hz();
    let period_s = f64::from(decimation) / f64::from(rate_hz);
    cli::scope::capture(c, cfg, names, rate_hz, timeout_s, |c| {
        if let Some(file) = run {
            let r = cli::run_program(c, file, period_s, false, None)?;
            eprint!("{}", host_sim::gcode::report::table(&r));
            if r.status != "completed" {
                bail!("the program did not complete: {}", r.status);
            }
        }
        Ok(())
    })
}

/// The capture to its CSV file, and its figure beside it unless `no_plot`.
fn write_scope(out: &Path, cap: &Capture, no_plot: bool) -> Result<()> {
    cli::scope::write_csv(out, cap)?;
    println!("{} samples written to {}", cap.rows.len(), out.display());
    if !no_plot {
        let dir = out.parent().filter(|p| !p.as_os_str().is_empty());
        let dir = dir.unwrap_or(std::path::Path::new("."));
        let stem = out
            .file_stem()
            .map_or("scope".into(), |s| s.to_string_lossy().into_owned());
        host_sim::output::scope_plots::figure(dir, &stem, cap)?;
        println!("figure: {}", dir.join(format!("{stem}.png")).display());
    }
    Ok(())
}

/// `gantry faults`: the latched faults and their history.
fn faults<T: Transport>(c: &mut Client<T>, json: bool) -> Result<()> {
    let s = c.status()?;
    let history = view::fault_history(&s);
    if json {
        let j = serde_json::json!({
            "first": s.first_fault.as_deref(),
            "system_bits": s.fault_bits.0,
            "axis_bits": s.fault_bits.1,
            "history": history,
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else {
        println!(
            "first fault: {}",
            s.first_fault.as_deref().unwrap_or("none")
        );
        println!(
            "history (oldest first, kept across resets): {}",
            if history.is_empty() {
                "none".into()
            } else {
                history.join(", ")
            }
        );
    }
    Ok(())
}

/// `gantry arm`: outputs on, holding (what is wrong and what to do when it cannot).
fn arm<T: Transport>(c: &mut Client<T>) -> Result<()> {
    let s = c.status()?;
    match s.state {
        MachineState::Disabled => {
            expect_done("arm", c.exec(Request::Arm)?)?;
            println!("armed: holding position");
        }
        MachineState::Fault => bail!(
            "cannot arm: a fault is latched ({}): `gantry reset` once its cause is gone",
            s.first_fault.as_deref().unwrap_or("unknown")
        ),
        MachineState::Stopping | MachineState::EncoderCheck => bail!(
            "cannot arm now: {}; try again when it is done",
            view::state_words(&s)
        ),
        _ => println!("already armed: {}", view::state_words(&s)),
    }
    Ok(())
}

/// `gantry disarm`: outputs off.
fn disarm<T: Transport>(c: &mut Client<T>) -> Result<()> {
    let s = c.status()?;
    if matches!(s.state, MachineState::Disabled | MachineState::Fault) {
        println!("already disarmed: {}", view::state_words(&s));
    } else {
        expect_done("disarm", c.exec(Request::Disarm)?)?;
        println!("disarmed: outputs off");
    }
    Ok(())
}

/// `gantry reset`: clear the faults whose cause is gone.
fn reset<T: Transport>(c: &mut Client<T>) -> Result<()> {
    let s = c.status()?;
    if s.state != MachineState::Fault {
        println!(
            "no fault latched: nothing to reset ({})",
            view::state_words(&s)
        );
    } else {
        expect_done("reset", c.exec(Request::Reset)?).map_err(|e| {
            anyhow::anyhow!(
                "{e} (latched: {}; `gantry status` shows what is still active)",
                s.first_fault.as_deref().unwrap_or("unknown")
            )
        })?;
        let after = cli::wait_while(c, |s| s.state == MachineState::EncoderCheck)?;
        println!("reset: {}", view::state_words(&after));
    }
    Ok(())
}

/// `gantry home`: arm and home.
fn home<T: Transport>(c: &mut Client<T>) -> Result<()> {
    let s = cli::ready(c, true)?;
    println!(
        "homed at x {:.3} y {:.3} z {:.3} mm",
        s.pos_mm[0], s.pos_mm[1], s.pos_mm[2]
    );
    Ok(())
}

/// `gantry jog`: one axis at `vel_mm_s` for `seconds` of machine time (or until Ctrl-C).
fn jog<T: Transport>(c: &mut Client<T>, axis: &str, vel_mm_s: f32, seconds: f32) -> Result<()> {
    let i = axis_index(axis)?;
    cli::ready(c, true)?;
    let ms = (seconds.max(0.0) * 1000.0) as u32;
    let mut t = 0;
    while t < ms && !host_sim::cli::interrupt::requested() {
        // jog requests keep coming, or the jog stops by itself (the timeout)
        let jog = Request::Jog {
            axis: i as u8,
            vel_mm_s,
        };
        expect_done("jog", c.exec(jog)?)?;
        c.sleep_ms(100)?;
        t += 100;
    }
    let stop = Request::Jog {
        axis: i as u8,
        vel_mm_s: 0.0,
    };
    expect_done("jog", c.exec(stop)?)?;
    let s = cli::wait_while(c, |s| s.state == MachineState::Jog)?;
    println!("{} at {:.3} mm ({:?})", AXES[i], s.pos_mm[i], s.state);
    Ok(())
}

/// `gantry move`: to a position in machine coordinates, mm.
fn move_to<T: Transport>(c: &mut Client<T>, target_mm: [f32; 3]) -> Result<()> {
    cli::ready(c, true)?;
    let s = cli::move_to(c, target_mm)?;
    println!(
        "at x {:.3} y {:.3} z {:.3} mm",
        s.pos_mm[0], s.pos_mm[1], s.pos_mm[2]
    );
    Ok(())
}

/// `gantry run FILE`: the program run on the machine and its report; the exit code says
/// how it ended.
fn run_file<T: Transport>(
    c: &mut Client<T>,
    file: &Path,
    json: Option<&Path>,
    hold_at_s: Option<f32>,
    hold_for_s: f32,
    decimation: u32,
) -> Result<ExitCode> {
    let hold = hold_at_s.map(|at_s| Hold {
        at_s,
        for_s: hold_for_s,
    });
    let progress = std::io::stderr().is_terminal();
    let period_s = f64::from(decimation) / f64::from(c.control_rate_hz());
    let r = cli::run_program(c, file, period_s, progress, hold)?;
    print!("{}", host_sim::gcode::report::table(&r));
    if let Some(j) = json {
        write_json(j, &r)?;
    }
    if !r.completed() {
        // the reason on stderr too: a script that reads only the exit status
        // still leaves the operator a line saying why
        eprintln!(
            "{}: not completed: {} (program_end {}, {} of {} segments executed)",
            file.display(),
            r.status,
            r.program_end,
            r.segments,
            r.segments_planned
        );
    }
    Ok(ExitCode::from(cli::run_exit_code(&r)))
}

/// `gantry identify`: identify `axis` (x, y, z or all), storing the models if `accept`.
fn identify<T: Transport>(
    c: &mut Client<T>,
    axis: &str,
    accept: bool,
    window_mm: Option<f32>,
    json: Option<&Path>,
) -> Result<ExitCode> {
    let axes: Vec<usize> = if axis.eq_ignore_ascii_case("all") {
        vec![0, 1, 2]
    } else {
        vec![axis_index(axis)?]
    };
    let r = cli::identify(c, &axes, accept, window_mm)?;
    for a in &r {
        println!(
            "{}: {}  J {}  B {}  f+ {}  f- {}  NRMSE {:.4}  R² {:.4}  {:.2} s{}",
            a.axis,
            a.status,
            fmt(a.j),
            fmt(a.b),
            fmt(a.f_pos),
            fmt(a.f_neg),
            a.nrmse,
            a.r2,
            a.machine_time_s,
            if a.accepted { "  (stored)" } else { "" }
        );
    }
    if let Some(j) = json {
        write_json(j, &r)?;
    }
    if r.iter().any(|a| a.status != "done") {
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

/// `gantry freqresp AXIS`: measure, print the table, write the JSON and the plot; fails
/// when the measurement did not finish.
fn freqresp<T: Transport>(
    c: &mut Client<T>,
    axis: &str,
    window_mm: Option<f32>,
    output: &host_sim::output::freqresp_plots::FreqRespOutput,
) -> Result<ExitCode> {
    let i = axis_index(axis)?;
    let r = cli::freqresp::measure(c, i, window_mm, "the machine over the link")?;
    print!("{}", host_sim::studies::freqresp::table(&r));
    output.write(&r)?;
    Ok(if r.all_done() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// `gantry settings …`: list, get, set, defaults, save, repair, export, import.
fn settings<T: Transport>(c: &mut Client<T>, op: SettingsOp) -> Result<()> {
    match op {
        SettingsOp::List => {
            for k in controller_core::settings::keys::keys() {
                let v = cli::get(c, k.name).unwrap_or_else(|_| "-".into());
                println!("{:<36} {:>12} {:<10} {}", k.name, v, k.unit, k.doc);
            }
        }
        SettingsOp::Get { key } => println!("{}", cli::get(c, &key)?),
        SettingsOp::Set { args } => {
            let changes = cli::parse_set_args(&args)?;
            if let [(key, value)] = &changes[..] {
                cli::set(c, key, value)?;
            } else {
                cli::apply_settings(c, &changes)
                    .map_err(|e| anyhow::anyhow!("settings set rejected, nothing changed: {e}"))?;
            }
            for (key, _) in &changes {
                println!("{key} = {}", cli::get(c, key)?);
            }
        }
        SettingsOp::Defaults => {
            expect_done("settings defaults", c.exec(Request::SettingsDefaults)?)?;
            println!("factory settings restored");
        }
        SettingsOp::Save => {
            expect_done("settings save", c.exec(Request::SettingsSave)?)?;
            println!("settings saved to the machine's flash (loaded at its next boot)");
        }
        SettingsOp::Repair => {
            expect_done("settings repair", c.exec(Request::SettingsRepair)?)?;
            println!("settings store erased and rewritten with the settings the machine runs");
        }
        SettingsOp::Export { file } => {
            let all = cli::read_settings(c)?;
            std::fs::write(&file, cli::export_toml(&all))
                .with_context(|| format!("cannot write {}", file.display()))?;
            println!("{} settings written to {}", all.len(), file.display());
        }
        SettingsOp::Import { file } => {
            let name = file.display().to_string();
            let text = gantry_scenario::file::read_regular(&file, SETTINGS_FILE_MAX_BYTES)
                .map_err(anyhow::Error::msg)?;
            let changes = cli::parse_settings_toml(&name, &text)?;
            let rate_hz = c.control_rate_hz();
            let changed = cli::import_settings(c, &changes, rate_hz)?;
            println!("{} settings changed: {}", changed.len(), changed.join(", "));
        }
    }
    Ok(())
}

fn fmt(v: Option<f32>) -> String {
    v.map_or("-".into(), |x| format!("{x:.4}"))
}

fn status_json(s: &Status) -> serde_json::Value {
    serde_json::json!({
        "state": format!("{:?}", s.state),
        "period": s.period,
        "homed": s.homed,
        "model_missing": s.model_missing,
        "comp": s.comp,
        "pos_mm": s.pos_mm,
        "vel_mm_s": s.vel_mm_s,
        "first_fault": s.first_fault.as_deref(),
        "fault_bits": { "system": s.fault_bits.0, "axes": s.fault_bits.1 },
        "planner_free": s.planner_free,
        "queued": s.queued,
    })
}
