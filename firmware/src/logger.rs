//! Turns telemetry snapshots into defmt log lines (low-priority task only).

use firmware::safety::SafetyState;
use firmware::telemetry::{Figures, Snapshot};

/// Logs state changes (with the fault reason) as they are seen, and a status line.
pub struct Logger {
    last_state: SafetyState,
}

impl Logger {
    pub const fn new() -> Self {
        Self {
            last_state: SafetyState::Disabled,
        }
    }

    /// One call per telemetry period.
    pub fn report(&mut self, s: &Snapshot) {
        if s.state != self.last_state {
            match s.state {
                SafetyState::Fault(reason) => {
                    defmt::error!("FAULT, outputs disabled: {}", reason)
                }
                SafetyState::Enabled => defmt::info!("outputs ENABLED"),
                SafetyState::Disabled => defmt::warn!("outputs disabled"),
            }
            self.last_state = s.state;
        }
        defmt::info!(
            "k={=u32} t={=f32}s pos=[{=f32},{=f32},{=f32}] trk=[{=f32},{=f32},{=f32}] ctr={=f32} u=[{=f32},{=f32},{=f32}] overruns={=u32} isr_cyc={=u32}/{=u32}",
            s.period,
            s.traj_t_s,
            s.pos[0],
            s.pos[1],
            s.pos[2],
            s.tracking[0],
            s.tracking[1],
            s.tracking[2],
            s.contour,
            s.effort[0],
            s.effort[1],
            s.effort[2],
            s.timing.overruns,
            s.timing.last_cycles,
            s.timing.max_cycles
        );
    }
}

/// Logs a set of run figures under `label`.
pub fn figures(label: &str, f: &Figures) {
    defmt::info!(
        "{=str}: samples={=u32} ITSE=[{=f32}, {=f32}, {=f32}] max|e|=[{=f32}, {=f32}, {=f32}] contour max={=f32} rms={=f32}",
        label,
        f.samples,
        f.itse[0],
        f.itse[1],
        f.itse[2],
        f.tracking_max[0],
        f.tracking_max[1],
        f.tracking_max[2],
        f.contour_max,
        f.contour_rms
    );
}
