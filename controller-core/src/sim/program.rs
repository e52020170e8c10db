//! A program run's requests ([`super::run::RunConfig::program`]): what a host sends the
//! machine over its link to run a polyline as a program — arm, run, one line segment per
//! edge at the path's speed (tagged with the edge's number from 1) while the machine's
//! request queue has room, then the end of the program. The machine's supervisor and
//! planner do the rest, as on the board.

use crate::machine::messages::Request;
use crate::machine::{Machine, MachineMemory};
use crate::motion::planner::{PlannerHandle, Segment};
use crate::motion::trajectory::Polyline;
use crate::Real;
use core::ops::DerefMut;

/// Requests still to send for one program.
#[derive(Clone, Copy, Debug)]
pub struct ProgramFeed {
    path: Polyline<f64>,
    /// Arm and run were sent.
    started: bool,
    /// Edges sent.
    sent: usize,
    /// The end of the program was sent.
    ended: bool,
}

impl ProgramFeed {
    pub fn new(path: &Polyline<f64>) -> Self {
        Self {
            path: *path,
            started: false,
            sent: 0,
            ended: false,
        }
    }

    /// Every request was sent.
    pub fn done(&self) -> bool {
        self.ended
    }

    /// Send what the machine's request queue has room for (the link's credit).
    pub fn send<P, M, R>(&mut self, machine: &mut Machine<P, M, R>)
    where
        P: DerefMut<Target = MachineMemory<M>>,
        M: PlannerHandle,
        R: Real,
    {
        let submit = |m: &mut Machine<P, M, R>, r: Request| {
            if m.free_slots() == 0 {
                return false;
            }
            m.submit(r);
            true
        };
        if !self.started {
            if machine.free_slots() < 2 {
                return;
            }
            submit(machine, Request::Arm);
            submit(machine, Request::Run);
            self.started = true;
        }
        while let Some(end) = self.path.edge_end(self.sent) {
            let feed_mm_s = self.path.speed() as f32;
            let seg = Segment::line(
                end.cast::<f32>().to_array(),
                feed_mm_s,
                self.sent as u32 + 1,
            );
            if !submit(machine, Request::Segment(seg)) {
                return;
            }
            self.sent += 1;
        }
        if !self.ended && submit(machine, Request::EndProgram) {
            self.ended = true;
        }
    }
}
