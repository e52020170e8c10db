//! What produces the servo step's reference each period: holding a point, the
//! configured path, a controlled stop, a jog or the homing sequence (the planner's
//! reference comes from its executor, see [`crate::servo::Servo::period`]).
//!
//! A controlled stop starts from the reference of the period the fault was found in and
//! decelerates along that reference's direction of motion at the largest rate every
//! axis allows (`stop_decel_mm_s2` projected on the direction), so no axis exceeds its
//! own limit; the reference then holds the point where it came to rest.

use super::homing::Homing;
use super::jog::Jog;
use super::ramp::Ramp;
use crate::axes::AXES;
use crate::motion::trajectory::{RefSample, Trajectory};
use crate::{Real, Vec3};

/// The reference generator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReferenceMode<R> {
    /// Hold a point.
    Hold(Vec3<R>),
    /// Follow the configured path: `k` periods since it started, shifted by `origin`.
    Path { k: u32, origin: Option<Vec3<R>> },
    /// Decelerate from `p0`, `v0` along `dir` (unit) at `decel` to rest after `t_stop`
    /// seconds; `k` periods since the stop began.
    Stop {
        p0: Vec3<R>,
        v0: Vec3<R>,
        dir: Vec3<R>,
        decel: R,
        t_stop: R,
        k: u32,
    },
    /// Jogging (the ramps step at the start of each period).
    Jog(Jog),
    /// Homing: the axis being homed follows the sequence's ramp, the others hold.
    Homing { hold: Vec3<R>, run: Homing },
    /// The planner's reference: the executor's sample of this period, handed to the servo
    /// before the period by [`crate::servo::Servo::set_planner_reference`] (the executor runs in
    /// the same interrupt, just before the servo step; host-sim does the same).
    Planner(RefSample<R>),
}

impl<R: Real> ReferenceMode<R> {
    /// A controlled stop from `from` with per-axis decelerations `decel_mm_s2`.
    pub fn stop_from(from: &RefSample<R>, decel_mm_s2: &[f32; AXES]) -> Self {
        let speed = from.vel.norm();
        let dir = from.vel * R::ONE.div_or(speed, R::ZERO);
        // the largest deceleration along `dir` that keeps every axis within its limit
        let mut decel = R::from_f32(f32::MAX);
        for i in 0..AXES {
            let share = dir[i].abs();
            if share > R::ZERO {
                decel = decel.min_of(R::from_f32(decel_mm_s2[i]).div_or(share, decel));
            }
        }
        let t_stop = speed.div_or(decel, R::ZERO);
        ReferenceMode::Stop {
            p0: from.pos,
            v0: from.vel,
            dir,
            decel,
            t_stop,
            k: 0,
        }
    }

    /// Advance one period.
    pub fn advance(&mut self) {
        match self {
            ReferenceMode::Hold(_)
            | ReferenceMode::Jog(_)
            | ReferenceMode::Homing { .. }
            | ReferenceMode::Planner(_) => {}
            ReferenceMode::Path { k, .. } | ReferenceMode::Stop { k, .. } => {
                *k = k.saturating_add(1)
            }
        }
    }

    /// The stop reference at `t` seconds since it began, and whether it is at rest.
    pub fn stop_sample(
        p0: Vec3<R>,
        v0: Vec3<R>,
        dir: Vec3<R>,
        decel: R,
        t_stop: R,
        t: R,
    ) -> (RefSample<R>, bool) {
        let half = R::from_f32(0.5);
        if t < t_stop {
            let r = RefSample {
                pos: p0 + v0 * t - dir * (half * decel * t * t),
                vel: v0 - dir * (decel * t),
                acc: -(dir * decel),
            };
            (r, false)
        } else {
            let r = RefSample {
                pos: p0 + v0 * t_stop - dir * (half * decel * t_stop * t_stop),
                vel: Vec3::zero(),
                acc: Vec3::zero(),
            };
            (r, true)
        }
    }
}

/// Time from an integer period count, without `f64` (soft float on the board): whole
/// seconds `k / rate` plus the remaining periods times the period, each exact before the
/// one rounding of the sum, so the time is within one unit in the last place of `R` for
/// any `k` (after 24 h at 10 kHz, `k = 8.64·10⁸` still fits a `u32`). Paths that run for
/// hours lose precision with `f32` time itself (its ulp at 3600 s is 0.24 ms); the
/// planner's references use segment-local times and do not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clock<R> {
    // non-zero by type: the division below needs no zero check in the interrupt
    rate_hz: core::num::NonZeroU32,
    dt: R,
}

impl<R: Real> Clock<R> {
    pub fn new(rate_hz: u32) -> Self {
        Self {
            rate_hz: core::num::NonZeroU32::new(rate_hz).unwrap_or(core::num::NonZeroU32::MIN),
            dt: R::from_f64(1.0 / f64::from(rate_hz.max(1))),
        }
    }

    /// `k` periods, in seconds.
    pub fn time(&self, k: u32) -> R {
        let whole = k / self.rate_hz;
        let rest = k % self.rate_hz;
        R::from_f32(whole as f32) + R::from_f32(rest as f32) * self.dt
    }
}

/// The reference of `motion` this period; `path` is the configured path. Returns the
/// reference, the time since the motion began, and whether the reference is at rest.
pub fn sample<R: Real>(
    motion: &ReferenceMode<R>,
    path: Option<&(Trajectory<R>, Option<u32>)>,
    clock: &Clock<R>,
) -> (RefSample<R>, R, bool) {
    let hold = |pos| {
        let r = RefSample {
            pos,
            vel: Vec3::zero(),
            acc: Vec3::zero(),
        };
        (r, R::ZERO, true)
    };
    match *motion {
        ReferenceMode::Hold(p) => hold(p),
        ReferenceMode::Planner(r) => (r, R::ZERO, false),
        ReferenceMode::Jog(ref j) => {
            let r = ramps_sample(&j.ramps);
            let rest = j.finished();
            (r, R::ZERO, rest)
        }
        ReferenceMode::Homing { hold: h, ref run } => {
            let mut r = RefSample {
                pos: h,
                vel: Vec3::zero(),
                acc: Vec3::zero(),
            };
            let i = run.axis().min(AXES - 1);
            r.pos[i] = R::from_f32(run.ramp.pos_mm);
            r.vel[i] = R::from_f32(run.ramp.vel_mm_s);
            r.acc[i] = R::from_f32(run.ramp.acc_mm_s2);
            (r, R::ZERO, run.ramp.at_rest())
        }
        ReferenceMode::Stop {
            p0,
            v0,
            dir,
            decel,
            t_stop,
            k,
        } => {
            let t = clock.time(k);
            let (r, rest) = ReferenceMode::stop_sample(p0, v0, dir, decel, t_stop, t);
            (r, t, rest)
        }
        ReferenceMode::Path { k, origin } => {
            let Some((traj, end)) = path else {
                return hold(Vec3::zero());
            };
            // after the path's duration its point at that time is held
            let held_at = end.filter(|e| k > *e);
            let t = clock.time(k);
            let mut r = match held_at {
                None => traj.sample(t),
                Some(e) => {
                    let mut r = traj.sample(clock.time(e));
                    r.vel = Vec3::zero();
                    r.acc = Vec3::zero();
                    r
                }
            };
            if let Some(o) = origin {
                r.pos = r.pos + o;
            }
            (r, t, held_at.is_some())
        }
    }
}

/// The reference of three one-axis ramps.
pub fn ramps_sample<R: Real>(ramps: &[Ramp; AXES]) -> RefSample<R> {
    let mut r = RefSample {
        pos: Vec3::zero(),
        vel: Vec3::zero(),
        acc: Vec3::zero(),
    };
    for (i, q) in ramps.iter().enumerate() {
        r.pos[i] = R::from_f32(q.pos_mm);
        r.vel[i] = R::from_f32(q.vel_mm_s);
        r.acc[i] = R::from_f32(q.acc_mm_s2);
    }
    r
}
