//! The discrete mode: controller-core's [`SimRun`] (the machine's period, its servo step,
//! against the simulated world), one control period at a time, plus the trace. Studies
//! that need more than the figures (e.g. the adaptive law's estimates over time) watch
//! every period through an [`Observer`].
//!
//! A program run (`program = true`) has a machine with the planner split as the board
//! splits it ([`super::split_memory`]): its planning half runs once after every period.

use super::split_memory::SplitParts;
use super::{Decimator, RunResult, Trace, TRACE_EVERY_S};
use anyhow::{anyhow, Result};
use controller_core::axes::Axis;
use controller_core::machine::MachineMemory;
use controller_core::motion::planner::PlannerHandle;
use controller_core::servo::Servo;
use controller_core::sim::run::{factory_planner, RunMachine, SimRun};
use controller_core::Real;
use gantry_scenario::Resolved;
use std::ops::DerefMut;

/// What an [`Observer`] sees of a run after a period's servo step.
pub struct PeriodView<'a, R> {
    pub servo: &'a Servo<R>,
    /// Periods run before this one.
    pub periods_run: u32,
    /// The run's period of the injection, once it happened.
    pub injected_at: Option<u32>,
}

/// Watches a run after every period's servo step.
pub trait Observer<R> {
    fn period(&mut self, run: &PeriodView<'_, R>);
}

impl<R> Observer<R> for () {
    fn period(&mut self, _: &PeriodView<'_, R>) {}
}

/// Run `r` in discrete mode with the controller in number type `R`.
pub fn run<R: Real>(r: &Resolved, obs: &mut impl Observer<R>) -> Result<RunResult> {
    let invalid = |e| anyhow!("run `{}`: invalid configuration: {e}", r.name);
    if r.run.program {
        let mut parts = SplitParts::new();
        let (memory, mut task) = parts.split();
        let planner = factory_planner(r.run.servo.rate_hz);
        let mut run = SimRun::<R, _, _>::with_memory(&r.run, &planner, memory).map_err(invalid)?;
        compensate(r, run.machine_mut())?;
        Ok(drive(r, run, obs, || task.run()))
    } else {
        let mut run = SimRun::<R>::new(&r.run).map_err(invalid)?;
        compensate(r, run.machine_mut())?;
        Ok(drive(r, run, obs, || {}))
    }
}

/// The run's compensation tables entered into its machine, if it has any.
fn compensate<R: Real, P, M>(r: &Resolved, m: &mut RunMachine<R, P, M>) -> Result<()>
where
    P: DerefMut<Target = MachineMemory<M>>,
    M: PlannerHandle,
{
    if let Some(c) = &r.compensation {
        for (axis, t) in Axis::ALL.into_iter().zip(c.iter()) {
            m.set_compensation(axis, *t)
                .map_err(|e| anyhow!("run `{}`: compensation of {axis:?}: {e:?}", r.name))?;
        }
    }
    Ok(())
}

/// Every period of `run`, then `after_period` (the planning half of a split planner).
fn drive<R, P, M>(
    r: &Resolved,
    mut run: SimRun<R, P, M>,
    obs: &mut impl Observer<R>,
    mut after_period: impl FnMut(),
) -> RunResult
where
    R: Real,
    P: DerefMut<Target = MachineMemory<M>>,
    M: PlannerHandle,
{
    let dt = 1.0 / f64::from(r.run.servo.rate_hz);
    let mut trace = Trace::default();
    let mut dec = Decimator::new(TRACE_EVERY_S);
    while !run.done() {
        let snap = *run.control();
        obs.period(&PeriodView {
            servo: run.servo(),
            periods_run: run.periods_run(),
            injected_at: run.injected_at(),
        });
        let t = run.world().time_s();
        if dec.due(t, dt) {
            trace.t.push(t);
            trace
                .reference
                .push(run.reference().sample(t).pos.to_array());
            trace.position.push(run.world().tool_pos());
            trace.u.push(run.world().effort());
            trace.s.push(snap.s.map(f64::from));
            trace.contour_model.push(snap.contour.map(f64::from));
        }
        run.finish_period();
        after_period();
    }
    RunResult::from_figures(&run.figures(), trace)
}
