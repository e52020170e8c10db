//! `gantry`: command a machine over the host link. `--sim` runs the machine's supervisor,
//! planner and servo step in-process against the simulated physical gantry; `--qemu`
//! boots the firmware's QEMU build in its link rig and talks to it over its emulated
//! USART2 (one machine per invocation either way: it powers up at the work origin,
//! unhomed, disarmed); `--port DEV` talks to a board over its UART. See the README ("The gantry CLI") and docs/link-protocol.md.

use anyhow::{bail, Context, Result};

/// The simulated machine's control rate (host-sim/scenarios/gcode.toml), Hz.
const CONTROL_RATE_HZ: u32 = 10_000;
/// Largest settings file `settings import` reads (an export is a few KiB).
const SETTINGS_FILE_MAX_BYTES: u64 = 1 << 20;
use clap::{ArgGroup, Parser, Subcommand};
use controller_core::machine::messages::{MachineState, Request, Status};
use controller_core::machine::scope::ScopeConfig;
use host_sim::cli::client::{expect_done, Client};
use host_sim::cli::port::BoardPort;
use host_sim::cli::qemu::{QemuMachine, DEFAULT_ELF};
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self, Hold, Transport, AXES};
use host_sim::output::report::write_json;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "gantry", about = "Command a gantry over the host link")]
#[command(group(ArgGroup::new("machine").required(true).args(["sim", "qemu", "port", "twin"])))]
struct Cli {
    /// The simulated gantry in-process.
    #[arg(long)]
    sim: bool,
    /// The firmware's QEMU build (its link rig: the simulated gantry behind the real
    /// firmware's USART2 link), booted on qemu-system-arm.
    #[arg(long)]
    qemu: bool,
    /// A board: its UART's device (921,600 baud 8N1), e.g. /dev/ttyACM0.
    #[arg(long, value_name = "DEV")]
    port: Option<String>,
    /// The board twin: the release firmware ELF on the emulated STM32F407, serving its
    /// USART2 at PTY (`firmware/twin/run --serve PTY`); timeouts count its machine clock.
    #[arg(long, value_name = "PTY")]
    twin: Option<String>,
    /// The firmware ELF for --qemu (default: what `cargo fw-qemu-build` builds).
    #[arg(long, requires = "qemu")]
    elf: Option<PathBuf>,
    /// Start the simulated machine with factory settings (no axis model: identify first).
    #[arg(long, requires = "sim")]
    factory: bool,
    /// Telemetry rate of the session, Hz (1-10000).
    #[arg(long, default_value_t = 1000)]
    telemetry_hz: u32,
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// The machine's status.
    Status {
        #[arg(long)]
        json: bool,
    },
    /// Telemetry to a CSV file for a while of machine time (one row per sample: period,
    /// state, position, reference, reference velocity and acceleration, contour, feed
    /// ratio, segment tag).
    Log {
        out: PathBuf,
        #[arg(long, default_value_t = 1.0, value_parser = cli::args::duration_s)]
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
        #[arg(long, default_value_t = 10.0, value_parser = cli::args::duration_s)]
        timeout_s: f32,
        /// No figure.
        #[arg(long)]
        no_plot: bool,
    },
    /// Latched faults.
    Faults {
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
        axis: String,
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        vel_mm_s: f32,
        #[arg(long, default_value_t = 1.0, value_parser = cli::args::duration_s)]
        seconds: f32,
    },
    /// Move to a point (machine mm) at the rapid rate, homing and arming first; refused
    /// before anything moves when the point is outside the travel.
    Move {
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        x_mm: f32,
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        y_mm: f32,
        #[arg(allow_negative_numbers = true, value_parser = cli::args::finite)]
        z_mm: f32,
    },
    /// Run a G-code program (homes and arms first); prints the `cargo sim gcode` keys.
    Run {
        file: PathBuf,
        /// Write the report as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Feed hold after this many seconds of machine time...
        #[arg(long, value_parser = cli::args::instant_s)]
        hold_at_s: Option<f32>,
        /// ...and resume this long after it.
        #[arg(long, default_value_t = 0.5, value_parser = cli::args::duration_s)]
        hold_for_s: f32,
    },
    /// Identify axes (x, y, z or all); --accept stores the models in the settings.
    Identify {
        #[arg(long)]
        axis: String,
        #[arg(long)]
        accept: bool,
        /// Identify unhomed axes within ± this many mm of where they stand (needed while
        /// the machine has no model and so cannot arm to home).
        #[arg(long)]
        window_mm: Option<f32>,
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Settings: list, get KEY, set KEY VALUE | set KEY=VALUE..., defaults, save, repair,
    /// export FILE, import FILE.
    Settings {
        #[command(subcommand)]
        op: SettingsOp,
    },
}

#[derive(Subcommand)]
enum SettingsOp {
    List,
    Get {
        key: String,
    },
    /// `set KEY VALUE`, or `set KEY=VALUE KEY=VALUE ...`: several keys applied as one
    /// change, all or nothing (for keys only valid together).
    Set {
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
        file: PathBuf,
    },
    /// Apply a TOML file of settings: all checked together first, nothing changes when one
    /// is bad.
    Import {
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
    // (clap's `requires` counts the flag's default as given)
    if cli.elf.is_some() && !cli.qemu {
        bail!("--elf is the firmware for --qemu; it does nothing with --sim, --port or --twin");
    }
    if cli.factory && !cli.sim {
        bail!("--factory starts the simulated machine; it goes with --sim only");
    }
    if cli.telemetry_hz == 0 || cli.telemetry_hz > 10_000 {
        bail!(
            "--telemetry-hz must be within 1-10000, got {}",
            cli.telemetry_hz
        );
    }
    let models = if cli.factory {
        SimModels::Factory
    } else {
        SimModels::Designed
    };
    let decimation = 10_000 / cli.telemetry_hz;
    if let Some(pty) = &cli.twin {
        session(
            subscribed(BoardPort::open_twin(pty)?, decimation)?,
            cli.command,
            decimation,
        )
    } else if let Some(dev) = &cli.port {
        session(
            subscribed(BoardPort::open(dev)?, decimation)?,
            cli.command,
            decimation,
        )
    } else if cli.qemu {
        let elf = cli.elf.unwrap_or_else(|| PathBuf::from(DEFAULT_ELF));
        session(
            subscribed(QemuMachine::boot(&elf)?, decimation)?,
            cli.command,
            decimation,
        )
    } else {
        session(
            Client::connect(SimMachine::new(models, decimation)?)?,
            cli.command,
            decimation,
        )
    }
}

/// A session with the machine behind `t`, telemetry every `decimation` periods.
fn subscribed<T: Transport>(t: T, decimation: u32) -> Result<Client<T>> {
    let mut c = Client::connect(t)?;
    cli::subscribe(&mut c, decimation)?;
    Ok(c)
}

/// What the subcommand does with the machine behind `c`.
fn session<T: Transport>(mut c: Client<T>, command: Cmd, decimation: u32) -> Result<ExitCode> {
    match command {
        Cmd::Status { json } => {
            let s = c.status()?;
            if json {
                println!("{}", serde_json::to_string_pretty(&status_json(&s))?);
            } else {
                println!("{s:#?}");
            }
        }
        Cmd::Log {
            out,
            seconds,
            signals,
        } => {
            let names: Vec<String> = match &signals {
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
            let n = cli::log_telemetry(&mut c, &out, seconds, &names)?;
            println!("{n} samples written to {}", out.display());
        }
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
            let channels = cli::scope::parse_signals(&signals)?;
            let names: Vec<String> = signals
                .split(',')
                .map(|n| n.trim().to_string())
                .filter(|n| !n.is_empty())
                .collect();
            let cfg = ScopeConfig {
                channels: heapless::Vec::from_slice(&channels)
                    .map_err(|_| anyhow::anyhow!("--signals: at most 4"))?,
                samples,
                every_periods: every,
                pre_trigger: pre,
                trigger: cli::scope::parse_trigger(&trigger)?,
            };
            let period_s = f64::from(decimation) / f64::from(CONTROL_RATE_HZ);
            let cap = cli::scope::capture(&mut c, cfg, names, CONTROL_RATE_HZ, timeout_s, |c| {
                if let Some(file) = &run {
                    let r = cli::run_program(c, file, period_s, false, None)?;
                    eprint!("{}", host_sim::studies::gcode::table(&r));
                    if r.status != "completed" {
                        bail!("the program did not complete: {}", r.status);
                    }
                }
                Ok(())
            })?;
            cli::scope::write_csv(&out, &cap)?;
            println!("{} samples written to {}", cap.rows.len(), out.display());
            if !no_plot {
                let dir = out.parent().filter(|p| !p.as_os_str().is_empty());
                let dir = dir.unwrap_or(std::path::Path::new("."));
                let stem = out
                    .file_stem()
                    .map_or("scope".into(), |s| s.to_string_lossy().into_owned());
                host_sim::output::scope_plots::figure(dir, &stem, &cap)?;
                println!("figure: {}", dir.join(format!("{stem}.png")).display());
            }
        }
        Cmd::Faults { json } => {
            let s = c.status()?;
            let history: Vec<String> = s
                .fault_history
                .iter()
                .map(|f| {
                    let kind = f.kind().map_or("unknown", |k| k.name());
                    match f.axis() {
                        Some(a) => format!("{kind} on {}", a.name()),
                        None => kind.to_string(),
                    }
                })
                .collect();
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
        }
        Cmd::Arm => {
            expect_done("arm", c.exec(Request::Arm)?)?;
            println!("armed");
        }
        Cmd::Disarm => {
            expect_done("disarm", c.exec(Request::Disarm)?)?;
            println!("disarmed");
        }
        Cmd::Reset => {
            expect_done("reset", c.exec(Request::Reset)?)?;
            println!("reset");
        }
        Cmd::Home => {
            let s = cli::ready(&mut c, true)?;
            println!(
                "homed at x {:.3} y {:.3} z {:.3} mm",
                s.pos_mm[0], s.pos_mm[1], s.pos_mm[2]
            );
        }
        Cmd::Jog {
            axis,
            vel_mm_s,
            seconds,
        } => {
            let i = axis_index(&axis)?;
            cli::ready(&mut c, true)?;
            let ms = (seconds.max(0.0) * 1000.0) as u32;
            let mut t = 0;
            while t < ms {
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
            let s = cli::wait_while(&mut c, |s| s.state == MachineState::Jog)?;
            println!("{} at {:.3} mm ({:?})", AXES[i], s.pos_mm[i], s.state);
        }
        Cmd::Move { x_mm, y_mm, z_mm } => {
            cli::ready(&mut c, true)?;
            let s = cli::move_to(&mut c, [x_mm, y_mm, z_mm])?;
            println!(
                "at x {:.3} y {:.3} z {:.3} mm",
                s.pos_mm[0], s.pos_mm[1], s.pos_mm[2]
            );
        }
        Cmd::Run {
            file,
            json,
            hold_at_s,
            hold_for_s,
        } => {
            let hold = hold_at_s.map(|at_s| Hold {
                at_s,
                for_s: hold_for_s,
            });
            let progress = std::io::stderr().is_terminal();
            let period_s = f64::from(decimation) / 10_000.0;
            let r = cli::run_program(&mut c, &file, period_s, progress, hold)?;
            print!("{}", host_sim::studies::gcode::table(&r));
            if let Some(j) = json {
                write_json(&j, &r)?;
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
            return Ok(ExitCode::from(cli::run_exit_code(&r)));
        }
        Cmd::Identify {
            axis,
            accept,
            window_mm,
            json,
        } => {
            let axes: Vec<usize> = if axis.eq_ignore_ascii_case("all") {
                vec![0, 1, 2]
            } else {
                vec![axis_index(&axis)?]
            };
            let r = cli::identify(&mut c, &axes, accept, window_mm)?;
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
                write_json(&j, &r)?;
            }
            if r.iter().any(|a| a.status != "done") {
                return Ok(ExitCode::FAILURE);
            }
        }
        Cmd::Settings { op } => match op {
            SettingsOp::List => {
                for k in controller_core::settings::keys::keys() {
                    let v = cli::get(&mut c, k.name).unwrap_or_else(|_| "-".into());
                    println!("{:<36} {:>12} {:<10} {}", k.name, v, k.unit, k.doc);
                }
            }
            SettingsOp::Get { key } => println!("{}", cli::get(&mut c, &key)?),
            SettingsOp::Set { args } => {
                let changes = cli::parse_set_args(&args)?;
                if let [(key, value)] = &changes[..] {
                    cli::set(&mut c, key, value)?;
                } else {
                    cli::apply_settings(&mut c, &changes).map_err(|e| {
                        anyhow::anyhow!("settings set rejected, nothing changed: {e}")
                    })?;
                }
                for (key, _) in &changes {
                    println!("{key} = {}", cli::get(&mut c, key)?);
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
                let all = cli::read_settings(&mut c)?;
                std::fs::write(&file, cli::export_toml(&all))
                    .with_context(|| format!("cannot write {}", file.display()))?;
                println!("{} settings written to {}", all.len(), file.display());
            }
            SettingsOp::Import { file } => {
                let name = file.display().to_string();
                let text = gantry_scenario::file::read_regular(&file, SETTINGS_FILE_MAX_BYTES)
                    .map_err(anyhow::Error::msg)?;
                let changes = cli::parse_settings_toml(&name, &text)?;
                let changed = cli::import_settings(&mut c, &changes, CONTROL_RATE_HZ)?;
                println!("{} settings changed: {}", changed.len(), changed.join(", "));
            }
        },
    }
    Ok(ExitCode::SUCCESS)
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
        "pos_mm": s.pos_mm,
        "vel_mm_s": s.vel_mm_s,
        "first_fault": s.first_fault.as_deref(),
        "fault_bits": { "system": s.fault_bits.0, "axes": s.fault_bits.1 },
        "planner_free": s.planner_free,
        "queued": s.queued,
    })
}
