//! Host link kernels on the machine's real message set (controller-core
//! `machine::messages`), what the firmware's link task does per frame:
//!
//! - `link_decode_segment`: one complete command frame carrying a planner segment
//!   (`ToDevice::Command { Request::Segment(line) }`), fed to the frame decoder and parsed;
//! - `link_encode_telemetry`: one telemetry sample encoded as a frame;
//! - `link_encode_status`: one status reply encoded as a frame (a refusal text included).

use controller_core::link::{encode, Feed, FrameDecoder, Seq, ToDevice, ToHost, MAX_FRAME_LEN};
use controller_core::machine::messages::{MachineState, Outcome, Request, Status, Telemetry};
use controller_core::motion::planner::Segment;

/// A decoder and one complete segment frame.
pub struct LinkDecode {
    decoder: FrameDecoder,
    frame: [u8; MAX_FRAME_LEN],
    len: usize,
}

impl LinkDecode {
    pub fn setup() -> Option<Self> {
        let msg: ToDevice<Request> = ToDevice::Command {
            seq: Seq(300),
            cmd: Request::Segment(Segment::line([123.456, -78.9, 12.5], 50.0, 1234)),
        };
        let mut frame = [0u8; MAX_FRAME_LEN];
        let len = encode(&msg, &mut frame).ok()?;
        let mut s = Self {
            decoder: FrameDecoder::new(),
            frame,
            len,
        };
        (s.step() == 1).then_some(s)
    }

    /// Decode the frame; 1 when it parsed.
    #[inline(never)]
    pub fn step(&mut self) -> u32 {
        match self
            .decoder
            .feed::<ToDevice<Request>>(self.frame.get(..self.len).unwrap_or(&[]))
        {
            Feed::Frame { result: Ok(_), .. } => 1,
            _ => 0,
        }
    }
}

/// A telemetry sample in motion (every field non-trivial).
const SAMPLE: Telemetry = Telemetry {
    period: 1_234_567,
    state: MachineState::Run { held: false },
    pos_mm: [123.456, -78.9, 12.5],
    reference_mm: [123.457, -78.901, 12.5],
    ref_vel_mm_s: [49.9, -2.5, 0.0],
    ref_acc_mm_s2: [12.0, -1500.0, 0.0],
    contour_mm: 0.0012,
    feed_ratio: 0.998,
    tag: 4321,
    signals: heapless::Vec::new(),
};

/// The encoder's output buffer and sequence number.
pub struct LinkEncode {
    out: [u8; MAX_FRAME_LEN],
    seq: u16,
    status: Status,
}

impl LinkEncode {
    pub fn setup() -> Option<Self> {
        let mut refusal = heapless::String::new();
        refusal
            .push_str("this change needs the outputs off: disarm first")
            .ok()?;
        let status = Status {
            state: MachineState::Run { held: false },
            period: 1_234_567,
            executed: 812,
            last: Outcome::Refused(refusal),
            fault_bits: (0, [0; 3]),
            first_fault: None,
            fault_history: heapless::Vec::new(),
            homed: 0b111,
            model_missing: 0,
            comp: 0,
            pos_mm: SAMPLE.pos_mm,
            vel_mm_s: SAMPLE.ref_vel_mm_s,
            planner_free: 3,
            queued: 12,
            program_done: false,
            program: controller_core::machine::messages::ProgramProgress {
                end: controller_core::machine::messages::ProgramEnd::Running,
                tag: 4_321,
            },
            progress: 0.0,
            identify: None,
            scope: controller_core::machine::scope::ScopeState::Off,
        };
        let mut s = Self {
            out: [0; MAX_FRAME_LEN],
            seq: 0,
            status,
        };
        (s.telemetry() > 0 && s.status() > 0).then_some(s)
    }

    /// One telemetry frame; its length.
    #[inline(never)]
    pub fn telemetry(&mut self) -> usize {
        self.seq = self.seq.wrapping_add(1);
        let f: ToHost<Telemetry, Status> = ToHost::Telemetry {
            seq: Seq(self.seq),
            sample: SAMPLE,
        };
        encode(&f, &mut self.out).unwrap_or(0)
    }

    /// One status frame; its length.
    #[inline(never)]
    pub fn status(&mut self) -> usize {
        self.seq = self.seq.wrapping_add(1);
        let f: ToHost<Telemetry, Status> = ToHost::Status {
            id: Seq(self.seq),
            status: self.status.clone(),
        };
        encode(&f, &mut self.out).unwrap_or(0)
    }
}
