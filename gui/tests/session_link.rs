//! The window never blocks the link: the session thread keeps the machine's heartbeat
//! and telemetry going while the window takes nothing for seconds (a stalled frame) and
//! while waking the window blocks (a frame holding egui's context lock), and the machine
//! is still armed, with no `link_lost`, when the window comes back.

use controller_core::machine::messages::MachineState;
use gantry_gui::served::Served;
use gantry_gui::session::{Command, Event, Session};
use host_sim::cli::client::Tapped;
use host_sim::cli::machine::MachineArgs;
use std::time::{Duration, Instant};

fn wait_finished(s: &Session, what: &str, limit: Duration) -> Result<String, String> {
    let t0 = Instant::now();
    while t0.elapsed() < limit {
        // (the tap is drained meanwhile: only the events matter here)
        while s.tapped.try_recv().is_ok() {}
        match s.events.recv_timeout(Duration::from_millis(50)) {
            Ok(Event::Finished { what: w, result }) if w == what => return result,
            Ok(Event::Lost(why)) => panic!("session lost: {why}"),
            _ => {}
        }
    }
    panic!("{what} did not finish within {limit:?}");
}

#[test]
fn a_stalled_window_does_not_stop_the_machines_heartbeat() {
    let sim = MachineArgs {
        sim: true,
        telemetry_hz: 1000,
        ..MachineArgs::default()
    };
    let (_served, args) = Served::start(&sim).expect("serve the simulated gantry");
    // waking the window blocks for a second each time: a window whose frames hold its
    // context lock that long
    let s = Session::start(args, || std::thread::sleep(Duration::from_secs(1)));
    s.send(Command::Arm);
    let armed = wait_finished(&s, "arm", Duration::from_secs(20));
    assert!(armed.is_ok(), "{armed:?}");
    while s.tapped.try_recv().is_ok() {}

    // the window stalls: nothing taken for 3 s, longer than the machine's link
    // watchdog (500 ms)
    let stall = Duration::from_secs(3);
    std::thread::sleep(stall);

    let (mut samples, mut last_status) = (0usize, None);
    let mut periods = Vec::new();
    for t in s.tapped.try_iter() {
        match t {
            Tapped::Telemetry(t) => {
                samples += 1;
                periods.push(t.period);
            }
            Tapped::Status(st) => last_status = Some(st),
        }
    }
    // 1 kHz telemetry kept flowing through the stall: at least 90 % of 3,000 samples
    assert!(
        samples >= 2_700,
        "{samples} telemetry samples in a 3 s stall"
    );
    let gaps = periods
        .windows(2)
        .filter(|w| w[1].wrapping_sub(w[0]) > 10)
        .count();
    assert!(gaps <= 30, "{gaps} gaps in the telemetry");
    let st = last_status.expect("status kept coming");
    assert_eq!(st.state, MachineState::Idle, "still armed after the stall");
    assert!(st.first_fault.is_none(), "fault: {:?}", st.first_fault);

    // and the session still takes commands
    s.send(Command::Disarm);
    let disarmed = wait_finished(&s, "disarm", Duration::from_secs(10));
    assert!(disarmed.is_ok(), "{disarmed:?}");
}

/// The scope is armed and the session goes on (the operator can jog or run what triggers
/// it); the capture is read when the machine says it is done. The tab's default form
/// (gantry scope's defaults, an immediate trigger) captures at rest.
#[test]
fn a_scope_capture_arrives_while_the_session_takes_other_commands() {
    let sim = MachineArgs {
        sim: true,
        telemetry_hz: 1000,
        ..MachineArgs::default()
    };
    let (_served, args) = Served::start(&sim).expect("serve the simulated gantry");
    let s = Session::start(args, || {});
    let form = gantry_gui::panels::scope::ScopePanel::default();
    let (config, names) = form.config().expect("the default form is valid");
    let samples = usize::from(config.samples);
    s.send(Command::Scope {
        config,
        names: names.clone(),
        timeout_s: 30.0,
        run: None,
    });
    let armed = wait_finished(&s, "scope", Duration::from_secs(20));
    assert!(armed.is_ok(), "{armed:?}");
    // the session takes a command while the capture is pending
    s.send(Command::Arm);
    let t0 = Instant::now();
    let (mut capture, mut armed_again) = (None, false);
    while t0.elapsed() < Duration::from_secs(30) && !(capture.is_some() && armed_again) {
        while s.tapped.try_recv().is_ok() {}
        match s.events.recv_timeout(Duration::from_millis(50)) {
            Ok(Event::Scope(cap)) => capture = Some(cap),
            Ok(Event::Finished { what, result }) if what == "arm" => {
                assert!(result.is_ok(), "{result:?}");
                armed_again = true;
            }
            Ok(Event::Lost(why)) => panic!("session lost: {why}"),
            _ => {}
        }
    }
    assert!(
        armed_again,
        "arm did not finish while the scope was pending"
    );
    let cap = capture.expect("the capture arrived");
    assert_eq!(cap.names, names);
    assert_eq!(cap.rows.len(), samples);
    assert!(cap.rows.iter().all(|(_, v)| v.len() == names.len()));
}
