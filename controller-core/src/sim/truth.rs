//! Figures of a run taken on the simulated machine's *true* state against the reference
//! path (never what the controller measures): ITSE (whole run and a window), IAE, largest
//! tracking error, the true contour error (distance to the path), and the chattering
//! (total variation) and peak of the effort. host-sim and the QEMU rig record the same
//! figures with this one recorder.

use crate::axes::AXES;
use crate::metrics::{distance_to_path, Itse, MaxRms, TotalVariation};
use crate::motion::trajectory::Trajectory;
use crate::Vec3;

/// What to measure besides the whole-run figures.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct TruthSpec {
    /// Extra ITSE over `[from, to)` (the paper's robustness window).
    #[cfg_attr(feature = "serde", serde(default))]
    pub itse_window_s: Option<[f64; 2]>,
    /// The true contour error is sampled from this time on (`None`: not at all).
    #[cfg_attr(feature = "serde", serde(default))]
    pub contour_from_s: Option<f64>,
    /// ...every this many seconds.
    #[cfg_attr(feature = "serde", serde(default = "default_contour_every"))]
    pub contour_every_s: f64,
    /// Half-width of the path-parameter window searched for the nearest point, s.
    #[cfg_attr(feature = "serde", serde(default = "default_contour_window"))]
    pub contour_window_s: f64,
}

/// Contour error sampling period by default: 1 ms.
pub const DEFAULT_CONTOUR_EVERY_S: f64 = 1e-3;
/// Nearest-point search half-window by default: 0.5 s of path time.
pub const DEFAULT_CONTOUR_WINDOW_S: f64 = 0.5;

#[cfg(feature = "serde")]
fn default_contour_every() -> f64 {
    DEFAULT_CONTOUR_EVERY_S
}
#[cfg(feature = "serde")]
fn default_contour_window() -> f64 {
    DEFAULT_CONTOUR_WINDOW_S
}

impl Default for TruthSpec {
    fn default() -> Self {
        Self {
            itse_window_s: None,
            contour_from_s: None,
            contour_every_s: DEFAULT_CONTOUR_EVERY_S,
            contour_window_s: DEFAULT_CONTOUR_WINDOW_S,
        }
    }
}

/// The figures of a run. Errors are `q_d - q` on the true plant state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TruthFigures {
    pub samples: u64,
    pub itse: [f64; AXES],
    pub itse_window: [f64; AXES],
    pub iae: [f64; AXES],
    pub max_abs_error: [f64; AXES],
    pub contour_max: f64,
    pub contour_rms: f64,
    /// Total variation of the effort over the run, per axis.
    pub tv_u: [f64; AXES],
    pub peak_u: [f64; AXES],
}

/// Accumulates [`TruthFigures`].
#[derive(Clone, Copy, Debug)]
pub struct Truth {
    spec: TruthSpec,
    samples: u64,
    itse: [Itse<f64>; AXES],
    window: [Itse<f64>; AXES],
    iae: [f64; AXES],
    max_err: [f64; AXES],
    contour: MaxRms<f64>,
    tv: [TotalVariation<f64>; AXES],
    peak: [f64; AXES],
    next_contour_t: f64,
}

impl Truth {
    pub fn new(spec: TruthSpec) -> Self {
        let [a, b] = spec.itse_window_s.unwrap_or([0.0, 0.0]);
        Self {
            spec,
            samples: 0,
            itse: [Itse::new(); AXES],
            window: [Itse::window(a, b); AXES],
            iae: [0.0; AXES],
            max_err: [0.0; AXES],
            contour: MaxRms::default(),
            tv: [TotalVariation::default(); AXES],
            peak: [0.0; AXES],
            next_contour_t: spec.contour_from_s.unwrap_or(f64::INFINITY),
        }
    }

    /// Record one period starting at `t` (length `dt`) with true positions `pos` and the
    /// effort `u` held over it. Returns the true contour error when it was sampled.
    pub fn record(
        &mut self,
        reference: &Trajectory<f64>,
        t: f64,
        dt: f64,
        pos: Vec3<f64>,
        u: [f64; AXES],
    ) -> Option<f64> {
        let r = reference.sample(t).pos;
        let window_s = self.spec.contour_window_s;
        self.record_at(r, t, dt, pos, u, || {
            distance_to_path(reference, pos, t, window_s)
        })
    }

    /// [`Self::record`] against the reference position `r` of this period (a program's:
    /// what the machine's planner sampled), with the contour error `contour` (the distance
    /// to the programmed path) when one is due.
    pub fn record_at(
        &mut self,
        r: Vec3<f64>,
        t: f64,
        dt: f64,
        pos: Vec3<f64>,
        u: [f64; AXES],
        contour: impl FnOnce() -> f64,
    ) -> Option<f64> {
        self.samples += 1;
        for i in 0..AXES {
            let e = r[i] - pos[i];
            self.itse[i].add(t, e, dt);
            self.window[i].add(t, e, dt);
            self.iae[i] += e.abs() * dt;
            self.max_err[i] = self.max_err[i].max(e.abs());
            self.tv[i].add(u[i]);
            self.peak[i] = self.peak[i].max(u[i].abs());
        }
        // half a step of slack so float drift in t never skips a sample
        if t + 0.5 * dt >= self.next_contour_t {
            let d = contour();
            self.contour.add(d);
            self.next_contour_t += self.spec.contour_every_s;
            Some(d)
        } else {
            None
        }
    }

    pub fn figures(&self) -> TruthFigures {
        TruthFigures {
            samples: self.samples,
            itse: self.itse.map(|i| i.value),
            itse_window: self.window.map(|i| i.value),
            iae: self.iae,
            max_abs_error: self.max_err,
            contour_max: self.contour.max,
            contour_rms: self.contour.rms(),
            tv_u: self.tv.map(|t| t.value),
            peak_u: self.peak,
        }
    }
}
