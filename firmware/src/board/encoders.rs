//! The three quadrature encoder timers: TIM2 (X) and TIM5 (Y) count in 32 bits, TIM3 (Z)
//! in 16 bits; the core's servo step extends each reading to a wide count. (The QEMU rig
//! configures them but reads the simulated machine instead.)

use stm32f4xx_hal::{pac, prelude::*, qei::Qei};

use controller_core::axes::AXES;

/// The encoder timers in encoder mode 3 (×4).
#[cfg_attr(feature = "qemu", allow(dead_code))]
pub struct Encoders {
    pub x: Qei<pac::TIM2>,
    pub y: Qei<pac::TIM5>,
    pub z: Qei<pac::TIM3>,
}

#[cfg_attr(feature = "qemu", allow(dead_code))]
impl Encoders {
    /// Raw counter registers X, Y, Z (Z is 16 bits wide).
    #[inline]
    pub fn read_raw(&self) -> [u32; AXES] {
        [self.x.count(), self.y.count(), u32::from(self.z.count())]
    }
}
