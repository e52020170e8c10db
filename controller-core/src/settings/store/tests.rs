//! Store tests on the NOR model of [`super::cut_flash`] (power cut after N byte operations,
//! raw bit access) and on the RAM flash through the blocking adapter. The exhaustive power
//! cut tests of save sequences are in [`super::power_cuts`].

extern crate std;

use std::vec::Vec;

use futures::executor::block_on;

use super::cut_flash::{CutFlash, EraseCut, ProgramCut};

use super::*;
use crate::presets::board::BOARD_RATE_HZ;
use crate::settings::keys::Value;
use crate::settings::PLACEHOLDER_MODELS;

/// Four 2 KiB pages, 4-byte words (a small external-flash-like geometry: many page
/// wraps in few saves).
type Mock = CutFlash<4, 2048>;
/// 2 KiB pages with 1-byte words (the STM32F4's write size).
type MockBytes = CutFlash<1, 2048>;

const RATE: u32 = BOARD_RATE_HZ;

fn mock() -> Mock {
    Mock::new(4, EraseCut::Random, ProgramCut::Bits)
}

/// A tree that differs from the factory one in a live and an outputs-off value and has a
/// model on X.
fn tree_a() -> Settings {
    let mut s = FACTORY;
    s.set("link.watchdog_ms", Value::U32(1000), RATE).unwrap();
    s.set("axis.x.model.known", Value::Bool(true), RATE)
        .unwrap();
    s.set("axis.x.model.inertia", Value::F32(0.07), RATE)
        .unwrap();
    s
}

fn tree_b() -> Settings {
    let mut s = FACTORY;
    s.set("link.watchdog_ms", Value::U32(2000), RATE).unwrap();
    s.set("axis.z.law.kind", Value::Choice("pid"), RATE)
        .unwrap();
    s
}

fn store<F: NorFlash>(flash: F) -> SettingsStore<F> {
    let len = u32::try_from(flash.capacity()).unwrap();
    SettingsStore::new(flash, 0..len).unwrap()
}

/// Bytes of a record's data in flash: version, tree.
fn data_len(s: &Settings) -> usize {
    2 + postcard_bytes(s).len()
}

fn postcard_bytes(s: &Settings) -> Vec<u8> {
    let mut buf = [0u8; RECORD_BUFFER];
    postcard::to_slice(s, &mut buf).unwrap().to_vec()
}

/// Write a raw record (version, body), intact, as other firmware would.
fn write_raw(flash: &mut Mock, record: &[u8]) {
    let mut st = store(&mut *flash);
    block_on(st.append(Payload::Raw(record))).unwrap();
}

#[test]
fn empty_store_gives_factory_without_fault_then_round_trips() {
    let mut st = store(mock());
    let (s, outcome) = block_on(st.load(RATE));
    assert_eq!((s, outcome.clone()), (FACTORY, LoadOutcome::Empty));
    assert!(!outcome.is_fault());

    let a = tree_a();
    block_on(st.save(&a, RATE)).unwrap();
    assert_eq!(block_on(st.load(RATE)), (a, LoadOutcome::Stored));
    // a new store on the same flash (a reboot)
    let mut st = store(st.into_flash());
    let (s, outcome) = block_on(st.load(RATE));
    assert_eq!(outcome, LoadOutcome::Stored);
    assert_eq!(postcard_bytes(&s), postcard_bytes(&a));
}

#[test]
fn blocking_ram_flash_round_trips_through_the_adapter() {
    // a 2-page window in the middle of a 4-page RAM flash
    let ram = RamFlash::<16384, 4096>::new();
    let window = BlockingFlash::new(ram, 4096, 8192).unwrap();
    let mut st = store(window);
    assert_eq!(block_on(st.load(RATE)).1, LoadOutcome::Empty);
    block_on(st.save(&tree_b(), RATE)).unwrap();
    assert_eq!(block_on(st.load(RATE)), (tree_b(), LoadOutcome::Stored));
    // nothing outside the window was touched
    let ram = st.into_flash().into_inner();
    assert!(ram.bytes()[..4096].iter().all(|b| *b == 0xFF));
    assert!(ram.bytes()[12288..].iter().all(|b| *b == 0xFF));
    assert!(ram.bytes()[4096..12288].iter().any(|b| *b != 0xFF));
}

#[test]
fn many_saves_wrap_the_pages_and_the_newest_wins() {
    let mut st = store(mock());
    let mut s = FACTORY;
    let before = st.flash.erases;
    for ms in 100..160u32 {
        s.set("link.watchdog_ms", Value::U32(ms), RATE).unwrap();
        block_on(st.save(&s, RATE)).unwrap();
        assert_eq!(block_on(st.load(RATE)), (s, LoadOutcome::Stored));
    }
    // 60 records of 924 bytes (54 KiB), two to a page, through 4 pages of 2 KiB: from
    // the 9th save on, every second moves onto a used page and erases it
    let erases = st.flash.erases - before;
    assert_eq!(erases, 26);
}

#[test]
fn byte_word_flash_like_the_stm32_round_trips() {
    let mut st = store(MockBytes::new(2, EraseCut::Random, ProgramCut::Bits));
    for s in [tree_a(), tree_b(), tree_a()] {
        block_on(st.save(&s, RATE)).unwrap();
        assert_eq!(block_on(st.load(RATE)), (s, LoadOutcome::Stored));
    }
}

#[test]
fn other_version_gives_factory_and_a_fault() {
    let mut flash = mock();
    let mut record = Vec::from((SETTINGS_VERSION + 1).to_le_bytes());
    record.extend(postcard_bytes(&tree_a()));
    write_raw(&mut flash, &record);
    let (s, outcome) = block_on(store(flash).load(RATE));
    assert_eq!(s, FACTORY);
    assert_eq!(
        outcome,
        LoadOutcome::VersionMismatch {
            found: SETTINGS_VERSION + 1
        }
    );
    assert!(outcome.is_fault());
}

#[test]
fn undecodable_and_truncated_records_give_factory_and_a_fault() {
    let full = {
        let mut r = Vec::from(SETTINGS_VERSION.to_le_bytes());
        r.extend(postcard_bytes(&tree_a()));
        r
    };
    let truncated = &full[..full.len() - 3];
    let mut trailing = full.clone();
    trailing.push(0);
    let junk = [&SETTINGS_VERSION.to_le_bytes()[..], &[0xFF; 40]].concat();
    for (what, record) in [
        ("truncated", truncated),
        ("trailing byte", &trailing[..]),
        ("junk", &junk[..]),
        ("one byte", &[1u8][..]),
    ] {
        let mut flash = mock();
        write_raw(&mut flash, record);
        let (s, outcome) = block_on(store(flash).load(RATE));
        assert_eq!(s, FACTORY, "{what}");
        assert_eq!(
            outcome,
            LoadOutcome::Corrupt(Corruption::Undecodable),
            "{what}"
        );
    }
}

#[test]
fn a_record_the_servo_rejects_gives_factory_and_a_fault() {
    // out of range for a key
    let mut bad = FACTORY;
    bad.axis[0].following_error_mm = 500.0;
    let mut record = Vec::from(SETTINGS_VERSION.to_le_bytes());
    record.extend(postcard_bytes(&bad));
    let mut flash = mock();
    write_raw(&mut flash, &record);
    let (s, outcome) = block_on(store(flash).load(RATE));
    assert_eq!(s, FACTORY);
    match outcome {
        LoadOutcome::Corrupt(Corruption::Invalid(SetError::OutOfRange { key, .. })) => {
            assert_eq!(key, "axis.x.following_error_mm")
        }
        other => panic!("{other:?}"),
    }

    // valid at 20 kHz, unstable at 2 kHz (firmware rebuilt for another rate)
    let mut fast = FACTORY;
    fast.estimator.pll_bandwidth_rad_s = 5000.0;
    let mut st = store(mock());
    block_on(st.save(&fast, 20_000)).unwrap();
    assert_eq!(block_on(st.load(20_000)), (fast, LoadOutcome::Stored));
    let (s, outcome) = block_on(st.load(2_000));
    assert_eq!(s, FACTORY);
    assert!(matches!(
        outcome,
        LoadOutcome::Corrupt(Corruption::Invalid(SetError::Tree(
            crate::settings::ServoConfigError::Servo(crate::config::ConfigError::Unstable(_))
        )))
    ));
}

#[test]
fn save_refuses_an_invalid_tree_and_writes_nothing() {
    let mut st = store(mock());
    let mut bad = FACTORY;
    bad.axis[2].vel_max_mm_s = f32::NAN;
    assert!(matches!(
        block_on(st.save(&bad, RATE)),
        Err(StoreError::Invalid(SetError::OutOfRange {
            key: "axis.z.vel_max_mm_s",
            ..
        }))
    ));
    assert!(st.flash.data.iter().all(|b| *b == 0xFF));
}

#[test]
fn erase_is_a_factory_reset() {
    let mut st = store(mock());
    block_on(st.save(&tree_a(), RATE)).unwrap();
    block_on(st.erase()).unwrap();
    assert_eq!(block_on(st.load(RATE)), (FACTORY, LoadOutcome::Empty));
}

#[test]
fn a_range_of_one_page_is_refused() {
    let flash = mock();
    assert!(matches!(
        SettingsStore::new(flash, 0..2048),
        Err(StoreError::Range(RangeError::TooFewPages))
    ));
    assert!(matches!(
        SettingsStore::new(mock(), 100..4196),
        Err(StoreError::Range(RangeError::NotPageAligned))
    ));
}

/// Classify a load: the settings must be one of `allowed` (stored), or the factory ones.
fn check_load(
    flash: Mock,
    allowed: &[Settings],
    counts: &mut [usize; 4],
    context: &dyn core::fmt::Display,
) {
    let (s, outcome) = block_on(store(flash).load(RATE));
    match outcome {
        LoadOutcome::Stored => {
            let i = allowed
                .iter()
                .position(|a| *a == s)
                .unwrap_or_else(|| panic!("{context}: loaded a tree that was never saved"));
            counts[i] += 1;
        }
        LoadOutcome::Empty => {
            assert_eq!(s, FACTORY, "{context}");
            counts[2] += 1;
        }
        LoadOutcome::Corrupt(_) | LoadOutcome::VersionMismatch { .. } => {
            assert_eq!(s, FACTORY, "{context}");
            counts[3] += 1;
        }
    }
}

#[test]
fn single_bit_flips_give_the_previous_record_or_factory_with_a_fault() {
    let mut flash = mock();
    {
        let mut st = store(&mut flash);
        block_on(st.save(&tree_a(), RATE)).unwrap();
        block_on(st.save(&tree_b(), RATE)).unwrap();
    }
    let used = flash.data.iter().rposition(|b| *b != 0xFF).unwrap() + 1;
    // [newest (b), previous (a), empty, factory + fault]
    let mut counts = [0usize; 4];
    for pos in 0..used {
        for bit in 0..8 {
            let mut f = flash.clone();
            f.data[pos] ^= 1 << bit;
            let ctx = std::format!("flip byte {pos} bit {bit}");
            check_load(f, &[tree_b(), tree_a()], &mut counts, &ctx);
        }
    }
    std::println!(
        "bit flips over {used} bytes: newest {}, previous {}, empty {}, factory+fault {}",
        counts[0],
        counts[1],
        counts[2],
        counts[3]
    );
    // every flip in the newest record's data is caught by its CRC and the previous record
    // runs; no flip anywhere loses both
    assert!(counts[1] >= 8 * data_len(&tree_b()), "{counts:?}");
    assert_eq!(counts[3], 0, "{counts:?}");
    assert_eq!(counts[2], 0, "{counts:?}");
}

#[test]
fn bit_flips_in_the_only_record_give_factory_with_a_fault() {
    let mut flash = mock();
    block_on(store(&mut flash).save(&tree_a(), RATE)).unwrap();
    let used = flash.data.iter().rposition(|b| *b != 0xFF).unwrap() + 1;
    let mut counts = [0usize; 4];
    for pos in 0..used {
        let mut f = flash.clone();
        f.data[pos] ^= 1 << (pos % 8);
        let ctx = std::format!("flip byte {pos}");
        check_load(f, &[tree_a(), tree_a()], &mut counts, &ctx);
    }
    std::println!(
        "only record, {used} bytes: kept {}, factory+fault {}",
        counts[0],
        counts[3]
    );
    assert_eq!(counts[2], 0);
    // every flip in the record's data is detected
    assert!(counts[3] >= data_len(&tree_a()), "{counts:?}");
}

/// Byte operations (written or erased bytes) and erases of a save of `s` on `flash`.
fn save_cost(flash: &Mock, s: &Settings) -> (u64, u64) {
    let mut f = flash.clone();
    let (ops, erases) = (f.ops, f.erases);
    block_on(store(&mut f).save(s, RATE)).unwrap();
    (f.ops - ops, f.erases - erases)
}

/// Cut the power after every byte operation of saving `next` on `flash`; the load must give
/// `next`, the previous record `prev`, or (no previous) the factory tree with a fault.
fn interrupt_every_byte(
    flash: &Mock,
    next: &Settings,
    prev: Option<&Settings>,
) -> ([usize; 4], usize) {
    let (ops, _) = save_cost(flash, next);
    let allowed = [*next, *prev.unwrap_or(next)];
    let mut counts = [0usize; 4];
    for cut in 0..=ops as u32 {
        let mut f = flash.clone();
        f.budget = Some(u64::from(cut));
        f.seed = u64::from(cut) + 1;
        let _ = block_on(store(&mut f).save(next, RATE));
        f.power_on();
        let ctx = std::format!("power cut after {cut} of {ops} byte operations");
        check_load(f.clone(), &allowed, &mut counts, &ctx);
        // the store recovers: the next save and load work
        let mut st = store(f);
        block_on(st.save(&tree_b(), RATE)).unwrap_or_else(|e| panic!("{ctx}: save after: {e:?}"));
        assert_eq!(
            block_on(st.load(RATE)),
            (tree_b(), LoadOutcome::Stored),
            "{ctx}"
        );
    }
    (counts, ops as usize)
}

#[test]
fn interrupted_first_save_gives_factory() {
    let (counts, ops) = interrupt_every_byte(&mock(), &tree_a(), None);
    std::println!(
        "first save of {ops} bytes cut: saved {}, empty {}, factory+fault {}",
        counts[0],
        counts[2],
        counts[3]
    );
    // every cut inside the record leaves no intact record (factory and a fault; in this
    // model even the cut before the first byte leaves some of its bits cleared); only the
    // complete save loads it, and so does one cut more: the byte it leaves unprogrammed is
    // 0xFF in the record (offset 62 of this tree's 924 bytes), as erased flash holds it
    assert_eq!(counts, [2, 0, 0, ops - 1]);
}

#[test]
fn interrupted_save_keeps_the_previous_record() {
    let mut flash = mock();
    block_on(store(&mut flash).save(&tree_b(), RATE)).unwrap();
    let (counts, ops) = interrupt_every_byte(&flash, &tree_a(), Some(&tree_b()));
    std::println!(
        "save of {ops} bytes cut: new {}, previous {}, factory+fault {}",
        counts[0],
        counts[1],
        counts[3]
    );
    // every cut keeps the previous record, but the one that leaves only the record's 0xFF
    // byte unprogrammed (see above)
    assert_eq!(counts, [2, ops - 1, 0, 0]);
}

#[test]
fn interrupted_save_that_erases_a_page_keeps_the_previous_record() {
    // fill the store until the next save has to erase a page (and move the live record)
    let mut flash = mock();
    let mut s = FACTORY;
    let mut ms = 100;
    loop {
        s.set("link.watchdog_ms", Value::U32(ms), RATE).unwrap();
        if save_cost(&flash, &tree_a()).1 > 0 {
            break;
        }
        block_on(store(&mut flash).save(&s, RATE)).unwrap();
        ms += 1;
        assert!(ms < 200, "never erased");
    }
    let prev = block_on(store(&mut flash).load(RATE)).0;
    let (counts, ops) = interrupt_every_byte(&flash, &tree_a(), Some(&prev));
    std::println!(
        "erasing save of {ops} byte operations cut: new {}, previous {}, factory+fault {}",
        counts[0],
        counts[1],
        counts[3]
    );
    // the 2048 byte erases are part of it (the page is random bytes after a cut in
    // them); every cut keeps the previous record
    assert_eq!(ops, 2048 + 924);
    // (but the cut that leaves only the record's 0xFF byte unprogrammed, see above)
    assert_eq!(counts, [2, ops - 1, 0, 0]);
}

#[test]
fn record_size() {
    let factory = postcard_bytes(&FACTORY).len();
    let mut all_models = FACTORY;
    for (a, m) in all_models.axis.iter_mut().zip(PLACEHOLDER_MODELS) {
        a.model = Some(m);
    }
    let with_models = postcard_bytes(&all_models).len();
    std::println!(
        "postcard bytes: factory {factory}, with three models {with_models}; size_of Settings {}, SettingsStore over the F4 window {}",
        core::mem::size_of::<Settings>(),
        core::mem::size_of::<SettingsStore<BlockingFlash<RamFlash<0, 4096>>>>()
    );
    // 3 models × 16 bytes more
    assert_eq!(with_models, factory + 3 * 16);
    // 345 before the work offsets (9 × 3 × 4 bytes), the tool table (8 × 2 × 4 bytes),
    // the brakes (3 × (1 + 4 + 4) bytes), the safety switch (1 byte) and the motors' and
    // encoders' directions (3 × 2 bytes), the input shapers (3 × (1 + 4 + 4) bytes), the
    // feed-forward (3 × 9 × 4 bytes) and the filter stages (3 × 4 × (1 + 4 × 4) bytes)
    assert_eq!(factory, 345 + 108 + 64 + 27 + 1 + 6 + 27 + 108 + 204);
    // in flash on the STM32 (1-byte words): header + version + tree
    type F4 = BlockingFlash<RamFlash<8192, 4096>>;
    assert_eq!(
        record_flash_bytes::<F4>(&all_models),
        Some(RECORD_HEADER + 2 + with_models)
    );
    // a quarter of the buffer kept free for settings to come
    assert!(RECORD_HEADER + 2 + with_models <= RECORD_BUFFER * 3 / 4);
}

#[test]
fn record_layout_is_pinned() {
    // If this fails, the stored record changed. Changed layout (a field added, removed,
    // retyped or moved): bump SETTINGS_VERSION. Only factory values changed: update the
    // pin. Either way old records must not be misread.
    const PIN: (u16, u32) = (8, 3_647_059_467);
    let mut all_models = FACTORY;
    for (a, m) in all_models.axis.iter_mut().zip(PLACEHOLDER_MODELS) {
        a.model = Some(m);
    }
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let mut d = crc.digest();
    d.update(&postcard_bytes(&FACTORY));
    d.update(&postcard_bytes(&all_models));
    assert_eq!((SETTINGS_VERSION, d.finalize()), PIN);
}

#[test]
fn blocking_window_checks_its_bounds() {
    type Ram = RamFlash<16384, 4096>;
    assert_eq!(
        BlockingFlash::new(Ram::new(), 100, 4096).err(),
        Some(WindowError::NotAligned)
    );
    assert_eq!(
        BlockingFlash::new(Ram::new(), 0, 0).err(),
        Some(WindowError::NotAligned)
    );
    assert_eq!(
        BlockingFlash::new(Ram::new(), 12288, 8192).err(),
        Some(WindowError::OutOfBounds)
    );
    assert_eq!(
        BlockingFlash::new(Ram::new(), 4096, u32::MAX - 4095).err(),
        Some(WindowError::OutOfBounds)
    );
    let mut w = BlockingFlash::new(Ram::new(), 8192, 4096).unwrap();
    assert_eq!(ReadNorFlash::capacity(&w), 4096);
    let mut buf = [0u8; 8];
    assert_eq!(
        block_on(w.read(4090, &mut buf)),
        Err(BlockingFlashError::OutOfBounds)
    );
    assert_eq!(
        block_on(w.read(u32::MAX - 2, &mut buf)),
        Err(BlockingFlashError::OutOfBounds)
    );
    assert_eq!(
        block_on(w.erase(4096, 0)),
        Err(BlockingFlashError::OutOfBounds)
    );
    assert_eq!(
        block_on(w.erase(0, 8192)),
        Err(BlockingFlashError::OutOfBounds)
    );
    assert_eq!(
        block_on(w.erase(100, 4096)),
        Err(BlockingFlashError::Flash(NorFlashErrorKind::NotAligned))
    );
    // offset 0 of the window is byte 8192 of the flash; writes only clear bits
    block_on(w.write(0, &[0x0F, 0xAA])).unwrap();
    block_on(w.write(0, &[0xF1])).unwrap();
    block_on(w.read(0, &mut buf)).unwrap();
    assert_eq!(buf[..3], [0x01, 0xAA, 0xFF]);
    let ram = w.into_inner();
    assert_eq!(ram.bytes()[8192..8194], [0x01, 0xAA]);
    assert_eq!(ram.bytes()[8191], 0xFF);
}

#[test]
fn ram_flash_checks_its_own_bounds() {
    use embedded_storage::nor_flash::{NorFlash as _, ReadNorFlash as _};
    let mut f = RamFlash::<8192, 4096>::new();
    let mut buf = [0u8; 4];
    assert_eq!(f.read(8190, &mut buf), Err(NorFlashErrorKind::OutOfBounds));
    assert_eq!(
        f.read(u32::MAX, &mut buf),
        Err(NorFlashErrorKind::OutOfBounds)
    );
    assert_eq!(f.write(8191, &[0, 0]), Err(NorFlashErrorKind::OutOfBounds));
    assert_eq!(f.erase(4096, 12288), Err(NorFlashErrorKind::OutOfBounds));
    assert_eq!(f.erase(4096, 0), Err(NorFlashErrorKind::OutOfBounds));
    assert_eq!(f.erase(1, 4096), Err(NorFlashErrorKind::NotAligned));
    f.write(4096, &[0x12]).unwrap();
    f.erase(0, 4096).unwrap();
    assert_eq!(f.bytes()[4096], 0x12);
    f.erase(4096, 8192).unwrap();
    assert!(f.bytes().iter().all(|b| *b == 0xFF));
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(500))]

        /// Any bytes as the record (after a valid version, or not): the load never
        /// panics and gives either a valid stored tree or the factory one with a fault.
        #[test]
        fn any_record_bytes_load_safely(
            current_version in any::<bool>(),
            body in prop::collection::vec(any::<u8>(), 0..400),
        ) {
            let mut record = if current_version {
                Vec::from(SETTINGS_VERSION.to_le_bytes())
            } else {
                Vec::new()
            };
            record.extend(body);
            prop_assume!(!record.is_empty());
            let mut flash = mock();
            write_raw(&mut flash, &record);
            let (s, outcome) = block_on(store(flash).load(RATE));
            match outcome {
                LoadOutcome::Stored => prop_assert_eq!(s.validate(RATE), Ok(())),
                LoadOutcome::Empty => prop_assert!(false, "written store reported empty"),
                _ => {
                    prop_assert!(outcome.is_fault());
                    prop_assert_eq!(s, FACTORY);
                }
            }
        }

        /// A valid tree with one byte of its record changed before the CRC is computed
        /// (what other firmware could have written): never panics, never loads an
        /// invalid tree.
        #[test]
        fn mutated_valid_records_load_safely(at in 0usize..300, byte in any::<u8>()) {
            let mut record = Vec::from(SETTINGS_VERSION.to_le_bytes());
            record.extend(postcard_bytes(&tree_a()));
            let i = 2 + at % (record.len() - 2);
            record[i] = byte;
            let mut flash = mock();
            write_raw(&mut flash, &record);
            let (s, outcome) = block_on(store(flash).load(RATE));
            if outcome == LoadOutcome::Stored {
                prop_assert_eq!(s.validate(RATE), Ok(()));
            } else {
                prop_assert!(outcome.is_fault());
                prop_assert_eq!(s, FACTORY);
            }
        }
    }
}
