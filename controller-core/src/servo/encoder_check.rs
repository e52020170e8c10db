//! The encoder checks' periods: the check at reset of an encoder fault (a small effort
//! on each faulted axis must move it both ways) and the closed-loop check at arming (every
//! axis' hold reference moves out and back each way; each reading must follow).

use super::checks::{ArmPhase, Check, ARM_CHECK_SETTLE_COUNTS};
use super::faults::{Fault, FaultKind};
use super::io::ServoIo;
use super::state::ServoState;
use super::step::{Sensed, Servo};
use crate::axes::{Axis, AXES};
use crate::motion::reference::ReferenceMode;
use crate::{Real, Vec3};

impl<R: Real> Servo<R> {
    /// The period of the check at reset: the checked axis' effort written out (none while
    /// its brake still opens), or the outputs off once the check ended. Returns the effort
    /// applied.
    #[inline(always)]
    pub(super) fn encoder_check_period<IO: ServoIo<R>>(
        &mut self,
        io: &mut IO,
        s: &Sensed<'_, R>,
        index_fault: Option<(Fault, f32)>,
    ) -> Vec3<R> {
        if let Some((f, v)) = index_fault {
            self.trip(f, v, None);
        }
        let mut applied = if s.held {
            Vec3::zero()
        } else {
            self.encoder_check(s.counts)
        };
        if self.state.drives() {
            io.write_outputs(&self.drive(applied));
        } else {
            applied = Vec3::zero();
            io.disable_outputs();
        }
        applied
    }

    /// The next axis after `after` (from the first without one) with an encoder fault
    /// latched: the one the encoder check at reset tries next.
    pub(super) fn next_check(&self, after: Option<usize>) -> Option<usize> {
        let from = after.map_or(0, |a| a + 1);
        (from..AXES).find(|&i| {
            FaultKind::ALL
                .iter()
                .any(|k| k.is_encoder() && self.faults.is_latched(*k, Axis::from_index(i)))
        })
    }

    /// One period of the arm check: each axis' reference one step further along its
    /// phase's way and its reading judged; armed once every axis is done.
    #[cold]
    #[inline(never)]
    pub(super) fn step_arm_check(&mut self, counts: &[i64; AXES]) {
        let Some(mut c) = self.checks.arm else {
            return;
        };
        let full = self.checks.counts as f32;
        let half = 0.5 * full;
        let mut hold = c.hold;
        let mut done = true;
        for (i, axis) in Axis::ALL.into_iter().enumerate() {
            let moved = counts[i].saturating_sub(c.base[i]) as f32;
            let phase = c.phase[i];
            let k = c.k[i].saturating_add(1);
            // (a wrong-way reading, and a reading that never follows: the fault and the
            // counts it moved)
            let (next, fault) = match phase {
                // a healthy axis settles within a couple of counts of where it armed once
                // its brake lets go; a swapped A/B turns the hold into positive feedback
                // and runs away from it (Z under gravity)
                ArmPhase::Settle
                    if moved.abs() > ARM_CHECK_SETTLE_COUNTS + self.checks.arm_wrong =>
                {
                    (phase, Some(FaultKind::EncoderJump))
                }
                ArmPhase::Settle if k >= self.stopping.settle_periods => {
                    // from here the reading must follow the reference
                    c.base[i] = counts[i];
                    (ArmPhase::Out, None)
                }
                ArmPhase::Out if moved <= -self.checks.arm_wrong => {
                    // counts the wrong way while the law pushes the axis out: swapped A/B
                    (phase, Some(FaultKind::EncoderJump))
                }
                ArmPhase::Out if moved >= half => (ArmPhase::Back, None),
                // (from the positive end, where the law may overshoot by part of the step:
                // twice the way out is no overshoot but the wrong way)
                ArmPhase::Back if moved >= 2.0 * full + self.checks.arm_wrong => {
                    (phase, Some(FaultKind::EncoderJump))
                }
                ArmPhase::Back if moved <= -half => (ArmPhase::Home, None),
                // back at the hold point, settled for the stop's settle time
                ArmPhase::Home if c.offset[i] == 0.0 && k >= self.stopping.settle_periods => {
                    (ArmPhase::Done, None)
                }
                ArmPhase::Out | ArmPhase::Back
                    if k >= self
                        .checks
                        .periods
                        .saturating_add(self.stopping.settle_periods) =>
                {
                    // the reference moved and the reading did not follow
                    (phase, Some(FaultKind::EncoderStuck))
                }
                _ => (phase, None),
            };
            if let Some(kind) = fault {
                self.checks.arm = None;
                self.trip(Fault::on(kind, axis), moved, None);
                return;
            }
            c.k[i] = if next == phase { k } else { 0 };
            c.phase[i] = next;
            let target = match phase {
                ArmPhase::Out => full,
                ArmPhase::Back => -full,
                ArmPhase::Settle | ArmPhase::Home | ArmPhase::Done => 0.0,
            };
            let (o, step) = (c.offset[i], self.checks.arm_step[i]);
            c.offset[i] = if o < target {
                (o + step).min(target)
            } else {
                (o - step).max(target)
            };
            hold[i] = c.hold[i] + R::from_f32(c.offset[i] * self.count_len_f32[i]);
            done &= next == ArmPhase::Done;
        }
        if done {
            // every axis followed both ways: armed, holding where it armed
            self.checks.arm = None;
            self.hold_motor(c.hold);
            self.state = ServoState::Idle;
            return;
        }
        self.motion = ReferenceMode::Hold(hold);
        self.checks.arm = Some(c);
    }

    /// One period of the encoder check: the effort on the checked axis (others zero).
    pub(super) fn encoder_check(&mut self, counts: &[i64; AXES]) -> Vec3<R> {
        let mut u = Vec3::zero();
        let Some(mut c) = self.checks.check else {
            self.state = ServoState::Fault;
            return u;
        };
        // (`get`: the axis always comes from `next_check`, but an index the optimiser
        // cannot bound would leave a panic path in the control interrupt)
        let Some(&now) = counts.get(c.axis) else {
            self.checks.check = None;
            self.state = ServoState::Fault;
            return u;
        };
        let moved = now.saturating_sub(c.n0);
        let sign: i64 = if c.positive { 1 } else { -1 };
        if moved * sign >= self.checks.counts {
            // followed: the other direction, or the next axis, or done
            if c.positive {
                c = Check {
                    positive: false,
                    k: 0,
                    n0: counts[c.axis],
                    ..c
                };
            } else {
                match self.next_check(Some(c.axis)) {
                    Some(axis) => {
                        c = Check {
                            axis,
                            positive: true,
                            k: 0,
                            n0: counts[axis],
                        }
                    }
                    None => {
                        self.checks.check = None;
                        self.faults.clear();
                        self.publish_faults();
                        self.state = ServoState::Disabled;
                        return u;
                    }
                }
            }
        } else if moved * sign <= -self.checks.counts || c.k >= self.checks.periods {
            // moved the wrong way, or not at all: the encoder is still faulty
            self.checks.check = None;
            self.state = ServoState::Fault;
            return u;
        }
        // ramp from 0 to the check effort over the check: breakaway is reached late, so a
        // still-stuck encoder lets the axis move little
        let ramp = c.k.min(self.checks.periods) as f32 / self.checks.periods.max(1) as f32;
        let effort = ramp * self.checks.effort[c.axis] * sign as f32;
        u[c.axis] = R::from_f32(effort).clamp_sym(self.full_scale[c.axis]);
        c.k += 1;
        self.checks.check = Some(c);
        u
    }
}
