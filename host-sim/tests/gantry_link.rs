//! The `gantry` CLI's session against the simulated machine, end to end over the link
//! protocol (frames, acks, status requests, telemetry): settings and their save, a program with a feed
//! hold, identification with acceptance, link loss, e-stop, and 1 % byte errors.

use anyhow::Result;
use controller_core::link::RealtimeRequest;
use controller_core::machine::messages::{MachineState, Outcome, Request};
use controller_core::settings::store::{block_on, LoadOutcome};
use controller_core::sim::rng::SplitMix64;
use controller_core::sim::world::Injection;
use host_sim::cli::client::{expect_done, Client};
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::{self, Hold, Transport};
use std::path::Path;

/// 1 kHz telemetry at 10 kHz.
const DECIMATION: u32 = 10;
const TELEMETRY_PERIOD_S: f64 = 1e-3;

fn square() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("programs/square.nc")
}

fn connect(models: SimModels) -> Client<SimMachine> {
    Client::connect_session(SimMachine::new(models, DECIMATION).unwrap(), 7).unwrap()
}

#[test]
fn settings_are_validated_and_a_bad_value_changes_nothing() {
    let mut c = connect(SimModels::Designed);
    let key = "axis.x.following_error_mm";
    let before = cli::get(&mut c, key).unwrap();
    let err = cli::set(&mut c, key, "1000").unwrap_err().to_string();
    assert!(err.contains("outside the allowed range"), "{err}");
    assert_eq!(cli::get(&mut c, key).unwrap(), before);
    let err = cli::get(&mut c, "axis.q.nothing").unwrap_err().to_string();
    assert!(err.contains("axis.q.nothing"), "{err}");
    cli::set(&mut c, key, "0.8").unwrap();
    assert_eq!(cli::get(&mut c, key).unwrap(), "0.8");
    assert_eq!(
        c.transport.machine().settings().axis[0].following_error_mm,
        0.8
    );
    // saved: what the machine's next boot loads
    expect_done("save", c.exec(Request::SettingsSave).unwrap()).unwrap();
    let (stored, how) = block_on(c.transport.store().load(10_000));
    assert_eq!(how, LoadOutcome::Stored);
    assert_eq!(stored, *c.transport.machine().settings());
    // gains change only with the outputs off, and so does the flash
    expect_done("arm", c.exec(Request::Arm).unwrap()).unwrap();
    let err = cli::set(&mut c, "axis.y.law.bandwidth_rad_s", "300")
        .unwrap_err()
        .to_string();
    assert!(err.contains("outputs off"), "{err}");
    let err = expect_done("save", c.exec(Request::SettingsSave).unwrap())
        .unwrap_err()
        .to_string();
    assert!(err.contains("disarm first"), "{err}");
    assert_eq!(block_on(c.transport.store().load(10_000)).0, stored);
}

#[test]
fn a_program_runs_over_the_link_with_a_feed_hold_and_stays_on_the_path() {
    let mut c = connect(SimModels::Designed);
    let plain = cli::run_program(&mut c, &square(), TELEMETRY_PERIOD_S, false, None).unwrap();
    assert_eq!(plain.status, "completed");
    assert!(plain.contour_max_mm < 0.02, "{}", plain.contour_max_mm);
    assert!(
        plain.corner_deviation_max_mm <= 0.0101,
        "{}",
        plain.corner_deviation_max_mm
    );
    assert_eq!(c.telemetry_gaps, 0);
    // the figures of `cargo sim gcode`, from telemetry: G61 throughout, held exactly, and
    // no faster than the time bound
    assert_eq!(plain.tolerances_mm, vec![0.0]);
    assert_eq!(
        plain.tolerance_violations, 0,
        "lines {:?}, by {} mm",
        plain.tolerance_violation_lines, plain.tolerance_violation_max_mm
    );
    assert!(plain.feed_ratio_mean > 0.9, "{}", plain.feed_ratio_mean);
    assert!(
        plain.time_bound_s > 9.0 && plain.time_bound_s <= plain.duration_s,
        "{} vs {}",
        plain.time_bound_s,
        plain.duration_s
    );

    let mut c = connect(SimModels::Designed);
    let hold = Hold {
        at_s: 6.0,
        for_s: 1.0,
    };
    let held = cli::run_program(&mut c, &square(), TELEMETRY_PERIOD_S, false, Some(hold)).unwrap();
    assert_eq!(held.status, "completed");
    // the hold adds its second (plus the stop and the restart when it catches the
    // machine moving); the path is the same
    assert!(
        held.duration_s >= plain.duration_s + 0.99,
        "{} vs {}",
        held.duration_s,
        plain.duration_s
    );
    assert!(held.contour_max_mm < 0.02, "{}", held.contour_max_mm);
}

#[test]
fn identification_over_the_link_is_stored_when_accepted_and_then_the_machine_arms() {
    let mut c = connect(SimModels::Factory);
    let err = expect_done("arm", c.exec(Request::Arm).unwrap())
        .unwrap_err()
        .to_string();
    assert!(err.contains("model"), "{err}");
    let r = cli::identify(&mut c, &[0], true, Some(50.0)).unwrap();
    assert_eq!(r[0].status, "done");
    assert!(r[0].accepted);
    // the simulated X: J 0.064, B 0.25, f+ 40, f- -32 (machines/gantry.toml)
    let j = r[0].j.unwrap();
    assert!((j - 0.064).abs() / 0.064 < 0.05, "{j}");
    assert!(r[0].machine_time_s < 10.0);
    let stored = c.transport.machine().settings().axis[0].model.unwrap();
    assert_eq!(stored.inertia, j);
    assert_eq!(
        cli::get(&mut c, "axis.x.model.inertia").unwrap(),
        j.to_string()
    );
}

#[test]
fn link_loss_stops_the_machine_within_the_watchdog_timeout() {
    let mut c = connect(SimModels::Designed);
    cli::ready(&mut c, true).unwrap();
    expect_done(
        "jog",
        c.exec(Request::Jog {
            axis: 0,
            vel_mm_s: 10.0,
        })
        .unwrap(),
    )
    .unwrap();
    // the host goes silent: only the machine's time passes
    let start = c.transport.periods();
    let mut lost_at = None;
    for _ in 0..2000 {
        c.transport.advance(10);
        if c.transport.machine().servo().faults().any() {
            lost_at = Some(c.transport.periods() - start);
            break;
        }
    }
    let periods = lost_at.expect("no fault after 2 s of silence");
    // 500 ms watchdog at 10 kHz, counted from the last frame the machine got
    assert!(periods <= 5_100, "{periods} periods");
    let first = c.transport.machine().servo().faults().first().unwrap();
    assert_eq!(first.fault.kind.name(), "link_lost");
}

#[test]
fn e_stop_switches_the_outputs_off_and_the_fault_is_reported() {
    let mut c = connect(SimModels::Designed);
    cli::ready(&mut c, true).unwrap();
    c.transport.inject(&Injection::Estop);
    let s = cli::wait_while(&mut c, |s| s.state != MachineState::Fault).unwrap();
    assert_eq!(s.first_fault.as_deref(), Some("estop"));
    assert!(!c.transport.machine().servo().snapshot().outputs_on);
    // the cause is still there: the reset is refused
    let o = c.exec(Request::Reset).unwrap();
    assert!(matches!(o, Outcome::Refused(_)), "{o:?}");
    let s = c.realtime(RealtimeRequest::Status).unwrap();
    // the history names it too (a system fault: no axis)
    let last = s.fault_history.last().expect("a fault in the history");
    assert_eq!(last.kind().map(|k| k.name()), Some("estop"));
    assert_eq!(last.axis(), None);
}

/// A transport that corrupts each byte with probability `p`, both ways.
struct Lossy {
    inner: SimMachine,
    rng: SplitMix64,
    p: f64,
    corrupted: u64,
}

impl Lossy {
    fn mangle(&mut self, bytes: &mut [u8]) {
        for b in bytes {
            if self.rng.unit() < self.p {
                *b ^= 1 << (self.rng.next_u64() % 8);
                self.corrupted += 1;
            }
        }
    }
}

impl Transport for Lossy {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        let mut b = bytes.to_vec();
        self.mangle(&mut b);
        self.inner.send(&b)
    }
    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        let mut b = Vec::new();
        self.inner.recv(&mut b)?;
        self.mangle(&mut b);
        buf.extend_from_slice(&b);
        Ok(())
    }
    fn now_ms(&self) -> u32 {
        self.inner.now_ms()
    }
    fn clock_runs_alone(&self) -> bool {
        self.inner.clock_runs_alone()
    }
    fn wait(&mut self) -> Result<()> {
        self.inner.wait()
    }
}

#[test]
fn a_program_completes_with_one_percent_byte_errors_on_the_link() {
    let lossy = Lossy {
        inner: SimMachine::new(SimModels::Designed, DECIMATION).unwrap(),
        rng: SplitMix64::new(11),
        p: 0.01,
        corrupted: 0,
    };
    // a fixed session id: the same bytes, so the same corruption, on every run
    let mut c = Client::connect_session(lossy, 7).unwrap();
    let r = cli::run_program(&mut c, &square(), TELEMETRY_PERIOD_S, false, None).unwrap();
    assert_eq!(r.status, "completed");
    assert_eq!(r.segments, 9);
    assert!(r.contour_max_mm < 0.02, "{}", r.contour_max_mm);
    assert!(c.transport.corrupted > 100, "{}", c.transport.corrupted);
    // corrupted telemetry frames are lost, not misread
    assert!(c.telemetry_gaps > 0);
}

#[test]
fn settings_export_round_trips_and_a_bad_import_changes_nothing() {
    let mut c = connect(SimModels::Designed);
    let all = cli::read_settings(&mut c).unwrap();
    // 123 + the work offsets (27), the tool table (16), the motors' and encoders'
    // directions (6), the input shapers (9), the feed-forward (27) and the output
    // filters (60)
    assert_eq!(all.len(), 268);
    let text = cli::export_toml(&all);
    let back = cli::parse_settings_toml("export.toml", &text).unwrap();
    assert_eq!(
        cli::import_settings(&mut c, &back, 10_000).unwrap(),
        Vec::<String>::new()
    );

    let before = *c.transport.machine().settings();
    let bad = "[axis.x]\nfollowing_error_mm = 0.8\nvel_max_mm_s = -5\n";
    let changes = cli::parse_settings_toml("bad.toml", bad).unwrap();
    let err = cli::import_settings(&mut c, &changes, 10_000)
        .unwrap_err()
        .to_string();
    assert!(err.contains("axis.x.vel_max_mm_s"), "{err}");
    assert_eq!(*c.transport.machine().settings(), before);

    let good = "[axis.x]\nfollowing_error_mm = 0.8\n";
    let changes = cli::parse_settings_toml("good.toml", good).unwrap();
    let changed = cli::import_settings(&mut c, &changes, 10_000).unwrap();
    assert_eq!(changed, ["axis.x.following_error_mm"]);
    assert_eq!(
        c.transport.machine().settings().axis[0].following_error_mm,
        0.8
    );
}

/// `gantry run` interprets a program in the machine's work offsets and tool table, and
/// writes back what its G10 changed once it completed; a rejected program changes nothing.
#[test]
fn a_program_uses_the_machines_offsets_and_its_g10_changes_are_written_back() {
    let dir = std::env::temp_dir().join(format!("gantry_link_g10_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut c = connect(SimModels::Designed);
    cli::set(&mut c, "work.g54.x_mm", "10").unwrap();
    cli::set(&mut c, "work.g54.y_mm", "-5").unwrap();
    cli::set(&mut c, "tool.1.length_mm", "5").unwrap();

    // rejected (line 4) after a G10: nothing runs, nothing is written
    let bad = dir.join("bad.nc");
    std::fs::write(&bad, "G21 G90\nG10 L2 P2 X-20\nG0 X1\nG81 X1 Y1 Z-1 R1\n").unwrap();
    let r = cli::run_program(&mut c, &bad, TELEMETRY_PERIOD_S, false, None).unwrap();
    assert_eq!(r.status, "rejected");
    assert_eq!(r.error.as_ref().and_then(|e| e.line), Some(4));
    assert!(r.settings_written.is_empty());
    assert_eq!(cli::get(&mut c, "work.g55.x_mm").unwrap(), "0");

    let good = dir.join("g10.nc");
    std::fs::write(
        &good,
        "G21 G90 G17\n\
         G43 H1\n\
         G0 X0 Y0 Z0\n\
         (G54 + tool 1: machine 10, -5, 5)\n\
         G10 L2 P2 X-20 Y5\n\
         G10 L1 P2 Z2.5 R3\n\
         G55 G0 X0 Y0\n\
         (G55: machine -20, 5, 5)\n\
         G10 L20 P0 X1\n\
         M2\n",
    )
    .unwrap();
    let r = cli::run_program(&mut c, &good, TELEMETRY_PERIOD_S, false, None).unwrap();
    assert_eq!(r.status, "completed");
    let end = c.status().unwrap().pos_mm;
    for (got, want) in end.iter().zip([-20.0f32, 5.0, 5.0]) {
        assert!((got - want).abs() < 0.01, "{end:?}");
    }
    // G55 from L2 then L20 (X1 at machine -20: origin -21), tool 2 from L1 (R3: 6 mm)
    let written: Vec<(&str, &str)> = r
        .settings_written
        .iter()
        .map(|(k, v)| (k.as_str(), v.as_str()))
        .collect();
    assert_eq!(
        written,
        [
            ("work.g55.x_mm", "-21"),
            ("work.g55.y_mm", "5"),
            ("tool.2.length_mm", "2.5"),
            ("tool.2.diameter_mm", "6")
        ]
    );
    let s = *c.transport.machine().settings();
    assert_eq!(s.work.g55.to_array(), [-21.0, 5.0, 0.0]);
    assert_eq!(s.work.g54.to_array(), [10.0, -5.0, 0.0]);
    assert_eq!((s.tool.t2.length_mm, s.tool.t2.diameter_mm), (2.5, 6.0));
    assert_eq!(s.tool.t1.length_mm, 5.0);
    // set, not saved: the flash still holds nothing
    let (_, how) = block_on(c.transport.store().load(10_000));
    assert_eq!(how, LoadOutcome::Empty);
    assert!(host_sim::gcode::report::table(&r).contains("work.g55.x_mm = -21"));
    std::fs::remove_dir_all(&dir).ok();
}

/// A feed hold while the host is still streaming (the planner full, the host waiting for
/// credit) and its resume get through: the program completes, longer by the hold.
#[test]
fn a_feed_hold_while_streaming_short_segments_resumes_and_completes() {
    let mut text = String::from("G21 G90 G64\nG1 X0 Y0 F1200\n");
    for k in 1..=400 {
        let th = std::f64::consts::TAU * f64::from(k) / 400.0;
        text += &format!("X{:.4} Y{:.4}\n", 12.7 * th.sin(), 12.7 * (1.0 - th.cos()));
    }
    text += "M2\n";
    let file = std::env::temp_dir().join(format!("gantry_link_stream_{}.nc", std::process::id()));
    std::fs::write(&file, text).unwrap();
    let mut c = connect(SimModels::Designed);
    let plain = cli::run_program(&mut c, &file, TELEMETRY_PERIOD_S, false, None).unwrap();
    assert_eq!(plain.status, "completed");
    let mut c = connect(SimModels::Designed);
    let hold = Hold {
        at_s: 1.0,
        for_s: 0.5,
    };
    let held = cli::run_program(&mut c, &file, TELEMETRY_PERIOD_S, false, Some(hold)).unwrap();
    let _ = std::fs::remove_file(&file);
    assert_eq!(held.status, "completed");
    assert!(
        held.duration_s >= plain.duration_s + 0.49,
        "{} vs {}",
        held.duration_s,
        plain.duration_s
    );
    assert!(held.contour_max_mm < 0.02, "{}", held.contour_max_mm);
}

/// `gantry log`: the session's telemetry to CSV, one row per sample at the subscribed rate.
#[test]
fn telemetry_logs_to_csv_at_the_session_rate() {
    let mut c = connect(SimModels::Designed);
    let out = std::env::temp_dir().join(format!("gantry_log_{}.csv", std::process::id()));
    let n = cli::log_telemetry(&mut c, &out, 0.2, &[]).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    let _ = std::fs::remove_file(&out);
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows.len(), n + 1);
    assert!(rows[0].starts_with("period,state,x_mm"), "{}", rows[0]);
    // 0.2 s at 1 kHz telemetry, periods 10 apart
    assert!((199..=202).contains(&n), "{n}");
    let periods: Vec<u32> = rows[1..]
        .iter()
        .map(|r| r.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert!(
        periods.windows(2).all(|w| w[1] == w[0] + DECIMATION),
        "{periods:?}"
    );
    assert!(cli::log_telemetry(&mut c, &out, -1.0, &[]).is_err());

    // chosen signals: more columns, each sample carrying them
    use controller_core::machine::scope::Signal;
    expect_done("arm", c.exec(Request::Arm).unwrap()).unwrap();
    // Z's brake opens 70 ms after arming; until then the brake, not the amplifier, holds Z
    c.sleep_ms(100).unwrap();
    let chosen = [Signal::Pos(0), Signal::Effort(2)];
    expect_done(
        "subscribe",
        c.exec(Request::Subscribe {
            every_periods: DECIMATION,
            signals: heapless::Vec::from_slice(&chosen).unwrap(),
        })
        .unwrap(),
    )
    .unwrap();
    let names = ["pos.x".to_string(), "effort.z".to_string()];
    let n = cli::log_telemetry(&mut c, &out, 0.1, &names).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    let _ = std::fs::remove_file(&out);
    let rows: Vec<Vec<&str>> = text.lines().map(|r| r.split(',').collect()).collect();
    assert!(
        rows[0].ends_with(&["tag", "pos.x", "effort.z"]),
        "{:?}",
        rows[0]
    );
    assert!(n >= 99);
    for r in &rows[1..] {
        // pos.x is the sample's x_mm; z holds against gravity with a non-zero effort
        assert_eq!(r[r.len() - 2], r[2], "{r:?}");
        assert!(r[r.len() - 1].parse::<f32>().unwrap() != 0.0, "{r:?}");
    }
}

/// `gantry move` outside the travel is refused before anything moves; inside, it arrives.
#[test]
fn a_move_outside_the_travel_is_refused_and_nothing_moves() {
    let mut c = connect(SimModels::Designed);
    let s0 = cli::ready(&mut c, true).unwrap();
    let err = cli::move_to(&mut c, [500.0, 0.0, 0.0])
        .unwrap_err()
        .to_string();
    assert!(err.contains("X would leave the travel"), "{err}");
    c.sleep_ms(100).unwrap();
    let s1 = c.status().unwrap();
    // only the travel was read (settings gets): no program started, nothing moved
    assert!(matches!(s1.last, Outcome::Value(_)), "{:?}", s1.last);
    assert_eq!(s1.state, MachineState::Idle);
    for i in 0..3 {
        assert!((s1.pos_mm[i] - s0.pos_mm[i]).abs() < 0.005, "{s0:?} {s1:?}");
    }
    let s = cli::move_to(&mut c, [10.0, -5.0, 2.0]).unwrap();
    assert!((s.pos_mm[0] - 10.0).abs() < 0.02, "{s:?}");
    assert!((s.pos_mm[1] + 5.0).abs() < 0.02, "{s:?}");
}

/// `gantry --port` on a device that does not exist: an error naming it.
#[test]
fn a_missing_serial_device_is_a_clear_error() {
    let err = host_sim::cli::port::BoardPort::open("/nonexistent/ttyGANTRY")
        .err()
        .expect("no such device")
        .to_string();
    assert!(err.contains("/nonexistent/ttyGANTRY"), "{err}");
}

#[test]
fn a_scope_capture_during_a_program_starts_at_its_trigger() {
    use controller_core::machine::scope::{ScopeConfig, Signal, Trigger};
    let mut c = connect(SimModels::Designed);
    // nothing captured yet: a read is refused with the reason
    let Outcome::Refused(why) = c.exec(Request::ScopeRead { offset: 0 }).unwrap() else {
        panic!("a read of no capture was not refused")
    };
    assert!(why.contains("arm it first"), "{why}");
    let cfg = ScopeConfig {
        channels: heapless::Vec::from_slice(&[Signal::RefVel(0), Signal::Pos(0)]).unwrap(),
        samples: 400,
        every_periods: 5,
        pre_trigger: 40,
        trigger: Trigger::Rising {
            signal: Signal::RefVel(0),
            level: 10.0,
        },
    };
    let names = vec!["ref_vel.x".to_string(), "pos.x".to_string()];
    let cap = cli::scope::capture(&mut c, cfg, names, 10_000, 30.0, |c| {
        let r = cli::run_program(c, &square(), TELEMETRY_PERIOD_S, false, None)?;
        assert_eq!(r.status, "completed");
        Ok(())
    })
    .unwrap();
    assert_eq!(cap.rows.len(), 400);
    // 5 periods (0.5 ms) apart, the trigger at t = 0, 40 samples in
    assert_eq!(cap.rows[40].0, 0.0);
    assert!((cap.rows[1].0 - cap.rows[0].0 - 5e-4).abs() < 1e-9);
    // the sample that triggered is the first at or above the level
    assert!(
        cap.rows[40].1[0] >= 10.0 && cap.rows[39].1[0] < 10.0,
        "{:?}",
        &cap.rows[38..42]
    );
    assert!(cap.rows[..40].iter().all(|r| r.1[0] < 10.0));
    // and the axis follows: 0.18 s after the trigger it has moved forward
    let moved = cap.rows[399].1[1] - cap.rows[40].1[1];
    assert!(moved > 10.0, "{moved} mm");
}
