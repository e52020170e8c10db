//! Link figures: bytes per typical frame, frames and telemetry samples per second at
//! 921,600 baud, and host time to decode / encode one frame.
//!
//! ```text
//! cargo run --release -p controller-core --example link_bench
//! ```
//! The MCU cost of the same two kernels (`link::kernels::decode_one_frame`,
//! `encode_one_telemetry_frame`) is for `cargo insns`.

use std::hint::black_box;
use std::time::Instant;

use controller_core::link::kernels::{
    decode_one_frame, encode_one_telemetry_frame, ExampleCommand, ExampleStatus, ExampleTelemetry,
    ExampleToDevice, ExampleToHost, EXAMPLE_COMMAND, EXAMPLE_COMMAND_FRAME, EXAMPLE_TELEMETRY,
};
use controller_core::link::{
    encode, schema_hash, FrameDecoder, RealtimeRequest, Role, Seq, ToHost, Version, MAX_FRAME_LEN,
};

/// 921,600 baud, 8N1: 10 bit times per byte.
const BYTES_PER_S: f64 = 921_600.0 / 10.0;

fn len<T: serde::Serialize>(msg: &T) -> usize {
    let mut buf = [0u8; MAX_FRAME_LEN];
    encode(msg, &mut buf).expect("fits")
}

fn main() {
    let hash = schema_hash::<ExampleCommand, ExampleTelemetry, ExampleStatus>();
    // Sequence numbers ≥ 128 take 2 varint bytes, ≥ 16384 take 3: use 2 (typical).
    let seq = Seq(300);
    let rows: Vec<(&str, usize)> = vec![
        (
            "hello",
            len(&ExampleToDevice::Hello(Version::current(hash).hello(
                Role::Host,
                1234,
                0,
            ))),
        ),
        ("heartbeat", len(&ExampleToDevice::Heartbeat)),
        (
            "command (29 B payload)",
            len(&ExampleToDevice::Command {
                seq,
                cmd: EXAMPLE_COMMAND,
            }),
        ),
        (
            "realtime request",
            len(&ExampleToDevice::Realtime {
                id: seq,
                req: RealtimeRequest::Hold,
            }),
        ),
        ("ack", len(&ExampleToHost::Ack { seq, credits: 16 })),
        (
            "nak",
            len(&ExampleToHost::Nak {
                seq,
                credits: 16,
                got: seq.add(2),
            }),
        ),
        (
            "status",
            len(&ExampleToHost::Status {
                id: seq,
                status: ExampleStatus {
                    mode: 2,
                    faults: 0,
                    queue_free: 16,
                },
            }),
        ),
        (
            "telemetry, 12 f32",
            len(&ExampleToHost::Telemetry {
                seq,
                sample: EXAMPLE_TELEMETRY,
            }),
        ),
        (
            "telemetry, 4 x 12 f32",
            len(&ToHost::<[ExampleTelemetry; 4], ExampleStatus>::Telemetry {
                seq,
                sample: [EXAMPLE_TELEMETRY; 4],
            }),
        ),
    ];
    println!("link at 921,600 baud 8N1 = {BYTES_PER_S:.0} B/s");
    println!("{:<24} {:>7} {:>10}", "frame", "bytes", "frames/s");
    for (name, n) in &rows {
        println!("{name:<24} {n:>7} {:>10.0}", BYTES_PER_S / *n as f64);
    }
    let tel = rows[7].1 as f64;
    let tel4 = rows[8].1 as f64;
    let cmd = rows[2].1 as f64;
    let ack = rows[4].1 as f64;
    println!(
        "telemetry samples/s, link to itself:        {:.0} (1/frame), {:.0} (4/frame)",
        BYTES_PER_S / tel,
        4.0 * BYTES_PER_S / tel4
    );
    println!(
        "commands/s, host -> device (each acked):   {:.0} (ack uplink {:.0} B/s)",
        BYTES_PER_S / cmd,
        BYTES_PER_S / cmd * ack
    );
    // Uplink shared: 500 commands/s acked, telemetry gets the rest.
    let left = BYTES_PER_S - 500.0 * ack;
    println!(
        "telemetry samples/s beside 500 acked commands/s: {:.0} (1/frame), {:.0} (4/frame)",
        left / tel,
        4.0 * left / tel4
    );

    // Host timing.
    const N: u32 = 2_000_000;
    let mut dec = FrameDecoder::new();
    let t = Instant::now();
    let mut ok = 0u32;
    for _ in 0..N {
        if decode_one_frame(&mut dec, black_box(&EXAMPLE_COMMAND_FRAME)).is_some() {
            ok += 1;
        }
    }
    let decode_ns = t.elapsed().as_nanos() as f64 / f64::from(N);
    assert_eq!(ok, N);
    let mut out = [0u8; MAX_FRAME_LEN];
    let t = Instant::now();
    let mut total = 0usize;
    for i in 0..N {
        total += encode_one_telemetry_frame(black_box(Seq(i as u16)), &mut out);
        black_box(&out);
    }
    let encode_ns = t.elapsed().as_nanos() as f64 / f64::from(N);
    assert!(total > 0);
    println!("host: decode one command frame {decode_ns:.0} ns, encode one telemetry frame {encode_ns:.0} ns");
}
