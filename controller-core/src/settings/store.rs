//! The settings in flash: a log of versioned postcard records of the tree, each checked by
//! a CRC-32, over any (async) `NorFlash`, that survives a power cut at any byte of any
//! program or erase; plus a blocking-to-async adapter for flash drivers that block
//! ([`BlockingFlash`], the STM32 HAL's), and a RAM-backed flash with NOR semantics
//! ([`RamFlash`]: the QEMU rig and the simulator, which have no flash to keep).
//!
//! Layout ([`STORE_FORMAT`] 2; format 1 was a sequential-storage 8 map, whose records
//! this format does not read): the range is split into its erase pages (at least two).
//! Records are appended within a page at word-aligned offsets (the word is the larger of
//! the flash's read and write sizes), each:
//!
//! | part | bytes | content |
//! | --- | --- | --- |
//! | magic | 4 | [`STORE_MAGIC`]: `GST` and the format |
//! | seq | 4 | the save's number, one more than the newest record's (LE) |
//! | len | 2 | bytes of data (LE) |
//! | !len | 2 | its complement: a torn or random length is seen before the CRC |
//! | crc | 4 | CRC-32 (ISO-HDLC) of seq, len, !len and the data |
//! | data | len | `[SETTINGS_VERSION as u16 LE][postcard of Settings]` |
//! | pad | to the word | `0xFF` |
//!
//! The settings are the newest intact record: the highest `seq` among the records whose
//! magic, length and CRC check, found by scanning every word of every page (so a damaged
//! record in the middle of a page hides nothing after it). Why a power cut anywhere
//! loses nothing (tested exhaustively, `store::power_cuts`):
//!
//! - A save appends in the page of the newest record only if every byte of that page from
//!   the record's end on is erased (`0xFF`); otherwise it moves to the next page, which
//!   it erases first unless it already reads erased. The page holding the newest record
//!   is never erased nor written over until a newer record is complete elsewhere, so after
//!   a cut the load finds it, or the new record.
//! - A torn program leaves a record whose CRC fails (it is skipped) and a page that is no
//!   longer erased after it (the next save moves on). A torn erase leaves the page
//!   undefined, random bytes on some flashes: it holds no record (magic, length and CRC-32
//!   by chance), is not erased, and the next save that needs it erases it again.
//!   Nothing is ever left that refuses a later save, so the store needs no repair to work;
//!   [`SettingsStore::repair`] compacts it (the current settings alone, in an erased
//!   page, the others erased) for a user who wants a clean store.
//!
//! Loading never fails and never writes: it returns the settings to run and how they were
//! found ([`LoadOutcome`]). A newest record that is of another version, undecodable, or
//! that the servo would reject gives [`FACTORY`]; the caller then latches
//! `FaultKind::SettingsCorrupt` with `Servo::latch_board_fault` ([`LoadOutcome::is_fault`]).
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

use super::keys::SetError;
use super::tree::{Settings, FACTORY, SETTINGS_VERSION};

/// Version of the flash layout (the record header and the page rules above), in the
/// magic of every record. Bump it when they change: records of another format are not
/// records to this firmware (the store then loads as corrupt, factory settings and a
/// fault, and the next save erases what it needs).
pub const STORE_FORMAT: u8 = 2;

/// The first bytes of every record.
pub const STORE_MAGIC: [u8; 4] = [b'G', b'S', b'T', STORE_FORMAT];

/// Bytes of a record's header (magic, seq, len, !len, crc).
pub const RECORD_HEADER: usize = 16;

/// Bytes of the record buffer: the header (16), the version (2) and the postcard tree
/// (890 bytes, 938 with three axis models, see the `record_size` test), with a quarter of
/// the buffer kept free for settings to come.
pub const RECORD_BUFFER: usize = 1536;

/// Largest flash word (read or write size) the store supports: the header is one or more
/// whole words.
const MAX_WORD: usize = RECORD_HEADER;

/// Bytes read at a time while scanning a page for records.
const SCAN_CHUNK: usize = 256;

/// The record buffer, aligned for flashes that need word-aligned source buffers.
#[repr(C, align(32))]
struct AlignedBuffer([u8; RECORD_BUFFER]);

/// CRC of the records (the link's polynomial).
const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

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
    /// The flash could not be read.
    Storage,
    /// Data is present but no intact record (the first save was cut short, bit flips in
    /// the only record, a torn erase, or records of another [`STORE_FORMAT`]).
    NoIntactRecord,
    /// The record's bytes do not decode as this version's tree.
    Undecodable,
    /// The record decodes, but a value is out of range or the servo rejects the tree (e.g.
    /// firmware built for another control rate).
    Invalid(SetError),
}

/// Why a flash range cannot hold the store.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangeError {
    /// Start or end not on the flash's erase-page boundaries.
    NotPageAligned,
    /// Fewer than two erase pages (the page with the current record must survive until
    /// the next record is complete in another).
    TooFewPages,
    /// Beyond the flash's capacity.
    OutOfBounds,
    /// Pages smaller than a record buffer, or a flash word (read or write size) that is
    /// not a power of two up to 16 bytes or does not divide the page.
    Geometry,
}

/// Why a store operation failed. `E` is the flash's error.
#[derive(Debug)]
pub enum StoreError<E> {
    /// The flash range cannot hold the store.
    Range(RangeError),
    /// The tree is not valid: it was not saved.
    Invalid(SetError),
    /// The tree does not fit the record buffer ([`RECORD_BUFFER`]).
    TooLarge,
    /// The flash failed.
    Flash(E),
    /// The record just written at this offset of the range does not read back intact (a
    /// worn or failing flash); the previous record is still in place.
    Verify { at: u32 },
}

impl<E: core::fmt::Debug> core::fmt::Display for StoreError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Range(e) => write!(f, "the store's flash range cannot hold it ({e:?})"),
            Self::Invalid(e) => write!(f, "{e}"),
            Self::TooLarge => write!(f, "the settings record exceeds {RECORD_BUFFER} bytes"),
            Self::Flash(e) => write!(f, "flash: {e:?}"),
            Self::Verify { at } => write!(
                f,
                "the record written at offset {at:#x} of the store does not read back intact"
            ),
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

/// What a record carries: the tree (a save) or given bytes (tests writing what other
/// firmware could have).
#[derive(Clone, Copy)]
enum Payload<'a> {
    Tree(&'a Settings),
    #[cfg(test)]
    Raw(&'a [u8]),
}

impl Payload<'_> {
    /// Write the record's data into `out`; its length.
    fn fill(&self, out: &mut [u8]) -> Option<usize> {
        match self {
            Self::Tree(s) => {
                let (head, body) = out.split_at_mut_checked(2)?;
                head.copy_from_slice(&SETTINGS_VERSION.to_le_bytes());
                Some(2 + postcard::to_slice(*s, body).ok()?.len())
            }
            #[cfg(test)]
            Self::Raw(bytes) => {
                out.get_mut(..bytes.len())?.copy_from_slice(bytes);
                Some(bytes.len())
            }
        }
    }
}

/// A record's data as read.
#[allow(clippy::large_enum_variant)]
enum Decoded {
    Current(Settings),
    OtherVersion(u16),
    Undecodable,
}

fn decode(data: &[u8]) -> Decoded {
    let Some((head, body)) = data.split_first_chunk::<2>() else {
        return Decoded::Undecodable;
    };
    let version = u16::from_le_bytes(*head);
    if version != SETTINGS_VERSION {
        return Decoded::OtherVersion(version);
    }
    match postcard::take_from_bytes::<Settings>(body) {
        Ok((s, [])) => Decoded::Current(s),
        _ => Decoded::Undecodable,
    }
}

/// An intact record: its number, where it starts (offset in the range) and its data's
/// length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Found {
    seq: u32,
    at: u32,
    len: u16,
}

/// What a scan of one page found.
#[derive(Clone, Copy, Debug)]
struct PageScan {
    /// The newest intact record of the page.
    newest: Option<Found>,
    /// Offset in the page just after the last intact record (0: none).
    tail: u32,
    /// Offset in the page just after the last byte that is not `0xFF` (0: erased).
    used: u32,
}

impl PageScan {
    /// The page takes a record of `slot` bytes at its tail: erased from there on.
    fn takes(&self, slot: u32, page: u32) -> bool {
        self.used <= self.tail && self.tail.saturating_add(slot) <= page
    }
}

/// The settings store over flash `F` (owned; [`Self::into_flash`] gives it back).
pub struct SettingsStore<F: NorFlash> {
    flash: F,
    /// Start of the range in the flash, its page size and page count.
    base: u32,
    page: u32,
    pages: u32,
    buf: AlignedBuffer,
}

/// The flash word: reads and writes are whole words.
const fn word_of<F: NorFlash>() -> usize {
    let r = if F::READ_SIZE > F::WRITE_SIZE {
        F::READ_SIZE
    } else {
        F::WRITE_SIZE
    };
    if r == 0 {
        1
    } else {
        r
    }
}

/// Bytes a record with `len` bytes of data takes in flash on a flash of word `word`.
const fn slot_len(len: usize, word: usize) -> usize {
    (RECORD_HEADER + len).div_ceil(word) * word
}

impl<F: NorFlash> SettingsStore<F> {
    /// The flash under the store (a host keeps a simulated flash's bytes in a file).
    pub fn flash(&self) -> &F {
        &self.flash
    }

    const WORD: usize = word_of::<F>();

    /// A store in `range` of `flash` (byte offsets of the flash; at least two erase pages,
    /// on page boundaries). Touches nothing.
    pub fn new(flash: F, range: AddrRange<u32>) -> Result<Self, StoreError<F::Error>> {
        let word = Self::WORD;
        let page = F::ERASE_SIZE;
        if !word.is_power_of_two()
            || word > MAX_WORD
            || page < RECORD_BUFFER
            || !page.is_multiple_of(word)
        {
            return Err(StoreError::Range(RangeError::Geometry));
        }
        let page = u32::try_from(page).map_err(|_| StoreError::Range(RangeError::Geometry))?;
        if !range.start.is_multiple_of(page) || !range.end.is_multiple_of(page) {
            return Err(StoreError::Range(RangeError::NotPageAligned));
        }
        let pages = range.end.saturating_sub(range.start) / page;
        if pages < 2 {
            return Err(StoreError::Range(RangeError::TooFewPages));
        }
        if range.end as usize > flash.capacity() {
            return Err(StoreError::Range(RangeError::OutOfBounds));
        }
        Ok(Self {
            flash,
            base: range.start,
            page,
            pages,
            buf: AlignedBuffer([0; RECORD_BUFFER]),
        })
    }

    /// Flash address of page `p`, offset `off`.
    fn addr(&self, p: u32, off: u32) -> u32 {
        self.base + p * self.page + off
    }

    /// The record starting at flash address `at` (word-aligned), if one is intact there
    /// and ends within the page `page_end`; its data is then in `buf[RECORD_HEADER..]`.
    async fn record_at(&mut self, at: u32, page_end: u32) -> Result<Option<Found>, F::Error> {
        if at.saturating_add(RECORD_HEADER as u32) > page_end {
            return Ok(None);
        }
        // (constant indices into the fixed buffer: in bounds)
        self.flash
            .read(at, &mut self.buf.0[..RECORD_HEADER])
            .await?;
        let h = &self.buf.0;
        if h[..4] != STORE_MAGIC {
            return Ok(None);
        }
        let len = u16::from_le_bytes([h[8], h[9]]);
        let not_len = u16::from_le_bytes([h[10], h[11]]);
        let slot = slot_len(usize::from(len), Self::WORD);
        if len != !not_len || slot > RECORD_BUFFER || at as usize + slot > page_end as usize {
            return Ok(None);
        }
        let seq = u32::from_le_bytes([h[4], h[5], h[6], h[7]]);
        let crc = u32::from_le_bytes([h[12], h[13], h[14], h[15]]);
        // the data padded to whole words (within the slot, within the page)
        let Some(data) = self.buf.0.get_mut(RECORD_HEADER..slot) else {
            return Ok(None);
        };
        self.flash.read(at + RECORD_HEADER as u32, data).await?;
        let mut d = CRC.digest();
        d.update(self.buf.0.get(4..12).unwrap_or(&[]));
        d.update(
            self.buf
                .0
                .get(RECORD_HEADER..RECORD_HEADER + usize::from(len))
                .unwrap_or(&[]),
        );
        Ok((d.finalize() == crc).then_some(Found { seq, at, len }))
    }

    /// Scan page `p` for intact records (every word is a possible start).
    async fn scan_page(&mut self, p: u32) -> Result<PageScan, F::Error> {
        let word = Self::WORD as u32;
        let start = self.addr(p, 0);
        let end = start + self.page;
        let mut scan = PageScan {
            newest: None,
            tail: 0,
            used: 0,
        };
        let mut chunk = [0u8; SCAN_CHUNK];
        // `next`: the first word not examined yet as a record start
        let mut next = start;
        while next < end {
            let n = (SCAN_CHUNK as u32).min(end - next);
            let bytes = chunk.get_mut(..n as usize).unwrap_or(&mut []);
            self.flash.read(next, bytes).await?;
            if let Some(last) = bytes.iter().rposition(|b| *b != 0xFF) {
                scan.used = scan.used.max(next - start + last as u32 + 1);
            }
            let chunk_start = next;
            // starts whose magic lies wholly in this chunk (the next chunk begins at the
            // first start not examined)
            let mut at = next;
            let mut skip_to = None;
            while at + 4 <= chunk_start + n {
                let i = (at - chunk_start) as usize;
                if chunk.get(i..i + 4) == Some(&STORE_MAGIC[..]) {
                    if let Some(f) = self.record_at(at, end).await? {
                        let slot = slot_len(usize::from(f.len), Self::WORD) as u32;
                        if scan.newest.is_none_or(|o| f.seq > o.seq) {
                            scan.newest = Some(f);
                        }
                        scan.tail = at + slot - start;
                        scan.used = scan.used.max(scan.tail);
                        skip_to = Some(at + slot);
                        break;
                    }
                }
                at += word;
            }
            next = match skip_to {
                Some(s) => s,
                // (a chunk shorter than a magic at the page's end: nothing more to find)
                None if at == chunk_start => end,
                None => at,
            };
        }
        Ok(scan)
    }

    /// The newest intact record of the store and its page, and whether every byte is
    /// erased.
    async fn scan(&mut self) -> Result<(Option<(u32, Found)>, bool), F::Error> {
        let mut newest: Option<(u32, Found)> = None;
        let mut erased = true;
        for p in 0..self.pages {
            let s = self.scan_page(p).await?;
            erased &= s.used == 0;
            if let Some(f) = s.newest {
                if newest.is_none_or(|(_, o)| f.seq > o.seq) {
                    newest = Some((p, f));
                }
            }
        }
        Ok((newest, erased))
    }

    /// The settings to run at control rate `rate_hz`, and how they were found (see the
    /// module docs). A valid record is returned as stored; anything else gives
    /// [`FACTORY`]. Reads only.
    pub async fn load(&mut self, rate_hz: u32) -> (Settings, LoadOutcome) {
        let outcome = match self.load_newest().await {
            Err(_) => LoadOutcome::Corrupt(Corruption::Storage),
            Ok(None) => match self.scan().await {
                Ok((_, true)) => LoadOutcome::Empty,
                Ok((_, false)) => LoadOutcome::Corrupt(Corruption::NoIntactRecord),
                Err(_) => LoadOutcome::Corrupt(Corruption::Storage),
            },
            Ok(Some(Decoded::Current(s))) => match s.validate(rate_hz) {
                Ok(()) => return (s, LoadOutcome::Stored),
                Err(e) => LoadOutcome::Corrupt(Corruption::Invalid(e)),
            },
            Ok(Some(Decoded::OtherVersion(found))) => LoadOutcome::VersionMismatch { found },
            Ok(Some(Decoded::Undecodable)) => LoadOutcome::Corrupt(Corruption::Undecodable),
        };
        (FACTORY, outcome)
    }

    /// The newest intact record, decoded (`None`: there is none).
    async fn load_newest(&mut self) -> Result<Option<Decoded>, F::Error> {
        let Some((p, f)) = self.scan().await?.0 else {
            return Ok(None);
        };
        let page_end = self.addr(p, self.page);
        // (read again: the scan used the buffer for later candidates)
        match self.record_at(f.at, page_end).await? {
            Some(again) if again == f => {}
            _ => return Ok(Some(Decoded::Undecodable)),
        }
        let data = self
            .buf
            .0
            .get(RECORD_HEADER..RECORD_HEADER + usize::from(f.len))
            .unwrap_or(&[]);
        Ok(Some(decode(data)))
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
        self.append(Payload::Tree(settings)).await
    }

    /// Append a record of `payload` where the module docs say.
    async fn append(&mut self, payload: Payload<'_>) -> Result<(), StoreError<F::Error>> {
        let slot = self.slot_of(payload)?;
        let (newest, _) = self.scan().await.map_err(StoreError::Flash)?;
        let seq = newest.map_or(1, |(_, f)| f.seq.wrapping_add(1));
        let (page, off) = match newest {
            Some((p, _)) => {
                let s = self.scan_page(p).await.map_err(StoreError::Flash)?;
                if s.takes(slot, self.page) {
                    (p, s.tail)
                } else {
                    // (`new` refuses a range without two pages: no division by zero)
                    let next = (p + 1).checked_rem(self.pages).unwrap_or(0);
                    self.prepare(next).await?;
                    (next, 0)
                }
            }
            None => {
                self.prepare(0).await?;
                (0, 0)
            }
        };
        self.write_record(page, off, seq, payload).await
    }

    /// Bytes the record of `payload` takes.
    fn slot_of(&mut self, payload: Payload<'_>) -> Result<u32, StoreError<F::Error>> {
        let data = self
            .buf
            .0
            .get_mut(RECORD_HEADER..)
            .ok_or(StoreError::TooLarge)?;
        let len = payload.fill(data).ok_or(StoreError::TooLarge)?;
        Ok(slot_len(len, Self::WORD) as u32)
    }

    /// Erase page `p` unless it reads erased.
    async fn prepare(&mut self, p: u32) -> Result<(), StoreError<F::Error>> {
        if self.scan_page(p).await.map_err(StoreError::Flash)?.used != 0 {
            self.erase_page(p).await?;
        }
        Ok(())
    }

    async fn erase_page(&mut self, p: u32) -> Result<(), StoreError<F::Error>> {
        let from = self.addr(p, 0);
        self.flash
            .erase(from, from + self.page)
            .await
            .map_err(StoreError::Flash)
    }

    /// Write the record of `payload` numbered `seq` at offset `off` of page `p` (erased
    /// there), and check it reads back intact.
    async fn write_record(
        &mut self,
        p: u32,
        off: u32,
        seq: u32,
        payload: Payload<'_>,
    ) -> Result<(), StoreError<F::Error>> {
        let buf = &mut self.buf.0;
        let data = buf.get_mut(RECORD_HEADER..).ok_or(StoreError::TooLarge)?;
        let len = payload.fill(data).ok_or(StoreError::TooLarge)?;
        let len16 = u16::try_from(len).map_err(|_| StoreError::TooLarge)?;
        let slot = slot_len(len, Self::WORD);
        let pad = buf
            .get_mut(RECORD_HEADER + len..slot)
            .ok_or(StoreError::TooLarge)?;
        pad.fill(0xFF);
        buf[..4].copy_from_slice(&STORE_MAGIC);
        buf[4..8].copy_from_slice(&seq.to_le_bytes());
        buf[8..10].copy_from_slice(&len16.to_le_bytes());
        buf[10..12].copy_from_slice(&(!len16).to_le_bytes());
        let mut d = CRC.digest();
        d.update(&buf[4..12]);
        d.update(buf.get(RECORD_HEADER..RECORD_HEADER + len).unwrap_or(&[]));
        buf[12..16].copy_from_slice(&d.finalize().to_le_bytes());
        let at = self.addr(p, off);
        let bytes = self.buf.0.get(..slot).ok_or(StoreError::TooLarge)?;
        self.flash
            .write(at, bytes)
            .await
            .map_err(StoreError::Flash)?;
        let page_end = self.addr(p, self.page);
        match self
            .record_at(at, page_end)
            .await
            .map_err(StoreError::Flash)?
        {
            Some(f) if f.seq == seq && f.len == len16 => Ok(()),
            _ => Err(StoreError::Verify { at: at - self.base }),
        }
    }

    /// Compact the store (`gantry settings repair`): validate `settings` whole at
    /// `rate_hz`, write them as the only record into a freshly erased page, then erase
    /// every other page. The page of the newest record is erased only once the new one
    /// is complete, so a power cut keeps the old record or the new one.
    pub async fn repair(
        &mut self,
        settings: &Settings,
        rate_hz: u32,
    ) -> Result<(), StoreError<F::Error>> {
        settings.validate(rate_hz).map_err(StoreError::Invalid)?;
        // (after the check: `slot_of` only sizes the record)
        self.slot_of(Payload::Tree(settings))?;
        let newest = self.scan().await.map_err(StoreError::Flash)?.0;
        let seq = newest.map_or(1, |(_, f)| f.seq.wrapping_add(1));
        let target = newest.map_or(0, |(p, _)| (p + 1).checked_rem(self.pages).unwrap_or(0));
        // erased even when it reads erased: a clean start
        self.erase_page(target).await?;
        self.write_record(target, 0, seq, Payload::Tree(settings))
            .await?;
        for p in (0..self.pages).filter(|p| *p != target) {
            self.erase_page(p).await?;
        }
        Ok(())
    }

    /// Erase the whole store (factory reset: the next load is [`LoadOutcome::Empty`]).
    pub async fn erase(&mut self) -> Result<(), StoreError<F::Error>> {
        for p in 0..self.pages {
            self.erase_page(p).await?;
        }
        Ok(())
    }

    /// Give the flash back.
    pub fn into_flash(self) -> F {
        self.flash
    }
}

/// Bytes one stored record takes in flash for `settings` (the header plus the data,
/// padded to the flash word), on a flash like `F`.
pub fn record_flash_bytes<F: NorFlash>(settings: &Settings) -> Option<usize> {
    let mut buf = [0u8; RECORD_BUFFER];
    let data = Payload::Tree(settings).fill(&mut buf)?;
    Some(slot_len(data, word_of::<F>()))
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

    /// The flash the window lies in.
    pub fn inner(&self) -> &F {
        &self.flash
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
mod cut_flash;
#[cfg(test)]
mod power_cuts;
#[cfg(test)]
mod tests;
