//! The settings in flash: one versioned postcard record of the tree in a
//! `sequential-storage` map over any (async) `NorFlash`, plus a blocking-to-async adapter
//! for flash drivers that block ([`BlockingFlash`], the STM32 HAL's), and a RAM-backed
//! flash with NOR semantics ([`RamFlash`]: the QEMU rig and the simulator, which have no
//! flash to keep).
//!
//! Layout: the map's flash range (at least two erase pages: sequential-storage keeps the
//! old page until the new item is complete, which is what makes a save power-fail safe)
//! holds items of key [`RECORD_KEY`]; each item is sequential-storage's header (length with
//! its CRC-16, CRC-32 of the data) and the data `[SETTINGS_VERSION as u16 LE][postcard of
//! Settings]`. A save appends a new item; the newest intact one is the settings. Pages are
//! used in turn (wear levelling); a page is erased only when the map wraps onto it.
//!
//! Loading never fails: it returns the settings to run and how they were found
//! ([`LoadOutcome`]). A record that is damaged, of another version, or that the servo
//! would reject gives [`FACTORY`]; the caller then latches `FaultKind::SettingsCorrupt`
//! with `Servo::latch_board_fault` ([`LoadOutcome::is_fault`]). Power-fail safety is
//! sequential-storage's: a save cut short leaves the previous record (or, for the very
//! first save, nothing intact: defaults and a fault).
//!
//! Nothing here panics on flash contents; the flash operations are async (RTIC 2 tasks and
//! the host's executors await them). Erasing a 128 KiB STM32F4 sector stalls the CPU for
//! up to seconds: save only while the outputs are off, with the watchdog stretched
//! (firmware/src/board/flash.rs).

use core::ops::Range as AddrRange;

use embedded_storage::nor_flash::{
    NorFlash as BlockingNorFlash, NorFlashErrorKind, ReadNorFlash as BlockingReadNorFlash,
};
use embedded_storage_async::nor_flash::{
    ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError, ReadNorFlash,
};
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapConfigError, MapStorage, SerializationError, Value};

use super::keys::SettingError;
use super::tree::{Settings, FACTORY, SETTINGS_VERSION};

/// Map key of the settings record (the map has room for other records later, e.g. a
/// machine name or calibration, under other keys).
pub const RECORD_KEY: u8 = 0;

/// Bytes of the record buffer: the key (1), the version (2) and the postcard tree (513
/// bytes, 561 with three axis models, see the `record_size` test), with a quarter of the
/// buffer kept free for settings to come.
pub const RECORD_BUFFER: usize = 1024;

/// The record buffer, aligned for flashes that need word-aligned source buffers (up to
/// sequential-storage's largest word, 32 bytes).
#[repr(C, align(32))]
struct AlignedBuffer([u8; RECORD_BUFFER]);

/// How [`SettingsStore::load`] found the settings.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadOutcome {
    /// The stored record, valid.
    Stored,
    /// The store is erased (a new board, or after [`SettingsStore::erase`]): factory
    /// settings, no fault.
    Empty,
    /// The store holds something but no usable record: factory settings, and a fault.
    Corrupt(Corruption),
    /// The record was written by firmware with another settings layout: factory settings,
    /// and a fault (the user re-enters or re-imports the settings).
    VersionMismatch { found: u16 },
}

impl LoadOutcome {
    /// The caller latches `FaultKind::SettingsCorrupt` (the settings running are the
    /// factory ones although the user had stored others).
    pub fn is_fault(&self) -> bool {
        matches!(self, Self::Corrupt(_) | Self::VersionMismatch { .. })
    }
}

/// What was wrong with the store.
#[derive(Clone, Debug, PartialEq)]
pub enum Corruption {
    /// The flash could not be read, or sequential-storage found its own structure broken
    /// (and could not repair it).
    Storage,
    /// Data is present but no intact record (the first save was cut short, or bit flips
    /// in the only record).
    NoIntactRecord,
    /// The record's bytes do not decode as this version's tree.
    Undecodable,
    /// The record decodes, but a value is out of range or the servo rejects the tree (e.g.
    /// firmware built for another control rate).
    Invalid(SettingError),
}

/// Why a store operation failed. `E` is the flash's error.
#[derive(Debug)]
pub enum StoreError<E> {
    /// The flash range cannot hold a map (not on erase-page boundaries, fewer than two
    /// pages, or pages too small).
    Range(MapConfigError),
    /// The tree is not valid: it was not saved.
    Invalid(SettingError),
    /// sequential-storage or the flash failed.
    Storage(sequential_storage::Error<E>),
}

impl<E: core::fmt::Debug> core::fmt::Display for StoreError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Range(e) => write!(f, "the store's flash range cannot hold a map ({e:?})"),
            Self::Invalid(e) => write!(f, "{e}"),
            Self::Storage(e) => write!(f, "flash: {e:?}"),
        }
    }
}

/// Runs a future that never waits — the store over a blocking flash ([`BlockingFlash`],
/// [`RamFlash`]) — to its end. For callers without an executor (the firmware's `init`
/// and link task, the simulator); a future that does wait would spin here.
pub fn block_on<F: core::future::Future>(f: F) -> F::Output {
    let mut f = core::pin::pin!(f);
    let mut cx = core::task::Context::from_waker(core::task::Waker::noop());
    loop {
        if let core::task::Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
}

/// The record as written: the version, then the tree.
struct RecordOut<'s>(&'s Settings);

impl<'a> Value<'a> for RecordOut<'_> {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        let (head, body) = buffer
            .split_at_mut_checked(2)
            .ok_or(SerializationError::BufferTooSmall)?;
        head.copy_from_slice(&SETTINGS_VERSION.to_le_bytes());
        let used = postcard::to_slice(self.0, body)
            .map_err(|_| SerializationError::BufferTooSmall)?
            .len();
        Ok(2 + used)
    }

    fn deserialize_from(_buffer: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        // write-only view; records are read as `RecordIn`
        Err(SerializationError::InvalidFormat)
    }
}

/// The record as read (a transient value: the size difference does not matter).
#[allow(clippy::large_enum_variant)]
enum RecordIn {
    Current(Settings),
    OtherVersion(u16),
}

impl<'a> Value<'a> for RecordIn {
    fn serialize_into(&self, _buffer: &mut [u8]) -> Result<usize, SerializationError> {
        // read-only view; records are written as `RecordOut`
        Err(SerializationError::InvalidData)
    }

    fn deserialize_from(buffer: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        let (head, body) = buffer
            .split_first_chunk::<2>()
            .ok_or(SerializationError::InvalidFormat)?;
        let version = u16::from_le_bytes(*head);
        if version != SETTINGS_VERSION {
            return Ok((Self::OtherVersion(version), buffer.len()));
        }
        match postcard::take_from_bytes::<Settings>(body) {
            Ok((s, [])) => Ok((Self::Current(s), buffer.len())),
            _ => Err(SerializationError::InvalidFormat),
        }
    }
}

/// The settings store over flash `F` (owned; [`Self::into_flash`] gives it back).
pub struct SettingsStore<F: NorFlash> {
    map: MapStorage<u8, F, Cache<Uncached, Uncached, Uncached, u8>>,
    buf: AlignedBuffer,
}

impl<F: NorFlash> SettingsStore<F> {
    /// A store in `range` of `flash` (byte offsets of the flash; at least two erase pages,
    /// on page boundaries). Touches nothing.
    pub fn new(flash: F, range: AddrRange<u32>) -> Result<Self, StoreError<F::Error>> {
        let config = MapConfig::try_new(range).map_err(StoreError::Range)?;
        Ok(Self {
            map: MapStorage::new(flash, config, Cache::new_uncached()),
            buf: AlignedBuffer([0; RECORD_BUFFER]),
        })
    }

    /// The settings to run at control rate `rate_hz`, and how they were found (see the
    /// module docs). A valid record is returned as stored; anything else gives
    /// [`FACTORY`].
    pub async fn load(&mut self, rate_hz: u32) -> (Settings, LoadOutcome) {
        let outcome = match self
            .map
            .fetch_item::<RecordIn>(&mut self.buf.0, &RECORD_KEY)
            .await
        {
            Ok(Some(RecordIn::Current(s))) => match s.validate(rate_hz) {
                Ok(()) => return (s, LoadOutcome::Stored),
                Err(e) => LoadOutcome::Corrupt(Corruption::Invalid(e)),
            },
            Ok(Some(RecordIn::OtherVersion(found))) => LoadOutcome::VersionMismatch { found },
            Ok(None) => match self.erased().await {
                Ok(true) => LoadOutcome::Empty,
                Ok(false) => LoadOutcome::Corrupt(Corruption::NoIntactRecord),
                Err(()) => LoadOutcome::Corrupt(Corruption::Storage),
            },
            Err(sequential_storage::Error::SerializationError(_)) => {
                LoadOutcome::Corrupt(Corruption::Undecodable)
            }
            Err(_) => LoadOutcome::Corrupt(Corruption::Storage),
        };
        (FACTORY, outcome)
    }

    /// Every byte of the map's range is erased (`0xFF`).
    async fn erased(&mut self) -> Result<bool, ()> {
        let range = self.map.flash_range();
        let mut chunk = [0u8; 64];
        // read in multiples of the flash's read size (64 is one for every flash this
        // supports: read sizes are powers of two up to 32)
        let step = chunk.len() - chunk.len() % F::READ_SIZE.max(1);
        let mut at = range.start;
        while at < range.end {
            let n = step.min((range.end - at) as usize);
            let part = chunk.get_mut(..n).ok_or(())?;
            self.map.flash().read(at, part).await.map_err(|_| ())?;
            if part.iter().any(|b| *b != 0xFF) {
                return Ok(false);
            }
            at = at.saturating_add(n as u32);
        }
        Ok(true)
    }

    /// Store `settings` as the new record, after validating it whole at `rate_hz` (a tree
    /// the next boot would reject is never stored). The caller ensures the outputs are off
    /// (a save may erase a flash page).
    pub async fn save(
        &mut self,
        settings: &Settings,
        rate_hz: u32,
    ) -> Result<(), StoreError<F::Error>> {
        settings.validate(rate_hz).map_err(StoreError::Invalid)?;
        self.map
            .store_item(&mut self.buf.0, &RECORD_KEY, &RecordOut(settings))
            .await
            .map_err(StoreError::Storage)
    }

    /// Erase the whole store (factory reset: the next load is [`LoadOutcome::Empty`]).
    pub async fn erase(&mut self) -> Result<(), StoreError<F::Error>> {
        self.map.erase_all().await.map_err(StoreError::Storage)
    }

    /// Give the flash back.
    pub fn into_flash(self) -> F {
        self.map.destroy().0
    }
}

/// Bytes one stored record takes in flash for `settings` (sequential-storage's item
/// header plus the data, padded to the flash word), on a flash like `F`.
pub fn record_flash_bytes<F: NorFlash>(settings: &Settings) -> Option<usize> {
    let mut buf = [0u8; RECORD_BUFFER];
    let data = 1 + RecordOut(settings).serialize_into(&mut buf).ok()?;
    let word = F::WRITE_SIZE.max(F::READ_SIZE).max(1);
    let overhead =
        MapStorage::<u8, F, Cache<Uncached, Uncached, Uncached, u8>>::item_overhead_size();
    Some(overhead as usize + data.div_ceil(word) * word)
}

/// Why a [`BlockingFlash`] window cannot be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindowError {
    /// Start or length not on the flash's erase-page boundaries, or zero length.
    NotAligned,
    /// The window does not lie within the flash.
    OutOfBounds,
}

/// A window `[base, base + len)` of a blocking `NorFlash` (the STM32 HAL's) seen as an
/// async `NorFlash` whose offsets start at 0: the blocking-to-async adapter the store
/// needs, and the bounds check the HAL's flash does not do (it indexes a slice). Every
/// operation completes before its future returns (the CPU is busy for its whole length,
/// as it would be anyway on a single-bank flash that stalls instruction fetch).
pub struct BlockingFlash<F> {
    flash: F,
    base: u32,
    len: u32,
}

/// An error of a [`BlockingFlash`]: outside the window, or the flash's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockingFlashError<E> {
    OutOfBounds,
    Flash(E),
}

impl<E: NorFlashError> NorFlashError for BlockingFlashError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::Flash(e) => e.kind(),
        }
    }
}

impl<F: BlockingNorFlash> BlockingFlash<F> {
    /// The window of `len` bytes at `base` (byte offsets of `flash`; both multiples of its
    /// erase size).
    pub fn new(flash: F, base: u32, len: u32) -> Result<Self, WindowError> {
        let page = u32::try_from(F::ERASE_SIZE).map_err(|_| WindowError::NotAligned)?;
        if page == 0 || len == 0 || !base.is_multiple_of(page) || !len.is_multiple_of(page) {
            return Err(WindowError::NotAligned);
        }
        let end = base.checked_add(len).ok_or(WindowError::OutOfBounds)?;
        if end as usize > flash.capacity() {
            return Err(WindowError::OutOfBounds);
        }
        Ok(Self { flash, base, len })
    }

    /// The address in the flash of window offset `offset` for `n` bytes.
    fn address(&self, offset: u32, n: usize) -> Result<u32, BlockingFlashError<F::Error>> {
        let n = u32::try_from(n).map_err(|_| BlockingFlashError::OutOfBounds)?;
        match offset.checked_add(n) {
            // base + len fits in u32 (checked in `new`), so base + offset does too
            Some(end) if end <= self.len => Ok(self.base + offset),
            _ => Err(BlockingFlashError::OutOfBounds),
        }
    }

    pub fn into_inner(self) -> F {
        self.flash
    }
}

impl<F: BlockingNorFlash> ErrorType for BlockingFlash<F> {
    type Error = BlockingFlashError<F::Error>;
}

impl<F: BlockingNorFlash> ReadNorFlash for BlockingFlash<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = self.address(offset, bytes.len())?;
        self.flash
            .read(at, bytes)
            .map_err(BlockingFlashError::Flash)
    }

    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl<F: BlockingNorFlash> NorFlash for BlockingFlash<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let n = to
            .checked_sub(from)
            .ok_or(BlockingFlashError::OutOfBounds)?;
        let at = self.address(from, n as usize)?;
        self.flash
            .erase(at, at + n)
            .map_err(BlockingFlashError::Flash)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = self.address(offset, bytes.len())?;
        self.flash
            .write(at, bytes)
            .map_err(BlockingFlashError::Flash)
    }
}

impl<F: embedded_storage::nor_flash::MultiwriteNorFlash> MultiwriteNorFlash for BlockingFlash<F> {}

/// A flash in RAM with NOR semantics (erase sets bytes to `0xFF`, writes can only clear
/// bits): `BYTES` bytes in pages of `ERASE` bytes. For the QEMU rig and the simulator,
/// which have no flash to keep settings in (`BlockingFlash<RamFlash<8192, 4096>>` is a
/// two-page store in 8 KiB of RAM), and for tests.
pub struct RamFlash<const BYTES: usize, const ERASE: usize> {
    data: [u8; BYTES],
}

impl<const BYTES: usize, const ERASE: usize> RamFlash<BYTES, ERASE> {
    const GEOMETRY: () = assert!(
        ERASE > 0 && BYTES.is_multiple_of(ERASE) && BYTES <= u32::MAX as usize,
        "RamFlash: BYTES must be a multiple of ERASE"
    );

    /// An erased flash.
    pub const fn new() -> Self {
        let () = Self::GEOMETRY;
        Self {
            data: [0xFF; BYTES],
        }
    }

    pub fn bytes(&self) -> &[u8] {
        &self.data
    }

    /// Raw access (tests flip bits through it).
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }
}

impl<const BYTES: usize, const ERASE: usize> Default for RamFlash<BYTES, ERASE> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const BYTES: usize, const ERASE: usize> embedded_storage::nor_flash::ErrorType
    for RamFlash<BYTES, ERASE>
{
    type Error = NorFlashErrorKind;
}

impl<const BYTES: usize, const ERASE: usize> BlockingReadNorFlash for RamFlash<BYTES, ERASE> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let src = self
            .data
            .get(span(offset, bytes.len())?)
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        BYTES
    }
}

impl<const BYTES: usize, const ERASE: usize> BlockingNorFlash for RamFlash<BYTES, ERASE> {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = ERASE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if !(from as usize).is_multiple_of(ERASE) || !(to as usize).is_multiple_of(ERASE) {
            return Err(NorFlashErrorKind::NotAligned);
        }
        let n = to.checked_sub(from).ok_or(NorFlashErrorKind::OutOfBounds)?;
        self.data
            .get_mut(span(from, n as usize)?)
            .ok_or(NorFlashErrorKind::OutOfBounds)?
            .fill(0xFF);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let dst = self
            .data
            .get_mut(span(offset, bytes.len())?)
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        for (d, s) in dst.iter_mut().zip(bytes) {
            // NOR: programming only clears bits
            *d &= *s;
        }
        Ok(())
    }
}

/// The byte range `offset .. offset + len` (without overflow; bounds are checked by the
/// slice `get`).
fn span(offset: u32, len: usize) -> Result<core::ops::Range<usize>, NorFlashErrorKind> {
    let start = usize::try_from(offset).map_err(|_| NorFlashErrorKind::OutOfBounds)?;
    let end = start
        .checked_add(len)
        .ok_or(NorFlashErrorKind::OutOfBounds)?;
    Ok(start..end)
}

impl<const BYTES: usize, const ERASE: usize> embedded_storage::nor_flash::MultiwriteNorFlash
    for RamFlash<BYTES, ERASE>
{
}

#[cfg(test)]
mod tests;
