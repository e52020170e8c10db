//! Power cuts at every byte operation of a sequence of saves, on the NOR model of
//! [`super::cut_flash`].
//!
//! The sequence: [`SAVES`] saves of distinct trees into an empty store of two 3 KiB pages
//! (three records a page, so saves 7 and 10 wrap onto the older page and erase it first).
//! For every byte operation of every save (programmed bytes, and each of the 3072 bytes of
//! an erase) the power fails there, from the flash as the saves before left it; then,
//! after power-on, a load must give the new tree or the previous one (for the first save:
//! the new tree, or nothing), and a save of another tree and its load must work.
//!
//! Counts (every cut tested, none sampled): with 4-byte words the 12 saves program 10 960
//! bytes and erase 2 pages of 3 072: 17 104 cuts per model; with 1-byte words (the
//! STM32F4's) 10 948 and 6 144: 17 092. Four models (erase: undefined page or prefix;
//! program: partial bits or untouched) for 4-byte words, two for 1-byte words: 102 600
//! cuts, 0 losses of the previous record, 0 refused later saves. Of the cuts of a model,
//! 907 (in the first save) load nothing, and a few the new record: the cuts in a record's
//! byte of padding with 4-byte words, which has nothing left to program (12), and, where a
//! cut leaves a word's bits partly programmed, the cuts that leave only a byte unprogrammed
//! that is 0xFF in the record (2); the rest load the previous record. About 11 s in the
//! test profile.

extern crate std;

use futures::executor::block_on;

use super::cut_flash::{CutFlash, EraseCut, ProgramCut};
use super::*;
use crate::presets::board::BOARD_RATE_HZ;
use crate::settings::keys::Value;

const RATE: u32 = BOARD_RATE_HZ;
/// Saves in the sequence.
const SAVES: usize = 12;
const PAGE: usize = 3072;

/// The `i`-th tree of the sequence (distinct; with and without an axis model, so the
/// records differ in length too).
fn tree(i: usize) -> Settings {
    let mut s = FACTORY;
    s.set("link.watchdog_ms", Value::U32(100 + i as u32), RATE)
        .unwrap();
    if i % 3 == 1 {
        s.set("axis.y.model.known", Value::Bool(true), RATE)
            .unwrap();
    }
    s
}

/// A tree saved after the cut (never one of the sequence).
fn probe() -> Settings {
    let mut s = FACTORY;
    s.set("link.watchdog_ms", Value::U32(4321), RATE).unwrap();
    s
}

#[derive(Debug, Default, PartialEq)]
struct Figures {
    cuts: usize,
    /// The load gave the new tree / the previous one / nothing (first save only).
    new: usize,
    previous: usize,
    nothing_first: usize,
    /// The previous record was lost (or an older one, or one never saved, came back).
    losses: usize,
    /// The save after power-on failed, or its record did not load.
    refusals: usize,
    erases_cut: usize,
}

fn store_on<const W: usize>(f: CutFlash<W, PAGE>) -> SettingsStore<CutFlash<W, PAGE>> {
    SettingsStore::new(f, 0..(2 * PAGE) as u32).unwrap()
}

fn run<const W: usize>(erase_cut: EraseCut, program_cut: ProgramCut) -> Figures {
    let mut fig = Figures::default();
    let mut before = CutFlash::<W, PAGE>::new(2, erase_cut, program_cut);
    for i in 0..SAVES {
        let next = tree(i);
        let prev = i.checked_sub(1).map(tree);
        // the whole save: its byte operations, and the flash for the next save
        let mut whole = before.clone();
        whole.ops = 0;
        let erases = whole.erases;
        let mut st = store_on(whole);
        block_on(st.save(&next, RATE)).unwrap();
        let whole = st.into_flash();
        let ops = whole.ops;
        let erasing = whole.erases > erases;
        for cut in 0..ops {
            let mut f = before.clone();
            f.budget = Some(cut);
            f.seed = (i as u64) << 32 | cut ^ 0x9E37_79B9;
            let mut st = store_on(f);
            assert!(
                block_on(st.save(&next, RATE)).is_err(),
                "save {i} cut {cut}"
            );
            let mut f = st.into_flash();
            assert!(f.cut);
            f.power_on();
            fig.cuts += 1;
            let mut st = store_on(f);
            let (s, how) = block_on(st.load(RATE));
            match (how, prev) {
                (LoadOutcome::Stored, _) if s == next => fig.new += 1,
                (LoadOutcome::Stored, Some(p)) if s == p => fig.previous += 1,
                (LoadOutcome::Empty | LoadOutcome::Corrupt(Corruption::NoIntactRecord), None) => {
                    fig.nothing_first += 1
                }
                (how, _) => {
                    fig.losses += 1;
                    std::eprintln!("save {i}, cut at byte operation {cut} of {ops}: {how:?}");
                }
            }
            let saved = block_on(st.save(&probe(), RATE));
            let reloaded = block_on(store_on(st.into_flash()).load(RATE));
            if saved.is_err() || reloaded != (probe(), LoadOutcome::Stored) {
                fig.refusals += 1;
                std::eprintln!(
                    "save {i}, cut at byte operation {cut} of {ops}: later save {saved:?}, load {:?}",
                    reloaded.1
                );
            }
        }
        if erasing {
            fig.erases_cut += 1;
        }
        before = whole;
    }
    fig
}

/// `completed`: the cuts that leave a complete new record, where nothing of it was left
/// to program (its padding to the word, and a byte that is 0xFF in the record).
fn check(name: &str, fig: &Figures, expected_cuts: usize, completed: usize) {
    std::println!("{name}: {fig:?}");
    assert_eq!(fig.cuts, expected_cuts, "{name}");
    assert_eq!(fig.losses, 0, "{name}: previous record lost");
    assert_eq!(fig.refusals, 0, "{name}: later save refused");
    // the sequence wrapped onto an old page twice (each an erase)
    assert_eq!(fig.erases_cut, 2, "{name}");
    // a cut never completes a record, except where nothing was left to program
    assert_eq!(fig.new, completed, "{name}");
    assert_eq!(fig.previous, expected_cuts - completed - 907, "{name}");
    assert_eq!(fig.nothing_first, 907, "{name}");
    assert_eq!(
        fig.new + fig.previous + fig.nothing_first,
        fig.cuts,
        "{name}"
    );
}

/// Bytes of record data the sequence writes.
fn record_bytes(word: usize) -> usize {
    (0..SAVES)
        .map(|i| {
            let mut buf = [0u8; RECORD_BUFFER];
            let len = Payload::Tree(&tree(i)).fill(&mut buf).unwrap();
            slot_len(len, word)
        })
        .sum()
}

#[test]
fn every_cut_of_a_save_sequence_keeps_a_record_on_4_byte_words() {
    let cuts = record_bytes(4) + 2 * PAGE;
    assert_eq!(cuts, 17_104);
    for (e, p) in [
        (EraseCut::Random, ProgramCut::Bits),
        (EraseCut::Random, ProgramCut::Untouched),
        (EraseCut::Prefix, ProgramCut::Bits),
        (EraseCut::Prefix, ProgramCut::Untouched),
    ] {
        let fig = run::<4>(e, p);
        check(
            &std::format!("4-byte words, erase {e:?}, program {p:?}"),
            &fig,
            cuts,
            // the record's padding to the word (1 byte a record since the filters and the
            // feed-forward), and, where a cut word keeps some of its bits, a 0xFF byte in 2
            // of the 12 records
            SAVES + if matches!(p, ProgramCut::Bits) { 2 } else { 0 },
        );
    }
}

#[test]
fn every_cut_of_a_save_sequence_keeps_a_record_on_1_byte_words() {
    let cuts = record_bytes(1) + 2 * PAGE;
    assert_eq!(cuts, 17_092);
    for (e, p) in [
        (EraseCut::Random, ProgramCut::Bits),
        (EraseCut::Prefix, ProgramCut::Bits),
    ] {
        let fig = run::<1>(e, p);
        check(
            &std::format!("1-byte words, erase {e:?}, program {p:?}"),
            &fig,
            cuts,
            // a 0xFF byte in 2 of the 12 records
            2,
        );
    }
}

/// A repair cut at every byte operation keeps the previous record or writes the new one,
/// and leaves a store that saves.
#[test]
fn every_cut_of_a_repair_keeps_a_record() {
    let mut before = CutFlash::<4, PAGE>::new(2, EraseCut::Random, ProgramCut::Bits);
    {
        let mut st = store_on(before);
        for i in 0..4 {
            block_on(st.save(&tree(i), RATE)).unwrap();
        }
        before = st.into_flash();
    }
    let prev = tree(3);
    let next = probe();
    let mut whole = before.clone();
    whole.ops = 0;
    let mut st = store_on(whole);
    block_on(st.repair(&next, RATE)).unwrap();
    let whole = st.into_flash();
    // one record, the other page erased
    assert_eq!(whole.erases - before.erases, 2);
    let (mut kept, mut new) = (0, 0);
    for cut in 0..whole.ops {
        let mut f = before.clone();
        f.budget = Some(cut);
        f.seed = cut ^ 0x5EED;
        let mut st = store_on(f);
        assert!(block_on(st.repair(&next, RATE)).is_err());
        let mut f = st.into_flash();
        f.power_on();
        let mut st = store_on(f);
        match block_on(st.load(RATE)) {
            (s, LoadOutcome::Stored) if s == prev => kept += 1,
            (s, LoadOutcome::Stored) if s == next => new += 1,
            other => panic!("repair cut at {cut}: {other:?}"),
        }
        block_on(st.save(&tree(9), RATE)).unwrap_or_else(|e| panic!("cut {cut}: {e:?}"));
        assert_eq!(block_on(st.load(RATE)), (tree(9), LoadOutcome::Stored));
    }
    std::println!(
        "repair: {} cuts, previous kept {kept}, new {new}",
        whole.ops
    );
    assert_eq!(kept + new, whole.ops as usize);
    assert!(kept > 0 && new > 0);
}

/// A page of random bytes (a torn erase) is neither a record nor an obstacle: loads give
/// the record of the other page, and saves go on, on every one of 200 random pages.
#[test]
fn random_pages_hold_no_record_and_block_no_save() {
    let mut refused = 0;
    for seed in 0..200u64 {
        let mut f = CutFlash::<4, PAGE>::new(2, EraseCut::Random, ProgramCut::Bits);
        {
            let mut st = store_on(f);
            block_on(st.save(&tree(0), RATE)).unwrap();
            f = st.into_flash();
        }
        f.seed = seed + 1;
        for b in PAGE..2 * PAGE {
            f.data[b] = f.random_byte();
        }
        let mut st = store_on(f);
        assert_eq!(block_on(st.load(RATE)), (tree(0), LoadOutcome::Stored));
        for i in 1..8 {
            if block_on(st.save(&tree(i), RATE)).is_err()
                || block_on(st.load(RATE)) != (tree(i), LoadOutcome::Stored)
            {
                refused += 1;
            }
        }
    }
    assert_eq!(refused, 0);
}
