//! One control period on the board: a clock fault flagged by the clock security system,
//! the commands that arrived since the last period (from the mailbox: the arm button
//! today, the host link later), then the core's servo step on the board's IO. This is the
//! whole measured body of the control interrupt; it never logs, allocates or blocks.

use controller_core::servo::faults::FaultKind;
use controller_core::servo::io::ServoIo;
use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::{Command, Servo};
use heapless::spsc::Consumer;

use crate::board::{clock, io::BoardIo, watchdog::Watchdog};
use firmware::watchdog::IwdgSetting;

/// Commands the control task takes at most per period (the rest wait for the next one).
pub const COMMANDS_PER_PERIOD: usize = 4;

/// A finished run's result; the board's servo runs forever.
pub type End = core::convert::Infallible;

/// The control interrupt's state on the board.
pub struct BoardPeriod {
    servo: Servo<f32>,
    io: BoardIo,
    commands: Consumer<'static, Command>,
    /// Fed at the end of every period that ran on time, by nothing else.
    watchdog: Watchdog,
}

impl BoardPeriod {
    pub fn new(
        servo: Servo<f32>,
        io: BoardIo,
        commands: Consumer<'static, Command>,
        watchdog: Watchdog,
    ) -> Self {
        Self {
            servo,
            io,
            commands,
            watchdog,
        }
    }

    /// Starts the independent watchdog (the last step of `init`).
    pub fn start_watchdog(&mut self, setting: IwdgSetting) {
        self.watchdog.start(setting);
    }

    /// Latch a board fault found outside the servo step (e.g. the crystal failed to start)
    /// and switch the outputs off now.
    pub fn latch_board_fault(&mut self, kind: FaultKind) {
        self.io.disable_outputs();
        self.servo.latch_board_fault(kind);
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

    /// Latch a clock fault from the clock security system, drain the mailbox, run the
    /// servo step.
    #[inline]
    pub fn control(&mut self) -> &Snapshot {
        if clock::take_css_fault() {
            self.latch_board_fault(FaultKind::ClockFault);
        }
        let mut cmds = [Command::Disarm; COMMANDS_PER_PERIOD];
        let mut n = 0;
        while n < COMMANDS_PER_PERIOD {
            match self.commands.dequeue() {
                Some(c) => {
                    cmds[n] = c;
                    n += 1;
                }
                None => break,
            }
        }
        self.servo.period(&mut self.io, &cmds[..n])
    }

    /// The last period's snapshot.
    pub fn snapshot(&self) -> &Snapshot {
        self.servo.snapshot()
    }

    /// After the measured part: nothing to do on the board.
    #[inline]
    pub fn finish(&mut self) -> Option<End> {
        None
    }
}
