//! The continuous mode: the controller is evaluated at every RK4 stage of step `dt` and its
//! laws' integrals are integrated together with the plants (the paper's Matlab setting).
//! The plant models are the simulated world's, the figures the same recorder's; the
//! controller sees the exact plant state (no encoder, no amplifier).

use super::{Decimator, RunResult, Trace, TRACE_EVERY_S};
use anyhow::{anyhow, bail, Result};
use controller_core::controller::{ControlOutput, Controller3, Measured};
use controller_core::coupling::variable_gain::VariableGainState;
use controller_core::law::LawState;
use controller_core::motion::trajectory::Trajectory;
use controller_core::num::ode::{rk4, OdeState};
use controller_core::plant::state::{axis_derivative, AxisDynamics, AxisState};
use controller_core::sim::truth::Truth;
use controller_core::sim::world::{Plant, PlantConfig};
use controller_core::{Real, Vec3};
use gantry_scenario::Resolved;

/// Plant states plus the controller's integral states: the ODE state.
#[derive(Clone, Copy)]
struct Augmented {
    plant: [AxisState<f64>; 3],
    integral: [f64; 3],
}

impl OdeState<f64> for Augmented {
    fn add_scaled(&self, d: &Self, h: f64) -> Self {
        let mut integral = self.integral;
        for (x, dx) in integral.iter_mut().zip(d.integral) {
            *x += dx * h;
        }
        Self {
            plant: self.plant.add_scaled(&d.plant, h),
            integral,
        }
    }
}

/// Run `r` in continuous mode with step `dt_s` and the controller in number type `R`.
pub fn run<R: Real>(r: &Resolved, dt_s: f64) -> Result<RunResult> {
    if r.compensation.is_some() {
        anyhow::bail!(
            "run `{}`: compensation tables need the discrete mode (the servo step applies them)",
            r.name
        );
    }
    let cfg = &r.run;
    let mut ctl = Controller3::<R>::new(&cfg.servo.controller)
        .map_err(|e| anyhow!("run `{}`: invalid controller configuration: {e}", r.name))?;
    let plants = [0, 1, 2]
        .map(|i| Plant::new(&cfg.world.plants[i]))
        .into_iter()
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow!("run `{}`: invalid plant: {e}", r.name))?;
    let plants: [Plant; 3] = [plants[0], plants[1], plants[2]];
    if cfg
        .world
        .plants
        .iter()
        .any(|p| matches!(p, PlantConfig::Physical(a) if a.frame.is_some()))
    {
        bail!(
            "run `{}`: an axis with a frame runs in discrete mode only",
            r.name
        );
    }
    let traj: Trajectory<R> = r.reference.cast();
    let n = (r.horizon_s / dt_s).round() as usize;
    let init = cfg.world.initial;
    let mut x = Augmented {
        plant: init.map(|s| AxisState {
            pos: s.pos_mm,
            vel: s.vel_mm_s,
        }),
        integral: [0.0; 3],
    };
    let vg = VariableGainState::default();
    let eval = |c: &Controller3<R>, t: f64, x: &Augmented| -> ControlOutput<R> {
        let states = x.integral.map(|v| LawState {
            integral: R::from_f64(v),
            ..Default::default()
        });
        let rs = traj.sample(R::from_f64(t));
        let m = Measured {
            pos: Vec3::new(x.plant[0].pos, x.plant[1].pos, x.plant[2].pos).cast(),
            vel: Vec3::new(x.plant[0].vel, x.plant[1].vel, x.plant[2].vel).cast(),
        };
        c.evaluate_with(&states, &vg, &rs, &m, rs.vel)
    };
    let mut truth = Truth::new(cfg.truth);
    let mut trace = Trace::default();
    let mut dec = Decimator::new(TRACE_EVERY_S);
    for k in 0..n {
        let t = k as f64 * dt_s;
        let out = eval(&ctl, t, &x);
        let u = out.u.cast::<f64>().to_array();
        let pos = Vec3::new(x.plant[0].pos, x.plant[1].pos, x.plant[2].pos);
        truth.record(&r.reference, t, dt_s, pos, u);
        if dec.due(t, dt_s) {
            trace.t.push(t);
            trace.reference.push(r.reference.sample(t).pos.to_array());
            trace.position.push(pos.to_array());
            trace.u.push(u);
            trace.s.push(out.s.cast::<f64>().to_array());
            trace
                .contour_model
                .push(out.contour.cast::<f64>().to_array());
        }
        x = rk4(&x, t, dt_s, |tt, s| {
            let o = eval(&ctl, tt, s);
            let rates = o.integral_rates();
            let mut d = *s;
            for (i, plant) in plants.iter().enumerate() {
                let acc = plant.accel(s.plant[i], o.u[i].to_f64(), tt);
                d.plant[i] = axis_derivative(s.plant[i], acc);
                d.integral[i] = rates[i].to_f64();
            }
            d
        });
        // integral limits apply to the continuous state as well
        ctl.set_states(x.integral.map(|v| LawState {
            integral: R::from_f64(v),
            ..Default::default()
        }));
        for i in 0..3 {
            x.integral[i] = ctl.states()[i].integral.to_f64();
        }
    }
    Ok(RunResult::from_figures(&truth.figures(), trace))
}
