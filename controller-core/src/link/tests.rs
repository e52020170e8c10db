//! Tests of the two link ends together, message level (byte level with a lossy channel:
//! `controller-core/tests/link_lossy.rs`).
extern crate std;
use std::vec::Vec;

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::device::DEFAULT_DEVICE_LINK_CONFIG;
use super::host::DEFAULT_HOST_LINK_CONFIG;
use super::kernels::*;
use super::*;

const HASH: u32 = schema_hash::<ExampleCommand, ExampleTelemetry, ExampleStatus>();

type Host = HostLink<ExampleCommand, 8>;
type Up = ToHost<ExampleTelemetry, ExampleStatus>;

fn host_frames(host: &mut Host, now: u32) -> Vec<ExampleToDevice> {
    let mut out = Vec::new();
    let _ = host.poll(now, |f| out.push(clone_frame(&f)));
    out
}

fn clone_frame(f: &ToDevice<&ExampleCommand>) -> ExampleToDevice {
    match *f {
        ToDevice::Hello(h) => ToDevice::Hello(h),
        ToDevice::Heartbeat => ToDevice::Heartbeat,
        ToDevice::Command { seq, cmd } => ToDevice::Command { seq, cmd: *cmd },
        ToDevice::Realtime { id, req } => ToDevice::Realtime { id, req },
        ToDevice::Goodbye => ToDevice::Goodbye,
    }
}

/// Host and device after a completed handshake at t = 0.
fn connected() -> (Host, DeviceLink) {
    let mut host = Host::new(&DEFAULT_HOST_LINK_CONFIG, HASH, 77).unwrap();
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).unwrap();
    let hello = host_frames(&mut host, 0);
    assert_eq!(hello.len(), 1);
    let step = dev.on_frame(hello[0].clone(), 0, 10);
    assert_eq!(step.event, DeviceEvent::SessionStarted { session: 77 });
    let reply: Up = step.reply.unwrap().into_frame();
    assert_eq!(host.on_frame(reply, 1), Ok(HostEvent::Ready));
    assert_eq!(host.state(), HostState::Ready);
    // The device advertises its credits on its next poll.
    let p = dev.poll(1, 10);
    assert_eq!(
        p.reply,
        Some(Reply::Ack(Ack {
            seq: Seq(65535),
            credits: 10
        }))
    );
    assert_eq!(
        host.on_frame::<ExampleTelemetry, ExampleStatus>(p.reply.unwrap().into_frame(), 1),
        Ok(HostEvent::None)
    );
    (host, dev)
}

#[test]
fn schema_hash_is_pinned() {
    // Changing an envelope, Hello or RealtimeRequest changes these values: bump
    // PROTOCOL_VERSION when that happens, then update them.
    assert_eq!(schema_hash::<(), (), ()>(), 0xf3c3_2782);
    assert_eq!(HASH, 0xb303_9fc8);
}

#[test]
fn schema_hash_sees_names_types_and_order() {
    #[derive(Serialize, Deserialize, Schema)]
    struct A {
        x_mm: f32,
        y_mm: f32,
    }
    #[derive(Serialize, Deserialize, Schema)]
    struct Renamed {
        x_mm: f32,
        z_mm: f32,
    }
    #[derive(Serialize, Deserialize, Schema)]
    struct Retyped {
        x_mm: f32,
        y_mm: f64,
    }
    #[derive(Serialize, Deserialize, Schema)]
    struct Reordered {
        y_mm: f32,
        x_mm: f32,
    }
    let base = schema_hash::<A, (), ()>();
    let others = [
        schema_hash::<Renamed, (), ()>(),
        schema_hash::<Retyped, (), ()>(),
        schema_hash::<Reordered, (), ()>(),
        schema_hash::<(), A, ()>(),
        schema_hash::<(), (), A>(),
    ];
    for (i, h) in others.iter().enumerate() {
        assert_ne!(*h, base, "variant {i}");
    }
    assert_eq!(schema_hash::<A, (), ()>(), base);
}

#[test]
fn commands_flow_and_duplicates_are_not_executed_twice() {
    let (mut host, mut dev) = connected();
    for line in 0..3 {
        host.send(ExampleCommand {
            line,
            ..EXAMPLE_COMMAND
        })
        .unwrap();
    }
    let frames = host_frames(&mut host, 2);
    assert_eq!(frames.len(), 3);
    let mut executed = Vec::new();
    let mut acks = Vec::new();
    for f in frames.iter().chain(frames.iter()) {
        let step = dev.on_frame(f.clone(), 3, 10 - executed.len() as u16);
        if let DeviceEvent::Command(c) = step.event {
            executed.push(c.line);
        }
        acks.push(step.reply.unwrap());
    }
    assert_eq!(executed, [0, 1, 2]);
    assert_eq!(dev.command_stats().duplicates, 3);
    for a in acks {
        let _ = host.on_frame::<ExampleTelemetry, ExampleStatus>(a.into_frame(), 4);
    }
    assert_eq!(host.in_flight(), 0);
    assert_eq!(host.stats().command.acked, 3);
}

#[test]
fn mismatch_is_reported_on_both_sides_and_commands_are_refused() {
    let mut host = Host::new(&DEFAULT_HOST_LINK_CONFIG, HASH ^ 1, 5).unwrap();
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).unwrap();
    let hello = host_frames(&mut host, 0);
    let step = dev.on_frame(hello[0].clone(), 0, 10);
    let expected = ProtocolMismatch {
        ours: Version {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: HASH,
        },
        theirs: Version {
            protocol_version: PROTOCOL_VERSION,
            schema_hash: HASH ^ 1,
        },
    };
    assert_eq!(step.event, DeviceEvent::Mismatch(expected));
    let host_err =
        host.on_frame::<ExampleTelemetry, ExampleStatus>(step.reply.unwrap().into_frame(), 1);
    let host_side = ProtocolMismatch {
        ours: expected.theirs,
        theirs: expected.ours,
    };
    assert_eq!(host_err, Err(LinkError::ProtocolMismatch(host_side)));
    assert_eq!(
        host.state(),
        HostState::Failed(LinkError::ProtocolMismatch(host_side))
    );
    let text = std::format!("{host_side}");
    let expected_text = std::format!(
        "link protocol mismatch: ours is protocol {PROTOCOL_VERSION} schema {:#010x}, theirs is protocol {PROTOCOL_VERSION} schema {:#010x}",
        HASH ^ 1,
        HASH
    );
    assert!(text.starts_with(&expected_text), "{text}");
    // The host refuses to send; the device refuses a command anyway.
    assert!(matches!(
        host.send(EXAMPLE_COMMAND),
        Err((LinkError::ProtocolMismatch(_), _))
    ));
    let step = dev.on_frame(
        ToDevice::Command {
            seq: Seq(0),
            cmd: EXAMPLE_COMMAND,
        },
        2,
        10,
    );
    assert_eq!(step.event, DeviceEvent::None);
    assert_eq!(
        step.reply,
        Some(Reply::Refused {
            what: RefusedFrame::Command(Seq(0)),
            reason: Refusal::ProtocolMismatch
        })
    );
    // A stop still works.
    let step = dev.on_frame::<ExampleCommand>(
        ToDevice::Realtime {
            id: Seq(0),
            req: RealtimeRequest::Stop,
        },
        3,
        10,
    );
    assert_eq!(
        step.event,
        DeviceEvent::Realtime {
            id: Seq(0),
            req: RealtimeRequest::Stop
        }
    );
    // Other protocol version, same schema: also a mismatch.
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).unwrap();
    let old = Hello {
        protocol_version: PROTOCOL_VERSION + 1,
        schema_hash: HASH,
        role: Role::Host,
        session: 1,
        control_rate_hz: 0,
    };
    assert!(matches!(
        dev.on_frame::<ExampleCommand>(ToDevice::Hello(old), 0, 10)
            .event,
        DeviceEvent::Mismatch(_)
    ));
}

#[test]
fn repeated_hello_keeps_the_session_and_a_new_one_restarts_numbering() {
    let (mut host, mut dev) = connected();
    host.send(EXAMPLE_COMMAND).unwrap();
    let f = host_frames(&mut host, 2);
    assert!(matches!(
        dev.on_frame(f[0].clone(), 2, 10).event,
        DeviceEvent::Command(_)
    ));
    let same = Hello {
        protocol_version: PROTOCOL_VERSION,
        schema_hash: HASH,
        role: Role::Host,
        session: 77,
        control_rate_hz: 0,
    };
    assert_eq!(
        dev.on_frame::<ExampleCommand>(ToDevice::Hello(same), 3, 10)
            .event,
        DeviceEvent::None
    );
    // Seq 0 is now a duplicate: the session was not reset.
    assert_eq!(dev.on_frame(f[0].clone(), 4, 9).event, DeviceEvent::None);
    let new = Hello {
        session: 78,
        ..same
    };
    assert_eq!(
        dev.on_frame::<ExampleCommand>(ToDevice::Hello(new), 5, 10)
            .event,
        DeviceEvent::SessionStarted { session: 78 }
    );
    assert!(matches!(
        dev.on_frame(f[0].clone(), 6, 10).event,
        DeviceEvent::Command(_)
    ));
    // The host ignores a Hello answer for another session.
    let other = Hello {
        role: Role::Device,
        session: 3,
        ..same
    };
    assert_eq!(
        host.on_frame::<ExampleTelemetry, ExampleStatus>(ToHost::Hello(other), 7),
        Ok(HostEvent::None)
    );
}

#[test]
fn a_goodbye_ends_the_session_with_the_watchdog_off_and_no_link_lost() {
    let (_host, mut dev) = connected();
    let timeout = DEFAULT_DEVICE_LINK_CONFIG.watchdog.timeout_ms;
    let step = dev.on_frame(ExampleToDevice::Goodbye, 10, 10);
    assert_eq!(step.event, DeviceEvent::SessionEnded);
    assert_eq!(step.reply, None);
    assert_eq!(dev.session(), DeviceSession::None);
    // silence far past the timeout: no `LinkLost` (the watchdog is off)
    for now in 10..10 + 3 * timeout {
        assert!(!dev.poll(now, 10).link_lost, "t = {now}");
    }
    // a second goodbye (or one without a session) is nothing
    let again = dev.on_frame(ExampleToDevice::Goodbye, 3 * timeout, 10);
    assert_eq!(again.event, DeviceEvent::None);
    // commands after it are refused until the next handshake
    command_refused_without_a_session(&mut dev, 3 * timeout);
}

/// Command 0 at `now` is refused with `NoSession`; the refusal frame.
fn command_refused_without_a_session(dev: &mut DeviceLink, now: u32) -> Reply {
    let step = dev.on_frame(
        ToDevice::Command {
            seq: Seq(0),
            cmd: EXAMPLE_COMMAND,
        },
        now,
        10,
    );
    let refused = Reply::Refused {
        what: RefusedFrame::Command(Seq(0)),
        reason: Refusal::NoSession,
    };
    assert_eq!(step.reply, Some(refused));
    refused
}

#[test]
fn device_watchdog_expires_without_frames_and_heartbeats_prevent_it() {
    let (mut host, mut dev) = connected();
    let timeout = DEFAULT_DEVICE_LINK_CONFIG.watchdog.timeout_ms;
    // The host, idle, sends heartbeats every timeout/4; each feeds the device.
    let mut heartbeats = 0;
    for now in 2..3 * timeout {
        for f in host_frames(&mut host, now) {
            assert_eq!(f, ToDevice::Heartbeat);
            heartbeats += 1;
            let step = dev.on_frame(f, now, 10);
            let _ = host
                .on_frame::<ExampleTelemetry, ExampleStatus>(step.reply.unwrap().into_frame(), now);
        }
        assert!(!dev.poll(now, 10).link_lost, "t = {now}");
    }
    // The first heartbeat right after the handshake, then one per 125 ms.
    assert_eq!(heartbeats, 1 + (3 * timeout - 2) / (timeout / 4));
    // Silence: expires exactly timeout after the last frame, reported once.
    let last = 3 * timeout - 1;
    let mut lost_at = Vec::new();
    for now in last..last + 2 * timeout {
        if dev.poll(now, 10).link_lost {
            lost_at.push(now);
        }
    }
    let last_fed = (3 * timeout - 2) / (timeout / 4) * (timeout / 4) + 2;
    assert_eq!(lost_at, [last_fed + timeout]);
    assert_eq!(dev.session(), DeviceSession::None);
    let refused = command_refused_without_a_session(&mut dev, last + 3 * timeout);
    // Host side: the refusal latches.
    let e =
        host.on_frame::<ExampleTelemetry, ExampleStatus>(refused.into_frame(), last + 3 * timeout);
    assert!(matches!(e, Err(LinkError::Refused { .. })));
    assert!(matches!(
        host.state(),
        HostState::Failed(LinkError::Refused { .. })
    ));
}

#[test]
fn host_watchdog_reports_link_lost_and_handshake_gives_up() {
    let (mut host, _dev) = connected();
    let timeout = DEFAULT_HOST_LINK_CONFIG.watchdog.timeout_ms;
    assert!(host.poll(timeout, |_| {}).is_ok());
    assert_eq!(host.poll(timeout + 1, |_| {}), Err(LinkError::LinkLost));
    // Nobody answers the Hello: 20 attempts, 100 ms apart, then NoAnswer.
    let mut host = Host::new(&DEFAULT_HOST_LINK_CONFIG, HASH, 1).unwrap();
    let mut hellos = 0;
    let mut result = Ok(());
    for now in 0..5000 {
        result = host.poll(now, |f| {
            assert!(matches!(f, ToDevice::Hello(_)));
            hellos += 1;
        });
        if result.is_err() {
            assert_eq!(now, 2000);
            break;
        }
    }
    assert_eq!((hellos, result), (20, Err(LinkError::NoAnswer)));
}

#[test]
fn realtime_requests_bypass_the_queue_and_are_answered_by_status() {
    let (mut host, mut dev) = connected();
    // A full window of commands is in flight; the hold still goes out at once.
    for _ in 0..8 {
        host.send(EXAMPLE_COMMAND).unwrap();
    }
    assert!(!host.can_send());
    let _ = host_frames(&mut host, 2);
    let id = host.request(RealtimeRequest::Hold);
    let f = host_frames(&mut host, 3);
    assert_eq!(
        f,
        [ToDevice::Realtime {
            id,
            req: RealtimeRequest::Hold
        }]
    );
    // Queue full (0 free slots) does not matter to a real-time request.
    let step = dev.on_frame(f[0].clone(), 3, 0);
    assert_eq!(
        step.event,
        DeviceEvent::Realtime {
            id,
            req: RealtimeRequest::Hold
        }
    );
    // Repeated (status reply lost): status only, not executed again.
    assert_eq!(
        dev.on_frame(f[0].clone(), 4, 0).event,
        DeviceEvent::StatusOnly { id }
    );
    let status = ExampleStatus {
        mode: 2,
        faults: 0,
        queue_free: 0,
    };
    let ev = host
        .on_frame::<ExampleTelemetry, ExampleStatus>(ToHost::Status { id, status }, 5)
        .unwrap();
    assert_eq!(
        ev,
        HostEvent::Status {
            id,
            status,
            answered: true
        }
    );
    assert_eq!(host.stats().realtime_repeats, 0);
}

#[test]
fn realtime_without_session_only_stops_and_holds() {
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).unwrap();
    for (req, executes) in [
        (RealtimeRequest::Stop, true),
        (RealtimeRequest::Hold, true),
        (RealtimeRequest::Status, true),
        (RealtimeRequest::Resume, false),
    ] {
        let step = dev.on_frame::<ExampleCommand>(ToDevice::Realtime { id: Seq(9), req }, 0, 10);
        assert_eq!(
            matches!(step.event, DeviceEvent::Realtime { .. }),
            executes,
            "{req:?}"
        );
        if !executes {
            assert_eq!(
                step.reply,
                Some(Reply::Refused {
                    what: RefusedFrame::Realtime(Seq(9)),
                    reason: Refusal::NoSession
                })
            );
        }
    }
}

#[test]
fn telemetry_only_in_a_session_and_gaps_are_counted() {
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).unwrap();
    assert_eq!(
        dev.telemetry::<ExampleTelemetry, ExampleStatus>(EXAMPLE_TELEMETRY),
        None
    );
    let (mut host, mut dev) = connected();
    let frames: Vec<Up> = (0..10)
        .map(|_| dev.telemetry(EXAMPLE_TELEMETRY).unwrap())
        .collect();
    for (i, f) in frames.into_iter().enumerate() {
        if i == 3 || i == 4 || i == 8 {
            continue; // lost
        }
        let ev = host.on_frame(f, 10).unwrap();
        assert!(matches!(ev, HostEvent::Telemetry { seq, .. } if seq == Seq(i as u16)));
    }
    let t = host.stats().telemetry;
    assert_eq!((t.received, t.lost), (7, 3));
}

#[test]
fn credit_updates_follow_the_queue() {
    let (_host, mut dev) = connected();
    // Advertised 10. Fewer than 4 more free slots: no update; 4 more: update.
    assert_eq!(dev.poll(2, 13).reply, None);
    assert_eq!(
        dev.poll(3, 14).reply,
        Some(Reply::Ack(Ack {
            seq: Seq(65535),
            credits: 14
        }))
    );
    // After advertising 0 (queue full on a command), any free slot is advertised.
    let step = dev.on_frame(
        ToDevice::Command {
            seq: Seq(0),
            cmd: EXAMPLE_COMMAND,
        },
        4,
        1,
    );
    assert_eq!(
        step.reply,
        Some(Reply::Ack(Ack {
            seq: Seq(0),
            credits: 0
        }))
    );
    assert_eq!(dev.poll(5, 0).reply, None);
    assert_eq!(
        dev.poll(6, 1).reply,
        Some(Reply::Ack(Ack {
            seq: Seq(0),
            credits: 1
        }))
    );
}

#[test]
fn kernels_match_their_fixed_inputs() {
    let mut dec = FrameDecoder::new();
    let msg = decode_one_frame(&mut dec, &EXAMPLE_COMMAND_FRAME).unwrap();
    assert_eq!(
        msg,
        ToDevice::Command {
            seq: Seq(300),
            cmd: EXAMPLE_COMMAND
        }
    );
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode_one_telemetry_frame(Seq(300), &mut out);
    // 1 variant + 2 seq + 3 period + 48 values + 4 CRC + 1 COBS + 1 delimiter.
    assert_eq!(n, 60);
    let back: Vec<_> = dec.frames::<ExampleToHost>(&out[..n]).collect();
    assert_eq!(
        back,
        [Ok(ToHost::Telemetry {
            seq: Seq(300),
            sample: EXAMPLE_TELEMETRY
        })]
    );
}

#[test]
fn config_errors_name_the_field() {
    let mut c = DEFAULT_HOST_LINK_CONFIG;
    c.hello_attempts = 0;
    assert_eq!(
        Host::new(&c, HASH, 1).err(),
        Some(LinkConfigError::OutOfRange("hello_attempts"))
    );
    let mut c = DEFAULT_HOST_LINK_CONFIG;
    c.watchdog.timeout_ms = 5;
    assert_eq!(
        Host::new(&c, HASH, 1).err(),
        Some(LinkConfigError::OutOfRange("watchdog.timeout_ms"))
    );
    let mut d = DEFAULT_DEVICE_LINK_CONFIG;
    d.credit_update_step = 0;
    assert_eq!(
        DeviceLink::new(&d, HASH, 10_000).err(),
        Some(LinkConfigError::OutOfRange("credit_update_step"))
    );
    assert_eq!(
        DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 0).err(),
        Some(LinkConfigError::OutOfRange("control_rate_hz"))
    );
}

#[test]
fn the_host_learns_the_device_control_rate_in_the_handshake() {
    let mut host = Host::new(&DEFAULT_HOST_LINK_CONFIG, HASH, 5).unwrap();
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 20_000).unwrap();
    assert_eq!(host.device_control_rate_hz(), None);
    let hello = host_frames(&mut host, 0);
    // (the host announces no rate: it runs no control loop)
    assert!(matches!(&hello[0], ToDevice::Hello(h) if h.control_rate_hz == 0));
    let step = dev.on_frame(hello[0].clone(), 0, 10);
    let answer = step
        .reply
        .unwrap()
        .into_frame::<ExampleTelemetry, ExampleStatus>();
    assert!(matches!(&answer, ToHost::Hello(h) if h.control_rate_hz == 20_000));
    assert_eq!(host.on_frame(answer, 1), Ok(HostEvent::Ready));
    assert_eq!(host.device_control_rate_hz(), Some(20_000));
}

#[test]
fn a_borrowed_command_frame_encodes_to_the_same_bytes() {
    let owned: ExampleToDevice = ToDevice::Command {
        seq: Seq(300),
        cmd: EXAMPLE_COMMAND,
    };
    let mut a = [0u8; MAX_FRAME_LEN];
    let n = encode(&owned.as_ref(), &mut a).unwrap();
    assert_eq!(&a[..n], &EXAMPLE_COMMAND_FRAME[..]);
}

#[test]
fn an_expected_silence_holds_the_watchdog_and_the_repeats_until_it_ends() {
    // a settings save that erases flash stalls the board for seconds: 5 s here
    let silent_ms = 5_000;
    let silent_poll = |expect: bool| {
        let (mut host, _dev) = connected();
        host.request(RealtimeRequest::Status);
        if expect {
            host.expect_silence(0, silent_ms);
        }
        let mut requests = 0;
        let failed = (0..silent_ms).find_map(|now| {
            host.poll(now, |f| {
                if matches!(f, ToDevice::Realtime { .. }) {
                    requests += 1;
                }
            })
            .err()
            .map(|e| (now, e))
        });
        (host, failed, requests)
    };
    // not expected: the unanswered request and the watchdog give up long before
    let (_, failed, _) = silent_poll(false);
    let (at, _) = failed.expect("a silent device fails the link");
    assert!(
        at < DEFAULT_HOST_LINK_CONFIG.watchdog.timeout_ms + 1,
        "failed at {at} ms"
    );
    // expected: nothing fails while it lasts, the request keeps being repeated
    let (mut host, failed, requests) = silent_poll(true);
    assert_eq!(failed, None);
    let every = DEFAULT_HOST_LINK_CONFIG.realtime.retry_timeout_ms;
    assert!(requests >= silent_ms / every, "{requests} repetitions");
    // still silent once it ends: the link is lost
    assert_eq!(host.poll(silent_ms, |_| {}), Err(LinkError::LinkLost));
}

#[test]
fn a_device_back_within_the_expected_silence_keeps_the_link() {
    let (mut host, mut dev) = connected();
    host.expect_silence(0, 5_000);
    for now in 0..3_000 {
        assert_eq!(host.poll(now, |_| {}), Ok(()));
    }
    // from 3 s on the device answers again: the link goes on through the window's end.
    // The stalled board's clock stood still (its tick interrupt could not run): it saw
    // no silence.
    let timeout = DEFAULT_HOST_LINK_CONFIG.watchdog.timeout_ms;
    for now in 3_000..5_000 + 4 * timeout {
        let dev_now = now - 2_999;
        let frames = host_frames(&mut host, now);
        for f in frames {
            if let Some(reply) = dev.on_frame(f, dev_now, 10).reply {
                host.on_frame::<ExampleTelemetry, ExampleStatus>(reply.into_frame(), now)
                    .unwrap();
            }
        }
        if let Some(reply) = dev.poll(dev_now, 10).reply {
            host.on_frame::<ExampleTelemetry, ExampleStatus>(reply.into_frame(), now)
                .unwrap();
        }
        assert_eq!(host.state(), HostState::Ready, "at {now} ms");
    }
}
