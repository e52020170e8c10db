//! G-code front end: turns a G-code program into a validated list of machine moves in
//! machine coordinates (mm, mm/s, s) **before any motion**. The whole program is rejected
//! with `FILE:LINE: <message>` if anything in it is unsupported or invalid; a later step
//! streams the [`Move`]s to the motion planner in controller-core.
//!
//! Beside the front end: [`program`] (a program in a machine's context, checked against
//! its travel, as the planner's segments), [`runner`] (`host-sim gcode`: the program run on
//! the simulated machine), [`measure`] (a run against the programmed path) and [`report`]
//! (the report of a run, from `host-sim gcode` and `gantry run` alike).
//!
//! # Accepted subset (what a CAM post for a 3-axis router/mill emits, and what LinuxCNC
//! users send; LinuxCNC's RS274NGC semantics)
//! - Motion: G0, G1, G2, G3 (I/J/K centre offsets, incremental from the start by default
//!   (G91.1), absolute coordinates in the current coordinate system under G90.1, which
//!   then needs both in-plane words; R form with negative R for arcs over 180°; full
//!   circles when the end equals the start in the plane, I/J/K form only; helical arcs
//!   via the normal axis; optional `P` = number of turns ≥ 1 as in LinuxCNC). An arc with
//!   axis words outside its plane only (e.g. `G2 Z-1 I5` in G17) keeps the in-plane end
//!   at the start: a full helical turn.
//! - Coordinates ([`offsets`]): machine = programmed + the active work coordinate
//!   system's origin + the G92/G52 offset + (on Z) the tool length offset.
//!   - G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3 select one of the nine systems
//!     ([`ParseOptions::work_offsets_mm`], the machine's `work.<cs>.*_mm` settings); a
//!     program starts in G54.
//!   - G10 L2 P0–P9 sets a system's origin (machine coordinates; P0 = the active one,
//!     P1 = G54 .. P9 = G59.3; axis words not given keep their value); G10 L20 P0–P9
//!     sets it so that the current point gets the given coordinates (with the G92/G52
//!     offset and the tool length in effect). A change to the active system applies to
//!     the next move. The origins as the program leaves them are
//!     [`Program::work_offsets_mm`], for the caller to write back (LinuxCNC keeps them).
//!   - `G10 L1 P<tool> Z<length> R<radius>` sets a tool of the table
//!     ([`ParseOptions::tools`], the machine's `tool.<n>.*`); [`Program::tools`]. The
//!     offset in effect changes only with the next G43, as in LinuxCNC.
//!   - `G43 H<n>` applies tool n's length (H0: none), `G43.1 Z<length>` a given one, G49
//!     cancels: machine Z = programmed Z + length (LinuxCNC's sign). Nothing moves; the
//!     next Z end point is compensated. G43 without H is an error: no tool is ever
//!     loaded (M6 is not supported).
//!   - G92 (offset so that the current point gets the given coordinates; values always
//!     absolute; axes not given keep theirs), G52 (the same register set directly,
//!     relative to the work coordinate system: `G52 X0 Y0 Z0` cancels), G92.1 (clears
//!     both). They last for the program (LinuxCNC's `DISABLE_G92_PERSISTENCE`).
//!   - G53: machine coordinates for that line (no offset, no tool length), needs G0/G1;
//!     rejected under G91. G28: rapid to [`ParseOptions::g28_position_mm`], via the
//!     intermediate point (in the current coordinates) if axis words are given, then only
//!     the named axes move home, as grbl 1.1 and LinuxCNC.
//!   - G10 (L0, L10, L11, R rotation), G43.2, G92.2, G92.3 stay rejected.
//! - Feed: F in units per minute (G94, the default); G93 inverse time: every G1, G2 and
//!   G3 needs its own F on its line and takes 1/F minutes (feed = length · F / 60 mm/s,
//!   arcs with their full helical length); after G93, G94 needs a new F. Rapids are not
//!   affected.
//! - Path control ([`Blend`]): G61 exact path (tolerance 0: corners stop, junctions that
//!   go on in the same direction do not), G61.1 exact stop (at rest after every move),
//!   `G64 P<tol> [Q<naive-CAM tol>]` (Q defaults to P, Q0: no merging; Q without P is an
//!   error), G64 alone (the planner's default tolerance).
//! - G4 P (dwell, seconds), G17/G18/G19, G20/G21 (inch input converted to mm), G90/G91,
//!   N (ignored: messages name the file line), M0 (pause), M2/M30 (end), `( … )` and
//!   `; …` comments, `%` lines.
//! - Accepted and reported once in [`Program::ignored`] (they do not move the machine): S,
//!   T, M3/M4/M5, M7/M8/M9, G40, G80. G80 also cancels the modal motion (it is in the
//!   motion group), so bare axis words after it are rejected, not guessed.
//! - Everything else is `FILE:LINE: <what> is not supported`: O-words, parameters `#…`,
//!   expressions `[…]`, block delete `/` (running or skipping the line would depend on an
//!   operator switch the gantry does not have), canned cycles (G73, G76, G81–G89, G98/G99),
//!   G33, G38.x, G28.1, G30, G41/G42, G43.2, G92.2/G92.3, G95, M1, M6, …, and the letters A
//!   B C D E U V W.
//!
//! # Errors (grbl's set, with the file line)
//! Line longer than [`MAX_LINE_CHARS`], bad numbers, two words of one modal group on a line
//! (`G0 G1`), a word repeated on a line, words no command on the line uses (`G0 I5`, `H1`
//! without G43), two commands that would use the axis words (`G10 L2 P1 X0 G0 Y1`, `G43.1
//! Z1 G1 X5`), feed moves without a feed rate, arc end points off the circle (tolerance:
//! larger of 0.005 mm and 0.1 % of the radius, at most 0.5 mm: grbl's rule), zero-radius
//! arcs, R arcs whose chord exceeds 2|R|; G10 without L or P, P outside 0–9 (L2/L20) or
//! the tool table (L1), origins beyond ±[`MAX_WORK_OFFSET_MM`] and tools beyond
//! [`MAX_TOOL_LENGTH_MM`] / [`MAX_TOOL_DIAMETER_MM`] (the machine's settings ranges, so a
//! G10 can always be written back), negative radii; G43 without H or with an H not in
//! the table, G43.1 without Z. Zero-length moves (≤ [`ZERO_LENGTH_MM`]) are skipped
//! silently.
//!
//! # After M2/M30
//! Lines after the end are still tokenized and their G/M codes classified, so a syntax
//! error or an unsupported word anywhere in the file rejects it (a file with a second
//! program appended is suspicious); they are not interpreted: no moves, no ignored-word
//! report, no modal checks.
//!
//! # Soft limits
//! [`check_travel`] rejects a program whose path (end points and exact arc extremes, in
//! machine coordinates: work offsets and tool length applied) leaves the machine's
//! [`Travel`]; [`Travel::check_point`] does the same for a jog target.

mod arc;
mod codes;
pub mod compress;
mod interp;
mod lexer;
pub mod measure;
pub mod offsets;
pub mod program;
pub mod report;
pub mod runner;
pub mod samples;
mod setup;
mod travel;

use std::{fmt, io::Read, path::Path};

pub use arc::{arc_extent, arc_length_mm, arc_tolerance_mm, ARC_TOLERANCE_CAP_MM};
pub use offsets::{
    Tool, WorkOffsets, MAX_TOOL_DIAMETER_MM, MAX_TOOL_LENGTH_MM, MAX_WORK_OFFSET_MM, WORK_SYSTEMS,
    WORK_SYSTEM_CODES,
};
pub use travel::{check_travel, Travel, TravelError, TravelViolation, TRAVEL_SLACK_MM};

/// Longest accepted line, in characters without the line end (grblHAL's buffer is 256).
pub const MAX_LINE_CHARS: usize = 256;
/// Largest accepted file (bytes): far above any router program, small enough to read whole.
pub const MAX_FILE_BYTES: u64 = 16 * 1024 * 1024;
/// Exact inch definition.
pub const MM_PER_INCH: f64 = 25.4;
/// Largest magnitude of any number in a word: 10 km in mm, keeps every later product
/// finite (squares stay below 1e15) so no NaN or infinity can reach a move.
pub const MAX_WORD_MAGNITUDE: f64 = 1e7;
/// Moves at most this long (mm) are skipped: only float noise (e.g. `G90 X0.3` after G91
/// steps 0.1 + 0.2), a million times below an encoder count.
pub const ZERO_LENGTH_MM: f64 = 1e-9;
/// An arc whose end is within this distance (mm, in its plane) of its start is a full
/// circle; below any programmable resolution (4 decimals of mm = 1e-4 mm).
pub const FULL_CIRCLE_CHORD_MM: f64 = 1e-6;
/// Smallest arc radius (mm); below it the radius counts as zero.
pub const MIN_ARC_RADIUS_MM: f64 = 1e-6;
/// Largest arc radius (mm): the planner's arc through a point takes up to this
/// (`MAX_ARC_THROUGH_RADIUS_MM`, 10 m); beyond it the planner's f32 centre and angles lose
/// the path (`G2 X10 R9999999` ran 0.73 mm off), and within any tolerance such an arc is a
/// line anyway.
pub const MAX_ARC_RADIUS_MM: f64 =
    controller_core::motion::planner::segment::MAX_ARC_THROUGH_RADIUS_MM as f64;
/// Most turns of one arc (`P`): the planner queues an arc as one piece a turn, at most
/// `MAX_ARC_PIECES` (16).
pub const MAX_ARC_TURNS: u32 = controller_core::motion::planner::segment::MAX_ARC_PIECES as u32;
/// Longest dwell (`G4 P`, s): an hour. A longer one is a typo (`P10000000` is 116 days);
/// the operator's feed hold is the way to wait longer.
pub const MAX_DWELL_S: f64 = 3600.0;
/// Slowest feed (mm/min): 0.01 mm/min, a micrometre in 6 s, below any cutting feed. Below
/// it a move of a few mm would take days of machine time.
pub const MIN_FEED_MM_MIN: f64 = 0.01;

/// Axis names by index.
pub const AXIS_NAMES: [char; 3] = ['X', 'Y', 'Z'];

/// Arc plane (G17/G18/G19): the planner's own, which the program's segments carry.
pub use controller_core::motion::planner::Plane;

/// Path control mode (G61/G61.1/G64) in force for the moves that follow (LinuxCNC's
/// trajectory control).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Blend {
    /// G61.1: exact stop, the machine comes to rest at the end of every move.
    ExactStop,
    /// G61: exact path, every programmed point is reached exactly (path tolerance 0); a
    /// junction between moves that continue in the same direction (collinear lines, a
    /// line tangent to an arc) is passed without stopping.
    ExactPath,
    /// G64 P Q: corners may be blended within `mm` of the programmed path.
    Tolerance {
        /// Path tolerance P (mm), ≥ 0.
        mm: f64,
        /// Naive-CAM tolerance Q (mm), ≥ 0: runs of short feed moves at one feed that are
        /// within it of collinear may be merged into one (0: no merging). Without Q,
        /// LinuxCNC takes P.
        naive_cam_mm: f64,
    },
    /// G64 without P: the planner's configured default tolerance.
    MachineDefault,
}

/// What a move does. Coordinates are machine coordinates (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoveKind {
    /// G0 (also G28): straight line at the machine's rapid rates.
    Rapid {
        /// End point.
        to: [f64; 3],
    },
    /// G1: straight line at `feed_mm_s`.
    Line {
        /// End point.
        to: [f64; 3],
        /// Path speed (mm/s).
        feed_mm_s: f64,
    },
    /// G2/G3: circular or helical arc at `feed_mm_s` along the (helical) path.
    ///
    /// The planner should interpolate the radius linearly with the angle from the start
    /// radius to the end radius (they differ by at most the arc tolerance) so that the arc
    /// ends exactly on `to`, and the normal-axis coordinate linearly with the angle.
    Arc {
        /// End point.
        to: [f64; 3],
        /// Centre; its normal-axis component is the start's.
        center: [f64; 3],
        /// Plane of the arc.
        plane: Plane,
        /// G2 (true) or G3, as seen from the positive normal axis.
        clockwise: bool,
        /// Turns as programmed (P, default 1): the arc makes `turns − 1` extra full turns.
        turns: u32,
        /// Total swept angle (rad, > 0): the partial angle from start to end in the
        /// direction of travel (2π when end = start in the plane) plus 2π·(turns − 1).
        sweep_rad: f64,
        /// Path speed (mm/s).
        feed_mm_s: f64,
    },
    /// G4: stand still for `s` seconds.
    Dwell {
        /// Dwell time (s), ≥ 0.
        s: f64,
    },
    /// M0: stop and wait for the operator to resume.
    Pause,
    /// G61/G61.1/G64: path control for the moves that follow (emitted when it changes).
    SetBlend(Blend),
}

/// One step of the program, from the file line that caused it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Move {
    /// 1-based line in the file.
    pub line: u32,
    /// Where the machine is when the move starts (machine mm).
    pub from: [f64; 3],
    /// What it does.
    pub kind: MoveKind,
}

impl Move {
    /// Where the machine is when the move ends (`from` for dwell, pause, blend changes).
    pub fn to(&self) -> [f64; 3] {
        match self.kind {
            MoveKind::Rapid { to } | MoveKind::Line { to, .. } | MoveKind::Arc { to, .. } => to,
            _ => self.from,
        }
    }

    /// Length of the path of this move (mm; 0 for dwell, pause, blend changes): the chord
    /// of a straight move, the full (helical, multi-turn) length of an arc
    /// ([`arc_length_mm`]).
    pub fn length_mm(&self) -> f64 {
        match self.kind {
            MoveKind::Rapid { to } | MoveKind::Line { to, .. } => (0..3)
                .map(|a| (to[a] - self.from[a]).powi(2))
                .sum::<f64>()
                .sqrt(),
            MoveKind::Arc {
                to,
                center,
                plane,
                sweep_rad,
                ..
            } => arc_length_mm(self.from, to, center, plane, sweep_rad),
            _ => 0.0,
        }
    }

    /// Axis-aligned extent `[[min, max]; 3]` of the path of this move (exact for arcs).
    pub fn extent_mm(&self) -> [[f64; 2]; 3] {
        match self.kind {
            MoveKind::Arc {
                to,
                center,
                plane,
                clockwise,
                sweep_rad,
                ..
            } => arc_extent(self.from, to, center, plane, clockwise, sweep_rad),
            _ => {
                let (a, b) = (self.from, self.to());
                [0, 1, 2].map(|i| [a[i].min(b[i]), a[i].max(b[i])])
            }
        }
    }
}

/// A word that was accepted but has no effect on the gantry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ignored {
    /// The word: a letter (`"S"`, `"T"`) or a code (`"M3"`, `"G40"`).
    pub word: String,
    /// First file line it appeared on.
    pub first_line: u32,
    /// How many times it appeared.
    pub count: u32,
}

/// A validated program.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// File name used in messages.
    pub name: String,
    /// Machine position the program was interpreted from ([`ParseOptions::start_mm`]).
    pub start_mm: [f64; 3],
    /// The moves, in order; zero-length moves are left out.
    pub moves: Vec<Move>,
    /// Ignored words, in order of first appearance.
    pub ignored: Vec<Ignored>,
    /// Extent `[[min, max]; 3]` of the whole path including the start point (machine mm).
    pub bounds_mm: [[f64; 2]; 3],
    /// Line of the M2/M30 that ended the program, if any.
    pub end_line: Option<u32>,
    /// The work coordinate systems' origins as the program leaves them: the
    /// [`ParseOptions::work_offsets_mm`] it was given with its G10 L2 / L20 applied. The
    /// caller writes back what differs (LinuxCNC keeps G10 changes for the next program).
    pub work_offsets_mm: WorkOffsets,
    /// The tool table as the program leaves it: [`ParseOptions::tools`] with its G10 L1
    /// applied.
    pub tools: Vec<Tool>,
    /// The step the axis words are written in: the finest one seen, as posts drop
    /// trailing zeros (mm; `X1.2345` in G20 is 0.00254 mm). A CAM post's rounding moves
    /// every point by up to half of it, which the path compressor's budget must exceed
    /// (`compress::budget_mm`). 0 without axis words.
    pub coordinate_resolution_mm: f64,
}

impl Program {
    /// The work offsets this program changed with G10 relative to `options` (what it was
    /// parsed with): `(system, axis, mm)`, system 0 = G54, axis 0 = X.
    pub fn work_offset_changes(&self, options: &ParseOptions) -> Vec<(usize, usize, f64)> {
        let mut out = Vec::new();
        for (s, (new, old)) in self
            .work_offsets_mm
            .iter()
            .zip(&options.work_offsets_mm)
            .enumerate()
        {
            for a in 0..3 {
                if new[a].to_bits() != old[a].to_bits() {
                    out.push((s, a, new[a]));
                }
            }
        }
        out
    }

    /// The tools this program changed with G10 L1 relative to `options`: `(tool number,
    /// entry)`, numbered from 1.
    pub fn tool_changes(&self, options: &ParseOptions) -> Vec<(usize, Tool)> {
        self.tools
            .iter()
            .zip(&options.tools)
            .enumerate()
            .filter(|(_, (new, old))| new != old)
            .map(|(i, (new, _))| (i + 1, *new))
            .collect()
    }
}

/// Machine context for interpreting a program.
#[derive(Debug, Clone, PartialEq)]
pub struct ParseOptions {
    /// Machine position when the program starts (mm): origin of G91 moves and G92.
    pub start_mm: [f64; 3],
    /// Origins of the work coordinate systems G54 .. G59.3 in machine coordinates (mm),
    /// `[system][axis]` (the machine's `work.<cs>.*_mm` settings). A program starts in
    /// G54. Default: all at machine zero (so G54 is machine coordinates, as before).
    pub work_offsets_mm: WorkOffsets,
    /// The tool table, tool `n` at index `n − 1` (the machine's `tool.<n>.*` settings):
    /// `G43 H<n>` takes its length. Default: empty (`G43 H<n>` with n ≥ 1 is an error).
    pub tools: Vec<Tool>,
    /// Where G28 goes, in machine coordinates (mm). Default 0: machine zero (home).
    pub g28_position_mm: [f64; 3],
    /// Absolute part of the arc end-point tolerance (mm); grbl: 0.005 mm.
    pub arc_tolerance_mm: f64,
    /// Relative part of the arc end-point tolerance (fraction of the radius); grbl: 0.001.
    pub arc_tolerance_rel: f64,
}

impl Default for ParseOptions {
    fn default() -> Self {
        Self {
            start_mm: [0.0; 3],
            work_offsets_mm: [[0.0; 3]; WORK_SYSTEMS],
            tools: Vec::new(),
            g28_position_mm: [0.0; 3],
            arc_tolerance_mm: 0.005,
            arc_tolerance_rel: 0.001,
        }
    }
}

impl ParseOptions {
    fn validate(&self) -> Result<(), String> {
        let vectors = [
            ("start_mm", self.start_mm),
            ("g28_position_mm", self.g28_position_mm),
        ];
        for (name, v) in vectors {
            if !v.iter().all(|x| x.abs() <= MAX_WORD_MAGNITUDE) {
                return Err(format!(
                    "option {name} must be finite and at most {MAX_WORD_MAGNITUDE:e} mm in magnitude, got {v:?}"
                ));
            }
        }
        for (code, v) in WORK_SYSTEM_CODES.iter().zip(&self.work_offsets_mm) {
            if !v.iter().all(|x| x.abs() <= MAX_WORK_OFFSET_MM) {
                return Err(format!(
                    "option work_offsets_mm: the {code} origin must be finite and within \
                     ±{MAX_WORK_OFFSET_MM} mm, got {v:?}"
                ));
            }
        }
        for (i, t) in self.tools.iter().enumerate() {
            if !(t.length_mm.abs() <= MAX_TOOL_LENGTH_MM
                && t.diameter_mm >= 0.0
                && t.diameter_mm <= MAX_TOOL_DIAMETER_MM)
            {
                return Err(format!(
                    "option tools: tool {} must have a finite length within ±{MAX_TOOL_LENGTH_MM} mm \
                     and a diameter in [0, {MAX_TOOL_DIAMETER_MM}] mm, got {t:?}",
                    i + 1
                ));
            }
        }
        if !(self.arc_tolerance_mm > 0.0 && self.arc_tolerance_mm <= ARC_TOLERANCE_CAP_MM) {
            return Err(format!(
                "option arc_tolerance_mm must be in (0, {ARC_TOLERANCE_CAP_MM}] mm, got {}",
                self.arc_tolerance_mm
            ));
        }
        if !(self.arc_tolerance_rel >= 0.0 && self.arc_tolerance_rel <= 0.1) {
            return Err(format!(
                "option arc_tolerance_rel must be in [0, 0.1], got {}",
                self.arc_tolerance_rel
            ));
        }
        Ok(())
    }
}

/// Kind of error, for callers that react differently (grbl's error numbers in brackets).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The file cannot be read.
    Io,
    /// The file exceeds [`MAX_FILE_BYTES`].
    TooLarge,
    /// The file is not UTF-8 text.
    NotUtf8,
    /// Invalid [`ParseOptions`].
    Options,
    /// A line exceeds [`MAX_LINE_CHARS`] (grbl 11 "line overflow").
    LineTooLong,
    /// Malformed text: bad number, stray character, unclosed comment (grbl 1, 2).
    Syntax,
    /// `<what> is not supported` (grbl 20).
    Unsupported,
    /// Two words of one modal group on a line (grbl 21).
    ModalConflict,
    /// A value word twice on a line (grbl 25).
    RepeatedWord,
    /// A word no command on the line uses (grbl 36).
    UnusedWord,
    /// A feed move without a feed rate (grbl 22).
    NoFeed,
    /// Invalid arc (grbl 33–35).
    Arc,
    /// Any other invalid command (missing or out-of-range value).
    Invalid,
    /// The program would leave the travel (soft limit).
    Travel,
}

/// A rejected program: `FILE:LINE: message` (or `FILE: message` without a line).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Error {
    /// File name as given.
    pub file: String,
    /// 1-based line, if the error belongs to one.
    pub line: Option<u32>,
    /// Kind of error.
    pub kind: ErrorKind,
    /// What is wrong; for [`ErrorKind::Unsupported`] it ends in "is not supported".
    pub message: String,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.file, line, self.message),
            None => write!(f, "{}: {}", self.file, self.message),
        }
    }
}

impl std::error::Error for Error {}

/// Parses a program held in memory with default [`ParseOptions`] (start at machine zero,
/// every work offset 0, no tools). `name` is used in messages.
pub fn parse_str(name: &str, text: &str) -> Result<Program, Error> {
    parse_str_with(name, text, &ParseOptions::default())
}

/// Parses a program held in memory in the given machine context.
pub fn parse_str_with(name: &str, text: &str, options: &ParseOptions) -> Result<Program, Error> {
    options.validate().map_err(|message| Error {
        file: name.to_string(),
        line: None,
        kind: ErrorKind::Options,
        message,
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut state = interp::Interp::new(name, options);
    for (index, raw) in text.split('\n').enumerate() {
        let line = u32::try_from(index.saturating_add(1)).unwrap_or(u32::MAX);
        let err = |kind, message| Error {
            file: name.to_string(),
            line: Some(line),
            kind,
            message,
        };
        let raw = raw.strip_suffix('\r').unwrap_or(raw);
        let chars = raw.chars().count();
        if chars > MAX_LINE_CHARS {
            return Err(err(
                ErrorKind::LineTooLong,
                format!("line is too long: {chars} characters (at most {MAX_LINE_CHARS})"),
            ));
        }
        let words = lexer::lex_line(raw).map_err(|e| match e {
            lexer::LexError::Unsupported(what) => {
                err(ErrorKind::Unsupported, format!("{what} is not supported"))
            }
            lexer::LexError::Syntax(message) => err(ErrorKind::Syntax, message),
        })?;
        state.block(line, &words)?;
    }
    Ok(state.finish())
}

/// Reads and parses a file with default [`ParseOptions`]; files over [`MAX_FILE_BYTES`]
/// are rejected without being read whole.
pub fn parse_file(path: &Path) -> Result<Program, Error> {
    parse_file_with(path, &ParseOptions::default())
}

/// Reads and parses a file in the given machine context.
pub fn parse_file_with(path: &Path, options: &ParseOptions) -> Result<Program, Error> {
    let name = path.display().to_string();
    let err = |kind, line, message| Error {
        file: name.clone(),
        line,
        kind,
        message,
    };
    // (a pipe or a device is refused before it is opened: opening a pipe waits for a
    // writer, and a device such as /dev/zero never ends)
    let meta = std::fs::metadata(path)
        .map_err(|e| err(ErrorKind::Io, None, format!("cannot open the file: {e}")))?;
    if !meta.is_file() {
        return Err(err(
            ErrorKind::Io,
            None,
            "not a regular file (pipes, devices and directories are refused)".into(),
        ));
    }
    let file = std::fs::File::open(path)
        .map_err(|e| err(ErrorKind::Io, None, format!("cannot open the file: {e}")))?;
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| err(ErrorKind::Io, None, format!("cannot read the file: {e}")))?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(err(
            ErrorKind::TooLarge,
            None,
            format!(
                "file is larger than the {} MiB limit",
                MAX_FILE_BYTES / (1024 * 1024)
            ),
        ));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes
            .get(..at)
            .unwrap_or_default()
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        err(
            ErrorKind::NotUtf8,
            Some(u32::try_from(line).unwrap_or(u32::MAX)),
            format!("not UTF-8 text (invalid byte at offset {at})"),
        )
    })?;
    parse_str_with(&name, &text, options)
}
