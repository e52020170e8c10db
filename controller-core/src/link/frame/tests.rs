extern crate std;
use std::vec::Vec;

use proptest::prelude::*;
use serde::{Deserialize, Serialize};

use super::*;
use crate::link::kernels::{
    ExampleCommand, ExampleToDevice, EXAMPLE_COMMAND, EXAMPLE_COMMAND_FRAME,
};
use crate::link::{Seq, ToDevice};

fn frame_of<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode(msg, &mut out).unwrap();
    out[..n].to_vec()
}

fn decode_all<T: DeserializeOwned>(
    dec: &mut FrameDecoder,
    bytes: &[u8],
) -> Vec<Result<T, FrameError>> {
    dec.frames::<T>(bytes).collect()
}

fn command(seq: u16, line: u32) -> ExampleToDevice {
    ToDevice::Command {
        seq: Seq(seq),
        cmd: ExampleCommand {
            line,
            ..EXAMPLE_COMMAND
        },
    }
}

/// 256-byte postcard payload without a single zero byte: 25 × u64::MAX (10-byte varints)
/// plus 6 bytes. COBS has nothing to shorten: the worst-case frame length.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Biggest {
    a: [u64; 25],
    b: [u8; 6],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct TooBig {
    a: [u64; 25],
    b: [u8; 7],
}

#[test]
fn frame_layout_is_cobs_of_payload_and_crc_with_one_trailing_zero() {
    let f = frame_of(&command(300, 1234));
    assert_eq!(f, EXAMPLE_COMMAND_FRAME);
    assert_eq!(f.iter().filter(|&&b| b == 0).count(), 1);
    assert_eq!(*f.last().unwrap(), 0);
    let mut raw = f[..f.len() - 1].to_vec();
    let n = cobs::decode_in_place(&mut raw).unwrap();
    let payload = postcard::to_slice(&command(300, 1234), &mut [0u8; 64])
        .unwrap()
        .to_vec();
    assert_eq!(n, payload.len() + CRC_LEN);
    assert_eq!(&raw[..payload.len()], &payload[..]);
    assert_eq!(raw[payload.len()..n], crc32(&payload).to_le_bytes());
}

#[test]
fn crc_is_the_standard_crc32() {
    // The CRC-32/ISO-HDLC check value.
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
}

#[test]
fn payload_limit_is_exact_and_the_worst_case_frame_decodes() {
    let big = Biggest {
        a: [u64::MAX; 25],
        b: [0xFF; 6],
    };
    let f = frame_of(&big);
    assert_eq!(
        f.len(),
        MAX_FRAME_LEN,
        "no-zero 256 B payload is the longest frame"
    );
    let mut dec = FrameDecoder::new();
    assert_eq!(decode_all::<Biggest>(&mut dec, &f), [Ok(big)]);
    assert_eq!(dec.peak_len(), MAX_ENCODED_LEN);

    let too_big = TooBig {
        a: [u64::MAX; 25],
        b: [0xFF; 7],
    };
    let mut out = [0u8; 1024];
    assert_eq!(
        encode(&too_big, &mut out),
        Err(EncodeError::PayloadTooLarge)
    );
}

#[test]
fn small_output_buffer_is_an_error() {
    let mut out = [0u8; 34];
    assert_eq!(
        encode(&command(300, 1234), &mut out),
        Err(EncodeError::OutputTooSmall)
    );
    let mut out = [0u8; 35];
    assert_eq!(encode(&command(300, 1234), &mut out), Ok(35));
}

#[test]
fn empty_frames_are_ignored_and_errors_are_counted_by_kind() {
    let mut dec = FrameDecoder::new();
    assert!(decode_all::<ExampleToDevice>(&mut dec, &[0, 0, 0]).is_empty());
    assert_eq!(dec.stats().errors(), 0);

    // COBS code byte pointing past the end.
    assert_eq!(
        decode_all::<ExampleToDevice>(&mut dec, &[0x09, 1, 2, 0]),
        [Err(FrameError::Cobs)]
    );
    // Decodes to 3 bytes: shorter than a CRC.
    assert_eq!(
        decode_all::<ExampleToDevice>(&mut dec, &[0x04, 1, 2, 3, 0]),
        [Err(FrameError::TooShort)]
    );
    // Valid CRC, but variant 9 does not exist.
    let mut bad = [9u8, 0, 0, 0, 0];
    let c = crc32(&bad[..1]).to_le_bytes();
    bad[1..].copy_from_slice(&c);
    let mut enc = [0u8; 16];
    let n = cobs::encode(&bad, &mut enc);
    enc[n] = 0;
    assert_eq!(
        decode_all::<ExampleToDevice>(&mut dec, &enc[..=n]),
        [Err(FrameError::Parse)]
    );
    // Trailing bytes after a valid message are a parse error too.
    let two = frame_of(&(7u8, 8u8));
    assert_eq!(decode_all::<u8>(&mut dec, &two), [Err(FrameError::Parse)]);
    // Oversized: discarded up to the delimiter, counted once.
    let mut long = std::vec![0x55u8; 1000];
    long.push(0);
    assert_eq!(
        decode_all::<ExampleToDevice>(&mut dec, &long),
        [Err(FrameError::Oversized)]
    );
    // CRC.
    let mut f = frame_of(&command(1, 1));
    f[10] ^= 0x10;
    assert_eq!(
        decode_all::<ExampleToDevice>(&mut dec, &f),
        [Err(FrameError::Crc)]
    );

    let s = dec.stats();
    assert_eq!(
        (
            s.cobs_errors,
            s.too_short,
            s.parse_errors,
            s.oversized,
            s.crc_errors,
            s.frames
        ),
        (1, 1, 2, 1, 1, 0)
    );
    assert_eq!(s.errors(), 6);
    assert!(dec.peak_len() <= MAX_ENCODED_LEN);
}

#[test]
fn every_single_bit_flip_is_detected_and_the_next_frame_survives() {
    let good = frame_of(&command(7, 42));
    let next = frame_of(&command(8, 43));
    for bit in 0..good.len() * 8 {
        let mut f = good.clone();
        f[bit / 8] ^= 1 << (bit % 8);
        let mut dec = FrameDecoder::new();
        let mut stream = f.clone();
        stream.extend_from_slice(&next);
        let out = decode_all::<ExampleToDevice>(&mut dec, &stream);
        // Flipping the delimiter merges the two frames into one bad frame; otherwise the
        // damaged frame is rejected (possibly split in two by a new 0x00) and the next
        // frame decodes.
        let oks: Vec<_> = out.iter().filter_map(|r| r.as_ref().ok()).collect();
        if bit / 8 == good.len() - 1 {
            assert!(oks.is_empty(), "bit {bit}");
        } else {
            assert_eq!(oks, [&command(8, 43)], "bit {bit}");
        }
        assert!(
            out.iter().any(Result::is_err),
            "bit {bit}: corruption not detected"
        );
    }
}

#[test]
fn truncated_duplicated_and_reordered_frames() {
    let a = frame_of(&command(1, 1));
    let b = frame_of(&command(2, 2));
    let c = frame_of(&command(3, 3));
    // Truncated with its delimiter kept (bytes lost in the middle): one error.
    for cut in 1..a.len() - 1 {
        let mut s = a[..cut].to_vec();
        s.push(0);
        s.extend_from_slice(&b);
        let mut dec = FrameDecoder::new();
        let out = decode_all::<ExampleToDevice>(&mut dec, &s);
        assert_eq!(out.len(), 2, "cut {cut}");
        assert!(out[0].is_err(), "cut {cut}");
        assert_eq!(out[1], Ok(command(2, 2)));
    }
    // Truncated without its delimiter: merges with the next frame, the one after decodes.
    for cut in 1..a.len() - 1 {
        let mut s = a[..cut].to_vec();
        s.extend_from_slice(&b);
        s.extend_from_slice(&c);
        let mut dec = FrameDecoder::new();
        let out = decode_all::<ExampleToDevice>(&mut dec, &s);
        assert_eq!(out.len(), 2, "cut {cut}");
        assert!(out[0].is_err());
        assert_eq!(out[1], Ok(command(3, 3)));
    }
    // Duplicated and reordered frames decode as they come (the channels deal with them).
    let mut s = b.clone();
    s.extend_from_slice(&a);
    s.extend_from_slice(&a);
    let mut dec = FrameDecoder::new();
    assert_eq!(
        decode_all::<ExampleToDevice>(&mut dec, &s),
        [Ok(command(2, 2)), Ok(command(1, 1)), Ok(command(1, 1))]
    );
}

fn arb_command() -> impl Strategy<Value = ExampleToDevice> {
    (any::<u16>(), any::<u32>(), any::<[f32; 3]>(), any::<f32>()).prop_map(
        |(seq, line, end_mm, feed)| ToDevice::Command {
            seq: Seq(seq),
            cmd: ExampleCommand {
                line,
                end_mm,
                feed_mm_s: feed,
                ..EXAMPLE_COMMAND
            },
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_never_panic_and_stay_bounded(
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..400), 0..8)
    ) {
        let mut dec = FrameDecoder::new();
        let mut total = 0u64;
        for c in &chunks {
            total += c.len() as u64;
            for r in dec.frames::<ExampleToDevice>(c) {
                let _ = r;
            }
            prop_assert!(dec.pending_len() <= MAX_ENCODED_LEN);
        }
        prop_assert_eq!(dec.stats().bytes, total);
        prop_assert!(dec.peak_len() <= MAX_ENCODED_LEN);
        // Whatever came before, a delimiter and a valid frame resynchronise.
        let mut tail = std::vec![0u8];
        tail.extend_from_slice(&EXAMPLE_COMMAND_FRAME);
        let out: Vec<_> = dec.frames::<ExampleToDevice>(&tail).collect();
        prop_assert_eq!(out.last(), Some(&Ok(command(300, 1234))));
    }

    #[test]
    fn valid_frames_decode_identically_for_any_split(
        msgs in proptest::collection::vec(arb_command(), 1..20),
        cuts in proptest::collection::vec(any::<prop::sample::Index>(), 0..30),
    ) {
        let mut stream = Vec::new();
        for m in &msgs {
            stream.extend_from_slice(&frame_of(m));
        }
        let mut points: Vec<usize> = cuts.iter().map(|i| i.index(stream.len() + 1)).collect();
        points.push(0);
        points.push(stream.len());
        points.sort_unstable();
        let mut dec = FrameDecoder::new();
        let mut out = Vec::new();
        for w in points.windows(2) {
            for r in dec.frames::<ExampleToDevice>(&stream[w[0]..w[1]]) {
                out.push(r.unwrap());
            }
        }
        // Bit-exact: compare encodings (f32 NaN payloads included).
        prop_assert_eq!(out.len(), msgs.len());
        for (a, b) in out.iter().zip(&msgs) {
            prop_assert_eq!(frame_of(a), frame_of(b));
        }
        prop_assert_eq!(dec.stats().frames as usize, msgs.len());
        prop_assert_eq!(dec.stats().errors(), 0);
    }

    #[test]
    fn random_corruption_never_yields_a_wrong_message(
        msgs in proptest::collection::vec(arb_command(), 1..10),
        flips in proptest::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 1..6),
    ) {
        let mut stream = Vec::new();
        for m in &msgs {
            stream.extend_from_slice(&frame_of(m));
        }
        for (i, x) in &flips {
            let k = i.index(stream.len());
            stream[k] ^= x;
        }
        let expected: Vec<Vec<u8>> = msgs.iter().map(frame_of).collect();
        let mut dec = FrameDecoder::new();
        for m in dec.frames::<ExampleToDevice>(&stream).flatten() {
            // A message that passes the CRC is one that was sent (CRC-32 misses a random
            // corruption with probability 2^-32).
            prop_assert!(expected.contains(&frame_of(&m)));
        }
    }
}

/// The frame decoder's own COBS decoding (no panic path) gives the crate's result for
/// every input: all buffers of up to 3 bytes over an alphabet with the interesting code
/// bytes, and pseudo-random ones up to 300 bytes (codes past the end, 0xFF runs, 0x00).
#[test]
fn own_cobs_decode_matches_the_crate() {
    fn both(input: &[u8]) {
        let mut ours = input.to_vec();
        let mut theirs = input.to_vec();
        let a = cobs_decode_in_place(&mut ours);
        let b = cobs::decode_in_place(&mut theirs).ok();
        assert_eq!(a, b, "input {input:02x?}");
        if let Some(n) = a {
            assert_eq!(ours[..n], theirs[..n], "input {input:02x?}");
        }
    }
    let alphabet = [0x00, 0x01, 0x02, 0x03, 0x05, 0x7F, 0xFE, 0xFF];
    both(&[]);
    for &a in &alphabet {
        both(&[a]);
        for &b in &alphabet {
            both(&[a, b]);
            for &c in &alphabet {
                both(&[a, b, c]);
            }
        }
    }
    let mut x: u32 = 0x1234_5678;
    for len in 1..300 {
        for _ in 0..20 {
            let buf: Vec<u8> = (0..len)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    // mostly small codes, some long runs and delimiters
                    match x % 8 {
                        0 => 0xFF,
                        1 => 0,
                        _ => (x >> 8) as u8 % 12,
                    }
                })
                .collect();
            both(&buf);
        }
    }
    // real frames round-trip
    let mut enc = [0u8; 300];
    let raw: Vec<u8> = (0..=255).chain(0..40).map(|i| i as u8).collect();
    let n = cobs::encode(&raw, &mut enc);
    both(&enc[..n]);
}
