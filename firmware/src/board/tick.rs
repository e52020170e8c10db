//! The control timer: TIM4's update interrupt runs the control task. TIM4 (not a basic
//! timer) because QEMU's STM32F405 model emulates it, so the QEMU rig binds the very same
//! interrupt.

use stm32f4xx_hal::{
    pac,
    prelude::*,
    timer::{CounterHz, Event, Flag},
};

/// Rate programmed into the control timer (TIM4).
#[cfg(not(feature = "qemu"))]
pub const CONTROL_TICK_PROGRAMMED_HZ: u32 = firmware::config::CONTROL_RATE_HZ;

/// QEMU: the emulated TIM4 counts 1 GHz of *virtual* time (1 ns per instruction with
/// `-icount shift=0`) whatever the RCC says, while the HAL computes the prescaler for the
/// 16 MHz HSI. Programming 4 Hz therefore gives an emulated period of 4 ms, i.e.
/// 4 000 000 instructions: room for the servo step *and* the simulated machine with its
/// true contour error (a nearest-point search on the path in soft-float `f64` every
/// millisecond of simulated time: over 1.6 M instructions on the square's polyline), so
/// the telemetry task runs between periods and the overrun counter means something. Each interrupt still advances
/// the simulated machine by the scenario's control period: the run is a faithful discrete
/// simulation at the scenario's rate; only the emulated wall clock runs slower (idle time
/// costs no host time with `-icount sleep=off`).
#[cfg(feature = "qemu")]
pub const CONTROL_TICK_PROGRAMMED_HZ: u32 = 4;

/// The timer whose update interrupt runs the control task.
pub struct ControlTick {
    timer: CounterHz<pac::TIM4>,
}

impl ControlTick {
    pub fn new(timer: CounterHz<pac::TIM4>) -> Self {
        Self { timer }
    }

    /// Starts the timer at `rate_hz` with its update interrupt enabled.
    pub fn start(&mut self, rate_hz: u32) {
        // `start` only fails for an ARR out of range; at 84 MHz every rate from 2 Hz to
        // 42 MHz fits (PSC is computed), so a failure means a misconfigured build.
        if self.timer.start(rate_hz.Hz()).is_err() {
            defmt::error!("control timer rejected rate {=u32} Hz", rate_hz);
        }
        self.timer.listen(Event::Update);
    }

    /// Acknowledges the update interrupt (first thing in the control task).
    #[inline]
    pub fn acknowledge(&mut self) {
        self.timer.clear_flags(Flag::Update);
    }

    /// True if another update happened since [`acknowledge`](Self::acknowledge): the
    /// control task did not finish within its period.
    #[inline]
    pub fn overran(&self) -> bool {
        self.timer.flags().contains(Flag::Update)
    }

    /// Stops the timer interrupt (end of a finite QEMU run).
    #[cfg_attr(not(feature = "qemu"), allow(dead_code))]
    pub fn stop(&mut self) {
        self.timer.unlisten(Event::Update);
    }
}
