//! The link side's half of a settings save or repair: once the machine holds its outputs
//! off ([`LinkSide::save_due`]), write the settings it runs to the store (a repair: erase
//! the store and write them, `SettingsStore::repair`) and hand the outcome down
//! ([`LinkSide::save_finished`]), which releases the machine. One implementation for the
//! board, the QEMU rig and `gantry --sim`. Blocking: the link
//! task (or the simulator's link end) waits for the flash; the control interrupt does
//! not (on the STM32F4 it stalls while the flash erases: see
//! firmware/src/board/flash.rs for what the board does around it).

use core::fmt::{Debug, Write};

use embedded_storage_async::nor_flash::NorFlash;
use heapless::String;

use super::messages::{Outcome, TEXT_MAX};
use super::port::{LinkSide, SaveJob};
use crate::settings::store::{block_on, SettingsStore};
use crate::settings::Settings;

/// Write `settings` (validated whole at `rate_hz` first) to `store` now, as the save
/// request's outcome: done, or why not (named, for the host to print).
pub fn save_blocking<F: NorFlash>(
    store: &mut SettingsStore<F>,
    settings: &Settings,
    rate_hz: u32,
) -> Outcome
where
    F::Error: Debug,
{
    match block_on(store.save(settings, rate_hz)) {
        Ok(()) => Outcome::Done,
        Err(e) => {
            let mut t: String<TEXT_MAX> = String::new();
            // (a longer message is cut; it still says what failed first)
            let _ = write!(t, "save failed: {e}");
            Outcome::Refused(t)
        }
    }
}

/// Carry out `job` on `store` now (a save, or a repair: the store erased and the settings
/// written into it; validated whole at `rate_hz` first), as the request's outcome.
pub fn write_blocking<F: NorFlash>(
    store: &mut SettingsStore<F>,
    job: &SaveJob,
    rate_hz: u32,
) -> Outcome
where
    F::Error: Debug,
{
    if !job.repair {
        return save_blocking(store, &job.settings, rate_hz);
    }
    match block_on(store.repair(&job.settings, rate_hz)) {
        Ok(()) => Outcome::Done,
        Err(e) => {
            let mut t: String<TEXT_MAX> = String::new();
            let _ = write!(t, "repair failed: {e}");
            Outcome::Refused(t)
        }
    }
}

/// Carry out a save or repair that is due on `port`, if one is: write, then release the
/// machine. Returns whether one was.
pub fn save_due_into<F: NorFlash>(port: &mut LinkSide<'_, '_>, store: &mut SettingsStore<F>) -> bool
where
    F::Error: Debug,
{
    let Some(job) = port.save_due() else {
        return false;
    };
    let outcome = write_blocking(store, &job, port.rate_hz());
    port.save_finished(outcome);
    true
}
