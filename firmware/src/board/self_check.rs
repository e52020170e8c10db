//! The boot self-check: the board's peripheral configuration after init, read back field
//! by field against the register table `firmware/twin/expect.toml` (every pin's mode,
//! alternate function, pull and output type; the PLL, the flash latency and the BOR level;
//! TIM1's period, break and LOCK; the control tick; the encoder timers' mode and filters;
//! USART2's baud; the IWDG's timeout; the interrupt priorities). The same table is what the
//! board twin checks after boot (`firmware/twin/run --scenario boot`); firmware/build.rs
//! turns it into the register fields below. A mismatch (a HAL update that changed a
//! default, a pin taken by something else, a register that did not take its value) is
//! logged with its address and latches `board_config`: the outputs never get enabled.

/// One register field the board must show after init.
pub struct Expect {
    pub addr: u32,
    pub shift: u8,
    pub width: u8,
    pub value: u32,
    pub what: &'static str,
}

include!(concat!(env!("OUT_DIR"), "/board_expect.rs"));

impl Expect {
    /// The field as the board has it now.
    pub fn read(&self) -> u32 {
        // SAFETY: a volatile read of a register of the table (the peripherals and SCS
        // registers of RM0090 / PM0214 the firmware itself configured in `init`, every
        // one clocked by then); reading them has no side effects.
        let word = unsafe { (self.addr as usize as *const u32).read_volatile() };
        let mask = if self.width >= 32 {
            u32::MAX
        } else {
            (1 << self.width) - 1
        };
        (word >> self.shift) & mask
    }
}

/// The first field that differs from the table, with what it reads; `None`: all as
/// expected.
pub fn first_mismatch() -> Option<(&'static Expect, u32)> {
    BOARD_EXPECT.iter().find_map(|e| {
        let v = e.read();
        (v != e.value).then_some((e, v))
    })
}

/// The entries checked.
pub fn entries() -> usize {
    BOARD_EXPECT.len()
}
