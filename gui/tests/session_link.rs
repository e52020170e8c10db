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
