//! The comparator of the QEMU link rig's machine against host-sim's
//! (`host_sim::studies::machine_replay`) must be able to fail: a recording of a short
//! program made in host-sim itself replays bit-exactly; one bit changed in one input
//! (a segment's end point, one more e-stop press, a planning run skipped) makes it fail,
//! naming the first period that differs. The log lines round-trip through the parser.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use controller_core::machine::messages::Request;
use controller_core::machine::record::{RecordRef, Recorder};
use controller_core::machine::{record::Record, Down};
use controller_core::motion::planner::{Motion, Segment};
use controller_core::settings::Apply;
use host_sim::sim_gantry::designed_settings;
use host_sim::studies::machine_replay::{parse, record_on_host, replay, Recording};

const PERIODS: u32 = 12_000;

/// A 10 mm square at 60 mm/s after arming (homing off), one request per period as the
/// link would pass them down.
fn inputs() -> Recording {
    let mut settings = designed_settings();
    for a in &mut settings.axis {
        a.homing.enabled = false;
    }
    let mut r: BTreeMap<u32, Vec<Record>> = BTreeMap::new();
    r.insert(
        1,
        vec![Record::Plan {
            runs: 0,
            busy: false,
        }],
    );
    r.insert(
        2,
        vec![
            Record::Down(Down::Apply {
                class: Some(Apply::OutputsOff),
            }),
            Record::Settings(settings),
        ],
    );
    let mut reqs = vec![Request::Arm, Request::Run];
    for (k, p) in [[10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [0.0, 0.0]]
        .iter()
        .enumerate()
    {
        reqs.push(Request::Segment(Segment::line(
            [p[0], p[1], 0.0],
            60.0,
            k as u32 + 1,
        )));
    }
    reqs.push(Request::EndProgram);
    for (i, q) in reqs.into_iter().enumerate() {
        r.insert(3 + 2 * i as u32, vec![Record::Down(Down::Request(q))]);
    }
    Recording {
        records: r,
        blocks: Vec::new(),
        lost: None,
    }
}

fn first_period(why: &str) -> u32 {
    let rest = why
        .strip_prefix("period ")
        .unwrap_or_else(|| panic!("no period named: {why}"));
    rest.split(' ').next().unwrap().parse().unwrap()
}

#[test]
fn a_recording_replays_bit_exactly_and_one_changed_bit_is_found() {
    let rec = record_on_host(&inputs(), PERIODS).unwrap();
    assert_eq!(rec.blocks.len(), 120);
    let a = replay(&rec)
        .unwrap()
        .expect("the same inputs replay bit for bit");
    assert_eq!((a.periods, a.segments), (PERIODS, 4));
    // the program moved the machine
    assert!(
        a.pos_mm[0].abs() < 0.05 && a.pos_mm[1].abs() < 0.05,
        "{a:?}"
    );

    // one bit of one segment's end point
    let mut bad = rec.clone();
    let seg_period = 3 + 2 * 3; // the second segment
    let Some(Record::Down(Down::Request(Request::Segment(s)))) =
        bad.records.get_mut(&seg_period).and_then(|v| v.first_mut())
    else {
        panic!("no segment at {seg_period}")
    };
    let Motion::Line { end_mm, .. } = &mut s.motion else {
        panic!("not a line")
    };
    end_mm[1] = f32::from_bits(end_mm[1].to_bits() ^ 1);
    let why = replay(&bad).unwrap().unwrap_err();
    eprintln!("one bit of a segment: {why}");
    assert!(first_period(&why) > seg_period, "{why}");

    // the e-stop pressed at period 2500: that period is the first to differ
    let mut bad = rec.clone();
    bad.records
        .entry(2_500)
        .or_default()
        .push(Record::Estop(true));
    let why = replay(&bad).unwrap().unwrap_err();
    assert_eq!(first_period(&why), 2_500, "{why}");

    // the planning half not run between periods 1000 and 1100 (the program running): one
    // skipped run alone may change nothing (32 steps are buffered ahead)
    let mut bad = rec.clone();
    for p in 1_000..1_100 {
        bad.records.entry(p).or_default().push(Record::Plan {
            runs: 0,
            busy: false,
        });
    }
    let why = replay(&bad).unwrap().unwrap_err();
    assert!(first_period(&why) >= 1_000, "{why}");

    // a period that found the planning half running cannot be replayed
    let mut bad = rec.clone();
    bad.records.entry(30).or_default().push(Record::Plan {
        runs: 1,
        busy: true,
    });
    let why = replay(&bad).unwrap().unwrap_err();
    assert!(why.contains("not replayable"), "{why}");
}

/// The log as defmt-print shows the rig's lines (`{=[u8]}`: `[1, 2, 3]`), with other
/// lines between, and a last line cut off.
fn log_text(rec: &Recording) -> String {
    let mut t = String::from("INFO link rig: the simulated gantry at 10000 Hz\n");
    let mut recorder = Recorder::<2048>::new();
    let mut blocks = rec.blocks.iter().peekable();
    let last = rec.blocks.last().unwrap().end;
    for p in 1..=last {
        for r in rec.records.get(&p).map(Vec::as_slice).unwrap_or(&[]) {
            recorder.note(match r {
                Record::Down(d) => RecordRef::Down(d),
                Record::Settings(s) => RecordRef::Settings(s),
                Record::Estop(e) => RecordRef::Estop(*e),
                Record::Plan { runs, busy } => RecordRef::Plan {
                    runs: *runs,
                    busy: *busy,
                },
            });
        }
        if !recorder.is_empty() {
            let (b, lost) = recorder.take();
            assert!(!lost);
            writeln!(t, "INFO machine-record {p} {b:?}").unwrap();
        }
        if blocks.peek().is_some_and(|b| b.end == p) {
            let b = blocks.next().unwrap();
            let bytes: Vec<u8> = b.tags.iter().flat_map(|g| g.to_le_bytes()).collect();
            writeln!(t, "INFO machine-digest {p} {:x} {bytes:?}", b.digest).unwrap();
        }
    }
    t.push_str("INFO machine-digest 4100 1234 [1, 2");
    t
}

#[test]
fn the_log_lines_parse_back_into_the_recording() {
    let rec = record_on_host(&inputs(), 300).unwrap();
    let parsed = parse(&log_text(&rec)).unwrap();
    assert_eq!(parsed, rec);
    assert!(replay(&parsed).unwrap().is_ok());
}

#[test]
fn a_corrupt_or_empty_log_is_refused_by_line_and_nothing_is_replayed() {
    // a record line whose bytes are not bytes, then a line after it (not the cut-off last)
    let text = "INFO machine-record 12 [1, 2, zz]\nINFO machine-digest 100 ab [1]\n";
    let err = format!("{:#}", parse(text).unwrap_err());
    assert!(err.contains("log line 1"), "{err}");
    assert!(err.contains("bad byte"), "{err}");
    // a digest line with the wrong number of tags
    let text = "INFO machine-digest 100 ab [1, 2]\nINFO other\n";
    let err = format!("{:#}", parse(text).unwrap_err());
    assert!(
        err.contains("log line 1") && err.contains("2 tag bytes"),
        "{err}"
    );
    // a log with none of the rig's lines: nothing to compare, said so
    let empty = parse("INFO gantry firmware up\n").unwrap();
    let why = replay(&empty).unwrap().unwrap_err();
    assert!(why.contains("no digest"), "{why}");
}
