//! The discrete mode: controller-core's [`SimRun`] (the machine's period, its servo step,
//! against the simulated world), one control period at a time, plus the trace. Studies
//! that need more than the figures (e.g. the adaptive law's estimates over time) watch
//! every period through an [`Observer`].

use super::{Decimator, RunResult, Trace, TRACE_EVERY_S};
use anyhow::{anyhow, Result};
use controller_core::sim::run::SimRun;
use controller_core::Real;
use gantry_scenario::Resolved;

/// Watches a run after every period's servo step.
pub trait Observer<R> {
    fn period(&mut self, run: &SimRun<R>);
}

impl<R> Observer<R> for () {
    fn period(&mut self, _: &SimRun<R>) {}
}

/// Run `r` in discrete mode with the controller in number type `R`.
pub fn run<R: Real>(r: &Resolved, obs: &mut impl Observer<R>) -> Result<RunResult> {
    let mut run = SimRun::<R>::new(&r.run)
        .map_err(|e| anyhow!("run `{}`: invalid configuration: {e}", r.name))?;
    let dt = 1.0 / f64::from(r.run.servo.rate_hz);
    let mut trace = Trace::default();
    let mut dec = Decimator::new(TRACE_EVERY_S);
    while !run.done() {
        let snap = *run.control();
        obs.period(&run);
        let t = run.world().time_s();
        if dec.due(t, dt) {
            let st = run.world().state();
            trace.t.push(t);
            trace
                .reference
                .push(run.reference().sample(t).pos.to_array());
            trace.position.push([st[0].pos, st[1].pos, st[2].pos]);
            trace.u.push(run.world().effort());
            trace.s.push(snap.s.map(f64::from));
            trace.contour_model.push(snap.contour.map(f64::from));
        }
        run.finish_period();
    }
    Ok(RunResult::from_figures(&run.figures(), trace))
}
