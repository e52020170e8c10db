//! The three quadrature encoder timers: TIM2 (X) and TIM5 (Y) count in 32 bits, TIM3 (Z)
//! in 16 bits; the core's servo step extends each reading to a wide count. (The QEMU rig
//! configures them but reads the simulated machine instead.)
//!
//! Each timer's A/B inputs pass its digital input filter (TIMx_CCMR1 IC1F/IC2F =
//! `firmware::encoder_filter::ENCODER_IC_FILTER`: 8 samples at 21 MHz, glitches up to
//! 381 ns dropped, up to 4.67 M counts/s passed, 11.7 times the gantry's top speed).

use stm32f4xx_hal::{pac, prelude::*, qei::Qei};

use controller_core::axes::AXES;
use firmware::encoder_filter::ENCODER_IC_FILTER;

/// The encoder timers in encoder mode 3 (×4).
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct Encoders {
    pub x: Qei<pac::TIM2>,
    pub y: Qei<pac::TIM5>,
    pub z: Qei<pac::TIM3>,
}

#[cfg_attr(feature = "qemu", allow(dead_code))]
impl Encoders {
    /// Switches the input filters of TIM2, TIM5 and TIM3 on (after the HAL's encoder-mode
    /// setup, which leaves them off).
    pub fn enable_input_filters(&mut self) {
        // SAFETY: CCMR1 of the encoder timers is written only here, once, in `init`; the
        // HAL's `Qei` only reads the counter afterwards.
        unsafe {
            (*pac::TIM2::ptr()).ccmr1_input().modify(|_, w| {
                w.ic1f()
                    .bits(ENCODER_IC_FILTER)
                    .ic2f()
                    .bits(ENCODER_IC_FILTER)
            });
            (*pac::TIM5::ptr()).ccmr1_input().modify(|_, w| {
                w.ic1f()
                    .bits(ENCODER_IC_FILTER)
                    .ic2f()
                    .bits(ENCODER_IC_FILTER)
            });
            (*pac::TIM3::ptr()).ccmr1_input().modify(|_, w| {
                w.ic1f()
                    .bits(ENCODER_IC_FILTER)
                    .ic2f()
                    .bits(ENCODER_IC_FILTER)
            });
        }
    }

    /// Raw counter registers X, Y, Z (Z is 16 bits wide).
    #[inline]
    pub fn read_raw(&self) -> [u32; AXES] {
        [self.x.count(), self.y.count(), u32::from(self.z.count())]
    }
}
