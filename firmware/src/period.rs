//! One control period on the board: the commands that arrived since the last period (from
//! the mailbox: the arm button today, the host link later), then the core's servo step on
//! the board's IO. This is the whole measured body of the control interrupt; it never
//! logs, allocates or blocks.

use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::{Command, Servo};
use heapless::spsc::Consumer;

use crate::board::io::BoardIo;

/// Commands the control task takes at most per period (the rest wait for the next one).
pub const COMMANDS_PER_PERIOD: usize = 4;

/// A finished run's result; the board's servo runs forever.
pub type End = core::convert::Infallible;

/// The control interrupt's state on the board.
pub struct BoardPeriod {
    servo: Servo<f32>,
    io: BoardIo,
    commands: Consumer<'static, Command>,
}

impl BoardPeriod {
    pub fn new(servo: Servo<f32>, io: BoardIo, commands: Consumer<'static, Command>) -> Self {
        Self {
            servo,
            io,
            commands,
        }
    }

    /// Drain the mailbox, run the servo step.
    #[inline]
    pub fn control(&mut self) -> &Snapshot {
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
