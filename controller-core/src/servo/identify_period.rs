//! The servo's identification periods: the identified axis' effort (the identifier's, the
//! others holding or unpowered) and its reference (none: its law sees no error; the loop
//! measurement's own, which the law follows). How an identification starts and ends is
//! in [`super::modes`], the run in [`super::identify`].

use super::state::ServoState;
use super::step::Servo;
use crate::axes::AXES;
use crate::controller::Measured;
use crate::motion::trajectory::RefSample;
use crate::sysid::AxisSample;
use crate::{Real, Vec3};

impl<R: Real> Servo<R> {
    /// The identified axis' effort this period (the others: their laws' when holding,
    /// else zero); ends the identification when it is finished.
    #[cold]
    #[inline(never)]
    pub(super) fn identify_effort(
        &mut self,
        mut u: Vec3<R>,
        meas: &Measured<R>,
        vel: &[f32; AXES],
    ) -> Vec3<R> {
        let faulted = self.faults.any();
        let Some(run) = &mut self.ident.run else {
            self.state = ServoState::Fault;
            return Vec3::zero();
        };
        let i = run.axis.min(AXES - 1);
        let sample = AxisSample {
            pos_mm: meas.pos[i].to_f32(),
            vel_mm_s: vel[i],
            effort_applied_mnm: self.applied[i].to_f32(),
            fault: faulted,
        };
        let out = run.step(&sample, u[i].to_f32());
        if !run.hold_others {
            u = Vec3::zero();
        }
        u[i] = R::from_f32(out.effort_mnm)
            .finite_or_zero()
            .clamp_sym(self.full_scale[i]);
        if run.finished() {
            let hold = run.hold_others;
            self.end_identify(false);
            self.state = if hold {
                ServoState::Idle
            } else {
                ServoState::Disabled
            };
            // holding: from here on the identified axis holds where it came to rest
            self.hold_motor(meas.pos);
            self.controller.reset();
            if !hold {
                u = Vec3::zero();
            }
        }
        u
    }

    /// The identified axis has no reference (its law sees no error), or the loop
    /// measurement's.
    #[cold]
    #[inline(never)]
    pub(super) fn identify_reference(&self, reference: &mut RefSample<R>, meas: &Measured<R>) {
        if let Some(run) = &self.ident.run {
            let i = run.axis.min(AXES - 1);
            match run.reference() {
                Some(r) => {
                    reference.pos[i] = R::from_f32(r.pos_mm);
                    reference.vel[i] = R::from_f32(r.vel_mm_s);
                    reference.acc[i] = R::from_f32(r.acc_mm_s2);
                }
                None => {
                    reference.pos[i] = meas.pos[i];
                    reference.vel[i] = meas.vel[i];
                    reference.acc[i] = R::ZERO;
                }
            }
        }
    }
}
