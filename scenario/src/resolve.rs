//! One run of a scenario file turned into the core's configurations: the servo step's
//! ([`ServoConfig`]: encoders, amplifiers, controller, estimators, limits, path), the
//! simulated world's ([`WorldConfig`]) and the figures' ([`TruthSpec`]), all validated by
//! building them once.

use crate::file::{Run, ScenarioError};
use crate::schema::{AccelSpec, BrakeSpec, LawSpec, Mode, Numeric, Scenario, TunedLaw};
use controller_core::controller::ControllerConfig;
use controller_core::coupling::CouplingConfig;
use controller_core::estimator::{AccelInput, EstimatorBankConfig};
use controller_core::law::LawConfig;
use controller_core::motion::compensation::AxisCompensation;
use controller_core::motion::homing::HomingConfig;
use controller_core::motion::jog::JogConfig;
use controller_core::motion::trajectory::Trajectory;
use controller_core::plant::PlantParams;
use controller_core::presets::gantry::{adaptive_for, dob_smc_for, dsmc_for, pid_for};
use controller_core::servo::travel::TravelConfig;
use controller_core::servo::{PathPlan, ServoConfig};
use controller_core::sim::run::{factory_planner, RunConfig, SimRun};
use controller_core::sim::run_memory::RunMemory;
use controller_core::sim::world::{InitialState, PlantConfig, WorldConfig};

/// Most plant integration steps one run may take (horizon × rate × substeps in discrete
/// mode, horizon / dt in continuous mode): 2·10⁸, a few minutes of host time. Longer runs
/// are refused rather than left to look like a hang.
pub const MAX_SIM_STEPS: f64 = 2e8;

/// A run ready to simulate.
#[derive(Clone, Debug)]
pub struct Resolved {
    pub name: String,
    pub case: Option<String>,
    pub variant: Option<String>,
    pub horizon_s: f64,
    pub numeric: Numeric,
    pub mode: Mode,
    pub run: RunConfig,
    /// The path in absolute coordinates, as the figures see it.
    pub reference: Trajectory<f64>,
    pub study: Option<toml::Value>,
    /// The machine's backlash and lead-screw compensation tables entered for the run
    /// (none from a scenario file; a study sets them, e.g. `host-sim circle --comp DIR`).
    pub compensation: Option<Box<[AxisCompensation; 3]>>,
}

impl Resolved {
    /// Resolve one run of file `file`.
    pub fn new(file: &str, run: &Run) -> Result<Self, ScenarioError> {
        let err = |m: String| ScenarioError::new(file, Some(&run.name), m);
        // the machine first, checked as the settings are (crate::machine)
        crate::machine::check(&run.scenario.machine).map_err(|m| {
            err(match &run.machine_file {
                Some(f) => format!("machine file {f} (with this file's overrides): {m}"),
                None => format!("machine: {m}"),
            })
        })?;
        resolve(&run.scenario)
            .map_err(err)
            .map(|(cfg, reference)| Self {
                name: run.name.clone(),
                case: run.case.clone(),
                variant: run.variant.clone(),
                horizon_s: run.scenario.horizon_s,
                numeric: run.scenario.numeric,
                mode: run.scenario.mode,
                run: cfg,
                reference,
                study: run.scenario.study.clone(),
                compensation: None,
            })
    }
}

fn law_of(spec: &LawSpec, plant: &PlantConfig, axis: &str) -> Result<LawConfig, String> {
    Ok(match *spec {
        LawSpec::Pid(c) => LawConfig::Pid(c),
        LawSpec::Smc(c) => LawConfig::Smc(c),
        LawSpec::DobSmc(c) => LawConfig::DobSmc(c),
        LawSpec::AdaptiveSmc(c) => LawConfig::AdaptiveSmc(c),
        LawSpec::Tuned(t) => {
            let PlantConfig::Physical(a) = plant else {
                return Err(format!(
                    "`controller.laws.{axis}`: a tuned law needs a physical plant on that axis"
                ));
            };
            match t {
                TunedLaw::Pid => LawConfig::Pid(pid_for(a)),
                TunedLaw::Dsmc => LawConfig::Smc(dsmc_for(a)),
                TunedLaw::DobSmc => LawConfig::DobSmc(dob_smc_for(a)),
                TunedLaw::AdaptiveSmc => LawConfig::AdaptiveSmc(adaptive_for(a)),
                TunedLaw::AdaptiveSmcFrozen => LawConfig::AdaptiveSmc(adaptive_for(a).frozen()),
            }
        }
    })
}

fn model_of(plant: &PlantConfig) -> PlantParams {
    match plant {
        PlantConfig::Paper(p) => PlantParams {
            a: p.a,
            b: p.b,
            k: p.k,
        },
        PlantConfig::Physical(a) => PlantParams::from_inertia(a.inertia, a.viscous),
    }
}

/// The axis' brake as the run has it: none when the run starts on the path, already
/// moving (a machine in motion has its brakes open, and the servo only opens them from
/// rest after arming: such a run models the machine from the middle of its motion,
/// without them).
fn brake_of(m: &crate::schema::MachineSpec, a: &crate::schema::AxisSpec) -> BrakeSpec {
    if m.start_on_path {
        BrakeSpec::default()
    } else {
        a.brake
    }
}

fn resolve(sc: &Scenario) -> Result<(RunConfig, Trajectory<f64>), String> {
    if !(sc.horizon_s > 0.0 && sc.horizon_s.is_finite()) {
        return Err(format!(
            "`horizon_s` must be positive and finite (got {})",
            sc.horizon_s
        ));
    }
    let m = &sc.machine;
    let reference = sc.path.build().map_err(|e| format!("`path`: {e}"))?;
    let names = ["x", "y", "z"];
    let r0 = reference.sample(0.0);
    let mut laws = [LawConfig::Pid(controller_core::presets::paper::PAPER_PID); 3];
    let mut initial = [InitialState::default(); 3];
    for i in 0..3 {
        let ax = &m.axes[i];
        laws[i] = law_of(&sc.controller.laws[i], &ax.plant, names[i])?;
        initial[i] = if m.start_on_path {
            InitialState {
                pos_mm: r0.pos[i],
                vel_mm_s: r0.vel[i],
            }
        } else {
            ax.initial
        };
    }
    let accel_input = match sc.estimator.accel_input {
        AccelSpec::None => AccelInput::None,
        AccelSpec::Reference => AccelInput::Reference,
        AccelSpec::Model => AccelInput::Model(m.axes.each_ref().map(|a| model_of(&a.plant))),
    };
    let servo = ServoConfig {
        rate_hz: m.rate_hz,
        encoders: m.axes.each_ref().map(|a| a.encoder),
        amplifiers: m.axes.each_ref().map(|a| a.amplifier),
        brakes: m.axes.each_ref().map(|a| brake_of(m, a).servo()),
        controller: ControllerConfig {
            laws,
            coupling: sc.controller.coupling,
        },
        estimator: EstimatorBankConfig {
            axes: sc.estimator.axes,
            accel_input,
        },
        safety: if m.fault_checks {
            m.safety.with_axes(m.axes.each_ref().map(|a| a.safety))
        } else {
            controller_core::servo::monitor::SafetyConfig::OFF
        },
        path: Some(PathPlan {
            path: sc.path,
            start: sc.path_start,
            duration_s: None,
        }),
        travel: TravelConfig {
            axes: m.axes.each_ref().map(|a| a.travel),
            ..TravelConfig::UNLIMITED
        },
        homing: HomingConfig {
            axes: m.axes.each_ref().map(|a| a.homing),
        },
        jog: JogConfig {
            axes: m.axes.each_ref().map(|a| a.jog),
            timeout_s: m.jog_timeout_s,
        },
        identify: m.identify,
        model_known: m.axes.each_ref().map(|a| a.model_known),
        feedforward: m.axes.each_ref().map(|a| a.feedforward),
        filters: m.axes.each_ref().map(|a| a.filters),
    };
    let world = WorldConfig {
        plants: m.axes.each_ref().map(|a| a.plant),
        plant_substeps: m.plant_substeps,
        initial,
        // the simulated encoders give the index pulses the controller is told of, unless
        // the machine file gives the simulated machine its own (a misconfiguration study)
        switches: m.axes.each_ref().map(|a| {
            let mut sw = a.switches;
            if sw.index_period_counts == 0 {
                sw.index_period_counts = a.encoder.index_period_counts;
            }
            sw
        }),
        imperfections: m.imperfections,
        brakes: m.axes.each_ref().map(|a| brake_of(m, a).plant()),
    };
    let steps = match sc.mode {
        Mode::Discrete => sc.horizon_s * f64::from(m.rate_hz) * f64::from(m.plant_substeps),
        Mode::Continuous { dt_s } => {
            if !(dt_s > 0.0 && dt_s.is_finite()) {
                return Err(format!(
                    "`mode.continuous.dt_s` must be positive (got {dt_s})"
                ));
            }
            sc.horizon_s / dt_s
        }
    };
    if steps.is_nan() || steps > MAX_SIM_STEPS {
        return Err(format!(
            "{steps:.3e} plant steps (horizon × rate × substeps, or horizon / dt) exceed the \
             cap of {MAX_SIM_STEPS:.0e}; shorten the horizon or lower the rate"
        ));
    }
    let periods = (sc.horizon_s * f64::from(m.rate_hz)).round() as u32;
    let run = RunConfig {
        servo,
        world,
        truth: sc.metrics,
        periods,
        hold: sc.hold,
        inject: sc.fault,
        program: sc.program,
    };
    validate(&run, sc)?;
    Ok((run, reference))
}

/// Build everything once: every block rejects its own bad parameters.
fn validate(run: &RunConfig, sc: &Scenario) -> Result<(), String> {
    let m = &sc.metrics;
    if let Some([a, b]) = m.itse_window_s {
        if !(a.is_finite() && b.is_finite() && b >= a) {
            return Err("`metrics.itse_window_s` must be [from, to] with from <= to".into());
        }
    }
    if let Some(f) = m.contour_from_s {
        if !f.is_finite() {
            return Err("`metrics.contour_from_s` must be finite".into());
        }
    }
    if !(m.contour_every_s > 0.0 && m.contour_every_s.is_finite()) {
        return Err("`metrics.contour_every_s` must be positive".into());
    }
    if !(m.contour_window_s > 0.0 && m.contour_window_s.is_finite()) {
        return Err("`metrics.contour_window_s` must be positive".into());
    }
    // (every part built once; a program run's planner is the caller's, so without one)
    SimRun::<f64>::with_memory(run, &factory_planner(run.servo.rate_hz), RunMemory::new())
        .map_err(|e| format!("invalid configuration: {e}"))?;
    let framed = run
        .world
        .plants
        .iter()
        .any(|p| matches!(p, PlantConfig::Physical(a) if a.frame.is_some()));
    if framed && !matches!(sc.mode, Mode::Discrete) {
        return Err(
            "an axis with a `frame` runs in discrete mode only (the simulated world's)".into(),
        );
    }
    if run.program && !matches!(sc.mode, Mode::Discrete) {
        return Err("`program = true` runs in discrete mode only (the machine's periods)".into());
    }
    if let Mode::Continuous { .. } = sc.mode {
        if matches!(sc.controller.coupling, CouplingConfig::VariableGain(_)) {
            return Err("continuous mode supports no variable-gain coupling".into());
        }
        for (i, l) in run.servo.controller.laws.iter().enumerate() {
            if !matches!(l, LawConfig::Pid(_) | LawConfig::Smc(_)) {
                return Err(format!(
                    "continuous mode runs PID and sliding-mode laws only (axis {} is {})",
                    ["x", "y", "z"][i],
                    l.kind()
                ));
            }
        }
    }
    Ok(())
}
