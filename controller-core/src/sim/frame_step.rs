//! One period of a framed axis in the simulated world: the motor side and the tool side
//! of [`crate::plant::frame`] integrated together (RK4, the world's substeps) under the
//! period's held effort. The motor side carries the motor's torque and the screw's
//! friction; the tool side the guides' friction, the load and an injected external push;
//! the frame's spring and damper join them. A gripping holding brake (on the motor) holds the motor side
//! still while the tool side swings on the frame (its slip under a push beyond its
//! holding torque is the rigid axis' model only).

use crate::num::ode::{rk4, OdeState};
use crate::plant::frame::Frame;
use crate::plant::physical::PhysicalAxis;
use crate::plant::state::AxisState;
use crate::Real;

/// Motor and tool side of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FramedState {
    pub motor: AxisState<f64>,
    pub tool: AxisState<f64>,
}

impl OdeState<f64> for FramedState {
    fn add_scaled(&self, d: &Self, h: f64) -> Self {
        Self {
            motor: self.motor.add_scaled(&d.motor, h),
            tool: self.tool.add_scaled(&d.tool, h),
        }
    }
}

/// What pushes a framed axis over a period besides its effort.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FramedPush {
    /// An external acceleration of the whole axis (an obstruction: the world's
    /// `external_accel` injection), mm/s², applied as a force on the tool side.
    pub ext_mm_s2: f64,
    /// Extra friction (the world's `extra_friction` injection) as an acceleration of the
    /// whole axis, mm/s², on the motor side.
    pub drag_mm_s2: f64,
    /// The holding brake grips: the motor side stands still.
    pub gripping: bool,
}

/// Regularisation velocity of the injected drag's sign, units/s: the framed step's and
/// the world's rigid step's (`crate::sim::world`), like the plant's own friction sign.
pub(crate) const DRAG_V_REG: f64 = 0.5;

/// `d/dt` of `s` under effort `u` at time `t`.
fn derivative(
    plant: &PhysicalAxis<f64>,
    frame: &Frame,
    push: &FramedPush,
    s: &FramedState,
    u: f64,
    t: f64,
) -> FramedState {
    let j = 1.0 / plant.inv_inertia();
    let phi = frame.tool_friction();
    let force = frame.coupling(s.motor, s.tool);
    let guides = phi * plant.friction(s.tool.vel);
    let tool_acc = (force - guides - plant.load(t) + j * push.ext_mm_s2) * frame.inv_j_tool();
    let motor_acc = if push.gripping {
        0.0
    } else {
        let v = s.motor.vel;
        let drag = j * push.drag_mm_s2 * v / libm::sqrt(v * v + DRAG_V_REG * DRAG_V_REG);
        let u = u.finite_or_zero().clamp_sym(plant.torque_max());
        (u - (1.0 - phi) * plant.friction(v) - drag - force) * frame.inv_j_motor()
    };
    FramedState {
        motor: AxisState {
            pos: if push.gripping { 0.0 } else { s.motor.vel },
            vel: motor_acc,
        },
        tool: AxisState {
            pos: s.tool.vel,
            vel: tool_acc,
        },
    }
}

/// The state after `substeps` RK4 steps of `h` from time `t` with the effort `u` held.
#[allow(clippy::too_many_arguments)]
pub fn advance(
    plant: &PhysicalAxis<f64>,
    frame: &Frame,
    push: &FramedPush,
    mut s: FramedState,
    t: f64,
    h: f64,
    substeps: u32,
    u: f64,
) -> FramedState {
    for j in 0..substeps {
        let tj = t + f64::from(j) * h;
        s = rk4(&s, tj, h, |tt, x| derivative(plant, frame, push, x, u, tt));
        if push.gripping {
            s.motor.vel = 0.0;
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::frame::{FrameConfig, PitchErrorConfig};
    use crate::plant::physical::PhysicalAxisConfig;
    use crate::presets::gantry::GANTRY_Y;

    fn axis() -> (PhysicalAxis<f64>, Frame) {
        let c = PhysicalAxisConfig {
            coulomb_pos_mnm: 0.0,
            coulomb_neg_mnm: 0.0,
            viscous: 0.0,
            ..GANTRY_Y
        };
        let f = FrameConfig {
            mode_hz: 35.0,
            damping_ratio: 0.0,
            tool_inertia_ratio: 0.6,
            tool_friction_ratio: 0.3,
            backlash_mm: 0.0,
            pitch_error: PitchErrorConfig::default(),
        };
        (
            PhysicalAxis::new(&c).unwrap(),
            Frame::new(&f, c.inertia).unwrap(),
        )
    }

    /// The undamped two masses, released with the spring stretched, swing against each
    /// other at the mode's frequency: count the deflection's zero crossings over 1 s.
    #[test]
    fn released_frame_rings_at_its_mode_frequency() {
        let (plant, frame) = axis();
        let mut s = FramedState {
            motor: AxisState {
                pos: 0.01,
                vel: 0.0,
            },
            tool: AxisState::default(),
        };
        let h = 25e-6;
        let mut crossings = 0;
        let mut last = s.motor.pos - s.tool.pos;
        let mut first = None;
        let mut last_at = 0.0;
        for k in 0..40_000 {
            s = advance(
                &plant,
                &frame,
                &FramedPush::default(),
                s,
                k as f64 * h,
                h,
                1,
                0.0,
            );
            let d = s.motor.pos - s.tool.pos;
            if d * last < 0.0 {
                let at = (k + 1) as f64 * h;
                crossings += 1;
                first.get_or_insert(at);
                last_at = at;
            }
            last = d;
        }
        // half a period between crossings
        let f = (crossings - 1) as f64 / (2.0 * (last_at - first.unwrap()));
        assert!((f - 35.0).abs() < 0.01, "{f} Hz");
        // momentum is conserved: the centre of mass stays put
        let j_m = 1.0 / frame.inv_j_motor();
        let j_t = 1.0 / frame.inv_j_tool();
        let p = j_m * s.motor.vel + j_t * s.tool.vel;
        assert!(p.abs() < 1e-9, "{p}");
    }

    #[test]
    fn a_gripping_brake_holds_the_motor_and_the_tool_hangs_on_the_spring() {
        let (plant, frame) = axis();
        let push = FramedPush {
            gripping: true,
            ..FramedPush::default()
        };
        let s = FramedState {
            motor: AxisState::default(),
            tool: AxisState {
                pos: -0.01,
                vel: 0.0,
            },
        };
        let s = advance(&plant, &frame, &push, s, 0.0, 25e-6, 40, 500.0);
        assert_eq!(s.motor, AxisState::default());
        // the spring pulls the tool towards the held motor
        assert!(s.tool.pos > -0.01 && s.tool.vel > 0.0, "{:?}", s.tool);
    }
}
