//! `host-sim`: the simulated gantry on a PC. With no subcommand it reproduces the
//! reference paper's Tables 1 and 3 and writes traces and plots (the main job); the
//! subcommands run the other studies, a G-code program on the simulated machine
//! (`gcode`), any scenario file, and the QEMU verdict.

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use host_sim::builtin;
use host_sim::output::report::{paper_tables, write_json, write_trace_csv};
use host_sim::output::{plots, seed_plots};
use host_sim::studies::{estimators, generic, machine_replay, paper, qemu_verdict, seeds};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(
    version,
    about = "Simulated gantry: runs controller-core against simulated machines",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Options of the default `paper` study (when no subcommand is given).
    #[command(flatten)]
    paper: PaperArgs,
}

#[derive(Args, Clone)]
struct PaperArgs {
    /// Paper study file (default: the built-in host-sim/scenarios/paper.toml).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Output folder for the figures (and the CSV traces with --traces).
    #[arg(long, default_value = "out/paper")]
    out: PathBuf,
    /// Also write the results as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Skip the figures (and the CSV traces).
    #[arg(long)]
    no_plots: bool,
    /// Also write one CSV trace per run (1 ms samples, about 3.5 MB each, 100 MB in all).
    #[arg(long, conflicts_with = "no_plots")]
    traces: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Reproduce the paper's Tables 1 and 3 (the default).
    Paper(PaperArgs),
    /// Run every run of a scenario file (e.g. host-sim/scenarios/helix_discrete_10khz.toml).
    Run {
        file: PathBuf,
        /// Output folder for CSV traces.
        #[arg(long, default_value = "out/run")]
        out: PathBuf,
        /// Also write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Skip CSV output.
        #[arg(long)]
        no_plots: bool,
    },
    /// Velocity sources (exact, backward difference, PLL, Kalman) x PID/SMC/DSMC on the
    /// paper helix, and x PID/DSMC/DOB-SMC on the physical gantry's helix
    /// (docs/velocity-estimation.md).
    Estimators {
        /// Add the paper's 10 s load disturbance on X (table 3) to the paper helix.
        #[arg(long)]
        disturbance: bool,
        /// Simulated time of the paper helix (s).
        #[arg(long, default_value_t = 15.0)]
        horizon_s: f64,
        /// Study file for the paper helix part (default: built-in estimators_paper.toml;
        /// --disturbance and --horizon-s apply to the built-in only).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Also write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// The seed methods (DOB-SMC, cross-coupling, adaptive friction SMC) on the physical
    /// gantry: host-sim/scenarios/seeds_*.toml (docs/seed-methods.md).
    Seeds {
        /// Output folder for the figures (and the CSV traces with --traces).
        #[arg(long, default_value = "out/seeds")]
        out: PathBuf,
        /// Also write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Skip the figures (and the CSV traces).
        #[arg(long)]
        no_plots: bool,
        /// Also write one CSV trace per run (about 20 MB in all).
        #[arg(long, conflicts_with = "no_plots")]
        traces: bool,
    },
    /// The fault matrix: every fault class injected into the simulated gantry through the
    /// real servo step (host-sim/scenarios/faults.toml); exits non-zero if a case misses
    /// its bounds.
    Faults {
        /// Study file (default: the built-in faults.toml).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Also write the matrix as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Identify every axis of a simulated machine through the servo step (it sees counts
    /// and its own effort only) and compare DSMC's contour with the true and the
    /// identified model (host-sim/scenarios/identify.toml, docs/identification.md).
    Identify {
        /// Machine file (default: the built-in physical gantry).
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Draw the machine's axes at random from the documented range with this seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Also write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Output folder for the plots.
        #[arg(long, default_value = "out/identify")]
        out: PathBuf,
        /// Skip the plots.
        #[arg(long)]
        no_plots: bool,
    },
    /// The ISO 230-4 circular test: circles of R 50 mm at 3000 mm/min and R 10 mm at
    /// 1000 mm/min, both directions, at the tool; circular deviation G, radius deviation D,
    /// reversal spikes, and each circle's polar plot (host-sim/scenarios/circle.toml,
    /// docs/precision.md).
    Circle {
        /// Machine file (default: the built-in physical gantry; e.g.
        /// host-sim/machines/gantry_flexible.toml).
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Also write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Enter the compensation tables of this folder (comp_x.txt, comp_y.txt,
        /// comp_z.txt: LinuxCNC COMP_FILEs of type 0, as `compensation --write` writes them).
        #[arg(long)]
        comp: Option<PathBuf>,
        /// Output folder for the polar plots.
        #[arg(long, default_value = "out/circle")]
        out: PathBuf,
        /// Skip the plots.
        #[arg(long)]
        no_plots: bool,
    },
    /// Backlash and lead-screw compensation: ISO 230-2's bidirectional positioning test at
    /// the tool (a simulated laser) on every axis, the readings written as LinuxCNC
    /// COMP_FILEs (type 0), read back as the machine's tables, and the test run again
    /// without and with them (docs/precision.md).
    Compensation {
        /// Machine file (default: host-sim/machines/gantry_flexible.toml).
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Write the COMP_FILEs (comp_x.txt, comp_y.txt, comp_z.txt) to this folder.
        #[arg(long)]
        write: Option<PathBuf>,
        /// Also write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Each axis' frequency response from effort to encoder, measured through the servo
    /// step (stepped sine on a slow travel), its resonances and anti-resonances against
    /// the machine file's modes (host-sim/scenarios/freqresp.toml, docs/precision.md).
    Freqresp {
        /// Machine file (default: the built-in flexible gantry,
        /// host-sim/machines/gantry_flexible.toml).
        #[arg(long)]
        machine: Option<PathBuf>,
        #[command(flatten)]
        output: host_sim::output::freqresp_plots::FreqRespOutput,
    },
    /// Each axis' output filters: notches placed from its measured resonances and the
    /// loop's bandwidth, accepted only when the loop measured with them on the running
    /// machine keeps its margins (gain ≥ 6 dB, phase ≥ 30°) (docs/precision.md §3).
    Filters {
        /// Machine file (default: the built-in flexible gantry,
        /// host-sim/machines/gantry_flexible.toml).
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Write the accepted filters to DIR/filters.toml (what `circle --comp DIR` reads).
        #[arg(long)]
        write: Option<PathBuf>,
        /// Check DIR/filters.toml's filters on the measured loop instead of placing any.
        #[arg(long, conflicts_with = "write")]
        check: Option<PathBuf>,
        /// Also write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Output folder for the loops' Bode plots.
        #[arg(long, default_value = "out/filters")]
        out: PathBuf,
        /// Skip the plots.
        #[arg(long)]
        no_plots: bool,
    },
    /// Residual vibration at the tool after a 200 mm/s rapid stop on each axis, unshaped
    /// and with every input shaper that fits at the axis' measured mode, with a stiff
    /// (jerk 1e6 mm/s³) and the factory planner (docs/precision.md "Input shaping").
    Vibration {
        /// Machine file (default: host-sim/machines/gantry_flexible.toml).
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Also write the results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Run a G-code program on a simulated machine through the planner and the servo step
    /// the board runs (host-sim/scenarios/gcode.toml, docs/planner.md). Exit 0 when it
    /// completed, 2 when it was rejected (nothing ran), 1 on a fault or an error.
    Gcode {
        file: PathBuf,
        /// Machine file (default: the built-in physical gantry, travel ±150/±150/±50 mm).
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Also write the report as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Output folder for the plots (default: out/gcode/<program name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Skip the plots.
        #[arg(long)]
        no_plots: bool,
        /// Override a setting for this run, `KEY=VALUE` (repeatable), on the factory
        /// settings by dotted key, checked as `gantry settings set` checks it: the
        /// planner's (`planner.*`, `axis.<a>.planner.*`), the work offsets and the tools
        /// (e.g. `--set planner.servo_reserve=0`).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Enter the backlash and lead-screw tables of this folder before the machine arms
        /// (comp_x.txt, comp_y.txt, comp_z.txt: LinuxCNC COMP_FILEs of type 0, as
        /// `compensation --write` writes them; an absent file: none on that axis), as
        /// `gantry comp load` enters them on a board. Only the tables: the feed-forward and
        /// the filters are settings here (`--set axis.<a>.feedforward.*`, `axis.<a>.filter.*`).
        #[arg(long, value_name = "DIR")]
        comp: Option<PathBuf>,
    },
    /// Write the planner's benchmark programs (host_sim::bench_programs) to DIR as
    /// `<name>.nc`, the rest-to-rest lines as `r2r_<dir>_<len>.nc` (docs/planner.md).
    BenchPrograms {
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Also write the 170,000-line `huge.nc` (4.7 MB).
        #[arg(long)]
        huge: bool,
    },
    /// Compare a QEMU scenario's figures from the firmware's log with host-sim's (used by
    /// firmware/qemu/run-all); prints `qemu <name> passed` or `qemu <name> FAILED: <why>`.
    QemuVerdict {
        file: PathBuf,
        /// The decoded defmt log of the firmware's QEMU run.
        #[arg(long)]
        log: PathBuf,
        /// The firmware's build rate (`GANTRY_CONTROL_HZ`): the scenario runs at it unless
        /// its name states its own (`…_20khz`).
        #[arg(long)]
        rate_hz: Option<u32>,
    },
    /// Replay the QEMU link rig's recorded machine inputs (its decoded defmt log) into
    /// host-sim's machine and compare bit for bit; prints `qemu machine_replay passed: …`
    /// or `qemu machine_replay FAILED: <why>` (naming the first period that differs).
    MachineReplay {
        /// The decoded defmt log of the link rig (`defmt-print -e ELF < LOG`).
        #[arg(long)]
        log: PathBuf,
    },
}

fn main() -> ExitCode {
    host_sim::closed_stdout::exit_quietly_on_closed_stdout();
    let cli = Cli::parse();
    let result = match cli.command {
        None => run_paper(&cli.paper),
        Some(Command::Paper(a)) => run_paper(&a),
        Some(Command::Run {
            file,
            out,
            json,
            no_plots,
        }) => run_file(&file, &out, json.as_deref(), no_plots),
        Some(Command::Estimators {
            disturbance,
            horizon_s,
            scenario,
            json,
        }) => run_estimators(disturbance, horizon_s, scenario.as_deref(), json.as_deref()),
        Some(Command::Seeds {
            out,
            json,
            no_plots,
            traces,
        }) => run_seeds(&out, json.as_deref(), no_plots, traces),
        Some(Command::Faults { scenario, json }) => {
            run_faults(scenario.as_deref(), json.as_deref())
        }
        Some(Command::Identify {
            machine,
            seed,
            json,
            out,
            no_plots,
        }) => run_identify(machine.as_deref(), seed, json.as_deref(), &out, no_plots),
        Some(Command::Circle {
            machine,
            json,
            comp,
            out,
            no_plots,
        }) => run_circle(
            machine.as_deref(),
            json.as_deref(),
            comp.as_deref(),
            &out,
            no_plots,
        ),
        Some(Command::Compensation {
            machine,
            write,
            json,
        }) => run_compensation(machine.as_deref(), write.as_deref(), json.as_deref()),
        Some(Command::Freqresp { machine, output }) => run_freqresp(machine.as_deref(), &output),
        Some(Command::Filters {
            machine,
            write,
            check,
            json,
            out,
            no_plots,
        }) => run_filters(
            machine.as_deref(),
            FiltersOut {
                write: write.as_deref(),
                check: check.as_deref(),
                json: json.as_deref(),
                plots: (!no_plots).then_some(out.as_path()),
            },
        ),
        Some(Command::Vibration { machine, json }) => {
            run_vibration(machine.as_deref(), json.as_deref())
        }
        Some(Command::Gcode {
            file,
            machine,
            json,
            out,
            no_plots,
            set,
            comp,
        }) => {
            return run_gcode(
                &file,
                machine.as_deref(),
                json.as_deref(),
                out.as_deref(),
                no_plots,
                &set,
                comp.as_deref(),
            )
        }
        Some(Command::BenchPrograms { out, huge }) => write_bench_programs(&out, huge),
        Some(Command::QemuVerdict { file, log, rate_hz }) => {
            return run_verdict(&file, &log, rate_hz)
        }
        Some(Command::MachineReplay { log }) => return run_machine_replay(&log),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))
}

fn run_paper(a: &PaperArgs) -> Result<()> {
    let started = Instant::now();
    let file = builtin::load_or("paper.toml", a.scenario.as_deref())?;
    let (info, report) = paper::run_paper(&file)?;
    print!("{}", paper_tables(&info, &report));
    if let Some(j) = &a.json {
        write_json(j, &report)?;
        println!("\nJSON: {}", j.display());
    }
    if !a.no_plots {
        create_dir(&a.out)?;
        if a.traces {
            for (name, r) in &report.traces {
                write_trace_csv(&a.out.join(format!("{name}.csv")), r)?;
            }
        }
        let files = plots::paper_figures(&a.out, &info, &report)?;
        println!(
            "\n{}{} figures (PNG + SVG) in {}",
            traces_note(a.traces),
            files,
            a.out.display()
        );
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn run_file(file: &Path, out: &Path, json: Option<&Path>, no_plots: bool) -> Result<()> {
    let f = builtin::load_path(file)?;
    let res = generic::run_file(&f)?;
    print!("{}", res.table());
    if let Some(j) = json {
        write_json(j, &res.to_json())?;
    }
    if !no_plots {
        create_dir(out)?;
        for (name, _, r) in &res.runs {
            write_trace_csv(&out.join(format!("{name}.csv")), r)?;
        }
    }
    Ok(())
}

/// What the figures line says about the CSV traces.
fn traces_note(traces: bool) -> &'static str {
    if traces {
        "Traces (CSV) and "
    } else {
        "(CSV traces with --traces) "
    }
}

fn run_seeds(out: &Path, json: Option<&Path>, no_plots: bool, traces: bool) -> Result<()> {
    let started = Instant::now();
    let rep = seeds::run_builtin()?;
    print!("{}", seeds::table(&rep));
    if let Some(j) = json {
        write_json(j, &rep.to_json())?;
        println!("\nJSON: {}", j.display());
    }
    if !no_plots {
        create_dir(out)?;
        if traces {
            for (name, r) in &rep.traces {
                write_trace_csv(&out.join(format!("{name}.csv")), r)?;
            }
        }
        let files = seed_plots::seed_figures(out, &rep)?;
        println!(
            "\n{}{files} figures (PNG + SVG) in {}",
            traces_note(traces),
            out.display()
        );
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn run_estimators(
    disturbance: bool,
    horizon_s: f64,
    scenario: Option<&Path>,
    json: Option<&Path>,
) -> Result<()> {
    let started = Instant::now();
    let paper_file = match scenario {
        Some(p) => {
            if disturbance || horizon_s != 15.0 {
                bail!("--disturbance and --horizon-s apply to the built-in study only; set them in {}", p.display());
            }
            builtin::load_path(p)?
        }
        None => estimators::paper_file(horizon_s, disturbance)?,
    };
    let physical_file = builtin::load("estimators_physical.toml")?;
    let c = estimators::compare(&paper_file)?;
    println!(
        "paper helix, 10 kHz, 1e-4 quantisation, |u| <= 500, {horizon_s} s{}; contour over t >= 1 s",
        if disturbance { ", load disturbance on X at 10 s" } else { "" },
    );
    print!("{}", estimators::table(&c));
    let p = estimators::compare(&physical_file)?;
    println!(
        "\nphysical gantry, seeds helix (r 20 mm, 50 mm/s, 150 mN·m load step on X at 1.5 s), \
         10 kHz, 0.625 µm counts, 3 s; lengths mm, torques mN·m"
    );
    print!("{}", estimators::table(&p));
    if let Some(j) = json {
        let mut v = estimators::to_json(&c);
        if let Some(m) = v.as_object_mut() {
            m.insert("physical".into(), estimators::to_json(&p));
        }
        write_json(j, &v)?;
        println!("JSON: {}", j.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn run_faults(scenario: Option<&Path>, json: Option<&Path>) -> Result<()> {
    let started = Instant::now();
    let m = host_sim::studies::faults::run_matrix(scenario)?;
    print!("{}", host_sim::studies::faults::table(&m));
    if let Some(j) = json {
        write_json(j, &m)?;
        println!("JSON: {}", j.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    if !m.passed {
        bail!("the fault matrix has failing cases");
    }
    Ok(())
}

fn run_identify(
    machine: Option<&Path>,
    seed: Option<u64>,
    json: Option<&Path>,
    out: &Path,
    no_plots: bool,
) -> Result<()> {
    let started = Instant::now();
    let r = host_sim::studies::identify::run(machine, seed)?;
    print!("{}", host_sim::studies::identify::table(&r));
    if let Some(j) = json {
        write_json(j, &r)?;
        println!("JSON: {}", j.display());
    }
    if !no_plots {
        create_dir(out)?;
        let n = host_sim::output::identify_plots::figures(out, &r)?;
        println!("{n} figures (PNG + SVG) in {}", out.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    if !r.all_done() {
        bail!("not every axis was identified");
    }
    Ok(())
}

fn run_circle(
    machine: Option<&Path>,
    json: Option<&Path>,
    comp: Option<&Path>,
    out: &Path,
    no_plots: bool,
) -> Result<()> {
    let started = Instant::now();
    let r = host_sim::studies::circle::run_compensated(machine, comp)?;
    print!("{}", host_sim::studies::circle::table(&r));
    if let Some(j) = json {
        write_json(j, &r)?;
        println!("JSON: {}", j.display());
    }
    if !no_plots {
        create_dir(out)?;
        let n = host_sim::output::circle_plots::figures(out, &r)?;
        println!("{n} figures (PNG + SVG) in {}", out.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn run_compensation(
    machine: Option<&Path>,
    write: Option<&Path>,
    json: Option<&Path>,
) -> Result<()> {
    let started = Instant::now();
    let r = host_sim::studies::compensation::run(machine, write)?;
    print!("{}", host_sim::studies::compensation::table(&r));
    if let Some(w) = write {
        println!("COMP_FILEs: {}", w.display());
    }
    if let Some(j) = json {
        write_json(j, &r)?;
        println!("JSON: {}", j.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn run_vibration(machine: Option<&Path>, json: Option<&Path>) -> Result<()> {
    let started = Instant::now();
    let r = host_sim::studies::vibration::run(machine)?;
    print!("{}", host_sim::studies::vibration::table(&r));
    if let Some(j) = json {
        write_json(j, &r)?;
        println!("JSON: {}", j.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn run_freqresp(
    machine: Option<&Path>,
    output: &host_sim::output::freqresp_plots::FreqRespOutput,
) -> Result<()> {
    let started = Instant::now();
    let r = host_sim::studies::freqresp::run(machine)?;
    print!("{}", host_sim::studies::freqresp::table(&r));
    output.write(&r)?;
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    if !r.all_done() {
        bail!("not every axis was measured to the end");
    }
    Ok(())
}

/// What `filters` reads and writes besides the machine.
struct FiltersOut<'a> {
    write: Option<&'a Path>,
    check: Option<&'a Path>,
    json: Option<&'a Path>,
    plots: Option<&'a Path>,
}

fn run_filters(machine: Option<&Path>, o: FiltersOut<'_>) -> Result<()> {
    use host_sim::studies::filters;
    let started = Instant::now();
    let given = match o.check {
        Some(dir) => {
            let rate = filters::loop_base(machine)?.servo.rate_hz;
            Some(
                host_sim::comp_file::read_filters(dir, rate)?.with_context(|| {
                    format!(
                        "{} has no {}",
                        dir.display(),
                        host_sim::comp_file::FILTERS_FILE
                    )
                })?,
            )
        }
        None => None,
    };
    let r = filters::run(machine, given.as_ref())?;
    print!("{}", filters::table(&r));
    if let Some(j) = o.json {
        write_json(j, &r)?;
        println!("JSON: {}", j.display());
    }
    if let Some(dir) = o.plots {
        create_dir(dir)?;
        let n = host_sim::output::loop_plots::figures(dir, &r)?;
        println!("{n} figures (PNG + SVG) in {}", dir.display());
    }
    if let Some(dir) = o.write {
        create_dir(dir)?;
        let path = dir.join(host_sim::comp_file::FILTERS_FILE);
        std::fs::write(&path, filters::filters_toml(&r))
            .with_context(|| format!("writing {}", path.display()))?;
        println!("filters: {}", path.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn run_gcode(
    file: &Path,
    machine: Option<&Path>,
    json: Option<&Path>,
    out: Option<&Path>,
    no_plots: bool,
    set: &[String],
    comp: Option<&Path>,
) -> ExitCode {
    use host_sim::gcode::report::{table, GcodeReport};
    use host_sim::gcode::runner::run_compensated;
    use host_sim::sim_gantry::machine_and_planner;
    let started = Instant::now();
    let res = (|| -> Result<GcodeReport> {
        // the overrides are checked at the machine's control rate, before anything runs
        let (machine_cfg, _) = machine_and_planner(machine)?;
        let settings = host_sim::overrides::gcode_run_settings(
            &controller_core::settings::FACTORY,
            set,
            machine_cfg.servo.rate_hz,
        )?;
        if !set.is_empty() {
            println!("settings overrides: {}", set.join(", "));
        }
        let tables = match comp {
            Some(dir) => {
                let t = host_sim::comp_file::read_dir(dir)?;
                println!("compensation tables: {}", dir.display());
                t
            }
            None => [controller_core::motion::compensation::AxisCompensation::NONE; 3],
        };
        let r = run_compensated(
            file,
            machine,
            &settings,
            &tables,
            std::io::stderr().is_terminal(),
        )?;
        print!("{}", table(&r));
        if let Some(j) = json {
            write_json(j, &r)?;
            println!("JSON: {}", j.display());
        }
        if !no_plots && r.status != "rejected" {
            let stem = file
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "program".into());
            let dir = out.map_or_else(|| Path::new("out/gcode").join(&stem), Path::to_path_buf);
            create_dir(&dir)?;
            let n = host_sim::output::gcode_plots::figures(&dir, &r)?;
            println!("{n} figures (PNG + SVG) in {}", dir.display());
        }
        println!("finished in {:.1} s", started.elapsed().as_secs_f64());
        Ok(r)
    })();
    match res {
        Ok(r) if r.completed() => ExitCode::SUCCESS,
        Ok(r) if r.status == "rejected" => ExitCode::from(2),
        Ok(_) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// `bench-programs --out DIR [--huge]`: the benchmark set as files.
fn write_bench_programs(out: &Path, huge: bool) -> Result<()> {
    use host_sim::bench_programs;
    create_dir(out)?;
    let mut files: Vec<(String, String)> = bench_programs::all()
        .into_iter()
        .map(|(name, text)| (name.to_string(), text))
        .collect();
    files.extend(
        bench_programs::rest_to_rest_cases()
            .into_iter()
            .map(|(name, len, dir)| (name, bench_programs::rest_to_rest(len, dir))),
    );
    if huge {
        files.push(("huge".into(), bench_programs::huge()));
    }
    for (name, text) in &files {
        let path = out.join(format!("{name}.nc"));
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    println!("{} programs in {}", files.len(), out.display());
    Ok(())
}

/// Largest QEMU log `qemu-verdict` reads (a scenario's defmt log is a few MiB at most).
const QEMU_LOG_MAX_BYTES: u64 = 256 << 20;

fn run_machine_replay(log: &Path) -> ExitCode {
    let res = (|| {
        let text = gantry_scenario::file::read_regular(log, QEMU_LOG_MAX_BYTES)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("cannot read log {}", log.display()))?;
        machine_replay::replay(&machine_replay::parse(&text)?)
    })();
    match res {
        Ok(Ok(a)) => {
            println!("qemu machine_replay passed: {}", a.line());
            ExitCode::SUCCESS
        }
        Ok(Err(why)) => {
            println!("qemu machine_replay FAILED: {why}");
            ExitCode::FAILURE
        }
        Err(e) => {
            println!("qemu machine_replay FAILED: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run_verdict(file: &Path, log: &Path, rate_hz: Option<u32>) -> ExitCode {
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let res = (|| {
        let f = gantry_scenario::file::load_at_rate(file, rate_hz)?;
        let text = gantry_scenario::file::read_regular(log, QEMU_LOG_MAX_BYTES)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("cannot read log {}", log.display()))?;
        qemu_verdict::verdict(&f, &text)
    })();
    match res {
        Ok((name, None)) => {
            println!("qemu {name} passed");
            ExitCode::SUCCESS
        }
        Ok((name, Some(why))) => {
            println!("qemu {name} FAILED: {why}");
            ExitCode::FAILURE
        }
        Err(e) => {
            println!("qemu {stem} FAILED: {e:#}");
            ExitCode::FAILURE
        }
    }
}
