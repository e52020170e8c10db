//! The servo's homing and jog periods: the ramps advanced (an axis re-based where homing
//! latched its switch), the jog's soft-limit bounds, and which limit switch is homing's
//! sensor rather than a fault. What the servo keeps of them is [`super::manual`].

use super::faults::{Fault, FaultKind};
use super::io::Inputs;
use super::state::ServoState;
use super::step::Servo;
use crate::axes::{Axis, AXES};
use crate::motion::homing::{HomingEvent, HomingInputs};
use crate::motion::reference::ReferenceMode;
use crate::{Real, Vec3};

impl<R: Real> Servo<R> {
    /// Soft-limit bounds of each axis for a jog: the travel once referenced, else none.
    pub(super) fn jog_bounds(&self) -> [(f32, f32); AXES] {
        [0, 1, 2].map(|i| {
            if self.referenced(i) {
                (self.travel.axes[i].min_mm, self.travel.axes[i].max_mm)
            } else {
                (f32::NEG_INFINITY, f32::INFINITY)
            }
        })
    }

    /// Advance the jog or homing ramps for this period (before the reference is sampled);
    /// re-bases an axis when homing latched its switch.
    #[cold]
    #[inline(never)]
    pub(super) fn step_manual(
        &mut self,
        inputs: &Inputs,
        index: [Option<u32>; AXES],
        counts: &mut [i64; AXES],
    ) {
        let dt = self.period_s as f32;
        let bounds = self.jog_bounds();
        match &mut self.motion {
            ReferenceMode::Jog(j) => j.advance(&self.manual.jog, &bounds, dt),
            ReferenceMode::Homing { hold, run } => {
                let axis = run.axis().min(AXES - 1);
                let side = self.manual.homing.axes[axis].direction.switch();
                let inp = HomingInputs {
                    switch: inputs.limits[axis][side],
                    counts: counts[axis],
                    index_counts: index[axis].map(|raw| self.counters[axis].extend(raw)),
                };
                match run.step(&self.manual.homing, &inp, self.count_len_f32[axis], dt) {
                    HomingEvent::Moving => {
                        if run.axis() != axis {
                            // the next axis: hold the finished one at its home point
                            hold[axis] = R::from_f32(run.ramp.pos_mm);
                            let next = run.axis().min(AXES - 1);
                            run.next_axis_at(hold[next].to_f32());
                        }
                    }
                    HomingEvent::Rebase {
                        axis,
                        latched_counts,
                        at_mm,
                    } => {
                        let axis = axis.min(AXES - 1);
                        let target = libm::roundf(at_mm * self.counts_per_mm[axis]) as i64;
                        let shift = latched_counts - target;
                        self.counters[axis].rebase(shift);
                        self.index.rebased(axis, shift);
                        counts[axis] = self.counters[axis].count();
                        let delta_mm = -(shift as f32) * self.count_len_f32[axis];
                        run.rebased(run.ramp.pos_mm + delta_mm);
                        hold[axis] = R::from_f32(run.ramp.pos_mm);
                        let mut d = Vec3::zero();
                        d[axis] = R::from_f32(delta_mm);
                        self.controller.shift_reference(d);
                        self.estimators.reset(*counts);
                        self.manual.homed |= 1 << axis;
                    }
                    HomingEvent::Done => {
                        let i = run.axis().min(AXES - 1);
                        self.manual.homed |= 1 << i;
                        hold[i] = R::from_f32(run.ramp.pos_mm);
                        let h = *hold;
                        self.motion = ReferenceMode::Hold(h);
                        self.state = ServoState::Idle;
                    }
                    HomingEvent::Failed { axis, .. } => {
                        let axis = Axis::ALL[axis.min(AXES - 1)];
                        let r = crate::motion::reference::sample(&self.motion, None, &self.clock).0;
                        self.trip(Fault::on(FaultKind::HomingFailed, axis), 0.0, Some(&r));
                    }
                }
            }
            _ => {}
        }
        self.publish_faults();
    }

    /// The first active limit switch while homing: the homed axis' switch on its homing
    /// side is the sensor, not a fault.
    #[cold]
    #[inline(never)]
    pub(super) fn homing_limit(&self, inputs: &Inputs) -> Option<(Axis, bool)> {
        let ReferenceMode::Homing { run, .. } = &self.motion else {
            return inputs.first_limit();
        };
        Axis::ALL
            .into_iter()
            .zip(inputs.limits)
            .find_map(|(axis, sides)| {
                (0..2).zip(sides).find_map(|(side, on)| {
                    let sensor = run.masks_switch(&self.manual.homing, axis.index(), side);
                    (on && !sensor).then_some((axis, side == 1))
                })
            })
    }
}
