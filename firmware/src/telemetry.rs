//! The telemetry snapshot the control interrupt publishes every period.
//!
//! The interrupt only *copies* plain numbers into a [`Snapshot`]; it never formats or logs.
//! A low-priority task copies the latest snapshot out (a short RTIC resource lock) and
//! turns it into defmt log lines at its own pace. Values lost between two log lines are
//! not needed: the running [`Figures`] carry the whole-run statistics.

use crate::safety::SafetyState;
use crate::AXES;

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
#[cfg_attr(target_os = "none", derive(defmt::Format))]
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
    /// Run statistics.
    pub figures: Figures,
    /// Interrupt timing.
    pub timing: Timing,
    /// True once a finite-horizon run (the QEMU scenario) has completed.
    pub finished: bool,
}

impl Snapshot {
    /// The snapshot before the first control period.
    pub const BOOT: Self = Self {
        period: 0,
        traj_t_s: 0.0,
        state: SafetyState::Disabled,
        pos: [0.0; AXES],
        reference: [0.0; AXES],
        tracking: [0.0; AXES],
        contour: 0.0,
        effort: [0.0; AXES],
        counts: [0; AXES],
        figures: Figures {
            samples: 0,
            itse: [0.0; AXES],
            tracking_max: [0.0; AXES],
            tracking_rms: [0.0; AXES],
            contour_max: 0.0,
            contour_rms: 0.0,
            effort_variation: [0.0; AXES],
        },
        timing: Timing {
            overruns: 0,
            last_cycles: 0,
            max_cycles: 0,
        },
        finished: false,
    };
}
