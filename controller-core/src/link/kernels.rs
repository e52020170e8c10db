//! Fixed-input link kernels: decode one frame, encode one telemetry frame.
//!
//! Plain functions on fixed inputs so that `cargo insns` can count their instructions on
//! the Cortex-M4 and the host benchmark (`cargo run --release -p controller-core --example
//! link_bench`) can time them. The example message types stand in for the supervisor's
//! message set with realistic sizes: a planner segment of ~30 B and a telemetry sample of
//! 12 `f32` values.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::envelope::{ToDevice, ToHost};
use super::frame::{encode, Feed, FrameDecoder, MAX_FRAME_LEN};
use super::seq::Seq;

/// A command of typical size: one 3-axis line segment for the planner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct ExampleCommand {
    /// Program line number.
    pub line: u32,
    /// End point (mm).
    pub end_mm: [f32; 3],
    /// Feed rate (mm/s).
    pub feed_mm_s: f32,
    /// Acceleration limit (mm/s²).
    pub accel_mm_s2: f32,
    /// Corner blend tolerance (mm).
    pub blend_mm: f32,
}

/// A telemetry sample of typical size: period stamp and 12 `f32` channels (per axis:
/// position, velocity, following error, output).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct ExampleTelemetry {
    /// Device time stamp in control periods.
    pub period: u32,
    /// The channels.
    pub values: [f32; 12],
}

/// A status reply of typical size.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub struct ExampleStatus {
    /// Supervisor mode.
    pub mode: u8,
    /// Latched fault bits.
    pub faults: u32,
    /// Free command queue slots.
    pub queue_free: u16,
}

/// Frames to the device with the example command.
pub type ExampleToDevice = ToDevice<ExampleCommand>;
/// Frames to the host with the example telemetry and status.
pub type ExampleToHost = ToHost<ExampleTelemetry, ExampleStatus>;

/// The fixed command of the decode kernel.
pub const EXAMPLE_COMMAND: ExampleCommand = ExampleCommand {
    line: 1234,
    end_mm: [123.456, -78.9, 12.5],
    feed_mm_s: 50.0,
    accel_mm_s2: 2000.0,
    blend_mm: 0.01,
};

/// The fixed sample of the telemetry kernel.
pub const EXAMPLE_TELEMETRY: ExampleTelemetry = ExampleTelemetry {
    period: 1_234_567,
    values: [
        123.456, 49.9, 0.0012, 0.31, -78.9, -12.5, -0.0008, -0.12, 12.5, 0.0, 0.0001, 0.05,
    ],
};

/// `ToDevice::Command { seq: 300, cmd: EXAMPLE_COMMAND }` as a complete frame (35 bytes):
/// the decode kernel's input, and a wire-format regression check (a unit test re-encodes it).
pub const EXAMPLE_COMMAND_FRAME: [u8; 35] = [
    0x0E, 0x02, 0xAC, 0x02, 0xD2, 0x09, 0x79, 0xE9, 0xF6, 0x42, 0xCD, 0xCC, 0x9D, 0xC2, 0x01, 0x03,
    0x48, 0x41, 0x01, 0x03, 0x48, 0x42, 0x01, 0x0B, 0xFA, 0x44, 0x0A, 0xD7, 0x23, 0x3C, 0xD1, 0x84,
    0xF2, 0x6D, 0x00,
];

/// Decode kernel: feed one complete frame to `decoder` and parse it as an
/// [`ExampleToDevice`]. `None` for anything but one valid frame.
pub fn decode_one_frame(decoder: &mut FrameDecoder, frame: &[u8]) -> Option<ExampleToDevice> {
    match decoder.feed::<ExampleToDevice>(frame) {
        Feed::Frame {
            result: Ok(msg), ..
        } => Some(msg),
        _ => None,
    }
}

/// Encode kernel: [`EXAMPLE_TELEMETRY`] as telemetry frame `seq` into `out`; returns the
/// frame length (0 if it did not fit, which a unit test rules out).
pub fn encode_one_telemetry_frame(seq: Seq, out: &mut [u8; MAX_FRAME_LEN]) -> usize {
    let frame: ExampleToHost = ToHost::Telemetry {
        seq,
        sample: EXAMPLE_TELEMETRY,
    };
    encode(&frame, out).unwrap_or(0)
}
