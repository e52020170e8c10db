//! `twin-plant [--rate-hz N]`: the board twin's plant, the simulated physical gantry of
//! `gantry --sim`, stepped one control period per request over stdin/stdout
//! (host_sim::twin_plant has the protocol). firmware/twin starts it; nobody else needs to.

use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use controller_core::settings::FACTORY;
use host_sim::sim_gantry::gantry_world;
use host_sim::twin_plant::{serve, TwinPlant};

fn rate(args: &[String]) -> Result<Option<u32>> {
    match args {
        [] => Ok(None),
        [flag, v] if flag == "--rate-hz" => {
            let hz: u32 = v
                .parse()
                .with_context(|| format!("--rate-hz {v}: not a whole number of Hz"))?;
            if !(100..=50_000).contains(&hz) {
                bail!("--rate-hz {hz}: outside 100..50000 Hz");
            }
            Ok(Some(hz))
        }
        _ => bail!("usage: twin-plant [--rate-hz N]"),
    }
}

fn run() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (world, _) = gantry_world(&FACTORY, rate(&args)?, true)?;
    let mut plant = TwinPlant::new(world);
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    serve(
        &mut plant,
        &mut stdin.lock(),
        &mut std::io::BufWriter::new(stdout.lock()),
    )
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("twin-plant: {e:#}");
            ExitCode::from(2)
        }
    }
}
