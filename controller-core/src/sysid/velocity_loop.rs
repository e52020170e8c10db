//! The identification's own velocity loop and setpoint ramp, and when an axis counts as
//! stopped ([`RestWatch`]).
//!
//! `u = Ĵ a_sp + f̂(v_sp) + kp (v_sp - v) + ki ∫(v_sp - v) dt`, clamped to the cap, with
//! `kp = Ĵ ω`, `ki = kp ω/5`. The loop knows the inertia only as `Ĵ` (the guess, then the
//! running estimate): its crossover is `ω Ĵ/J`. With the PI zero at `ω/5`, a crossover
//! from `ω/5` (J 5× the guess: phase margin ~45° minus the delays) to `5ω` (J a fifth of
//! the guess: the 100 Hz velocity PLL and the period of delay cost ~45° at 750 rad/s) keeps
//! the loop stable over the 25× range the friction passes may start with. The integral
//! carries the friction until the model's friction feed-forward `f̂` is known.
//!
//! Anti-windup: the integral stops while the output is clamped and the error would push
//! it further out, and is itself limited to the cap.

use crate::Real;

/// At rest below this |velocity|, mm/s (a third of one count per period at 10 kHz and
/// 0.625 µm; far above the PLL's noise of ~0.05 mm/s).
pub(crate) const STOPPED_MM_S: f32 = 2.0;
/// Time the axis must stay below [`STOPPED_MM_S`] to count as stopped, s.
pub(crate) const STOP_HOLD_S: f32 = 0.02;

/// Whether an axis has come to rest: its ramp's setpoint at rest and its speed below
/// [`STOPPED_MM_S`] for [`STOP_HOLD_S`] (the stepped sines' end and brake).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct RestWatch {
    since: Option<u32>,
}

impl RestWatch {
    /// Start over (a new stop).
    pub(crate) fn reset(&mut self) {
        self.since = None;
    }

    /// Period `k` (of `period_s`) with the ramp `ramp` and the measured `vel_mm_s`: true
    /// once at rest long enough.
    pub(crate) fn stopped(&mut self, ramp: &Ramp, vel_mm_s: f32, k: u32, period_s: f32) -> bool {
        if !(ramp.reached() && ramp.v_mm_s == 0.0 && vel_mm_s.abs() < STOPPED_MM_S) {
            self.since = None;
            return false;
        }
        let since = *self.since.get_or_insert(k);
        k.saturating_sub(since) as f32 * period_s >= STOP_HOLD_S
    }
}

/// PI zero at `ω / PI_ZERO_RATIO` (see the module docs).
pub const PI_ZERO_RATIO: f32 = 5.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VelocityLoop {
    kp: f32,
    ki: f32,
    integral_mnm: f32,
    cap_mnm: f32,
    period_s: f32,
    bandwidth_rad_s: f32,
}

impl VelocityLoop {
    pub(crate) fn new(inertia: f32, bandwidth_rad_s: f32, cap_mnm: f32, period_s: f32) -> Self {
        let mut l = Self {
            kp: 0.0,
            ki: 0.0,
            integral_mnm: 0.0,
            cap_mnm,
            period_s,
            bandwidth_rad_s,
        };
        l.retune(inertia);
        l
    }

    /// New gains for inertia estimate `inertia` (the integral, which holds the friction,
    /// is kept).
    pub(crate) fn retune(&mut self, inertia: f32) {
        self.kp = inertia * self.bandwidth_rad_s;
        self.ki = self.kp * self.bandwidth_rad_s / PI_ZERO_RATIO;
    }

    /// The integral term, mN·m (it carries the friction the feed-forward leaves).
    pub(crate) fn integral_mnm(&self) -> f32 {
        self.integral_mnm
    }

    /// Replace the integral term (e.g. with the friction of the direction a reversal
    /// goes into), limited to the cap.
    pub(crate) fn set_integral_mnm(&mut self, v: f32) {
        self.integral_mnm = v.finite_or_zero().clamp_sym(self.cap_mnm);
    }

    /// One period: the capped effort for setpoint `(v_sp, a_sp)`, measured `v` and
    /// feed-forward `ff` (inertia × acceleration + friction), mN·m.
    pub(crate) fn step(&mut self, v_sp: f32, v: f32, ff_mnm: f32) -> f32 {
        let e = (v_sp - v).finite_or_zero();
        let pre = (ff_mnm + self.kp * e + self.integral_mnm).finite_or_zero();
        let u = pre.clamp_sym(self.cap_mnm);
        let winding_up = (pre > self.cap_mnm && e > 0.0) || (pre < -self.cap_mnm && e < 0.0);
        if !winding_up {
            self.integral_mnm = (self.integral_mnm + self.ki * e * self.period_s)
                .finite_or_zero()
                .clamp_sym(self.cap_mnm);
        }
        u
    }
}

/// A velocity setpoint that ramps to its target at a bounded acceleration, and at a
/// (possibly larger) deceleration while its magnitude falls towards zero (friction helps
/// braking).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Ramp {
    pub(crate) v_mm_s: f32,
    pub(crate) a_mm_s2: f32,
    pub(crate) target_mm_s: f32,
    pub(crate) accel_mm_s2: f32,
    pub(crate) decel_mm_s2: f32,
}

impl Ramp {
    pub(crate) fn at_rest() -> Self {
        Self {
            v_mm_s: 0.0,
            a_mm_s2: 0.0,
            target_mm_s: 0.0,
            accel_mm_s2: 0.0,
            decel_mm_s2: 0.0,
        }
    }

    /// Ramp to `target_mm_s`, speeding up at `accel_mm_s2` and slowing down at
    /// `decel_mm_s2`.
    pub(crate) fn go(&mut self, target_mm_s: f32, accel_mm_s2: f32, decel_mm_s2: f32) {
        self.target_mm_s = target_mm_s;
        self.accel_mm_s2 = accel_mm_s2;
        self.decel_mm_s2 = decel_mm_s2;
    }

    /// Advance one period; true once the target is reached.
    pub(crate) fn step(&mut self, period_s: f32) -> bool {
        let dv = self.target_mm_s - self.v_mm_s;
        // slowing down: at most to zero in this period at the deceleration
        let slowing = self.v_mm_s * dv < 0.0;
        let max = if slowing {
            (self.decel_mm_s2 * period_s).min(self.v_mm_s.abs())
        } else {
            self.accel_mm_s2 * period_s
        };
        if dv.abs() <= max {
            // exact arrival (v + (t - v) need not round to t)
            self.a_mm_s2 = dv.div_or(period_s, 0.0);
            self.v_mm_s = self.target_mm_s;
            true
        } else {
            let step = dv.clamp_sym(max);
            self.v_mm_s += step;
            self.a_mm_s2 = step.div_or(period_s, 0.0);
            false
        }
    }

    pub(crate) fn reached(&self) -> bool {
        self.v_mm_s == self.target_mm_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_reaches_target_exactly_at_the_set_acceleration() {
        let mut r = Ramp::at_rest();
        r.go(10.0, 1000.0, 3000.0);
        let mut n = 0;
        while !r.step(1e-3) {
            assert!((r.a_mm_s2 - 1000.0).abs() < 1e-2);
            n += 1;
            assert!(n < 100);
        }
        assert_eq!(r.v_mm_s, 10.0);
        assert!((9..=10).contains(&n), "{n}");
        assert!(r.step(1e-3) && r.a_mm_s2 == 0.0);
        // reversal: down to zero at the deceleration, then up at the acceleration
        r.go(-10.0, 1000.0, 3000.0);
        let mut n = 0;
        while !r.step(1e-3) {
            let expect = if r.v_mm_s >= 0.0 { -3000.0 } else { -1000.0 };
            assert!((r.a_mm_s2 - expect).abs() < 1.0 || r.v_mm_s == 0.0, "{r:?}");
            n += 1;
            assert!(n < 100);
        }
        // 10/3 periods down (the 4th ends exactly at zero), then 10 up
        assert!((13..=15).contains(&n), "{n}");
    }

    #[test]
    fn loop_output_is_capped_and_never_nan() {
        let mut l = VelocityLoop::new(0.1, 150.0, 100.0, 1e-4);
        assert_eq!(l.step(1e6, 0.0, 0.0), 100.0);
        assert_eq!(l.step(f32::NAN, 0.0, 0.0), 0.0);
        assert!(l.step(0.0, f32::INFINITY, f32::NAN).is_finite());
        // integral is not wound up while saturated
        let mut l = VelocityLoop::new(0.1, 150.0, 100.0, 1e-4);
        for _ in 0..10_000 {
            l.step(1e6, 0.0, 0.0);
        }
        assert_eq!(l.integral_mnm, 0.0);
    }
}
