//! Running one resolved scenario run ([`gantry_scenario::Resolved`]) in its mode and number
//! type, with the figures taken on the true plant state and a decimated trace for plots.
//!
//! - [`discrete`]: the servo step against the simulated world, period by period
//!   (controller-core's [`controller_core::sim::run::SimRun`]): what the firmware does;
//! - [`continuous`]: the controller evaluated at every RK4 stage, its integrals integrated
//!   with the plant: the paper's Matlab setting.

pub mod continuous;
pub mod discrete;
pub mod split_memory;

use anyhow::Result;
use controller_core::num::fixed::{FxQ16, FxQ32};
use controller_core::sim::truth::TruthFigures;
use gantry_scenario::{Mode, Numeric, Resolved};

/// Trace decimation: one sample per millisecond.
pub const TRACE_EVERY_S: f64 = 1e-3;

/// Decimated time series of a run.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    pub t: Vec<f64>,
    pub reference: Vec<[f64; 3]>,
    pub position: Vec<[f64; 3]>,
    pub u: Vec<[f64; 3]>,
    pub s: Vec<[f64; 3]>,
    /// The controller's own contour-error vector (model of paper eq. 14).
    pub contour_model: Vec<[f64; 3]>,
}

/// Figures of one run (errors `q_d - q` on the true plant state) and its trace.
#[derive(Clone, Debug, Default)]
pub struct RunResult {
    pub itse: [f64; 3],
    pub itse_window: [f64; 3],
    pub iae: [f64; 3],
    pub max_abs_error: [f64; 3],
    pub contour_max: f64,
    pub contour_rms: f64,
    /// Total variation of u over the run, per axis.
    pub tv_u: [f64; 3],
    pub peak_u: [f64; 3],
    pub trace: Trace,
}

impl RunResult {
    pub(crate) fn from_figures(f: &TruthFigures, trace: Trace) -> Self {
        Self {
            itse: f.itse,
            itse_window: f.itse_window,
            iae: f.iae,
            max_abs_error: f.max_abs_error,
            contour_max: f.contour_max,
            contour_rms: f.contour_rms,
            tv_u: f.tv_u,
            peak_u: f.peak_u,
            trace,
        }
    }

    /// The first non-finite figure's name, if any (a run that produced NaN or ∞ is an error,
    /// never a number in a report).
    pub fn non_finite(&self) -> Option<&'static str> {
        let groups: [(&str, &[f64]); 8] = [
            ("itse", &self.itse),
            ("itse_window", &self.itse_window),
            ("iae", &self.iae),
            ("max_abs_error", &self.max_abs_error),
            ("contour_max", std::slice::from_ref(&self.contour_max)),
            ("contour_rms", std::slice::from_ref(&self.contour_rms)),
            ("tv_u", &self.tv_u),
            ("peak_u", &self.peak_u),
        ];
        groups
            .iter()
            .find(|(_, v)| v.iter().any(|x| !x.is_finite()))
            .map(|(n, _)| *n)
    }
}

/// Run `r` in its mode and number type; a run whose figures are not finite is an error
/// naming the figure.
pub fn simulate(r: &Resolved) -> Result<RunResult> {
    let res = match (r.mode, r.numeric) {
        (Mode::Discrete, Numeric::F32) => discrete::run::<f32>(r, &mut ())?,
        (Mode::Discrete, Numeric::F64) => discrete::run::<f64>(r, &mut ())?,
        (Mode::Discrete, Numeric::Fixed) => discrete::run::<FxQ32>(r, &mut ())?,
        (Mode::Discrete, Numeric::FixedQ16) => discrete::run::<FxQ16>(r, &mut ())?,
        (Mode::Continuous { dt_s }, Numeric::F32) => continuous::run::<f32>(r, dt_s)?,
        (Mode::Continuous { dt_s }, Numeric::F64) => continuous::run::<f64>(r, dt_s)?,
        (Mode::Continuous { dt_s }, Numeric::Fixed) => continuous::run::<FxQ32>(r, dt_s)?,
        (Mode::Continuous { dt_s }, Numeric::FixedQ16) => continuous::run::<FxQ16>(r, dt_s)?,
    };
    if let Some(name) = res.non_finite() {
        anyhow::bail!("run `{}`: the figure `{name}` is not finite", r.name);
    }
    Ok(res)
}

/// Decides when to take a trace sample: every [`TRACE_EVERY_S`], with half a step of
/// slack so float drift in `t` never skips one.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Decimator {
    next_t: f64,
    every: f64,
}

impl Decimator {
    pub(crate) fn new(every: f64) -> Self {
        Self { next_t: 0.0, every }
    }

    pub(crate) fn due(&mut self, t: f64, dt: f64) -> bool {
        if t + 0.5 * dt >= self.next_t {
            self.next_t += self.every;
            true
        } else {
            false
        }
    }
}
