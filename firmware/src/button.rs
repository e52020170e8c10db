//! The arm/reset button: debounced press detection and the commands a press sends.
//!
//! The button task samples the contact every millisecond (no extra interrupt, no blocking
//! delay). A press is reported once, after the contact has read "pressed" for
//! `hold_periods` consecutive samples; the button must be released before the next press
//! is reported, so holding it down arms at most once. [`press_commands`] turns a press
//! into servo commands, which the control task takes from its mailbox at the start of
//! the next period.

use controller_core::servo::{Command, ServoState};

/// What one press of the arm button asks for, given the servo's state:
///
/// - a latched fault is reset (to `Disabled`, once its cause is gone; the next press arms);
/// - `Disabled`: arm, which holds the position (arming never starts motion);
/// - `Idle`: with the `demo-helix` build feature, start the demo path; otherwise disarm;
/// - `Run`, `Jog`, `Homing`, `Identify`: disarm (a controlled stop, then outputs off;
///   identification stops at once);
/// - while stopping or checking an encoder: nothing.
pub fn press_commands(state: ServoState, demo: bool) -> &'static [Command] {
    match state {
        ServoState::Fault => &[Command::Reset],
        ServoState::Disabled => &[Command::Arm],
        ServoState::Idle if demo => &[Command::StartPath],
        ServoState::Idle
        | ServoState::Run
        | ServoState::Jog
        | ServoState::Homing
        | ServoState::Identify => &[Command::Disarm],
        ServoState::Stopping | ServoState::EncoderCheck => &[],
    }
}

/// Debouncer for one active button.
#[derive(Clone, Copy, Debug)]
pub struct Debounce {
    hold_periods: u16,
    pressed_for: u16,
    reported: bool,
}

impl Debounce {
    /// Reports a press after `hold_periods` consecutive pressed samples (at least 1).
    pub const fn new(hold_periods: u16) -> Self {
        Self {
            hold_periods: if hold_periods == 0 { 1 } else { hold_periods },
            pressed_for: 0,
            reported: false,
        }
    }

    /// Feeds one sample; returns `true` exactly once per debounced press.
    pub fn update(&mut self, pressed: bool) -> bool {
        if !pressed {
            self.pressed_for = 0;
            self.reported = false;
            return false;
        }
        self.pressed_for = self.pressed_for.saturating_add(1);
        if !self.reported && self.pressed_for >= self.hold_periods {
            self.reported = true;
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_once_after_hold_time() {
        let mut d = Debounce::new(3);
        assert!(!d.update(true));
        assert!(!d.update(true));
        assert!(d.update(true));
        for _ in 0..100 {
            assert!(!d.update(true));
        }
        assert!(!d.update(false));
        assert!(!d.update(true));
        assert!(!d.update(true));
        assert!(d.update(true));
    }

    #[test]
    fn a_press_resets_arms_or_disarms_and_never_arms_into_motion() {
        for demo in [false, true] {
            assert_eq!(press_commands(ServoState::Fault, demo), &[Command::Reset]);
            assert_eq!(press_commands(ServoState::Disabled, demo), &[Command::Arm]);
            assert_eq!(press_commands(ServoState::Run, demo), &[Command::Disarm]);
            assert!(press_commands(ServoState::Stopping, demo).is_empty());
        }
        // the path starts only from holding, and only in the demo build
        assert_eq!(
            press_commands(ServoState::Idle, true),
            &[Command::StartPath]
        );
        assert_eq!(press_commands(ServoState::Idle, false), &[Command::Disarm]);
    }

    #[test]
    fn bounces_are_ignored() {
        let mut d = Debounce::new(3);
        for _ in 0..10 {
            assert!(!d.update(true));
            assert!(!d.update(false));
        }
    }
}
