//! Scenario files (TOML) and their conversion into [`RunSpec`]s.
//!
//! Two kinds of file ship in `host-sim/scenarios/`: the paper reproduction
//! ([`crate::paper::PaperScenario`], `paper.toml` is the built-in default) and single runs
//! ([`RunScenario`], e.g. `helix_discrete_10khz.toml`) for `host-sim run FILE`.

use crate::engine::{MetricSpec, Mode, Numeric, RunSpec};
use anyhow::{bail, Context, Result};
use controller_core::gantry::GantryConfig;
use controller_core::params::PlantParams;
use controller_core::plant::{AxisState, DisturbedPaperAxis, PaperAxis};
use controller_core::trajectory::Trajectory;
use controller_core::Vec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Reference path as written in a scenario file (lengths in plant units).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TrajectorySpec {
    Step {
        target: [f64; 3],
        #[serde(default)]
        t0_s: f64,
    },
    Sine {
        amp: [f64; 3],
        omega: f64,
        #[serde(default)]
        phase: [f64; 3],
        #[serde(default)]
        offset: [f64; 3],
    },
    Line {
        start: [f64; 3],
        vel: [f64; 3],
    },
    Helix {
        #[serde(default)]
        center: [f64; 3],
        radius: f64,
        omega: f64,
        z_rate: f64,
    },
}

impl TrajectorySpec {
    pub fn build(&self) -> Result<Trajectory<f64>> {
        let v = Vec3::from_array;
        let all_finite = |xs: &[f64]| xs.iter().all(|x| x.is_finite());
        let tr = match *self {
            Self::Step { target, t0_s } => {
                if !all_finite(&[target[0], target[1], target[2], t0_s]) {
                    bail!("step trajectory: values must be finite");
                }
                Trajectory::Step {
                    target: v(target),
                    t0: t0_s,
                }
            }
            Self::Sine {
                amp,
                omega,
                phase,
                offset,
            } => Trajectory::Sine {
                amp: v(amp),
                omega,
                phase: v(phase),
                offset: v(offset),
            },
            Self::Line { start, vel } => Trajectory::Line {
                start: v(start),
                vel: v(vel),
            },
            Self::Helix {
                center,
                radius,
                omega,
                z_rate,
            } => {
                if !(radius > 0.0) {
                    bail!("helix trajectory: radius must be > 0 (got {radius})");
                }
                Trajectory::Helix {
                    center: v(center),
                    radius,
                    omega,
                    z_rate,
                }
            }
        };
        // a cheap, complete check: every parameter feeds the sample at t = 1
        let s = tr.sample(1.0);
        if !(s.pos.is_finite() && s.vel.is_finite() && s.acc.is_finite()) {
            bail!("trajectory parameters must be finite");
        }
        Ok(tr)
    }
}

/// A step load added to one axis's acceleration (plant 1.1: `θ'' = ... + d`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepDisturbance {
    /// 0 = x, 1 = y, 2 = z.
    pub axis: usize,
    pub t_s: f64,
    pub accel: f64,
}

/// Paper plants (`θ'' = -aθ' - bθ + ku`) with optional step disturbances.
pub fn paper_plants(
    p: &PlantParams,
    dist: &[StepDisturbance],
) -> Result<[DisturbedPaperAxis<f64>; 3]> {
    let axis = PaperAxis {
        a: p.a as f64,
        b: p.b as f64,
        k: p.k as f64,
    };
    let mut plants = [DisturbedPaperAxis {
        axis,
        d_step: 0.0,
        t_dist: f64::INFINITY,
    }; 3];
    for d in dist {
        if d.axis > 2 {
            bail!(
                "disturbance axis {} does not exist (0 = x, 1 = y, 2 = z)",
                d.axis
            );
        }
        if !(d.t_s.is_finite() && d.accel.is_finite()) {
            bail!("disturbance time and size must be finite");
        }
        plants[d.axis].d_step = d.accel;
        plants[d.axis].t_dist = d.t_s;
    }
    Ok(plants)
}

/// A single run on the paper plant: `host-sim run FILE`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunScenario {
    pub name: String,
    pub horizon_s: f64,
    #[serde(default)]
    pub numeric: Numeric,
    pub plant: PlantParams,
    pub trajectory: TrajectorySpec,
    pub controller: GantryConfig,
    pub mode: Mode,
    #[serde(default)]
    pub disturbances: Vec<StepDisturbance>,
    /// Contour error is measured from this time on (default 1 s).
    #[serde(default = "one")]
    pub contour_from_s: f64,
}

fn one() -> f64 {
    1.0
}

impl RunScenario {
    pub fn spec(&self) -> Result<RunSpec> {
        Ok(RunSpec {
            horizon_s: self.horizon_s,
            trajectory: self.trajectory.build()?,
            controller: self.controller,
            mode: self.mode,
            numeric: self.numeric,
            metrics: MetricSpec {
                contour_from_s: Some(self.contour_from_s),
                ..Default::default()
            },
            initial: [AxisState::default(); 3],
        })
    }
}

/// Read and parse a TOML file with a clear error naming the file.
pub fn load_toml<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read scenario file {}", path.display()))?;
    toml::from_str(&text).with_context(|| format!("invalid scenario file {}", path.display()))
}
