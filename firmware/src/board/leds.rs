//! Status LEDs: green (PD12) = outputs enabled, red (PD14) = fault latched (the LEDs of
//! an STM32F4DISCOVERY).

use stm32f4xx_hal::gpio::{AnyPin, Output, PinState};

/// The two status LEDs.
pub struct Leds {
    pub enabled: AnyPin<Output>,
    pub fault: AnyPin<Output>,
}

impl Leds {
    /// Shows the safety state.
    pub fn show(&mut self, enabled: bool, fault: bool) {
        self.enabled.set_state(PinState::from(enabled));
        self.fault.set_state(PinState::from(fault));
    }
}
