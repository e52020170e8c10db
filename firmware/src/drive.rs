//! Mapping of a (saturated) control effort to a sign-magnitude servo command.
//!
//! Each axis drive takes a PWM duty for the magnitude and a direction pin for the sign
//! (sign-magnitude, as used by common H-bridge servo amplifiers). Full duty corresponds to
//! the axis' effort limit `effort_limit` (the law's `u_max`). This is output scaling only: the
//! saturation itself is done by the control law in controller-core, the clamp here only
//! guards the timer register against out-of-range values.

/// What one axis' output stage is told for one period.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct DriveCommand {
    /// Compare value for the PWM channel, `0..=max_duty`.
    pub duty_counts: u16,
    /// Direction pin level: `true` drives towards negative positions.
    pub reverse: bool,
}

impl DriveCommand {
    /// Zero output.
    pub const OFF: Self = Self {
        duty_counts: 0,
        reverse: false,
    };

    /// Maps `effort` in `[-effort_limit, effort_limit]` onto `0..=max_duty_counts` and a direction.
    /// Non-finite efforts and non-positive limits give [`DriveCommand::OFF`].
    pub fn from_effort(effort: f32, effort_limit: f32, max_duty_counts: u16) -> Self {
        if !effort.is_finite() || !(effort_limit > 0.0) {
            return Self::OFF;
        }
        let fraction = (effort.abs() / effort_limit).min(1.0);
        // Round to nearest: `as` saturates and truncates, so add one half first.
        let duty_counts = (fraction * f32::from(max_duty_counts) + 0.5) as u16;
        Self {
            duty_counts: duty_counts.min(max_duty_counts),
            reverse: effort < 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_sign_and_magnitude() {
        assert_eq!(
            DriveCommand::from_effort(5.0, 10.0, 8399),
            DriveCommand {
                duty_counts: 4200,
                reverse: false
            }
        );
        assert_eq!(
            DriveCommand::from_effort(-10.0, 10.0, 8399),
            DriveCommand {
                duty_counts: 8399,
                reverse: true
            }
        );
    }

    #[test]
    fn clamps_and_rejects_garbage() {
        assert_eq!(DriveCommand::from_effort(1e9, 10.0, 100).duty_counts, 100);
        assert_eq!(
            DriveCommand::from_effort(f32::NAN, 10.0, 100),
            DriveCommand::OFF
        );
        assert_eq!(
            DriveCommand::from_effort(f32::INFINITY, 10.0, 100),
            DriveCommand::OFF
        );
        assert_eq!(DriveCommand::from_effort(1.0, 0.0, 100), DriveCommand::OFF);
    }
}
