//! The link over a byte channel with 1 % byte errors: a 2000-command program completes,
//! every command executed exactly once and in order, with telemetry streaming alongside.
//!
//! Byte level, end to end: `HostLink` → `encode` → lossy pipe → `FrameDecoder` →
//! `DeviceLink` → command queue, and back the same way for acks, telemetry and status.

use std::collections::VecDeque;

use controller_core::sim::rng::SplitMix64;

use controller_core::link::device::DEFAULT_DEVICE_LINK_CONFIG;
use controller_core::link::host::DEFAULT_HOST_LINK_CONFIG;
use controller_core::link::kernels::{
    ExampleCommand, ExampleStatus, ExampleTelemetry, ExampleToDevice, ExampleToHost,
    EXAMPLE_COMMAND, EXAMPLE_TELEMETRY,
};
use controller_core::link::{
    encode, schema_hash, DeviceEvent, DeviceLink, FrameDecoder, HostEvent, HostLink, HostState,
    RealtimeRequest, MAX_FRAME_LEN,
};

const HASH: u32 = schema_hash::<ExampleCommand, ExampleTelemetry, ExampleStatus>();
/// 921,600 baud 8N1 = 92,160 B/s: 92 bytes per 1 ms tick each way.
const BYTES_PER_MS: usize = 92;
const QUEUE_SLOTS: usize = 16;

struct Rng(SplitMix64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// True with probability `ppm` / 1e6.
    fn chance(&mut self, ppm: u64) -> bool {
        self.next() % 1_000_000 < ppm
    }
}

/// One direction of the serial line: whole frames go in, bytes come out at the line rate.
/// Each frame may be dropped or duplicated; each byte is corrupted with `byte_error_ppm`
/// (60 % bit flips, 20 % lost byte, 20 % inserted byte).
struct Pipe {
    bytes: VecDeque<u8>,
    byte_error_ppm: u64,
    frame_drop_ppm: u64,
    frame_dup_ppm: u64,
    corrupted: u64,
    dropped: u64,
    duplicated: u64,
}

impl Pipe {
    fn new(byte_error_ppm: u64) -> Self {
        Self {
            bytes: VecDeque::new(),
            byte_error_ppm,
            frame_drop_ppm: 5_000,
            frame_dup_ppm: 5_000,
            corrupted: 0,
            dropped: 0,
            duplicated: 0,
        }
    }

    fn write_frame(&mut self, frame: &[u8], rng: &mut Rng) {
        if rng.chance(self.frame_drop_ppm) {
            self.dropped += 1;
            return;
        }
        let copies = if rng.chance(self.frame_dup_ppm) {
            self.duplicated += 1;
            2
        } else {
            1
        };
        for _ in 0..copies {
            for &b in frame {
                if rng.chance(self.byte_error_ppm) {
                    self.corrupted += 1;
                    match rng.next() % 10 {
                        0 | 1 => {} // byte lost
                        2 | 3 => {
                            self.bytes.push_back(b);
                            self.bytes.push_back(rng.next() as u8);
                        }
                        _ => self.bytes.push_back(b ^ (1 + (rng.next() % 255) as u8)),
                    }
                } else {
                    self.bytes.push_back(b);
                }
            }
        }
    }

    fn read(&mut self, max: usize) -> Vec<u8> {
        let n = max.min(self.bytes.len());
        self.bytes.drain(..n).collect()
    }
}

struct Outcome {
    executed: Vec<u32>,
    ticks: u32,
    retransmitted: u32,
    telemetry_sent: u32,
    telemetry_received: u32,
    telemetry_lost: u32,
    newest_telemetry: u16,
    device_errors: u32,
    host_errors: u32,
    down: Pipe,
    up: Pipe,
    status_answered: bool,
}

fn run(n: u32, byte_error_ppm: u64, seed: u64) -> Outcome {
    let mut rng = Rng(SplitMix64::new(seed));
    let mut host =
        HostLink::<ExampleCommand, 8>::new(&DEFAULT_HOST_LINK_CONFIG, HASH, 4242).unwrap();
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).unwrap();
    let mut host_dec = FrameDecoder::new();
    let mut dev_dec = FrameDecoder::new();
    let mut down = Pipe::new(byte_error_ppm);
    let mut up = Pipe::new(byte_error_ppm);
    let mut queue: VecDeque<ExampleCommand> = VecDeque::new();
    let mut executed = Vec::new();
    let mut next_line = 0u32;
    let mut telemetry_sent = 0;
    let mut newest_telemetry = 0;
    let mut status_answered = false;
    let mut status_requested = false;
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut ticks = 0;
    for now in 0..600_000u32 {
        ticks = now;
        // Host: queue what the window and credits allow, then send what is due.
        while next_line < n && host.can_send() {
            host.send(ExampleCommand {
                line: next_line,
                ..EXAMPLE_COMMAND
            })
            .unwrap();
            next_line += 1;
        }
        if !status_requested && host.stats().command.acked >= n / 2 {
            status_requested = true;
            host.request(RealtimeRequest::Status);
        }
        host.poll(now, |f| {
            let len = encode(&f, &mut buf).unwrap();
            down.write_frame(&buf[..len], &mut rng);
        })
        .unwrap_or_else(|e| panic!("host failed at t = {now} ms: {e}"));

        // Device: read what arrived this ms, answer, execute one queued command per ms,
        // stream telemetry every 2 ms.
        let incoming = down.read(BYTES_PER_MS);
        let frames: Vec<_> = dev_dec.frames::<ExampleToDevice>(&incoming).collect();
        for r in frames {
            let Ok(frame) = r else { continue };
            let free = (QUEUE_SLOTS - queue.len()) as u16;
            let step = dev.on_frame(frame, now, free);
            if let Some(reply) = step.reply {
                let len = encode(
                    &reply.into_frame::<ExampleTelemetry, ExampleStatus>(),
                    &mut buf,
                )
                .unwrap();
                up.write_frame(&buf[..len], &mut rng);
            }
            match step.event {
                DeviceEvent::Command(c) => queue.push_back(c),
                DeviceEvent::Realtime { id, .. } | DeviceEvent::StatusOnly { id } => {
                    let status = ExampleStatus {
                        mode: 1,
                        faults: 0,
                        queue_free: free,
                    };
                    let len = encode(&ExampleToHost::Status { id, status }, &mut buf).unwrap();
                    up.write_frame(&buf[..len], &mut rng);
                }
                _ => {}
            }
        }
        if let Some(c) = queue.pop_front() {
            executed.push(c.line);
        }
        let p = dev.poll(now, (QUEUE_SLOTS - queue.len()) as u16);
        assert!(!p.link_lost, "device watchdog expired at t = {now} ms");
        if let Some(reply) = p.reply {
            let len = encode(
                &reply.into_frame::<ExampleTelemetry, ExampleStatus>(),
                &mut buf,
            )
            .unwrap();
            up.write_frame(&buf[..len], &mut rng);
        }
        if now % 2 == 0 {
            if let Some(t) = dev.telemetry::<_, ExampleStatus>(EXAMPLE_TELEMETRY) {
                telemetry_sent += 1;
                let len = encode(&t, &mut buf).unwrap();
                up.write_frame(&buf[..len], &mut rng);
            }
        }

        // Host: read device frames.
        let incoming = up.read(BYTES_PER_MS);
        let frames: Vec<_> = host_dec.frames::<ExampleToHost>(&incoming).collect();
        for r in frames {
            let Ok(frame) = r else { continue };
            match host
                .on_frame(frame, now)
                .unwrap_or_else(|e| panic!("host error at t = {now} ms: {e}"))
            {
                HostEvent::Telemetry { seq, arrival, .. } if arrival.is_new() => {
                    newest_telemetry = seq.0
                }
                HostEvent::Status { answered: true, .. } => status_answered = true,
                _ => {}
            }
        }
        if executed.len() as u32 == n && host.in_flight() == 0 {
            break;
        }
    }
    assert_eq!(host.state(), HostState::Ready);
    let t = host.stats().telemetry;
    Outcome {
        executed,
        ticks,
        retransmitted: host.stats().command.retransmitted,
        telemetry_sent,
        telemetry_received: t.received,
        telemetry_lost: t.lost,
        newest_telemetry,
        device_errors: dev_dec.stats().errors(),
        host_errors: host_dec.stats().errors(),
        down,
        up,
        status_answered,
    }
}

#[test]
fn program_of_2000_commands_completes_exactly_once_in_order_at_1_percent_byte_errors() {
    let n = 2000;
    let o = run(n, 10_000, 0x5EED);
    assert_eq!(
        o.executed,
        (0..n).collect::<Vec<_>>(),
        "every command once, in order"
    );
    // The channel really was bad, and the link really worked for it.
    assert!(
        o.down.corrupted > 500 && o.up.corrupted > 500,
        "{} {}",
        o.down.corrupted,
        o.up.corrupted
    );
    assert!(o.down.dropped > 0 && o.down.duplicated > 0);
    assert!(o.retransmitted > 100, "retransmissions {}", o.retransmitted);
    assert!(o.device_errors > 100 && o.host_errors > 100);
    // Telemetry is never retransmitted: its losses are counted, exactly.
    assert!(o.telemetry_lost > 0);
    assert_eq!(
        o.telemetry_received + o.telemetry_lost,
        u32::from(o.newest_telemetry) + 1
    );
    assert!(o.telemetry_received <= o.telemetry_sent);
    assert!(o.status_answered, "status request answered");
    println!(
        "2000 commands in {} ms simulated; {} retransmissions; frames dropped by decoders: device {}, host {}; \
         telemetry {} sent, {} received, {} lost",
        o.ticks, o.retransmitted, o.device_errors, o.host_errors, o.telemetry_sent, o.telemetry_received, o.telemetry_lost
    );
}

#[test]
fn clean_line_needs_no_retransmission() {
    let o = run(500, 0, 7);
    assert_eq!(o.executed, (0..500).collect::<Vec<_>>());
    // Whole-frame drops and duplicates (0.5 % each) are still on: only the drops cost
    // retransmissions, at most one window each.
    assert_eq!((o.device_errors, o.host_errors), (0, 0));
    assert_eq!(
        o.telemetry_received + o.telemetry_lost,
        u32::from(o.newest_telemetry) + 1
    );
    assert!(o.down.dropped + o.up.dropped > 0);
    assert!(
        o.retransmitted <= 8 * (o.down.dropped + o.up.dropped) as u32,
        "{}",
        o.retransmitted
    );
    // One command executed per ms: a clean line keeps the queue fed.
    assert!(o.ticks < 520, "{} ms", o.ticks);
}
