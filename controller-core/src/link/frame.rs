//! Framing: how one message becomes bytes on the wire and back.
//!
//! ```text
//! frame = COBS( postcard(message) ++ CRC-32(postcard(message)) as 4 bytes LE ) ++ 0x00
//! ```
//!
//! - postcard gives a compact, schema-less binary encoding (varint integers).
//! - CRC-32 (ISO-HDLC polynomial 0x04C11DB7, the Ethernet/zlib one) detects all burst
//!   errors up to 32 bits and any odd number of bit errors; Klipper uses CRC-16 on
//!   64-byte frames, our frames are up to 4 times longer.
//! - COBS removes every 0x00 from the frame, so 0x00 only ever marks a frame end: a
//!   receiver that starts mid-stream or loses bytes resynchronises at the next 0x00. COBS
//!   costs 1 byte per started 254 bytes.
//!
//! Nothing but frames is ever on the wire (no text console mixed in: ODrive users paid for
//! that). A sender may put an extra 0x00 before a frame (e.g. after opening the port) to
//! flush whatever a receiver had half-collected; empty frames are ignored.
//!
//! [`FrameDecoder`] is a streaming decoder with a fixed buffer: it takes byte slices of any
//! length split anywhere, and yields one result per 0x00-terminated frame: the message, or
//! a [`FrameError`] that it also counts in [`DecodeStats`]. It never allocates and never
//! panics whatever the input (property tests and the `link_fuzz` example check this).

use core::marker::PhantomData;

use serde::de::DeserializeOwned;
use serde::Serialize;

/// Frame delimiter: the only byte value COBS never produces inside a frame.
pub const DELIMITER: u8 = 0x00;

/// Largest postcard-encoded message, in bytes. 256 B holds any command the planner sends
/// (a 3-axis segment is ~30 B) and a telemetry frame of ~60 `f32` values; it keeps a
/// worst-case frame at 2.9 ms on the wire at 921,600 baud, so a real-time request waits
/// at most that long behind a frame already being sent.
pub const MAX_PAYLOAD_LEN: usize = 256;

/// Length of the CRC-32 that follows the payload inside the COBS block.
pub const CRC_LEN: usize = 4;

/// Worst-case COBS length for `n` input bytes: one code byte per started 254-byte block,
/// plus one (an upper bound for every COBS encoder variant).
#[must_use]
pub const fn cobs_max_len(n: usize) -> usize {
    n + n / 254 + 1
}

/// Largest COBS-encoded frame without its delimiter: the decoder's buffer size. Anything
/// longer before a 0x00 is discarded as [`FrameError::Oversized`].
pub const MAX_ENCODED_LEN: usize = cobs_max_len(MAX_PAYLOAD_LEN + CRC_LEN);

/// Largest frame on the wire, delimiter included: size a transmit buffer with this.
pub const MAX_FRAME_LEN: usize = MAX_ENCODED_LEN + 1;

/// The CRC-32 used on every frame (ISO-HDLC: reflected, init and xor-out 0xFFFFFFFF).
/// 256-entry table, 1 KiB of flash on the MCU.
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32 of `bytes` as used in frames.
#[must_use]
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// Why a message could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeError {
    /// The postcard encoding is longer than [`MAX_PAYLOAD_LEN`].
    PayloadTooLarge,
    /// postcard refused the value (a serde impl failed; not expected for derived types).
    Serialize,
    /// The caller's output buffer is too small: use [`MAX_FRAME_LEN`] bytes.
    OutputTooSmall,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::PayloadTooLarge => write!(
                f,
                "link encode: message longer than MAX_PAYLOAD_LEN = {MAX_PAYLOAD_LEN} bytes"
            ),
            Self::Serialize => write!(f, "link encode: postcard could not serialize the message"),
            Self::OutputTooSmall => write!(
                f,
                "link encode: output buffer too small (MAX_FRAME_LEN = {MAX_FRAME_LEN} bytes)"
            ),
        }
    }
}

/// Encode `msg` as one complete frame (delimiter included) into `out`; returns the number
/// of bytes written. `out` of [`MAX_FRAME_LEN`] bytes always suffices.
///
/// # Errors
/// [`EncodeError`] when the message is too long or `out` too small; nothing valid is
/// written then.
pub fn encode<T: Serialize + ?Sized>(msg: &T, out: &mut [u8]) -> Result<usize, EncodeError> {
    // postcard bytes and CRC are built on the stack (260 B), then COBS-encoded into `out`:
    // a copy, but it makes the payload limit exact whatever the COBS overhead.
    let mut raw = [0u8; MAX_PAYLOAD_LEN + CRC_LEN];
    let payload_len = {
        let payload_buf = raw
            .get_mut(..MAX_PAYLOAD_LEN)
            .ok_or(EncodeError::PayloadTooLarge)?;
        match postcard::to_slice(msg, payload_buf) {
            Ok(used) => used.len(),
            Err(postcard::Error::SerializeBufferFull) => return Err(EncodeError::PayloadTooLarge),
            Err(_) => return Err(EncodeError::Serialize),
        }
    };
    let crc = crc32(raw.get(..payload_len).ok_or(EncodeError::Serialize)?);
    let total = payload_len + CRC_LEN;
    raw.get_mut(payload_len..total)
        .ok_or(EncodeError::Serialize)?
        .copy_from_slice(&crc.to_le_bytes());
    let src = raw.get(..total).ok_or(EncodeError::Serialize)?;
    let n = cobs::try_encode(src, out).map_err(|_| EncodeError::OutputTooSmall)?;
    *out.get_mut(n).ok_or(EncodeError::OutputTooSmall)? = DELIMITER;
    Ok(n + 1)
}

/// COBS-decode `buf` in place: the decoded length, or `None` if it is not valid COBS.
/// The algorithm of `cobs::decode_in_place` (0.3), result for result (a code byte that
/// points past the end, or an empty frame, is invalid; decoding stops at a 0x00), but
/// with checked reads and writes: the crate's indexing kept two bounds-check panics in
/// the link task that the optimiser could not remove (`dst <= src < src_end <= len`
/// holds, so the checks never fail).
fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    if buf.is_empty() {
        return None;
    }
    let src_end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let (mut src, mut dst) = (0usize, 0usize);
    while src < src_end {
        let code = usize::from(*buf.get(src)?);
        if src + code > src_end && code != 1 {
            return None;
        }
        src += 1;
        for _ in 1..code {
            let b = *buf.get(src)?;
            *buf.get_mut(dst)? = b;
            src += 1;
            dst += 1;
        }
        if code != 0xFF && src < src_end {
            *buf.get_mut(dst)? = 0;
            dst += 1;
        }
    }
    Some(dst)
}

/// Why a received frame was dropped. Every case is also counted in [`DecodeStats`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// More than [`MAX_ENCODED_LEN`] bytes before a delimiter; discarded up to the 0x00.
    Oversized,
    /// Not valid COBS (a code byte points past the frame end).
    Cobs,
    /// Decoded frame shorter than a CRC plus one payload byte.
    TooShort,
    /// CRC-32 mismatch: bytes were corrupted on the wire.
    Crc,
    /// CRC good but the payload is not a valid message of the expected type (wrong schema
    /// or a sender bug), or has trailing bytes.
    Parse,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let what = match self {
            Self::Oversized => "frame longer than MAX_ENCODED_LEN before a 0x00 delimiter",
            Self::Cobs => "invalid COBS encoding",
            Self::TooShort => "frame shorter than CRC plus one payload byte",
            Self::Crc => "CRC-32 mismatch",
            Self::Parse => "payload is not a valid message (schema mismatch or trailing bytes)",
        };
        write!(f, "link frame dropped: {what}")
    }
}

/// Counters of everything the decoder saw. Saturating (never wrap).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecodeStats {
    /// Bytes fed in.
    pub bytes: u64,
    /// Frames decoded into a message.
    pub frames: u32,
    /// [`FrameError::Oversized`] count.
    pub oversized: u32,
    /// [`FrameError::Cobs`] count.
    pub cobs_errors: u32,
    /// [`FrameError::TooShort`] count.
    pub too_short: u32,
    /// [`FrameError::Crc`] count.
    pub crc_errors: u32,
    /// [`FrameError::Parse`] count.
    pub parse_errors: u32,
}

impl DecodeStats {
    /// All dropped frames.
    #[must_use]
    pub const fn errors(&self) -> u32 {
        self.oversized
            .saturating_add(self.cobs_errors)
            .saturating_add(self.too_short)
            .saturating_add(self.crc_errors)
            .saturating_add(self.parse_errors)
    }

    fn count(&mut self, e: FrameError) {
        let c = match e {
            FrameError::Oversized => &mut self.oversized,
            FrameError::Cobs => &mut self.cobs_errors,
            FrameError::TooShort => &mut self.too_short,
            FrameError::Crc => &mut self.crc_errors,
            FrameError::Parse => &mut self.parse_errors,
        };
        *c = c.saturating_add(1);
    }
}

/// Result of feeding bytes to [`FrameDecoder::feed`].
#[derive(Debug, PartialEq)]
pub enum Feed<'b, T> {
    /// All input consumed without completing a frame: feed more.
    NeedMore,
    /// A delimiter completed a frame; `rest` is the input after it, feed it next.
    Frame {
        /// The message or why the frame was dropped.
        result: Result<T, FrameError>,
        /// Unconsumed input.
        rest: &'b [u8],
    },
}

/// Streaming frame decoder with a fixed buffer of [`MAX_ENCODED_LEN`] bytes.
#[derive(Clone, Debug)]
pub struct FrameDecoder {
    buf: [u8; MAX_ENCODED_LEN],
    len: usize,
    /// Set when the current frame overflowed `buf`: drop bytes until the next delimiter.
    discarding: bool,
    peak_len: usize,
    stats: DecodeStats,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_ENCODED_LEN],
            len: 0,
            discarding: false,
            peak_len: 0,
            stats: DecodeStats {
                bytes: 0,
                frames: 0,
                oversized: 0,
                cobs_errors: 0,
                too_short: 0,
                crc_errors: 0,
                parse_errors: 0,
            },
        }
    }

    /// Counters so far.
    #[must_use]
    pub const fn stats(&self) -> DecodeStats {
        self.stats
    }

    /// Most bytes ever held in the buffer (≤ [`MAX_ENCODED_LEN`]).
    #[must_use]
    pub const fn peak_len(&self) -> usize {
        self.peak_len
    }

    /// Bytes of the frame collected so far.
    #[must_use]
    pub const fn pending_len(&self) -> usize {
        self.len
    }

    /// Drop a half-collected frame (e.g. after the port was reopened). Counters stay.
    pub fn reset(&mut self) {
        self.len = 0;
        self.discarding = false;
    }

    /// Feed bytes; stops after the first completed frame (see [`Feed`]). To handle a whole
    /// slice, call again with `rest`, or use [`FrameDecoder::frames`].
    pub fn feed<'b, T: DeserializeOwned>(&mut self, input: &'b [u8]) -> Feed<'b, T> {
        match self.feed_raw(input) {
            RawFeed::NeedMore => Feed::NeedMore,
            RawFeed::Frame { payload_len, rest } => {
                let result = match payload_len {
                    Ok(n) => {
                        let parsed = self.buf.get(..n).map(postcard::take_from_bytes::<T>);
                        match parsed {
                            Some(Ok((msg, []))) => {
                                self.stats.frames = self.stats.frames.saturating_add(1);
                                Ok(msg)
                            }
                            _ => {
                                self.stats.count(FrameError::Parse);
                                Err(FrameError::Parse)
                            }
                        }
                    }
                    Err(e) => Err(e),
                };
                Feed::Frame { result, rest }
            }
        }
    }

    /// Iterator over the results of all frames completed by `input`. Bytes after the last
    /// delimiter stay in the decoder for the next call.
    pub fn frames<'d, 'b, T: DeserializeOwned>(&'d mut self, input: &'b [u8]) -> Frames<'d, 'b, T> {
        Frames {
            decoder: self,
            rest: input,
            _msg: PhantomData,
        }
    }

    /// Collect bytes up to the first delimiter; on a delimiter check COBS and CRC and
    /// return the payload length (payload = `buf[..len]`).
    fn feed_raw<'b>(&mut self, input: &'b [u8]) -> RawFeed<'b> {
        let mut rest = input;
        loop {
            let (chunk, after, delimited) = match rest.iter().position(|&b| b == DELIMITER) {
                Some(i) => {
                    let (chunk, tail) = rest.split_at(i);
                    (chunk, tail.get(1..).unwrap_or(&[]), true)
                }
                None => (rest, &[][..], false),
            };
            self.stats.bytes = self
                .stats
                .bytes
                .saturating_add(chunk.len() as u64 + u64::from(delimited));
            self.collect(chunk);
            if !delimited {
                return RawFeed::NeedMore;
            }
            rest = after;
            if self.discarding {
                self.reset();
                self.stats.count(FrameError::Oversized);
                return RawFeed::Frame {
                    payload_len: Err(FrameError::Oversized),
                    rest,
                };
            }
            if self.len == 0 {
                // Empty frame (leading or repeated delimiter): a flush, not an error.
                continue;
            }
            let payload_len = self.check();
            if let Err(e) = payload_len {
                self.stats.count(e);
            }
            self.len = 0;
            return RawFeed::Frame { payload_len, rest };
        }
    }

    /// Append non-delimiter bytes to the buffer, switching to discard mode on overflow.
    fn collect(&mut self, chunk: &[u8]) {
        if self.discarding || chunk.is_empty() {
            return;
        }
        let end = self.len.saturating_add(chunk.len());
        match self.buf.get_mut(self.len..end) {
            Some(dst) => {
                // (`copy_from_slice` would keep a length-mismatch panic the optimiser
                // cannot remove: `end` saturates)
                for (d, s) in dst.iter_mut().zip(chunk) {
                    *d = *s;
                }
                self.len = end;
                self.peak_len = self.peak_len.max(end);
            }
            None => {
                self.discarding = true;
                self.len = 0;
            }
        }
    }

    /// COBS-decode the collected frame in place and verify its CRC.
    fn check(&mut self) -> Result<usize, FrameError> {
        let frame = self.buf.get_mut(..self.len).ok_or(FrameError::Oversized)?;
        let n = cobs_decode_in_place(frame).ok_or(FrameError::Cobs)?;
        let payload_len = n.checked_sub(CRC_LEN).ok_or(FrameError::TooShort)?;
        if payload_len == 0 {
            return Err(FrameError::TooShort);
        }
        let payload = self.buf.get(..payload_len).ok_or(FrameError::TooShort)?;
        let received: [u8; CRC_LEN] = self
            .buf
            .get(payload_len..n)
            .and_then(|b| b.try_into().ok())
            .ok_or(FrameError::TooShort)?;
        if crc32(payload) == u32::from_le_bytes(received) {
            Ok(payload_len)
        } else {
            Err(FrameError::Crc)
        }
    }
}

enum RawFeed<'b> {
    NeedMore,
    Frame {
        payload_len: Result<usize, FrameError>,
        rest: &'b [u8],
    },
}

/// Iterator returned by [`FrameDecoder::frames`].
pub struct Frames<'d, 'b, T> {
    decoder: &'d mut FrameDecoder,
    rest: &'b [u8],
    _msg: PhantomData<fn() -> T>,
}

impl<T: DeserializeOwned> Iterator for Frames<'_, '_, T> {
    type Item = Result<T, FrameError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() {
            return None;
        }
        match self.decoder.feed::<T>(self.rest) {
            Feed::NeedMore => {
                self.rest = &[];
                None
            }
            Feed::Frame { result, rest } => {
                self.rest = rest;
                Some(result)
            }
        }
    }
}

#[cfg(test)]
mod tests;
