//! Deterministic high-volume fuzzing of the link's frame decoder and message parser.
//!
//! ```text
//! cargo run --release -p controller-core --example link_fuzz -- [INPUTS] [SEED]
//! ```
//! (default 10,000,000 inputs, seed 1). Each input is one of:
//! - random bytes (0-600, with extra 0x00 delimiters mixed in),
//! - one to four valid frames (both directions, random contents) hit by 1-8 mutations
//!   (bit flips, byte writes, insertions, deletions, duplicated and swapped spans,
//!   truncation, stray delimiters, long runs),
//! - a valid frame whose *payload* was mutated and then re-framed with a correct CRC and
//!   COBS, so the mutation reaches the postcard parser instead of stopping at the CRC.
//!
//! Every input is fed to a device-side and a host-side decoder in random splits; every
//! decoded message is re-encoded (must succeed and decode to the same bytes) and fed to a
//! `DeviceLink` / `HostLink`, so the state machines see hostile input too. Panics are
//! caught and counted; the run fails if there is any. Reports inputs/s, outcomes and the
//! peak decoder buffer use. The same inputs come out for the same seed.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::Instant;

use controller_core::sim::rng::SplitMix64;

use controller_core::link::device::DEFAULT_DEVICE_LINK_CONFIG;
use controller_core::link::host::DEFAULT_HOST_LINK_CONFIG;
use controller_core::link::kernels::{
    ExampleCommand, ExampleStatus, ExampleTelemetry, ExampleToDevice, ExampleToHost,
};
use controller_core::link::{
    encode, frame::crc32, schema_hash, DeviceLink, FrameDecoder, Hello, HostLink, RealtimeRequest,
    Role, Seq, ToDevice, ToHost, MAX_FRAME_LEN, MAX_PAYLOAD_LEN,
};

const HASH: u32 = schema_hash::<ExampleCommand, ExampleTelemetry, ExampleStatus>();

struct Rng(SplitMix64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next_u64()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn f32(&mut self) -> f32 {
        // Mostly ordinary numbers, sometimes any bit pattern (NaN, inf, subnormal).
        if self.below(8) == 0 {
            f32::from_bits(self.next() as u32)
        } else {
            (self.next() % 2_000_000) as f32 / 1000.0 - 1000.0
        }
    }
}

fn random_down(r: &mut Rng) -> ExampleToDevice {
    match r.below(4) {
        0 => ToDevice::Hello(Hello {
            protocol_version: if r.below(4) == 0 { r.next() as u16 } else { 1 },
            schema_hash: if r.below(4) == 0 {
                r.next() as u32
            } else {
                HASH
            },
            role: if r.below(8) == 0 {
                Role::Device
            } else {
                Role::Host
            },
            session: r.below(3) as u16,
            control_rate_hz: 0,
        }),
        1 => ToDevice::Heartbeat,
        2 => ToDevice::Command {
            seq: Seq(r.next() as u16),
            cmd: ExampleCommand {
                line: r.next() as u32,
                end_mm: [r.f32(), r.f32(), r.f32()],
                feed_mm_s: r.f32(),
                accel_mm_s2: r.f32(),
                blend_mm: r.f32(),
            },
        },
        _ => ToDevice::Realtime {
            id: Seq(r.next() as u16),
            req: [
                RealtimeRequest::Hold,
                RealtimeRequest::Resume,
                RealtimeRequest::Stop,
                RealtimeRequest::Status,
            ][r.below(4)],
        },
    }
}

fn random_up(r: &mut Rng) -> ExampleToHost {
    match r.below(4) {
        0 => ToHost::Ack {
            seq: Seq(r.next() as u16),
            credits: r.next() as u16,
        },
        1 => ToHost::Nak {
            seq: Seq(r.next() as u16),
            credits: r.next() as u16,
            got: Seq(r.next() as u16),
        },
        2 => {
            let mut values = [0.0; 12];
            for v in &mut values {
                *v = r.f32();
            }
            ToHost::Telemetry {
                seq: Seq(r.next() as u16),
                sample: ExampleTelemetry {
                    period: r.next() as u32,
                    values,
                },
            }
        }
        _ => ToHost::Status {
            id: Seq(r.next() as u16),
            status: ExampleStatus {
                mode: r.next() as u8,
                faults: r.next() as u32,
                queue_free: r.next() as u16,
            },
        },
    }
}

fn push_frame<T: serde::Serialize>(msg: &T, out: &mut Vec<u8>) {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(msg, &mut buf).expect("example messages fit a frame");
    out.extend_from_slice(&buf[..n]);
}

fn mutate(r: &mut Rng, data: &mut Vec<u8>) {
    for _ in 0..1 + r.below(8) {
        let len = data.len();
        match r.below(10) {
            0 | 1 if len > 0 => {
                let i = r.below(len);
                data[i] ^= 1 << r.below(8);
            }
            2 if len > 0 => {
                let i = r.below(len);
                data[i] = r.next() as u8;
            }
            3 => {
                let i = r.below(len + 1);
                data.insert(i, r.next() as u8);
            }
            4 if len > 0 => {
                let i = r.below(len);
                data.remove(i);
            }
            5 if len > 1 => {
                let a = r.below(len);
                let b = (a + 1 + r.below(64)).min(len);
                let span = data[a..b].to_vec();
                let at = r.below(len + 1);
                data.splice(at..at, span);
            }
            6 if len > 0 => data.truncate(r.below(len)),
            7 => {
                let i = r.below(len + 1);
                data.insert(i, 0);
            }
            8 => {
                let i = r.below(len + 1);
                let run = vec![
                    if r.below(2) == 0 {
                        0xFF
                    } else {
                        r.next() as u8 | 1
                    };
                    r.below(700)
                ];
                data.splice(i..i, run);
            }
            _ if len > 3 => {
                let a = r.below(len / 2);
                let b = len / 2 + r.below(len / 2);
                data.swap(a, b);
            }
            _ => {}
        }
    }
}

/// A frame around an already-mutated payload: correct CRC and COBS.
fn reframe(payload: &[u8], out: &mut Vec<u8>) {
    let mut raw = payload[..payload.len().min(MAX_PAYLOAD_LEN)].to_vec();
    let crc = crc32(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut enc = vec![0u8; raw.len() + raw.len() / 254 + 2];
    let n = cobs::encode(&raw, &mut enc);
    out.extend_from_slice(&enc[..n]);
    out.push(0);
}

fn make_input(r: &mut Rng, out: &mut Vec<u8>) {
    out.clear();
    match r.below(3) {
        0 => {
            for _ in 0..r.below(600) {
                let b = r.next() as u8;
                out.push(if r.below(40) == 0 { 0 } else { b });
            }
        }
        1 => {
            for _ in 0..1 + r.below(4) {
                if r.below(2) == 0 {
                    push_frame(&random_down(r), out);
                } else {
                    push_frame(&random_up(r), out);
                }
            }
            mutate(r, out);
        }
        _ => {
            let mut payload = Vec::new();
            let mut buf = [0u8; MAX_PAYLOAD_LEN];
            let p = if r.below(2) == 0 {
                postcard::to_slice(&random_down(r), &mut buf)
                    .expect("fits")
                    .to_vec()
            } else {
                postcard::to_slice(&random_up(r), &mut buf)
                    .expect("fits")
                    .to_vec()
            };
            payload.extend_from_slice(&p);
            mutate(r, &mut payload);
            reframe(&payload, out);
        }
    }
}

#[derive(Default)]
struct Tally {
    inputs: u64,
    bytes: u64,
    down_ok: u64,
    up_ok: u64,
    panics: u64,
    reencode_mismatch: u64,
}

fn main() {
    let mut args = std::env::args().skip(1);
    let inputs: u64 = args
        .next()
        .map_or(10_000_000, |a| a.parse().expect("INPUTS is a number"));
    let seed: u64 = args
        .next()
        .map_or(1, |a| a.parse().expect("SEED is a number"));
    let mut r = Rng(SplitMix64::new(seed));
    let mut dev_dec = FrameDecoder::new();
    let mut host_dec = FrameDecoder::new();
    let mut dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).expect("valid config");
    let mut host = HostLink::<ExampleCommand, 8>::new(&DEFAULT_HOST_LINK_CONFIG, HASH, 1)
        .expect("valid config");
    let mut t = Tally::default();
    let mut input = Vec::with_capacity(4096);
    let mut scratch = Vec::with_capacity(512);
    let start = Instant::now();
    let mut now_ms = 0u32;
    std::panic::set_hook(Box::new(|info| eprintln!("PANIC: {info}")));
    for i in 0..inputs {
        make_input(&mut r, &mut input);
        t.inputs += 1;
        t.bytes += input.len() as u64;
        now_ms = now_ms.wrapping_add(1 + r.below(20) as u32);
        if i % 100_000 == 0 {
            // Fresh link state now and then, so handshakes happen again.
            dev = DeviceLink::new(&DEFAULT_DEVICE_LINK_CONFIG, HASH, 10_000).expect("valid config");
            host = HostLink::new(&DEFAULT_HOST_LINK_CONFIG, HASH, (i / 100_000) as u16 % 3)
                .expect("valid config");
        }
        let split = 1 + r.below(input.len() + 1);
        let free = r.below(20) as u16;
        let res = catch_unwind(AssertUnwindSafe(|| {
            for chunk in input.chunks(split) {
                for msg in dev_dec.frames::<ExampleToDevice>(chunk).flatten() {
                    t.down_ok += 1;
                    scratch.clear();
                    push_frame(&msg, &mut scratch);
                    let again: Vec<_> = FrameDecoder::new()
                        .frames::<ExampleToDevice>(&scratch)
                        .collect();
                    if again.len() != 1 || again[0].as_ref().map(frame_bytes) != Ok(scratch.clone())
                    {
                        t.reencode_mismatch += 1;
                    }
                    let _ = dev.on_frame(msg, now_ms, free);
                    let _ = dev.poll(now_ms, free);
                }
                for msg in host_dec.frames::<ExampleToHost>(chunk).flatten() {
                    t.up_ok += 1;
                    let _ = host.on_frame(msg, now_ms);
                    let _ = host.poll(now_ms, |_| {});
                }
            }
        }));
        if res.is_err() {
            t.panics += 1;
            dev_dec.reset();
            host_dec.reset();
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let (d, h) = (dev_dec.stats(), host_dec.stats());
    println!("link_fuzz: seed {seed}");
    println!("inputs            {}", t.inputs);
    println!(
        "bytes             {} ({:.1} MB)",
        t.bytes,
        t.bytes as f64 / 1e6
    );
    println!(
        "time              {secs:.1} s, {:.0} inputs/s, {:.1} MB/s",
        t.inputs as f64 / secs,
        t.bytes as f64 / secs / 1e6
    );
    println!("panics            {}", t.panics);
    println!("re-encode errors  {}", t.reencode_mismatch);
    for (name, s, ok) in [
        ("device decoder", d, t.down_ok),
        ("host decoder", h, t.up_ok),
    ] {
        println!(
            "{name:<17} frames ok {ok}, oversized {}, cobs {}, too short {}, crc {}, parse {}",
            s.oversized, s.cobs_errors, s.too_short, s.crc_errors, s.parse_errors
        );
    }
    println!(
        "peak buffer use   device {} / host {} of {} bytes; FrameDecoder is {} bytes, no heap",
        dev_dec.peak_len(),
        host_dec.peak_len(),
        controller_core::link::frame::MAX_ENCODED_LEN,
        std::mem::size_of::<FrameDecoder>()
    );
    if t.panics > 0 || t.reencode_mismatch > 0 {
        std::process::exit(1);
    }
}

fn frame_bytes(m: &ExampleToDevice) -> Vec<u8> {
    let mut v = Vec::new();
    push_frame(m, &mut v);
    v
}
