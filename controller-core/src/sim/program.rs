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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::port::REQUEST_QUEUE;
    use crate::presets::board::servo_config;
    use crate::sim::run::factory_planner;
    use crate::sim::run_memory::{NoPlanner, RunMemory};
    use crate::Vec3;

    fn machine() -> Machine<RunMemory, NoPlanner, f32> {
        let cfg = servo_config(10_000);
        Machine::from_config(
            &cfg,
            &factory_planner(10_000),
            [0; 3],
            [0; 3],
            RunMemory::new(),
        )
        .unwrap()
    }

    fn square() -> Polyline<f64> {
        Polyline::square(Vec3::zero(), 40.0, 50.0, 1000.0).unwrap()
    }

    #[test]
    fn sends_arm_run_every_edge_and_the_end_when_the_queue_has_room() {
        let mut m = machine();
        let mut feed = ProgramFeed::new(&square());
        feed.send(&mut m);
        assert!(feed.done());
        // arm, run, four segments, the end
        assert_eq!(usize::from(m.free_slots()), REQUEST_QUEUE - 7);
        // nothing more once done
        feed.send(&mut m);
        assert_eq!(usize::from(m.free_slots()), REQUEST_QUEUE - 7);
    }

    #[test]
    fn never_sends_beyond_the_queue_and_goes_on_where_it_stopped() {
        let mut m = machine();
        for _ in 0..REQUEST_QUEUE - 3 {
            m.submit(Request::Reset);
        }
        let mut feed = ProgramFeed::new(&square());
        feed.send(&mut m);
        // arm, run and one segment: the queue is full, nothing was dropped
        assert_eq!(m.free_slots(), 0);
        assert!(!feed.done());
        assert_eq!(feed.sent, 1);
        // with room again (a machine whose queue drained), it goes on from the second
        // segment: three more and the end, no second arm or run
        let mut m = machine();
        feed.send(&mut m);
        assert!(feed.done());
        assert_eq!(usize::from(m.free_slots()), REQUEST_QUEUE - 4);
    }
}
