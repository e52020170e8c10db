//! What produces the servo step's reference each period: holding a point, the
//! configured path, or a controlled stop.
//!
//! A controlled stop starts from the reference of the period the fault was found in and
//! decelerates along that reference's direction of motion at the largest rate every
//! axis allows (`stop_decel_mm_s2` projected on the direction), so no axis exceeds its
//! own limit; the reference then holds the point where it came to rest.

use crate::axes::AXES;
use crate::motion::trajectory::{RefSample, Trajectory};
use crate::{Real, Vec3};

/// The reference generator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Motion<R> {
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
}

impl<R: Real> Motion<R> {
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
        Motion::Stop {
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
            Motion::Hold(_) => {}
            Motion::Path { k, .. } | Motion::Stop { k, .. } => *k = k.saturating_add(1),
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

/// The reference of `motion` this period; `path` is the configured path.
pub fn sample<R: Real>(
    motion: &Motion<R>,
    path: Option<&(Trajectory<R>, Option<u32>)>,
    period_s: f64,
) -> (RefSample<R>, f64, bool) {
    let hold = |pos| {
        let r = RefSample {
            pos,
            vel: Vec3::zero(),
            acc: Vec3::zero(),
        };
        (r, 0.0, true)
    };
    match *motion {
        Motion::Hold(p) => hold(p),
        Motion::Stop {
            p0,
            v0,
            dir,
            decel,
            t_stop,
            k,
        } => {
            let t = f64::from(k) * period_s;
            let (r, rest) = Motion::stop_sample(p0, v0, dir, decel, t_stop, R::from_f64(t));
            (r, t, rest)
        }
        Motion::Path { k, origin } => {
            let Some((traj, end)) = path else {
                return hold(Vec3::zero());
            };
            // after the path's duration its point at that time is held
            let held_at = end.filter(|e| k > *e);
            let t = f64::from(held_at.unwrap_or(k)) * period_s;
            let mut r = traj.sample(R::from_f64(t));
            if held_at.is_some() {
                r.vel = Vec3::zero();
                r.acc = Vec3::zero();
            }
            if let Some(o) = origin {
                r.pos = r.pos + o;
            }
            (r, f64::from(k) * period_s, held_at.is_some())
        }
    }
}
