//! Settings changes over the link are all or nothing: `gantry settings
//! import`, `settings set` of several keys and a defaults reset go to the machine as one
//! transaction (`SettingsBegin`, `SettingSet`…, `SettingsCommit`), validated whole on the
//! machine's link side and swapped in at a period boundary, or refused whole; and
//! `settings repair` rewrites the store. Against the simulated machine (`gantry --sim`),
//! which runs the firmware's settings agent and store.

use controller_core::machine::messages::{Outcome, Request};
use controller_core::settings::store::{block_on, LoadOutcome};
use controller_core::settings::{Settings, FACTORY};
use host_sim::cli;
use host_sim::cli::client::{expect_done, Client};
use host_sim::cli::sim::{SimMachine, SimModels};

const RATE_HZ: u32 = 10_000;

fn connect() -> Client<SimMachine> {
    Client::connect_session(SimMachine::new(SimModels::Designed, 10).unwrap(), 3).unwrap()
}

/// The machine's settings as bytes (bit-identical comparison, NaN and -0 included).
fn bits(c: &Client<SimMachine>) -> Vec<u8> {
    let mut buf = [0u8; 1024];
    postcard::to_slice(c.transport.machine().settings(), &mut buf)
        .unwrap()
        .to_vec()
}

/// A good import of 24 keys; the first two are only valid together (the following error
/// at speed below the at-rest one until the at-rest one is lowered too).
const GOOD: [(&str, &str); 24] = [
    ("axis.x.following_error_mm", "0.05"),
    ("axis.x.min_ferror_mm", "0.02"),
    ("axis.y.following_error_mm", "0.9"),
    ("axis.z.following_error_mm", "0.8"),
    ("axis.x.stop_decel_mm_s2", "1800"),
    ("axis.y.stop_decel_mm_s2", "1400"),
    ("axis.x.jog.speed_max_mm_s", "40"),
    ("axis.y.jog.speed_max_mm_s", "40"),
    ("axis.z.jog.speed_max_mm_s", "30"),
    ("axis.x.planner.acc_max_mm_s2", "1800"),
    ("axis.y.planner.acc_max_mm_s2", "1800"),
    ("axis.z.planner.acc_max_mm_s2", "1500"),
    ("link.watchdog_ms", "800"),
    ("jog.timeout_s", "0.4"),
    ("identify.torque_cap_mnm", "400"),
    ("identify.edge_margin_mm", "6"),
    ("planner.tolerance_mm", "0.02"),
    ("planner.tangential_share", "0.6"),
    ("coupling.lambda", "1.5"),
    ("work.g54.x_mm", "10"),
    ("work.g54.y_mm", "-5"),
    ("tool.1.length_mm", "12.5"),
    ("axis.z.homing.seek_mm_s", "15"),
    ("axis.x.homing.seek_mm_s", "18"),
];

/// Values in range that break a rule between keys (with the rest of [`GOOD`] applied).
const CROSS: [(&str, &str); 6] = [
    // above the following error at speed (0.05)
    ("axis.x.min_ferror_mm", "5"),
    // faster than the seek (20)
    ("axis.y.homing.locate_mm_s", "50"),
    // above the travel's other end (50)
    ("axis.z.travel.min_mm", "60"),
    // the planner faster than the axis' overspeed limit (250)
    ("axis.x.planner.vel_max_mm_s", "300"),
    // the backward friction above the forward one (40)
    ("axis.x.model.coulomb_neg_mnm", "50"),
    // the home position (switch + pull-off) outside the travel (max 150)
    ("axis.y.homing.switch_pos_mm", "400"),
];

#[derive(Clone, Copy, Debug)]
enum Mutation {
    OutOfRange,
    WrongType,
    CrossKey,
    UnknownKey,
}

/// [`GOOD`] with entry `at` replaced by a bad one; the bad key.
fn mutated(at: usize, m: Mutation) -> (Vec<(String, String)>, String) {
    let mut v: Vec<(String, String)> = GOOD
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let key = GOOD[at].0.to_string();
    let bad = match m {
        Mutation::OutOfRange if key == "link.watchdog_ms" => (key, "4000000000".into()),
        Mutation::OutOfRange => (key, "-1e9".into()),
        Mutation::WrongType => (key, "fast".into()),
        // (one no later entry sets again)
        Mutation::CrossKey => (0..CROSS.len())
            .map(|i| CROSS[(at + i) % CROSS.len()])
            .find(|(k, _)| GOOD[at + 1..].iter().all(|(g, _)| g != k))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .unwrap(),
        Mutation::UnknownKey => ("axis.x.no_such_key".into(), "1".into()),
    };
    let name = bad.0.clone();
    v[at] = bad;
    (v, name)
}

/// 24 positions × 4 kinds of bad key = 96 mutated imports, each through `import_settings`
/// (the host's check first, then the machine's transaction) and through the transaction
/// alone (`apply_settings`: the machine's own check is all that stands between the file
/// and the servo): 192 refused imports, 0 partial applies (the machine's tree reads back
/// bit-identical), every refusal names the bad key. Then the good import applies all 24.
#[test]
fn mutated_imports_change_nothing_and_a_good_one_changes_every_key() {
    let mut c = connect();
    let before = bits(&c);
    let (mut refused, mut partial, mut unnamed) = (0, 0, 0);
    let kinds = [
        Mutation::OutOfRange,
        Mutation::WrongType,
        Mutation::CrossKey,
        Mutation::UnknownKey,
    ];
    for at in 0..GOOD.len() {
        for m in kinds {
            let (changes, key) = mutated(at, m);
            let via_import = cli::import_settings(&mut c, &changes, RATE_HZ);
            let via_link = cli::apply_settings(&mut c, &changes);
            for (path, r) in [
                ("import", via_import.map(|_| ())),
                ("transaction", via_link),
            ] {
                match r {
                    Ok(()) => panic!("{path} of {m:?} at {at} ({key}) was accepted"),
                    Err(e) => {
                        refused += 1;
                        let e = e.to_string();
                        // (replacing the second of the pair leaves the first alone, which
                        // the tree rejects too: either key is the cause)
                        let named = e.contains(&key) || at == 1 && e.contains(GOOD[0].0);
                        if !named {
                            unnamed += 1;
                            eprintln!("{path} of {m:?} at {at}: `{e}` does not name {key}");
                        }
                    }
                }
                if bits(&c) != before {
                    partial += 1;
                    eprintln!("{path} of {m:?} at {at} ({key}) changed the settings");
                }
            }
        }
    }
    println!("mutated imports: {refused} refused, {partial} partial applies, {unnamed} unnamed");
    assert_eq!(refused, 2 * 4 * GOOD.len());
    assert_eq!(partial, 0);
    assert_eq!(unnamed, 0);

    // the good one: every key, read back over the link
    let good: Vec<(String, String)> = GOOD
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let changed = cli::import_settings(&mut c, &good, RATE_HZ).unwrap();
    assert_eq!(changed.len(), GOOD.len());
    for (k, v) in GOOD {
        assert_eq!(cli::get(&mut c, k).unwrap(), v, "{k}");
    }
    let s = *c.transport.machine().settings();
    assert_eq!(s.axis[0].following_error_mm, 0.05);
    assert_eq!(s.axis[0].min_ferror_mm, 0.02);
    // the pair alone, key by key, would have been refused at its first key
    let mut c = connect();
    let err = cli::set(&mut c, "axis.x.following_error_mm", "0.05").unwrap_err();
    assert!(
        err.to_string().contains("axis.x.following_error_mm"),
        "{err}"
    );
}

/// `settings set a=1 b=2` is one transaction: a pair valid only together is taken, a pair
/// with a bad second value changes neither; with the outputs on a change that needs them
/// off is refused whole, and so is a defaults reset.
#[test]
fn several_keys_in_one_set_and_a_defaults_reset_are_all_or_nothing() {
    let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert_eq!(
        cli::parse_set_args(&args(&["axis.x.min_ferror_mm", "-0.5"])).unwrap(),
        [("axis.x.min_ferror_mm".to_string(), "-0.5".to_string())]
    );
    let pair = cli::parse_set_args(&args(&[
        "axis.x.following_error_mm=0.05",
        "axis.x.min_ferror_mm=0.02",
    ]))
    .unwrap();
    assert_eq!(pair.len(), 2);
    assert!(cli::parse_set_args(&args(&["a=1", "b"])).is_err());

    let mut c = connect();
    cli::apply_settings(&mut c, &pair).unwrap();
    assert_eq!(c.transport.machine().settings().axis[0].min_ferror_mm, 0.02);
    let before = bits(&c);
    let bad = cli::parse_set_args(&args(&[
        "axis.y.following_error_mm=0.5",
        "axis.y.min_ferror_mm=0.9",
    ]))
    .unwrap();
    let err = cli::apply_settings(&mut c, &bad).unwrap_err().to_string();
    assert!(err.contains("axis.y.min_ferror_mm"), "{err}");
    assert_eq!(bits(&c), before);

    // outputs on: a gain change and a defaults reset are refused whole
    expect_done("arm", c.exec(Request::Arm).unwrap()).unwrap();
    let gains = cli::parse_set_args(&args(&[
        "axis.x.law.bandwidth_rad_s=120",
        "axis.y.law.bandwidth_rad_s=120",
    ]))
    .unwrap();
    let err = cli::apply_settings(&mut c, &gains).unwrap_err().to_string();
    assert!(err.contains("outputs off"), "{err}");
    assert_eq!(bits(&c), before);
    let err = expect_done("defaults", c.exec(Request::SettingsDefaults).unwrap()).unwrap_err();
    assert!(err.to_string().contains("outputs off"), "{err}");
    assert_eq!(bits(&c), before);
    expect_done("disarm", c.exec(Request::Disarm).unwrap()).unwrap();
    cli::wait_while(&mut c, |s| {
        s.state == controller_core::machine::messages::MachineState::Stopping
    })
    .unwrap();
    cli::apply_settings(&mut c, &gains).unwrap();
    assert_eq!(
        c.transport.machine().settings().axis[1].law.bandwidth_rad_s,
        120.0
    );
    expect_done("defaults", c.exec(Request::SettingsDefaults).unwrap()).unwrap();
    assert_eq!(*c.transport.machine().settings(), FACTORY);

    // a transaction's commit without begin, and after a refused change, is refused
    match c.exec(Request::SettingsCommit).unwrap() {
        Outcome::Refused(why) => assert!(why.contains("no settings transaction"), "{why}"),
        other => panic!("{other:?}"),
    }
    expect_done("begin", c.exec(Request::SettingsBegin).unwrap()).unwrap();
    let refused = c
        .exec(Request::SettingSet {
            key: "link.watchdog_ms".try_into().unwrap(),
            value: "x".try_into().unwrap(),
        })
        .unwrap();
    assert!(matches!(refused, Outcome::Refused(_)));
    expect_done(
        "set",
        c.exec(Request::SettingSet {
            key: "link.watchdog_ms".try_into().unwrap(),
            value: "900".try_into().unwrap(),
        })
        .unwrap(),
    )
    .unwrap();
    match c.exec(Request::SettingsCommit).unwrap() {
        Outcome::Refused(why) => assert!(why.contains("nothing changed"), "{why}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(*c.transport.machine().settings(), FACTORY);
}

/// `settings repair` erases the store and writes the settings the machine runs, only with
/// the outputs off; the store then holds them alone.
#[test]
fn repair_rewrites_the_store_with_the_running_settings() {
    let mut c = connect();
    for ms in [600, 700, 800] {
        cli::set(&mut c, "link.watchdog_ms", &ms.to_string()).unwrap();
        expect_done("save", c.exec(Request::SettingsSave).unwrap()).unwrap();
    }
    cli::set(&mut c, "link.watchdog_ms", "900").unwrap();
    expect_done("arm", c.exec(Request::Arm).unwrap()).unwrap();
    let err = expect_done("repair", c.exec(Request::SettingsRepair).unwrap()).unwrap_err();
    assert!(err.to_string().contains("disarm first"), "{err}");
    let (s, how) = block_on(c.transport.store().load(RATE_HZ));
    assert_eq!((s.link.watchdog_ms, how), (800, LoadOutcome::Stored));
    expect_done("disarm", c.exec(Request::Disarm).unwrap()).unwrap();
    expect_done("repair", c.exec(Request::SettingsRepair).unwrap()).unwrap();
    let running: Settings = *c.transport.machine().settings();
    assert_eq!(
        block_on(c.transport.store().load(RATE_HZ)),
        (running, LoadOutcome::Stored)
    );
    assert_eq!(running.link.watchdog_ms, 900);
}
