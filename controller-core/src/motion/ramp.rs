//! A one-axis reference with bounded acceleration: what jogging and homing follow.
//!
//! Each period the velocity moves toward a target (a velocity, or the speed that still
//! lets the axis stop at a target position) by at most `accel · dt`, and the position
//! integrates the velocity with the trapezoidal rule, so the reference is continuous in
//! position and velocity and its acceleration is bounded by the configured value. Soft
//! limits are obeyed by braking early: the velocity toward a bound never exceeds the
//! speed from which the axis can still stop at it, `√(2·a·d)`.
//!
//! Positions are `f32` mm: at 1 m from the origin one unit in the last place is 0.06 µm,
//! a tenth of an encoder count, and the reference is re-based on the measured position at
//! every start, so rounding does not accumulate across moves.

/// Position and velocity of a one-axis reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ramp {
    pub pos_mm: f32,
    pub vel_mm_s: f32,
    /// Acceleration over the last period, mm/s².
    pub acc_mm_s2: f32,
}

/// Braking speed: the largest speed from which `accel` stops the axis within `dist`.
fn stop_speed(dist_mm: f32, accel_mm_s2: f32) -> f32 {
    libm::sqrtf(2.0 * accel_mm_s2 * dist_mm.max(0.0))
}

impl Ramp {
    /// At rest at `pos_mm`.
    pub const fn at(pos_mm: f32) -> Self {
        Self {
            pos_mm,
            vel_mm_s: 0.0,
            acc_mm_s2: 0.0,
        }
    }

    /// Toward `target_mm_s` with `|a| ≤ accel_mm_s2`, staying within `[lo_mm, hi_mm]`: the
    /// axis brakes so as to stop at a bound, and is held there.
    pub fn step_velocity(
        &mut self,
        target_mm_s: f32,
        accel_mm_s2: f32,
        lo_mm: f32,
        hi_mm: f32,
        dt_s: f32,
    ) {
        // the one-period lag of the discrete brake: aim a step's travel short of the bound
        let margin = self.vel_mm_s.abs() * dt_s;
        let up = stop_speed(hi_mm - self.pos_mm - margin, accel_mm_s2);
        let down = stop_speed(self.pos_mm - lo_mm - margin, accel_mm_s2);
        // (max/min, not clamp: clamp panics when the bounds cross, e.g. past a bound)
        let target = target_mm_s.max(-down).min(up);
        self.advance(target, accel_mm_s2, dt_s);
        if self.pos_mm >= hi_mm {
            self.pos_mm = hi_mm;
            self.vel_mm_s = self.vel_mm_s.min(0.0);
        } else if self.pos_mm <= lo_mm {
            self.pos_mm = lo_mm;
            self.vel_mm_s = self.vel_mm_s.max(0.0);
        }
    }

    /// Toward the point `target_mm` with `|v| ≤ speed_mm_s` and `|a| ≤ accel_mm_s2`;
    /// `true` once there at rest (the reference then sits exactly on the target).
    pub fn step_to(
        &mut self,
        target_mm: f32,
        speed_mm_s: f32,
        accel_mm_s2: f32,
        dt_s: f32,
    ) -> bool {
        let d = target_mm - self.pos_mm;
        let step = accel_mm_s2 * dt_s;
        if d.abs() <= 0.5 * step * dt_s && self.vel_mm_s.abs() <= step {
            self.pos_mm = target_mm;
            self.vel_mm_s = 0.0;
            self.acc_mm_s2 = 0.0;
            return true;
        }
        let margin = self.vel_mm_s.abs() * dt_s;
        let v = stop_speed(d.abs() - margin, accel_mm_s2).min(speed_mm_s);
        self.advance(if d > 0.0 { v } else { -v }, accel_mm_s2, dt_s);
        false
    }

    fn advance(&mut self, target_mm_s: f32, accel_mm_s2: f32, dt_s: f32) {
        let step = accel_mm_s2 * dt_s;
        let v0 = self.vel_mm_s;
        let v1 = v0 + (target_mm_s - v0).max(-step).min(step);
        self.acc_mm_s2 = if dt_s > 0.0 { (v1 - v0) / dt_s } else { 0.0 };
        self.vel_mm_s = v1;
        self.pos_mm += 0.5 * (v0 + v1) * dt_s;
    }

    /// At rest (the velocity is exactly zero).
    pub fn at_rest(&self) -> bool {
        self.vel_mm_s == 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f32 = 1e-4;

    #[test]
    fn velocity_ramp_respects_accel_and_stops_at_bound() {
        let mut r = Ramp::at(0.0);
        let mut max_acc = 0.0f32;
        for _ in 0..40_000 {
            r.step_velocity(100.0, 2000.0, -10.0, 20.0, DT);
            max_acc = max_acc.max(r.acc_mm_s2.abs());
            assert!(r.pos_mm <= 20.0);
        }
        assert!(max_acc <= 2000.0 * 1.0001, "{max_acc}");
        assert!((r.pos_mm - 20.0).abs() < 0.01, "{}", r.pos_mm);
        assert!(r.vel_mm_s.abs() < 0.5, "{}", r.vel_mm_s);
    }

    #[test]
    fn point_to_point_arrives_exactly() {
        let mut r = Ramp::at(1.0);
        let mut k = 0;
        while !r.step_to(-3.5, 20.0, 500.0, DT) {
            assert!(r.vel_mm_s.abs() <= 20.0 + 1e-3);
            assert!(
                r.pos_mm >= -3.5 - 1e-3 && r.pos_mm <= 1.0 + 1e-3,
                "{}",
                r.pos_mm
            );
            k += 1;
            assert!(k < 100_000);
        }
        assert_eq!(r.pos_mm, -3.5);
        // 4.5 mm at 20 mm/s with 40 ms ramps: 0.265 s
        assert!((2500..3000).contains(&k), "{k}");
    }
}
