//! One control period on the board: a clock fault flagged by the clock security system,
//! the arm button's commands (its mailbox), then the machine's period — the host link's
//! requests from its queues, supervisor, planner and servo step on the board's IO — and
//! the link's clock. This is the whole measured body of the control interrupt; it never
//! logs, allocates, formats or blocks.

use core::sync::atomic::Ordering;

use controller_core::link::LinkClock;
use controller_core::machine::ControlSide;
use controller_core::servo::faults::FaultKind;
use controller_core::servo::io::ServoIo;
use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::Command;
use heapless::spsc::Consumer;

use crate::board::{clock, io::BoardIo, watchdog::Watchdog, SYSCLK_HZ};
use crate::link::LINK_CLOCK_MS;
use crate::machine_slot::FwMachine;
use controller_core::axes::Axis;
use controller_core::estimator::CounterWidth;
use controller_core::presets::gantry::GANTRY_ENCODERS;
use firmware::stall::{alias_safe_s, StallWatch, POSITION_STALLS};
use firmware::watchdog::IwdgSetting;

/// Gaps between control interrupts up to this many periods are never a stall worth
/// checking (an overrun or two).
const QUICK_GAP_PERIODS: u32 = 4;

/// Button commands the control task takes at most per period (the rest wait).
pub const COMMANDS_PER_PERIOD: usize = 2;

/// A finished run's result; the board's machine runs forever.
pub type End = core::convert::Infallible;

/// The control interrupt's state on the board.
pub struct BoardPeriod {
    machine: &'static mut FwMachine,
    link: ControlSide<'static>,
    io: BoardIo,
    commands: Consumer<'static, Command>,
    /// Fed at the end of every period that ran on time, by nothing else.
    watchdog: Watchdog,
    /// Gaps between control interrupts: a stall too long for the 16-bit encoder counters
    /// (firmware::stall) makes their axes' homes forgotten.
    stall: StallWatch,
    /// Gaps up to this many cycles are never a stall ([`QUICK_GAP_PERIODS`]; computed
    /// once, no division in the interrupt).
    quick_gap_cycles: u32,
    /// The link's clock, counted from the periods run.
    clock: LinkClock,
}

impl BoardPeriod {
    pub fn new(
        machine: &'static mut FwMachine,
        link: ControlSide<'static>,
        io: BoardIo,
        commands: Consumer<'static, Command>,
        watchdog: Watchdog,
        rate_hz: u32,
    ) -> Self {
        Self {
            machine,
            link,
            io,
            commands,
            watchdog,
            stall: StallWatch::new(),
            quick_gap_cycles: QUICK_GAP_PERIODS
                .saturating_mul(SYSCLK_HZ.checked_div(rate_hz).unwrap_or(SYSCLK_HZ)),
            clock: LinkClock::new(rate_hz),
        }
    }

    /// Starts the independent watchdog (the last step of `init`).
    pub fn start_watchdog(&mut self, setting: IwdgSetting) {
        self.watchdog.start(setting);
    }

    /// Latch a board fault found outside the servo step (the crystal failed to start,
    /// the settings store is corrupt) and switch the outputs off now.
    pub fn latch_board_fault(&mut self, kind: FaultKind) {
        self.io.disable_outputs();
        self.machine.latch_board_fault(kind);
    }

    /// The end of the control interrupt: `overran` (the period that just ended missed its
    /// deadline) becomes the next period's `Inputs::overrun`, counted by the core's overrun
    /// monitor. Every period that completes feeds the watchdog, late or not: the watchdog
    /// is for a control interrupt that stopped running (a hang, a lock-up), which it
    /// answers with a reset (outputs off); lateness is the overrun monitor's, which
    /// answers with a controlled stop — a reset would cut that stop short and drop an
    /// axis that must be held (Z against gravity).
    #[inline]
    pub fn end_of_period(&mut self, overran: bool) {
        self.io.set_overrun(overran);
        self.watchdog.feed();
    }

    /// Latch a clock fault from the clock security system, take the button's commands,
    /// run the machine's period, advance the link's clock.
    #[inline]
    pub fn control(&mut self) -> &Snapshot {
        if clock::take_css_fault() {
            self.latch_board_fault(FaultKind::ClockFault);
        }
        let quick = self.quick_gap_cycles;
        let machine = &self.machine;
        let stalled = self
            .stall
            .entry(cortex_m::peripheral::DWT::cycle_count(), quick, || {
                let s = machine.settings();
                let shortest = AXES_16BIT
                    .iter()
                    .map(|a| alias_safe_s(s.axis[a.index()].encoder.counts_per_mm))
                    .fold(f32::INFINITY, f32::min);
                // (a float-to-int `as` saturates, and NaN gives 0: any gap is then a stall)
                (shortest * SYSCLK_HZ as f32) as u32
            });
        if stalled {
            self.position_lost();
        }
        for _ in 0..COMMANDS_PER_PERIOD {
            match self.commands.dequeue() {
                Some(c) => self.machine.local(c),
                None => break,
            }
        }
        let full_scale = self.machine.settings().axis.map(|a| a.amplifier.full_scale);
        self.io.set_full_scale(full_scale);
        self.machine.linked_period(&mut self.io, &mut self.link);
        LINK_CLOCK_MS.store(self.clock.period(), Ordering::Release);
        self.machine.servo().snapshot()
    }

    /// A stall the 16-bit counters cannot have followed: their axes must be homed again.
    #[cold]
    #[inline(never)]
    fn position_lost(&mut self) {
        for a in AXES_16BIT {
            self.machine.forget_home(a);
        }
        POSITION_STALLS.store(self.stall.stalls, Ordering::Relaxed);
        STALL_LONGEST_CYCLES.store(self.stall.longest_cycles, Ordering::Relaxed);
    }

    /// The last period's snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        self.machine.servo().snapshot()
    }

    /// After the measured part: nothing to do on the board.
    #[inline]
    pub fn finish(&mut self) -> Option<End> {
        None
    }
}

/// The axes whose encoder timer counts in 16 bits (the board's Z, TIM3).
const AXES_16BIT: [Axis; 1] = [Axis::Z];

const _: () = {
    // the list above is the preset's
    assert!(matches!(GANTRY_ENCODERS[0].counter, CounterWidth::Bits32));
    assert!(matches!(GANTRY_ENCODERS[1].counter, CounterWidth::Bits32));
    assert!(matches!(GANTRY_ENCODERS[2].counter, CounterWidth::Bits16));
};

/// The longest stall behind [`POSITION_STALLS`], cycles (for the log).
pub static STALL_LONGEST_CYCLES: core::sync::atomic::AtomicU32 =
    core::sync::atomic::AtomicU32::new(0);
