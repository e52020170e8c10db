//! A NOR flash model for the store's tests that can lose power at any byte of any program
//! or erase operation (host tests only).
//!
//! Power fails after [`CutFlash::budget`] byte operations (a programmed byte is one, an
//! erased byte is one: a page erase is `PAGE` of them). What the interrupted operation
//! leaves is the model's choice:
//!
//! - an interrupted program ([`ProgramCut::Bits`]): the bytes of the word before the cut
//!   are programmed, the rest of the word only partly — a random subset of the bits the
//!   program would clear is cleared (NOR programming only clears bits);
//! - an interrupted erase ([`EraseCut::Random`], the *undefined page*): the whole page is
//!   random bytes, as some flashes leave a sector whose erase was cut; or
//!   [`EraseCut::Prefix`]: erased up to the cut, the old bytes after it.
//!
//! The random bytes come from a seeded generator ([`CutFlash::seed`]), so every run is
//! the same. The model is strict where the store must be: a write must be word-aligned
//! and must only program words that are erased (the store never writes a word twice).

extern crate std;

use std::vec;
use std::vec::Vec;

use embedded_storage::nor_flash::NorFlashErrorKind;
use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

/// What an interrupted erase leaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EraseCut {
    /// The page is random bytes (undefined).
    Random,
    /// Erased up to the cut, the old bytes after it.
    Prefix,
}

/// What an interrupted program leaves of the word being programmed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProgramCut {
    /// A random subset of the bits to clear is cleared.
    Bits,
    /// Nothing of the word from the cut on.
    Untouched,
}

/// `PAGES` pages of `PAGE` bytes, written in words of `WORD` bytes.
#[derive(Clone)]
pub struct CutFlash<const WORD: usize, const PAGE: usize> {
    pub data: Vec<u8>,
    /// Byte operations until the power fails (`None`: it never does).
    pub budget: Option<u64>,
    pub erase_cut: EraseCut,
    pub program_cut: ProgramCut,
    /// Seed of the random bytes an interrupted operation leaves.
    pub seed: u64,
    /// The power failed: every operation fails until [`Self::power_on`].
    pub cut: bool,
    /// Byte operations done (programmed + erased bytes), and page erases.
    pub ops: u64,
    pub erases: u64,
}

impl<const WORD: usize, const PAGE: usize> CutFlash<WORD, PAGE> {
    /// An erased flash of `pages` pages.
    pub fn new(pages: usize, erase_cut: EraseCut, program_cut: ProgramCut) -> Self {
        Self {
            data: vec![0xFF; pages * PAGE],
            budget: None,
            erase_cut,
            program_cut,
            seed: 1,
            cut: false,
            ops: 0,
            erases: 0,
        }
    }

    /// Power back on (after a cut): operations work again, without a budget.
    pub fn power_on(&mut self) {
        self.cut = false;
        self.budget = None;
    }

    /// The next random number (xorshift64*).
    fn random(&mut self) -> u64 {
        let mut x = self.seed.max(1);
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.seed = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// One byte operation: `false` when the power fails at it.
    fn spend(&mut self) -> bool {
        match &mut self.budget {
            Some(0) => {
                self.cut = true;
                false
            }
            Some(n) => {
                *n -= 1;
                self.ops += 1;
                true
            }
            None => {
                self.ops += 1;
                true
            }
        }
    }

    fn range(&self, offset: u32, len: usize) -> Result<core::ops::Range<usize>, NorFlashErrorKind> {
        let start = offset as usize;
        let end = start
            .checked_add(len)
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        if end > self.data.len() {
            return Err(NorFlashErrorKind::OutOfBounds);
        }
        Ok(start..end)
    }
}

impl<const WORD: usize, const PAGE: usize> ErrorType for CutFlash<WORD, PAGE> {
    type Error = NorFlashErrorKind;
}

impl<const WORD: usize, const PAGE: usize> ReadNorFlash for CutFlash<WORD, PAGE> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if self.cut {
            return Err(NorFlashErrorKind::Other);
        }
        let r = self.range(offset, bytes.len())?;
        bytes.copy_from_slice(&self.data[r]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.data.len()
    }
}

impl<const WORD: usize, const PAGE: usize> NorFlash for CutFlash<WORD, PAGE> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if self.cut {
            return Err(NorFlashErrorKind::Other);
        }
        if !(from as usize).is_multiple_of(PAGE) || !(to as usize).is_multiple_of(PAGE) {
            return Err(NorFlashErrorKind::NotAligned);
        }
        let r = self.range(from, to.saturating_sub(from) as usize)?;
        for page in r.step_by(PAGE) {
            for i in 0..PAGE {
                if !self.spend() {
                    match self.erase_cut {
                        EraseCut::Random => {
                            for b in page..page + PAGE {
                                self.data[b] = self.random() as u8;
                            }
                        }
                        EraseCut::Prefix => self.data[page..page + i].fill(0xFF),
                    }
                    return Err(NorFlashErrorKind::Other);
                }
            }
            self.data[page..page + PAGE].fill(0xFF);
            self.erases += 1;
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if self.cut {
            return Err(NorFlashErrorKind::Other);
        }
        if !(offset as usize).is_multiple_of(WORD) || !bytes.len().is_multiple_of(WORD) {
            return Err(NorFlashErrorKind::NotAligned);
        }
        let r = self.range(offset, bytes.len())?;
        // strict: the store programs erased words only
        if self.data[r.clone()].iter().any(|b| *b != 0xFF) {
            return Err(NorFlashErrorKind::Other);
        }
        for (i, at) in r.enumerate() {
            if !self.spend() {
                if self.program_cut == ProgramCut::Bits {
                    let word_end = (i / WORD + 1) * WORD;
                    for (j, b) in bytes.iter().enumerate().take(word_end).skip(i) {
                        let clear = !b & self.random() as u8;
                        self.data[at - i + j] &= !clear;
                    }
                }
                return Err(NorFlashErrorKind::Other);
            }
            self.data[at] &= bytes[i];
        }
        Ok(())
    }
}

impl<const WORD: usize, const PAGE: usize> CutFlash<WORD, PAGE> {
    /// A random byte (tests filling a page with junk).
    pub fn random_byte(&mut self) -> u8 {
        self.random() as u8
    }
}
