//! The application messages of the host link: what the host asks of the machine
//! ([`Request`], on the reliable command channel), what the machine answers to a status
//! request ([`Status`]) and what it streams ([`Telemetry`]). One definition for the
//! firmware and every host tool; [`SCHEMA_HASH`] (from these types) is checked in the
//! handshake, so a host and a device built from different message sets refuse each other.

use heapless::String;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

use super::scope::{ScopeChunk, ScopeConfig, ScopeState, Signal};
use crate::link::schema_hash;
use crate::motion::planner::Segment;

/// Longest settings key on the wire (the longest key is 36 characters).
pub const KEY_MAX: usize = 48;
/// Longest settings value text on the wire.
pub const VALUE_MAX: usize = 32;
/// Longest refusal or error text on the wire.
pub const TEXT_MAX: usize = 96;
/// Chosen signals a telemetry sample carries at most (each adds 4 bytes to its frame).
pub const TELEMETRY_SIGNALS: usize = 4;
/// Compensation points a [`Request::CompPoints`] carries at most (8 × 12 bytes: the
/// request stays within the size of the largest other one, so the control interrupt's
/// copies of every queued request do not grow; a 256-point table is 32 requests).
pub const COMP_CHUNK: usize = 8;
/// Compensation points a read-back chunk ([`CompChunk`]) carries at most (the largest
/// status must fit a 256-byte frame: 6 points fit where a refusal's text does).
pub const COMP_READ_CHUNK: usize = 6;
/// Frequency-response points a read-out chunk ([`ResponseChunk`]) carries at most (6 × 12
/// bytes, as a compensation chunk: the largest status must fit a 256-byte frame).
pub const RESPONSE_READ_CHUNK: usize = 6;

/// A request on the reliable command channel, executed in order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum Request {
    /// Outputs on, holding where the machine stands (never starts motion).
    Arm,
    /// Outputs off (a controlled stop first when moving).
    Disarm,
    /// Clear the latched faults whose causes are gone.
    Reset,
    /// Run the homing sequence.
    Home,
    /// Jog axis 0/1/2 at `vel_mm_s` (0 stops); stops by itself when jog requests stop
    /// arriving (the jog timeout).
    Jog { axis: u8, vel_mm_s: f32 },
    /// Start a program: the servo follows the planner from where it holds.
    Run,
    /// One segment of the running program (queued in the planner when it has room).
    Segment(Segment),
    /// The program has no more segments: when the planner is idle, back to Idle.
    EndProgram,
    /// Feed override, 0.01-2.0.
    FeedOverride(f32),
    /// Read one setting (dotted key); the value is in [`Status::last`].
    SettingGet { key: String<KEY_MAX> },
    /// Change one setting (value as text, as `gantry settings set` reads it); applied at
    /// a period boundary, and only with the outputs off where a change could jump them.
    SettingSet {
        key: String<KEY_MAX>,
        value: String<VALUE_MAX>,
    },
    /// Back to the factory settings (outputs off).
    SettingsDefaults,
    /// Store the settings the machine runs in flash, for the next boot. Only with the
    /// outputs off (a flash write stalls the control loop); nothing arms until it is done.
    SettingsSave,
    /// Identify axis 0/1/2: homed, or within the user-confirmed window `[min, max]` in
    /// machine mm (an axis that cannot be homed yet: no model to arm with).
    Identify {
        axis: u8,
        window_mm: Option<[f32; 2]>,
    },
    /// Store the last identification's model of the axis in the settings (outputs off).
    AcceptIdentified { axis: u8 },
    /// Measure axis 0/1/2's frequency response from effort to encoder (a stepped sine,
    /// `servo::Command::MeasureResponse`: the identification's rules, window and torque
    /// cap); the state is [`MachineState::Identify`] while it runs, [`Status::progress`]
    /// its progress. The points are read with [`Request::ResponseRead`].
    MeasureResponse {
        axis: u8,
        window_mm: Option<[f32; 2]>,
    },
    /// Read the last frequency response's points from point `first` on (in the order they
    /// were measured): the chunk is in [`Status::last`] ([`Outcome::Response`]).
    ResponseRead { first: u8 },
    /// Telemetry: one sample every `every_periods` control periods (0: off), carrying
    /// the chosen `signals` besides its fixed fields ([`Telemetry::signals`]).
    Subscribe {
        every_periods: u32,
        signals: heapless::Vec<Signal, TELEMETRY_SIGNALS>,
    },
    /// Arm a scope capture (a running one is dropped); its progress is in
    /// [`Status::scope`].
    ScopeArm(ScopeConfig),
    /// Read a complete capture from value `offset`: the chunk is in [`Status::last`]
    /// ([`Outcome::Scope`]).
    ScopeRead { offset: u16 },
    /// Open a settings transaction (an open one is dropped): the [`Request::SettingSet`]s
    /// and [`Request::SettingsDefaults`] until [`Request::SettingsCommit`] change a
    /// candidate tree (each value type- and range-checked as it comes), not the machine.
    /// A new session or a lost link drops it.
    SettingsBegin,
    /// Validate the transaction's tree whole (the servo's own checks) and swap it in at a
    /// period boundary, all of it or, refused, nothing (the refusal names the key and
    /// why). Refused when a change of the transaction was refused.
    SettingsCommit,
    /// Drop the open transaction (nothing changes).
    SettingsAbort,
    /// Erase the settings store and write the settings the machine runs into it (like
    /// [`Request::SettingsSave`]: only with the outputs off, nothing arms until done).
    SettingsRepair,
    /// Start entering axis 0/1/2's backlash and lead-screw compensation
    /// (`motion::compensation`, LinuxCNC's `COMP_FILE` and `BACKLASH`): a table of `points`
    /// points (0: backlash alone, or nothing: clears the axis), the backlash and the
    /// applied offset's rate and acceleration limits. Drops a transfer under way. The
    /// points follow in [`Request::CompPoints`], then [`Request::CompCommit`].
    CompBegin {
        axis: u8,
        points: u16,
        backlash_mm: f32,
        rate_mm_s: f32,
        accel_mm_s2: f32,
    },
    /// The next points of the transfer, the first of them the table's point `first`
    /// (in order, each part validated as it comes; a refused part is not kept).
    CompPoints {
        first: u16,
        points: heapless::Vec<crate::motion::compensation::CompPoint, COMP_CHUNK>,
    },
    /// Put the transferred table in use, once every announced point came: only with the
    /// outputs off (it moves the reference). Kept in RAM until the next boot (the host
    /// loads it each session, as LinuxCNC reads its `COMP_FILE` at start).
    CompCommit,
    /// Read axis 0/1/2's compensation in use from point `first` on: the chunk is in
    /// [`Status::last`] ([`Outcome::Comp`]).
    CompRead { axis: u8, first: u16 },
    /// Measure axis 0/1/2's open loop on its laws (armed, holding: from Idle; a stepped
    /// sine added to the laws' effort while the axis travels back and forth,
    /// `servo::Command::MeasureLoop`: the identification's window and rules); as
    /// [`Request::MeasureResponse`] otherwise: [`MachineState::Identify`] while it runs,
    /// its points, `L(jω)`, read with [`Request::ResponseRead`].
    MeasureLoop {
        axis: u8,
        window_mm: Option<[f32; 2]>,
    },
}

/// A part of an axis' compensation in use, as [`Request::CompRead`] reads it (trims as
/// stored: rounded to 0.1 µm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct CompChunk {
    pub axis: u8,
    /// Points in the whole table.
    pub total: u16,
    /// The table's index of `points[0]`.
    pub first: u16,
    pub backlash_mm: f32,
    pub rate_mm_s: f32,
    pub accel_mm_s2: f32,
    pub points: heapless::Vec<crate::motion::compensation::CompPoint, COMP_READ_CHUNK>,
}

/// How the last executed request ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum Outcome {
    /// Nothing executed yet in this session.
    None,
    /// Done.
    Done,
    /// A setting's value, as text.
    Value(String<VALUE_MAX>),
    /// Not executed: why, and how to fix it.
    Refused(String<TEXT_MAX>),
    /// A chunk of the scope's capture.
    Scope(ScopeChunk),
    /// A chunk of an axis' compensation table.
    Comp(CompChunk),
    /// A chunk of the last frequency response.
    Response(ResponseChunk),
}

impl Outcome {
    /// A refusal with the text `why` (cut at [`TEXT_MAX`] characters; copied, never
    /// formatted: the control interrupt refuses with it).
    pub fn refused(why: &str) -> Self {
        let mut t = String::new();
        for c in why.chars() {
            if t.push(c).is_err() {
                break;
            }
        }
        Self::Refused(t)
    }
}

/// One measured frequency of [`Request::MeasureResponse`]: `H(j 2π freq_hz)` from effort
/// to encoder, mm/(mN·m) (`sysid::frequency::ResponsePoint`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, Schema)]
pub struct ResponsePointMsg {
    pub freq_hz: f32,
    pub re: f32,
    pub im: f32,
}

/// How a frequency-response measurement stands ([`ResponseChunk::state`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum ResponseState {
    /// Every frequency measured.
    Done,
    /// Stopped before the end (a fault, a stop, the window or the torque cap): the points
    /// measured until then.
    Aborted,
}

/// A part of the last frequency response, as [`Request::ResponseRead`] reads it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct ResponseChunk {
    pub axis: u8,
    pub state: ResponseState,
    /// Points measured in all.
    pub total: u8,
    /// The index of `points[0]` (in the order measured).
    pub first: u8,
    pub points: heapless::Vec<ResponsePointMsg, RESPONSE_READ_CHUNK>,
}

/// The machine's supervisor state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum MachineState {
    Disabled,
    Idle,
    Jog,
    Homing,
    /// Running a program (`held`: feed hold in force).
    Run {
        held: bool,
    },
    Identify,
    /// Decelerating to a stop.
    Stopping,
    /// Checking the encoders before a reset completes.
    EncoderCheck,
    Fault,
}

/// An identified model as the link carries it (mN·m, mm, s).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct ModelMsg {
    pub inertia: f32,
    pub viscous: f32,
    pub coulomb_pos_mnm: f32,
    pub coulomb_neg_mnm: f32,
}

/// The last identification's result.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct IdentifyMsg {
    pub axis: u8,
    /// `true` when it finished with a model.
    pub done: bool,
    pub model: Option<ModelMsg>,
    pub nrmse: f32,
    pub r2: f32,
    /// Machine time it took, s.
    pub time_s: f32,
}

/// One fault of the history in a byte (a status frame has room for 8 of them and no
/// more: its worst case must fit the link's 256-byte payload): the kind's code in bits
/// 0-4 (`servo::faults::FaultKind`), the axis in bits 5-6 (0-2, 3 for the system).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub struct FaultCode(pub u8);

impl FaultCode {
    const SYSTEM: u8 = 3;

    pub fn new(kind: crate::servo::faults::FaultKind, axis: Option<crate::axes::Axis>) -> Self {
        let a = axis.map_or(Self::SYSTEM, |a| a.index() as u8);
        Self((kind as u8 & 0x1F) | (a << 5))
    }

    /// The fault's kind, if the code is known.
    pub fn kind(self) -> Option<crate::servo::faults::FaultKind> {
        crate::servo::faults::FaultKind::ALL
            .into_iter()
            .find(|k| *k as u8 == self.0 & 0x1F)
    }

    /// The axis (`None`: a system fault).
    pub fn axis(self) -> Option<crate::axes::Axis> {
        crate::axes::Axis::from_index(usize::from((self.0 >> 5) & 0x03))
    }
}

/// How the latest program ended, or that it is still running. An abort names its cause,
/// so that a host never takes a program stopped by a fault, its own stop or a lost link
/// for one that completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum ProgramEnd {
    /// No program ran since boot.
    None,
    /// A program is running (`Run` executed, the end not reached).
    Running,
    /// Every segment executed after `EndProgram`, and the machine stopped at the end.
    Completed,
    /// A fault latched while it ran (the first fault: kind and axis).
    Fault(FaultCode),
    /// The host's real-time stop.
    HostStop,
    /// The link's watchdog expired (the host went silent).
    LinkLost,
    /// The planner refused one of its segments.
    SegmentRefused,
    /// The servo left its run state without a fault (a disarm).
    Stopped,
}

impl ProgramEnd {
    /// The program stopped before its end.
    pub const fn aborted(self) -> bool {
        !matches!(self, Self::None | Self::Running | Self::Completed)
    }
}

/// Where the machine is in the latest program: how it ended (or that it runs) and the tag
/// of the segment its executor is on (the last one it was on once the program ended).
/// Tags are the host's: it knows which of its segments come before a tag, so it counts
/// the executed segments and their length from what the machine executed, not from what
/// it sent. (No distance along the segment: the largest status must fit a 256-byte
/// payload, and it had 9 bytes to spare.)
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct ProgramProgress {
    pub end: ProgramEnd,
    pub tag: u32,
}

/// Answer to every real-time request.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct Status {
    pub state: MachineState,
    /// Control period number.
    pub period: u32,
    /// Requests executed in this session (the host counts what it sent).
    pub executed: u32,
    /// Outcome of the last executed request.
    pub last: Outcome,
    /// Latched fault bits (system, per axis) and the first fault's name.
    pub fault_bits: (u32, [u32; 3]),
    pub first_fault: Option<String<VALUE_MAX>>,
    /// The last faults, oldest first (kept across resets).
    pub fault_history: heapless::Vec<FaultCode, { crate::servo::faults::FAULT_HISTORY }>,
    /// Homed axes (bit per axis).
    pub homed: u8,
    /// Axes whose model is missing (a model-based law refuses to arm).
    pub model_missing: u8,
    /// Axes with a backlash or lead-screw compensation in use (bit per axis).
    pub comp: u8,
    pub pos_mm: [f32; 3],
    pub vel_mm_s: [f32; 3],
    /// Free slots in the planner's segment queue and requests waiting to be executed.
    pub planner_free: u16,
    pub queued: u16,
    /// No program runs, nothing is queued, and the latest program (if any) completed:
    /// false after an abort (`program.end` says why).
    pub program_done: bool,
    /// The latest program's end and the executor's place in it.
    pub program: ProgramProgress,
    /// Homing / identification progress, 0-1.
    pub progress: f32,
    pub identify: Option<IdentifyMsg>,
    pub scope: ScopeState,
}

/// One telemetry sample (every `decimation` periods).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub struct Telemetry {
    pub period: u32,
    pub state: MachineState,
    pub pos_mm: [f32; 3],
    pub reference_mm: [f32; 3],
    /// The planner's reference velocity and acceleration (zero outside a program).
    pub ref_vel_mm_s: [f32; 3],
    pub ref_acc_mm_s2: [f32; 3],
    pub contour_mm: f32,
    pub feed_ratio: f32,
    /// Tag of the planner segment being executed.
    pub tag: u32,
    /// The values of the signals chosen in [`Request::Subscribe`], in its order.
    pub signals: heapless::Vec<f32, TELEMETRY_SIGNALS>,
}

/// The handshake's schema hash of this message set.
pub const SCHEMA_HASH: u32 = schema_hash::<Request, Telemetry, Status>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::{encode, Seq, ToHost, MAX_FRAME_LEN};
    use crate::servo::faults::{FaultKind, FAULT_HISTORY};

    fn full<const N: usize>() -> String<N> {
        let mut t = String::new();
        while t.push('\u{7f}').is_ok() {}
        t
    }

    /// The largest status the machine can send fits one frame (else it would be dropped
    /// and the host would never hear).
    #[test]
    fn the_largest_status_fits_a_frame() {
        let model = ModelMsg {
            inertia: f32::MAX,
            viscous: f32::MAX,
            coulomb_pos_mnm: f32::MAX,
            coulomb_neg_mnm: f32::MAX,
        };
        let mut fault_history = heapless::Vec::new();
        while fault_history
            .push(FaultCode::new(FaultKind::SettingsCorrupt, None))
            .is_ok()
        {}
        assert_eq!(fault_history.len(), FAULT_HISTORY);
        let status = Status {
            state: MachineState::Run { held: true },
            period: u32::MAX,
            executed: u32::MAX,
            last: Outcome::Refused(full()),
            fault_bits: (u32::MAX, [u32::MAX; 3]),
            first_fault: Some(full()),
            fault_history,
            homed: u8::MAX,
            model_missing: u8::MAX,
            comp: u8::MAX,
            pos_mm: [f32::MAX; 3],
            vel_mm_s: [f32::MAX; 3],
            planner_free: u16::MAX,
            queued: u16::MAX,
            program_done: true,
            program: ProgramProgress {
                end: ProgramEnd::Fault(FaultCode(u8::MAX)),
                tag: u32::MAX,
            },
            progress: f32::MAX,
            identify: Some(IdentifyMsg {
                axis: u8::MAX,
                done: true,
                model: Some(model),
                nrmse: f32::MAX,
                r2: f32::MAX,
                time_s: f32::MAX,
            }),
            scope: ScopeState::Triggered,
        };
        // every read-out chunk at its largest in place of the refusal's text
        let mut points = heapless::Vec::new();
        while points
            .push(ResponsePointMsg {
                freq_hz: f32::MAX,
                re: f32::MAX,
                im: f32::MAX,
            })
            .is_ok()
        {}
        let mut comp = heapless::Vec::new();
        while comp
            .push(crate::motion::compensation::CompPoint {
                nominal_mm: f32::MAX,
                fwd_trim_mm: f32::MAX,
                rev_trim_mm: f32::MAX,
            })
            .is_ok()
        {}
        let lasts = [
            Outcome::Refused(full()),
            Outcome::Response(ResponseChunk {
                axis: u8::MAX,
                state: ResponseState::Aborted,
                total: u8::MAX,
                first: u8::MAX,
                points,
            }),
            Outcome::Comp(CompChunk {
                axis: u8::MAX,
                total: u16::MAX,
                first: u16::MAX,
                backlash_mm: f32::MAX,
                rate_mm_s: f32::MAX,
                accel_mm_s2: f32::MAX,
                points: comp,
            }),
        ];
        for last in lasts {
            let mut buf = [0u8; MAX_FRAME_LEN];
            let frame: ToHost<Telemetry, Status> = ToHost::Status {
                id: Seq(u16::MAX),
                status: Status {
                    last: last.clone(),
                    ..status.clone()
                },
            };
            let n = encode(&frame, &mut buf)
                .unwrap_or_else(|e| panic!("the largest status must fit a frame: {last:?}: {e:?}"));
            assert!(n <= MAX_FRAME_LEN);
        }
    }

    /// A telemetry frame takes at most 80 bytes, and 4 more per chosen signal (the link's
    /// throughput figures in docs/link-protocol.md count them).
    #[test]
    fn telemetry_frames_grow_by_four_bytes_per_signal() {
        let mut t = Telemetry {
            period: u32::MAX,
            state: MachineState::Run { held: true },
            pos_mm: [f32::MAX; 3],
            reference_mm: [f32::MAX; 3],
            ref_vel_mm_s: [f32::MAX; 3],
            ref_acc_mm_s2: [f32::MAX; 3],
            contour_mm: f32::MAX,
            feed_ratio: f32::MAX,
            tag: u32::MAX,
            signals: heapless::Vec::new(),
        };
        let len = |t: &Telemetry| {
            let mut buf = [0u8; MAX_FRAME_LEN];
            let frame: ToHost<Telemetry, Status> = ToHost::Telemetry {
                seq: Seq(u16::MAX),
                sample: t.clone(),
            };
            encode(&frame, &mut buf).unwrap()
        };
        let bare = len(&t);
        assert!(bare <= 80, "{bare}");
        while t.signals.push(f32::MAX).is_ok() {}
        assert_eq!(len(&t), bare + 4 * TELEMETRY_SIGNALS);
    }

    #[test]
    fn fault_codes_round_trip() {
        for k in FaultKind::ALL {
            for a in [None, Some(crate::axes::Axis::X), Some(crate::axes::Axis::Z)] {
                let c = FaultCode::new(k, a);
                assert_eq!(c.kind(), Some(k));
                assert_eq!(c.axis(), a);
            }
        }
    }
}
