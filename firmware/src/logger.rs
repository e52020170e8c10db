//! Turns the control interrupt's telemetry into defmt log lines (low-priority task only),
//! with the stack's high-water mark (`crate::stack`).

use controller_core::servo::ServoState;
use firmware::telemetry::Telemetry;

/// Logs state changes (with the fault reason) as they are seen, and a status line.
pub struct Logger {
    last_state: ServoState,
    /// `firmware::stall::POSITION_STALLS` last logged.
    stalls: u32,
}

impl Logger {
    pub const fn new() -> Self {
        Self {
            last_state: ServoState::Disabled,
            stalls: 0,
        }
    }

    /// One call per telemetry period.
    pub fn report(&mut self, t: &Telemetry) {
        let s = &t.snapshot;
        if s.state != self.last_state {
            match (s.state, s.fault) {
                (ServoState::Fault, Some(f)) => {
                    defmt::error!("FAULT, outputs off: {}", f)
                }
                (state, _) => defmt::info!("state {}", state),
            }
            self.last_state = s.state;
        }
        self.report_stalls();
        let (stack_size, stack_used) = crate::stack::high_water();
        defmt::info!(
            "k={=u32} t={=f32}s pos=[{=f32},{=f32},{=f32}] trk=[{=f32},{=f32},{=f32}] ctr={=f32} u=[{=f32},{=f32},{=f32}] overruns={=u32} isr_cyc={=u32}/{=u32} stack={=u32}/{=u32}",
            s.period,
            s.motion_t_s,
            s.pos[0],
            s.pos[1],
            s.pos[2],
            s.tracking[0],
            s.tracking[1],
            s.tracking[2],
            s.contour_norm(),
            s.effort[0],
            s.effort[1],
            s.effort[2],
            t.timing.overruns,
            t.timing.last,
            t.timing.max,
            stack_used,
            stack_size
        );
    }

    /// A control-loop stall longer than the 16-bit encoder counters can follow (board:
    /// `period::StallWatch`; QEMU: never).
    fn report_stalls(&mut self) {
        let n = firmware::stall::POSITION_STALLS.load(core::sync::atomic::Ordering::Relaxed);
        if n != self.stalls {
            self.stalls = n;
            #[cfg(not(feature = "qemu"))]
            let ms = crate::period::STALL_LONGEST_CYCLES
                .load(core::sync::atomic::Ordering::Relaxed)
                / (crate::board::SYSCLK_HZ / 1000);
            #[cfg(feature = "qemu")]
            let ms = 0;
            defmt::warn!(
                "the control loop stalled {=u32} ms (a flash erase): Z's 16-bit count may have wrapped unseen; home Z again before a program",
                ms
            );
        }
    }
}
