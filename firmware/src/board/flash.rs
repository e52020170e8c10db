//! The settings store's flash: the STM32F407's last two 128 KiB sectors (10 and 11,
//! `0x080C_0000..0x0810_0000`), which `memory.x` keeps out of the program's FLASH region.
//!
//! Two sectors, not one: the store needs at least two erase pages (it keeps the page
//! holding the current record until the next one is complete elsewhere, which is what
//! makes a save power-fail safe), and the F407's upper sectors are 128 KiB each.
//!
//! [`InternalFlash`] is the HAL's flash (`LockedFlash`, unlocked for each erase or write
//! and locked again) as a blocking `NorFlash`; the core's
//! [`BlockingFlash`](controller_core::settings::store::BlockingFlash) turns it into the
//! async `NorFlash` the store needs and confines it to the two sectors. Reads do not go
//! through the HAL's `read`, which indexes a slice (a panic path the no-panic check
//! finds): out of range is an error here, though the window refuses first.
//!
//! Timing (DS8626, flash programming characteristics; not measured on a board): the
//! HAL programs with 8-bit parallelism, 16 µs typical / 100 µs worst per byte, so a
//! ~310-byte record takes about 5 ms (30 ms worst); erasing one 128 KiB sector takes 2 s
//! typical, [`SECTOR_ERASE_MAX_MS`] worst. The F407 has a single flash bank: while it
//! erases or programs, every instruction fetch from flash stalls, including the control
//! interrupt's. Hence, for whoever calls the store:
//!
//! - save only while the outputs are off (`ServoState::drives()` false), as the servo
//!   refuses `reconfigure` otherwise;
//! - a save erases a sector whenever the store moves onto its other sector (about every
//!   230-250 saves), a repair erases both: the independent watchdog (a few ms) must be
//!   stretched above [`SECTOR_ERASE_MAX_MS`] around every save and restored after, or the
//!   board resets mid-erase (the previous record survives, the save is lost);
//! - load at boot before the watchdog starts (a load reads only, but scans both sectors).
//!
//! [`load_settings`] runs in `init` (before the watchdog) and hands the store to the link
//! task's [`BoardSaver`], which writes a save or repair over the link once the machine
//! holds its outputs off (`controller_core::machine::save`), with the watchdog stretched to
//! [`firmware::watchdog::SAVE_TIMEOUT_US`] around it.

use controller_core::machine::messages::Outcome;
use controller_core::machine::{write_blocking, LinkSide};

use crate::link::SettingsSaver;
use controller_core::settings::store::{block_on, BlockingFlash, SettingsStore, StoreError};
use embedded_storage::nor_flash::{ErrorType, MultiwriteNorFlash, NorFlash, ReadNorFlash};
use stm32f4xx_hal::flash::{self, FlashExt, LockedFlash};
use stm32f4xx_hal::pac;

/// Size of sectors 5..11 (RM0090, "Flash module organization").
pub const SECTOR_BYTES: u32 = 128 * 1024;
/// First sector of the store.
pub const FIRST_SECTOR: u8 = 10;
/// Offset of sector 10 from the flash base (0x0800_0000): sectors 0-3 of 16 KiB, 4 of
/// 64 KiB, 5-9 of 128 KiB.
pub const STORE_OFFSET: u32 = 4 * 16 * 1024 + 64 * 1024 + 5 * SECTOR_BYTES;
/// Size of the store: sectors 10 and 11.
pub const STORE_BYTES: u32 = 2 * SECTOR_BYTES;
/// Flash of the STM32F407VG.
pub const FLASH_BYTES: u32 = 1024 * 1024;
/// Worst-case erase of one 128 KiB sector at 8-bit parallelism, ms (DS8626: 2 s typical).
pub const SECTOR_ERASE_MAX_MS: u32 = controller_core::presets::board::FLASH_SECTOR_ERASE_MAX_MS;

const _: () = assert!(STORE_OFFSET == 0x000C_0000);
const _: () =
    assert!(STORE_OFFSET == 4 * 16 * 1024 + 64 * 1024 + (FIRST_SECTOR as u32 - 5) * SECTOR_BYTES);
// the watchdog's timeout around a save outlasts the worst erase with room to spare
const _: () = assert!(firmware::watchdog::SAVE_TIMEOUT_US >= 2 * SECTOR_ERASE_MAX_MS * 1000);
const _: () = assert!(STORE_OFFSET + STORE_BYTES == FLASH_BYTES);

/// `memory.x` must end the program's FLASH region where the store begins (768 KiB), so the
/// linker fails if the firmware ever grows into it.
const MEMORY_X: &[u8] = include_bytes!("../../memory.x");
const _: () = assert!(
    contains(MEMORY_X, b"FLASH : ORIGIN = 0x08000000, LENGTH = 768K"),
    "memory.x: FLASH must be 0x08000000 + 768K, ending where the settings sectors begin"
);

/// `needle` occurs in `haystack` (compile-time check of memory.x).
const fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    let mut i = 0;
    while i + needle.len() <= haystack.len() {
        let mut j = 0;
        while j < needle.len() && haystack[i + j] == needle[j] {
            j += 1;
        }
        if j == needle.len() {
            return true;
        }
        i += 1;
    }
    false
}

/// The internal flash as a blocking `NorFlash` (offsets from 0x0800_0000).
pub struct InternalFlash {
    flash: LockedFlash,
}

impl InternalFlash {
    pub fn new(flash: pac::FLASH) -> Self {
        Self {
            flash: LockedFlash::new(flash),
        }
    }
}

impl ErrorType for InternalFlash {
    type Error = flash::Error;
}

impl ReadNorFlash for InternalFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        // In range (only reached through the store's window), checked anyway: the HAL's
        // `read` would index the flash slice and panic.
        let src = usize::try_from(offset)
            .ok()
            .and_then(|o| FlashExt::read(&self.flash).get(o..))
            .and_then(|tail| tail.get(..bytes.len()))
            .ok_or(flash::Error::Operation)?;
        for (d, s) in bytes.iter_mut().zip(src) {
            *d = *s;
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.flash.len()
    }
}

impl NorFlash for InternalFlash {
    const WRITE_SIZE: usize = 1;
    /// The sectors the store uses are 128 KiB (the HAL's erase covers whole sectors).
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    // Not inlined: the HAL's `unlocked` asserts that the key sequence cleared
    // FLASH_CR.LOCK, and check-no-panic allows that assert by these two functions' names
    // (firmware/tools/check-no-panic, ALLOWED), not by the link task's.
    #[inline(never)]
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        clear_error_flags();
        let r = NorFlash::erase(&mut self.flash.unlocked(), from, to);
        // even a failed erase may have cleared part of a sector
        flush_caches();
        r
    }

    #[inline(never)]
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        clear_error_flags();
        NorFlash::write(&mut self.flash.unlocked(), offset, bytes)
    }
}

/// FLASH_SR's error flags (PGSERR, PGPERR, PGAERR, WRPERR, OPERR) and EOP, cleared before
/// each erase and program: the HAL checks them after an operation but never clears them,
/// and the flash starts no operation while one is set (RM0090 3.6.4), so one stray flag
/// (a stray store into the flash array sets PGSERR) would fail every later save.
fn clear_error_flags() {
    // SAFETY: the HAL's `LockedFlash` owns FLASH but is not in the middle of an operation
    // here (called between its calls, on the link task, the only user of the flash after
    // `init`); the write-1-to-clear bits touch nothing else.
    let flash = unsafe { &*pac::FLASH::ptr() };
    flash.sr().write(|w| {
        w.eop().clear_bit_by_one();
        w.operr().clear_bit_by_one();
        w.wrperr().clear_bit_by_one();
        w.pgaerr().clear_bit_by_one();
        w.pgperr().clear_bit_by_one();
        w.pgserr().clear_bit_by_one()
    });
}

/// After an erase, the ART accelerator's caches may hold lines of the old contents (the
/// HAL turns both on at clock set-up and never flushes them): each enabled cache is
/// turned off, reset (its reset bit may only be written with it off, RM0090 3.5.2) and
/// turned on again, as ST's `FLASH_FlushCaches` does after `HAL_FLASHEx_Erase`.
fn flush_caches() {
    // SAFETY: as in `clear_error_flags`; ACR's latency and prefetch bits are kept.
    let flash = unsafe { &*pac::FLASH::ptr() };
    let acr = flash.acr().read();
    if acr.icen().bit_is_set() {
        flash.acr().modify(|_, w| w.icen().clear_bit());
        flash.acr().modify(|_, w| w.icrst().set_bit());
        flash.acr().modify(|_, w| w.icrst().clear_bit());
        flash.acr().modify(|_, w| w.icen().set_bit());
    }
    if acr.dcen().bit_is_set() {
        flash.acr().modify(|_, w| w.dcen().clear_bit());
        flash.acr().modify(|_, w| w.dcrst().set_bit());
        flash.acr().modify(|_, w| w.dcrst().clear_bit());
        flash.acr().modify(|_, w| w.dcen().set_bit());
    }
}

/// Programming can only clear bits (RM0090: a byte may be programmed again with 0s).
impl MultiwriteNorFlash for InternalFlash {}

/// The store's flash: sectors 10 and 11 seen from offset 0.
pub type SettingsFlash = BlockingFlash<InternalFlash>;

/// Why the store could not be opened (a part with less than 1 MiB of flash, or a layout
/// the store refuses).
#[derive(Debug)]
pub enum OpenError {
    Window(controller_core::settings::store::WindowError),
    Store(StoreError<controller_core::settings::store::BlockingFlashError<flash::Error>>),
}

impl core::fmt::Display for OpenError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Window(e) => write!(f, "flash window: {e:?}"),
            Self::Store(e) => write!(f, "{e}"),
        }
    }
}

/// The settings store on sectors 10 and 11. Touches no flash; `load` then `save` as the
/// module docs say.
pub fn settings_store(flash: pac::FLASH) -> Result<SettingsStore<SettingsFlash>, OpenError> {
    let window = BlockingFlash::new(InternalFlash::new(flash), STORE_OFFSET, STORE_BYTES)
        .map_err(OpenError::Window)?;
    SettingsStore::new(window, 0..STORE_BYTES).map_err(OpenError::Store)
}

/// The settings to boot with: the stored record at `rate_hz`, or the factory settings
/// (with a fault to latch, `LoadOutcome::is_fault`, when the store held something
/// unusable or could not be opened); and the store, for saves. Blocking: the HAL's flash
/// is, and `init` may block.
pub fn load_settings(
    flash: pac::FLASH,
    rate_hz: u32,
) -> (
    controller_core::settings::Settings,
    controller_core::settings::store::LoadOutcome,
    Option<SettingsStore<SettingsFlash>>,
) {
    use controller_core::settings::store::{Corruption, LoadOutcome};
    match settings_store(flash) {
        Ok(mut store) => {
            let (settings, outcome) = block_on(store.load(rate_hz));
            (settings, outcome, Some(store))
        }
        Err(e) => {
            defmt::error!(
                "settings store cannot be opened: {}",
                defmt::Display2Format(&e)
            );
            (
                controller_core::settings::FACTORY,
                LoadOutcome::Corrupt(Corruption::Storage),
                None,
            )
        }
    }
}

/// The link task's settings saves on the board: the store on sectors 10 and 11, written
/// with the watchdog stretched (see the module docs).
pub struct BoardSaver {
    store: Option<SettingsStore<SettingsFlash>>,
    watchdog: super::watchdog::WatchdogStretch,
}

impl BoardSaver {
    pub fn new(
        store: Option<SettingsStore<SettingsFlash>>,
        watchdog: super::watchdog::WatchdogStretch,
    ) -> Self {
        Self { store, watchdog }
    }
}

impl SettingsSaver for BoardSaver {
    /// Write a save or repair that is due on `port` (the machine holds its outputs off).
    fn save_due(&mut self, port: &mut LinkSide<'_, '_>) {
        let Some(job) = port.save_due() else {
            return;
        };
        let Some(store) = self.store.as_mut() else {
            port.save_finished(refused(
                "save failed: the settings store could not be opened",
            ));
            return;
        };
        if !self.watchdog.stretch() {
            port.save_finished(refused("save failed: the watchdog could not be stretched"));
            return;
        }
        let outcome = write_blocking(store, &job, port.rate_hz());
        let outcome = if self.watchdog.restore() {
            outcome
        } else {
            // (the IWDG's registers never settled: hardware trouble; a hang would now
            // take seconds to reset the board)
            refused("save: the watchdog's timeout could not be restored; power-cycle before arming")
        };
        port.save_finished(outcome);
    }
}

fn refused(s: &str) -> Outcome {
    let mut t = heapless::String::new();
    let _ = t.push_str(s);
    Outcome::Refused(t)
}
