//! The settings store's flash: the STM32F407's last two 128 KiB sectors (10 and 11,
//! `0x080C_0000..0x0810_0000`), which `memory.x` keeps out of the program's FLASH region.
//!
//! Two sectors, not one: sequential-storage's map needs at least two erase pages (it
//! keeps the page holding the current record until the next one is complete, which is
//! what makes a save power-fail safe), and the F407's upper sectors are 128 KiB each.
//!
//! [`InternalFlash`] is the HAL's flash (`LockedFlash`, unlocked for each erase or write
//! and locked again) as a blocking `NorFlash`; the core's
//! [`BlockingFlash`](controller_core::settings::store::BlockingFlash) turns it into the
//! async `NorFlash` the store needs and confines it to the two sectors (the HAL's `read`
//! indexes a slice: out of range would panic, the window refuses first).
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
//! - a save erases a sector whenever the map wraps onto its other sector (about every
//!   370-420 saves): the independent watchdog (a few ms) must be stretched above
//!   [`SECTOR_ERASE_MAX_MS`] around every save and restored after, or the board resets
//!   mid-erase (sequential-storage repairs that at the next load, but the save is lost);
//! - load at boot before the watchdog starts (a load may repair an interrupted erase by
//!   erasing again).
//!
//! [`load_settings`] runs in `init` (before the watchdog); saving over the link is not
//! wired yet (it needs the watchdog stretched around an erase, above).
#![expect(
    dead_code,
    reason = "not wired yet: the link/flash task calls settings_store (remove this then)"
)]

use controller_core::settings::store::{BlockingFlash, SettingsStore, StoreError};
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
pub const SECTOR_ERASE_MAX_MS: u32 = 4_000;

const _: () = assert!(STORE_OFFSET == 0x000C_0000);
const _: () = assert!(STORE_OFFSET + STORE_BYTES == FLASH_BYTES);

/// `memory.x` must end the program's FLASH region where the store begins (768 KiB), so the
/// linker fails if the firmware ever grows into it.
const MEMORY_X: &[u8] = include_bytes!("../../../memory.x");
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
        // in range: only reached through the store's window
        ReadNorFlash::read(&mut self.flash, offset, bytes)
    }

    fn capacity(&self) -> usize {
        self.flash.len()
    }
}

impl NorFlash for InternalFlash {
    const WRITE_SIZE: usize = 1;
    /// The sectors the store uses are 128 KiB (the HAL's erase covers whole sectors).
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        NorFlash::erase(&mut self.flash.unlocked(), from, to)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        NorFlash::write(&mut self.flash.unlocked(), offset, bytes)
    }
}

/// Programming can only clear bits (RM0090: a byte may be programmed again with 0s).
impl MultiwriteNorFlash for InternalFlash {}

/// The store's flash: sectors 10 and 11 seen from offset 0.
pub type SettingsFlash = BlockingFlash<InternalFlash>;

/// Why the store could not be opened (a part with less than 1 MiB of flash, or a layout
/// sequential-storage refuses).
#[derive(Debug)]
pub enum OpenError {
    Window(controller_core::settings::store::WindowError),
    Store(StoreError<controller_core::settings::store::BlockingFlashError<flash::Error>>),
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
/// unusable or could not be opened). Blocking: the HAL's flash is, and `init` may block.
pub fn load_settings(
    flash: pac::FLASH,
    rate_hz: u32,
) -> (
    controller_core::settings::Settings,
    controller_core::settings::store::LoadOutcome,
) {
    use controller_core::settings::store::{Corruption, LoadOutcome};
    match settings_store(flash) {
        Ok(mut store) => block_on(store.load(rate_hz)),
        Err(_) => (
            controller_core::settings::FACTORY,
            LoadOutcome::Corrupt(Corruption::Storage),
        ),
    }
}

/// Runs a future that never waits (the store over a blocking flash) to its end.
fn block_on<F: core::future::Future>(f: F) -> F::Output {
    let mut f = core::pin::pin!(f);
    let mut cx = core::task::Context::from_waker(core::task::Waker::noop());
    loop {
        if let core::task::Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
}
