//! `host-sim`: the simulated gantry on a PC. With no arguments it reproduces the reference
//! paper's Tables 1 and 3 and writes traces and plots; `run FILE` runs a single scenario.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use host_sim::engine::run;
use host_sim::paper::{run_paper, PaperScenario};
use host_sim::plots;
use host_sim::report::{paper_tables, write_json, write_trace_csv};
use host_sim::scenario::{load_toml, paper_plants, RunScenario};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Parser)]
#[command(
    version,
    about = "Simulated gantry: runs controller-core against plant models"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Paper scenario file (default: the built-in host-sim/scenarios/paper.toml).
    #[arg(long, global = true)]
    scenario: Option<PathBuf>,
    /// Output folder for CSV traces and plots.
    #[arg(long, global = true, default_value = "out/paper")]
    out: PathBuf,
    /// Also write the results as JSON to this file.
    #[arg(long, global = true)]
    json: Option<PathBuf>,
    /// Skip CSV and plot output.
    #[arg(long, global = true)]
    no_plots: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Reproduce the paper's Tables 1 and 3 (the default).
    Paper,
    /// Run one scenario file (e.g. host-sim/scenarios/helix_discrete_10khz.toml).
    Run { file: PathBuf },
    /// Velocity sources (exact, backward difference, PLL, Kalman) x PID/SMC/DSMC on the
    /// paper helix at 10 kHz with 1e-4 quantisation, and x PID/DSMC/DOB-SMC on the
    /// physical gantry's helix with 0.625 µm counts (docs/velocity-estimation.md).
    Estimators {
        /// Add the paper's 10 s load disturbance on X (table 3).
        #[arg(long)]
        disturbance: bool,
        /// Simulated time (s); the paper's helix runs 15 s.
        #[arg(long, default_value_t = 15.0)]
        horizon_s: f64,
    },
    /// Compare the seed methods (DOB-SMC, cross-coupling, adaptive friction SMC) on the
    /// physical gantry: host-sim/scenarios/seeds_*.toml (docs/seed-methods.md).
    Seeds,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command.as_ref().unwrap_or(&Command::Paper) {
        Command::Paper => paper(&cli),
        Command::Run { file } => single(&cli, file),
        Command::Estimators {
            disturbance,
            horizon_s,
        } => estimators(&cli, *disturbance, *horizon_s),
        Command::Seeds => seeds(&cli),
    }
}

fn paper(cli: &Cli) -> Result<()> {
    let started = Instant::now();
    let sc = match &cli.scenario {
        Some(p) => load_toml::<PaperScenario>(p)?,
        None => PaperScenario::builtin()?,
    };
    let report = run_paper(&sc)?;
    print!("{}", paper_tables(&sc, &report));
    if let Some(j) = &cli.json {
        write_json(j, &report)?;
        println!("\nJSON: {}", j.display());
    }
    if !cli.no_plots {
        std::fs::create_dir_all(&cli.out)
            .with_context(|| format!("cannot create {}", cli.out.display()))?;
        for (name, r) in &report.traces {
            write_trace_csv(&cli.out.join(format!("{name}.csv")), r)?;
        }
        let files = plots::paper_figures(&cli.out, &sc, &report)?;
        println!(
            "\nTraces (CSV) and {} figures (PNG + SVG) in {}",
            files,
            cli.out.display()
        );
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn single(cli: &Cli, file: &Path) -> Result<()> {
    let sc: RunScenario = load_toml(file)?;
    let plants = paper_plants(&sc.plant, &sc.disturbances)?;
    let r = run(&sc.spec()?, &plants)?;
    println!("scenario {}", sc.name);
    println!(
        "  ITSE x y z      : {:.6e} {:.6e} {:.6e}",
        r.itse[0], r.itse[1], r.itse[2]
    );
    println!(
        "  max |e| x y z   : {:.6e} {:.6e} {:.6e}",
        r.max_abs_error[0], r.max_abs_error[1], r.max_abs_error[2]
    );
    println!(
        "  contour max rms : {:.6e} {:.6e} (t >= {} s)",
        r.contour_max, r.contour_rms, sc.contour_from_s
    );
    println!(
        "  TV(u) x y z     : {:.4e} {:.4e} {:.4e}",
        r.tv_u[0], r.tv_u[1], r.tv_u[2]
    );
    if let Some(j) = &cli.json {
        write_json(
            j,
            &serde_json::json!({
                "name": sc.name, "itse": r.itse, "max_abs_error": r.max_abs_error,
                "contour_max": r.contour_max, "contour_rms": r.contour_rms, "tv_u": r.tv_u, "peak_u": r.peak_u,
            }),
        )?;
    }
    if !cli.no_plots {
        std::fs::create_dir_all(&cli.out)?;
        write_trace_csv(&cli.out.join(format!("{}.csv", sc.name)), &r)?;
    }
    Ok(())
}

fn seeds(cli: &Cli) -> Result<()> {
    let started = Instant::now();
    let rep = host_sim::seeds::run_builtin()?;
    print!("{}", host_sim::seeds::table(&rep));
    if let Some(j) = &cli.json {
        write_json(j, &rep.to_json())?;
        println!("\nJSON: {}", j.display());
    }
    if !cli.no_plots {
        let dir = cli.out.join("seeds");
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        for (name, r) in &rep.traces {
            write_trace_csv(&dir.join(format!("{name}.csv")), r)?;
        }
        let files = host_sim::seed_plots::seed_figures(&dir, &rep)?;
        println!(
            "\nTraces (CSV) and {files} figures (PNG + SVG) in {}",
            dir.display()
        );
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn estimators(cli: &Cli, disturbance: bool, horizon_s: f64) -> Result<()> {
    use host_sim::estimators::{compare, default_sources, table};
    let started = Instant::now();
    let sc = match &cli.scenario {
        Some(p) => load_toml::<PaperScenario>(p)?,
        None => PaperScenario::builtin()?,
    };
    let sources = default_sources(sc.plant);
    let c = compare(&sc, &sources, horizon_s, disturbance)?;
    println!(
        "paper helix, 10 kHz, 1e-4 quantisation, |u| <= 500, {horizon_s} s{}; contour over t >= {} s",
        if disturbance { ", load disturbance on X at 10 s" } else { "" },
        sc.table3.contour_from_s
    );
    print!("{}", table(&c, &sources));
    use host_sim::estimators::physical::{
        compare_physical, default_physical_sources, physical_table, PHYSICAL_LAWS,
    };
    let psources = default_physical_sources();
    let p = compare_physical(&PHYSICAL_LAWS, &psources, None)?;
    println!(
        "\nphysical gantry, seeds helix (r 20 mm, 50 mm/s, 150 mN·m load step on X at 1.5 s), \
         10 kHz, 0.625 µm counts, 3 s; lengths mm, torques mN·m"
    );
    print!("{}", physical_table(&p, &psources));
    if let Some(j) = &cli.json {
        let mut v = serde_json::to_value(&c)?;
        if let Some(m) = v.as_object_mut() {
            m.insert("physical".into(), serde_json::to_value(&p)?);
        }
        write_json(j, &v)?;
        println!("JSON: {}", j.display());
    }
    println!("finished in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}
