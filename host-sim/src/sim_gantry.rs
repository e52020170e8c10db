//! The simulated gantry the host's machines are built on: the built-in `gcode.toml`
//! scenario (or one on a `--machine`) resolved with the planner configured from the
//! settings, the physical world of `gantry --sim` and of the board twin, and the factory
//! settings with the designed gantry's axis models entered (both built by controller-core's
//! `sim::gantry`, as the QEMU link rig builds its machine). `host-sim gcode`, `gantry
//! --sim`, the twin plant and the machine replay all start from here.

use crate::builtin::{self, resolve_all};
use anyhow::{anyhow, bail, Result};
use controller_core::axes::Axis;
use controller_core::motion::planner::PlannerConfig;
use controller_core::settings::{Settings, FACTORY};
use controller_core::sim::gantry::{self, GantryError, GantryOptions};
use controller_core::sim::run::RunConfig;
use controller_core::sim::world::World;
use std::path::Path;

/// The scenario (built-in `gcode.toml`, or on `machine`) resolved, and the planner's
/// configuration at the machine's rate.
pub fn machine_and_planner(machine: Option<&Path>) -> Result<(RunConfig, PlannerConfig)> {
    machine_and_planner_with(machine, &FACTORY)
}

/// [`machine_and_planner`] with the planner configured from `settings` instead of the
/// factory settings (`cargo sim gcode --set`).
pub fn machine_and_planner_with(
    machine: Option<&Path>,
    settings: &Settings,
) -> Result<(RunConfig, PlannerConfig)> {
    let file = match machine {
        Some(m) => builtin::load_on_machine("gcode.toml", m)?,
        None => builtin::load("gcode.toml")?,
    };
    let runs = resolve_all(&file)?;
    let r = runs
        .first()
        .ok_or_else(|| anyhow!("gcode.toml has no run"))?;
    // the settings' planner (controller-core settings, the factory's from GANTRY_PLANNER
    // unless `--set`), its speeds capped at the machine's own limits (a `--machine` may
    // be slower)
    let mut cfg = settings.planner_config(r.run.servo.rate_hz);
    for (v, safety) in cfg.vel_max_mm_s.iter_mut().zip(&r.run.servo.safety.axes) {
        if safety.vel_max_mm_s.is_finite() && safety.vel_max_mm_s > 0.0 {
            *v = v.min(safety.vel_max_mm_s);
        }
    }
    if r.study.is_some() {
        bail!("gcode.toml: no study table expected (the planner's limits are settings)");
    }
    // the settings' feed-forward and output filters (the factory's: none), each stage
    // designed at the run's rate
    let mut run = r.run;
    let period_s = 1.0 / run.servo.rate_hz.max(1) as f32;
    for (i, (a, axis)) in settings.axis.iter().zip(Axis::ALL).enumerate() {
        run.servo.feedforward[i] = a.feedforward;
        run.servo.filters[i] = a
            .filter_config(axis, period_s)
            .map_err(|e| anyhow!("settings: {e}"))?;
    }
    Ok((run, cfg))
}

/// The simulated physical gantry of `gantry --sim` (host-sim/scenarios/gcode.toml: travel
/// ±150/±150/±50 mm around where it starts) with limit switches where `settings`' homing
/// expects them and the machine's encoder index pulses (one per revolution, 8000 counts:
/// host-sim/machines/gantry.toml), at `rate_hz` (default: the scenario's), and its control
/// rate. Also the
/// board twin's plant (`twin-plant`), which passes `board_amplifier`: the amplifier
/// applies the duty the board's timer drives, unquantised here (the timer's own
/// resolution is the board's quantisation).
pub fn gantry_world(
    settings: &Settings,
    rate_hz: Option<u32>,
    board_amplifier: bool,
) -> Result<(World, u32)> {
    gantry_world_on(None, settings, rate_hz, board_amplifier)
}

/// [`gantry_world`] on the axes of a machine file (`gantry --sim --machine FILE`, e.g.
/// host-sim/machines/gantry_flexible.toml: its frame's modes, backlash and lead error) in
/// place of host-sim/machines/gantry.toml's.
pub fn gantry_world_on(
    machine: Option<&Path>,
    settings: &Settings,
    rate_hz: Option<u32>,
    board_amplifier: bool,
) -> Result<(World, u32)> {
    let (run, _) = machine_and_planner(machine)?;
    let rate_hz = rate_hz.unwrap_or(run.servo.rate_hz);
    let options = GantryOptions {
        index_pulses: true,
        board_amplifier,
    };
    let world =
        gantry::gantry_world(&run.world, settings, rate_hz, options).map_err(|e| match e {
            GantryError::Settings(e) => anyhow!("settings: {e:?}"),
            GantryError::World(e) => anyhow!("machine: {e}"),
        })?;
    Ok((world, rate_hz))
}

/// Factory settings with the designed gantry's axis models entered (`gantry --sim`'s
/// machine, and the QEMU link rig's: [`gantry::designed_settings`]).
pub fn designed_settings() -> Settings {
    gantry::designed_settings()
}
