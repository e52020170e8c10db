//! The arm/reset button: debounced press detection and the commands a press sends.
//!
//! The button task samples the contact every millisecond (no extra interrupt, no blocking
//! delay). A press is reported once, after the contact has read "pressed" for
//! `hold_periods` consecutive samples; the button must be released before the next press
//! is reported, so holding it down arms at most once. [`press_commands`] turns a press
//! into servo commands, which the control task takes from its mailbox at the start of
//! the next period.

use controller_core::servo::safety::SafetyState;
use controller_core::servo::Command;

/// What one press of the arm button asks for, given the servo's state: a latched fault
/// is reset (to `Disabled`; the next press arms); otherwise the outputs are armed and the
/// configured path starts from where the axes are.
pub fn press_commands(state: SafetyState) -> &'static [Command] {
    match state {
        SafetyState::Fault(_) => &[Command::Reset],
        SafetyState::Disabled | SafetyState::Enabled => &[Command::Arm, Command::StartPath],
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
    fn a_press_resets_a_fault_and_otherwise_arms_and_starts_the_path() {
        use controller_core::servo::safety::FaultReason;
        assert_eq!(
            press_commands(SafetyState::Fault(FaultReason::EStop)),
            &[Command::Reset]
        );
        for s in [SafetyState::Disabled, SafetyState::Enabled] {
            assert_eq!(press_commands(s), &[Command::Arm, Command::StartPath]);
        }
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
