//! The brown-out reset level: the option bytes' BOR_LEV, programmed once to 2.7 V.
//!
//! 168 MHz with 5 flash wait states needs a supply of 2.7–3.6 V (RM0090 table 10); the
//! factory option bytes leave the brown-out reset off (BOR_LEV = 11: only the 1.8 V
//! power-on/power-down reset), so a sagging supply between 1.8 and 2.7 V would run the
//! core out of its specification with the outputs live. BOR level 3 (BOR_LEV = 00, VBOR3
//! 2.70–3.60 V, RM0090 3.7.3 and DS8626 table 21) holds the chip in reset below that.
//!
//! RM0090's encoding is used as raw bits: the PAC's enumerated names for BOR_LEV (from the
//! SVD) count the other way (its `BorOff` is 00), and writing them would do the opposite.
//!
//! Programming the option bytes takes tens of milliseconds with the CPU stalled; it
//! happens once per chip (the level is kept in the option bytes), at boot, before the
//! watchdog starts and with every output off.

use stm32f4xx_hal::pac;

/// BOR_LEV bits for BOR level 3 (2.70–3.60 V), RM0090 3.9.10.
pub const BOR_LEV_2V7: u8 = 0b00;
const OPTKEY1: u32 = 0x0819_2A3B;
const OPTKEY2: u32 = 0x4C5D_6E7F;
/// Busy-wait bound for the option-byte programming, iterations of a loop of a few cycles
/// (RM0090 gives no figure; the twin models 16 ms; 168 MHz x 0.5 s covers any part).
const OPT_BUSY_SPINS: u32 = 84_000_000;

/// What [`ensure_2v7`] found and did.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum BorSetting {
    /// Already 2.7 V: nothing written.
    Kept,
    /// Was another level (its BOR_LEV bits): programmed to 2.7 V.
    Programmed { was: u8 },
    /// Programming did not finish or did not take: the level is still `now`.
    Failed { now: u8 },
}

/// Programs BOR_LEV to 2.7 V if it is not already, changing no other option bit.
pub fn ensure_2v7(flash: &pac::FLASH) -> BorSetting {
    let was = flash.optcr().read().bor_lev().bits();
    if was == BOR_LEV_2V7 {
        return BorSetting::Kept;
    }
    if flash.optcr().read().optlock().bit_is_set() {
        flash.optkeyr().write(|w| w.optkeyr().set(OPTKEY1));
        flash.optkeyr().write(|w| w.optkeyr().set(OPTKEY2));
    }
    let mut done = wait_not_busy(flash);
    if done {
        // `modify` keeps RDP, nWRP and the user bits as they are
        // SAFETY: 00 is a defined BOR_LEV value (BOR level 3 in RM0090's encoding, see
        // above); the PAC marks raw writes of an enumerated field unsafe
        flash
            .optcr()
            .modify(|_, w| unsafe { w.bor_lev().bits(BOR_LEV_2V7) });
        flash.optcr().modify(|_, w| w.optstrt().set_bit());
        done = wait_not_busy(flash);
    }
    flash.optcr().modify(|_, w| w.optlock().set_bit());
    let now = flash.optcr().read().bor_lev().bits();
    if done && now == BOR_LEV_2V7 {
        BorSetting::Programmed { was }
    } else {
        BorSetting::Failed { now }
    }
}

fn wait_not_busy(flash: &pac::FLASH) -> bool {
    for _ in 0..OPT_BUSY_SPINS {
        if flash.sr().read().bsy().bit_is_clear() {
            return true;
        }
    }
    false
}
