//! The telemetry snapshot the control interrupt publishes every period.
//!
//! The interrupt only *copies* plain numbers into a [`Snapshot`]; it never formats or logs.
//! A low-priority task copies the latest snapshot out (a short RTIC resource lock) and
//! turns it into defmt log lines at its own pace. Values lost between two log lines are
//! not needed: the running [`Figures`] carry the whole-run statistics.

use controller_core::metrics::{Itse, MaxRms, TotalVariation};

use crate::safety::SafetyState;
use crate::AXES;

/// Whole-run accumulators (controller-core metrics) of what the controller sees. The
/// control interrupt only adds samples; square roots and divisions for the RMS values are
/// left to whoever turns them into [`Figures`] (the low-priority logger).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunMetrics {
    itse: [Itse<f32>; AXES],
    tracking: [MaxRms<f32>; AXES],
    contour: MaxRms<f32>,
    variation: [TotalVariation<f32>; AXES],
}

impl RunMetrics {
    /// Adds one period: time, period, tracking error per axis, contour-error magnitude,
    /// applied effort per axis.
    pub fn add(
        &mut self,
        t_s: f32,
        dt_s: f32,
        tracking: &[f32; AXES],
        contour: f32,
        u: &[f32; AXES],
    ) {
        for i in 0..AXES {
            self.itse[i].add(t_s, tracking[i], dt_s);
            self.tracking[i].add(tracking[i]);
            self.variation[i].add(u[i]);
        }
        self.contour.add(contour);
    }

    /// The figures so far.
    pub fn figures(&self) -> Figures {
        let mut f = Figures {
            samples: self.contour.count(),
            contour_max: self.contour.max,
            contour_rms: self.contour.rms(),
            ..Figures::default()
        };
        for i in 0..AXES {
            f.itse[i] = self.itse[i].value;
            f.tracking_max[i] = self.tracking[i].max;
            f.tracking_rms[i] = self.tracking[i].rms();
            f.effort_variation[i] = self.variation[i].value;
        }
        f
    }
}

/// Whole-run tracking and contour figures (from controller-core's metric accumulators),
/// in the trajectory's length unit (mm on the machine, the paper's normalised unit in
/// the QEMU scenario) and seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Figures {
    /// Control periods accumulated.
    pub samples: u32,
    /// ITSE `∫ t E_i² dt` of the tracking error per axis.
    pub itse: [f32; AXES],
    /// Max |E_i| per axis.
    pub tracking_max: [f32; AXES],
    /// RMS of E_i per axis.
    pub tracking_rms: [f32; AXES],
    /// Max of the contour-error magnitude |e| (paper eq. 9 estimate).
    pub contour_max: f32,
    /// RMS of |e|.
    pub contour_rms: f32,
    /// Total variation of u per axis (chattering measure).
    pub effort_variation: [f32; AXES],
}

/// Timing of the control interrupt.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Timing {
    /// Periods whose next timer update had already happened when the interrupt finished.
    pub overruns: u32,
    /// Core cycles of the last interrupt body (DWT cycle counter; 0 where not available).
    pub last_cycles: u32,
    /// Largest `last_cycles` seen.
    pub max_cycles: u32,
}

/// Everything the logger needs, copied out of the control interrupt each period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Snapshot {
    /// Control periods since boot.
    pub period: u32,
    /// Trajectory time since the outputs were enabled, seconds.
    pub traj_t_s: f32,
    /// Safety state after this period.
    pub state: SafetyState,
    /// Measured positions (encoder counts converted to length).
    pub pos: [f32; AXES],
    /// Reference positions.
    pub reference: [f32; AXES],
    /// Tracking error reference - measured, per axis.
    pub tracking: [f32; AXES],
    /// Contour-error magnitude.
    pub contour: f32,
    /// Applied (saturated) control effort per axis; 0 while disabled.
    pub effort: [f32; AXES],
    /// Wide encoder positions, counts.
    pub counts: [i64; AXES],
    /// Run statistics (accumulators; [`RunMetrics::figures`] evaluates them).
    pub metrics: RunMetrics,
    /// Interrupt timing.
    pub timing: Timing,
    /// True once a finite-horizon run (the QEMU scenario) has completed.
    pub finished: bool,
}

impl Snapshot {
    /// The snapshot before the first control period.
    pub fn boot() -> Self {
        Self {
            period: 0,
            traj_t_s: 0.0,
            state: SafetyState::Disabled,
            pos: [0.0; AXES],
            reference: [0.0; AXES],
            tracking: [0.0; AXES],
            contour: 0.0,
            effort: [0.0; AXES],
            counts: [0; AXES],
            metrics: RunMetrics::default(),
            timing: Timing::default(),
            finished: false,
        }
    }
}
