//! Modal interpreter: executes one tokenized block at a time in RS274NGC order (feed,
//! dwell, plane, units, distance mode, path control, G28/G53/G92, motion, stop) and
//! appends [`Move`]s in machine coordinates.

use super::arc::{self, CentreForm};
use super::lexer::Word;
use super::{
    Blend, Error, ErrorKind, Ignored, Move, MoveKind, ParseOptions, Plane, Program, MM_PER_INCH,
    ZERO_LENGTH_MM,
};

/// Modal motion mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Motion {
    Rapid,
    Linear,
    Cw,
    Ccw,
}

impl Motion {
    fn code(self) -> &'static str {
        match self {
            Motion::Rapid => "G0",
            Motion::Linear => "G1",
            Motion::Cw => "G2",
            Motion::Ccw => "G3",
        }
    }
}

/// A supported G or M command.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Cmd {
    /// G0–G3; `None` is G80 (motion cancel).
    Motion(Option<Motion>),
    Plane(Plane),
    Distance {
        incremental: bool,
    },
    /// G91.1: the mode we are always in.
    ArcCentreIncremental,
    Units {
        inches: bool,
    },
    /// G40, G49, G94: accepted, ignored.
    NoEffect,
    WorkOffset54,
    ExactStop,
    Blending,
    Dwell,
    Home,
    MachineCoords,
    SetOffset,
    ClearOffset,
    Pause,
    End,
    /// M3/M4/M5, M7/M8/M9: accepted, ignored.
    Auxiliary,
}

/// Modal groups (RS274NGC numbering in the comments). Two commands of one group on a line
/// are a conflict.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Group {
    NonModal,    // 0
    Motion,      // 1
    Plane,       // 2
    Distance,    // 3
    ArcDistance, // 4
    FeedMode,    // 5
    Units,       // 6
    CutterComp,  // 7
    ToolLength,  // 8
    WorkOffset,  // 12
    PathControl, // 13
    Stopping,    // M 4
    Spindle,     // M 7
    Coolant,     // M 8
}

impl Group {
    fn name(self) -> &'static str {
        match self {
            Group::NonModal => "non-modal (G4, G28, G53, G92)",
            Group::Motion => "motion (G0, G1, G2, G3, G80)",
            Group::Plane => "plane (G17, G18, G19)",
            Group::Distance => "distance mode (G90, G91)",
            Group::ArcDistance => "arc distance mode (G91.1)",
            Group::FeedMode => "feed rate mode (G94)",
            Group::Units => "units (G20, G21)",
            Group::CutterComp => "cutter compensation (G40)",
            Group::ToolLength => "tool length offset (G49)",
            Group::WorkOffset => "work offset (G54)",
            Group::PathControl => "path control (G61, G64)",
            Group::Stopping => "stopping (M0, M2, M30)",
            Group::Spindle => "spindle (M3, M4, M5)",
            Group::Coolant => "coolant (M7, M8, M9)",
        }
    }
}

/// A G/M number ×10 (`G91.1` → 911), if it has at most one decimal.
fn code10(value: f64) -> Option<u32> {
    let x = value * 10.0;
    let r = x.round();
    ((0.0..=1e9).contains(&r) && (x - r).abs() <= 1e-6).then_some(r as u32)
}

/// `G91.1`, `M3`: the code as RS274NGC names it.
fn code_name(letter: char, c10: u32) -> String {
    if c10.is_multiple_of(10) {
        format!("{letter}{}", c10 / 10)
    } else {
        format!("{letter}{}.{}", c10 / 10, c10 % 10)
    }
}

fn classify_g(c10: u32) -> Result<(Cmd, Group), Option<&'static str>> {
    use Group as Gr;
    Ok(match c10 {
        0 => (Cmd::Motion(Some(Motion::Rapid)), Gr::Motion),
        10 => (Cmd::Motion(Some(Motion::Linear)), Gr::Motion),
        20 => (Cmd::Motion(Some(Motion::Cw)), Gr::Motion),
        30 => (Cmd::Motion(Some(Motion::Ccw)), Gr::Motion),
        800 => (Cmd::Motion(None), Gr::Motion),
        40 => (Cmd::Dwell, Gr::NonModal),
        280 => (Cmd::Home, Gr::NonModal),
        530 => (Cmd::MachineCoords, Gr::NonModal),
        920 => (Cmd::SetOffset, Gr::NonModal),
        921 => (Cmd::ClearOffset, Gr::NonModal),
        170 => (Cmd::Plane(Plane::XY), Gr::Plane),
        180 => (Cmd::Plane(Plane::ZX), Gr::Plane),
        190 => (Cmd::Plane(Plane::YZ), Gr::Plane),
        200 => (Cmd::Units { inches: true }, Gr::Units),
        210 => (Cmd::Units { inches: false }, Gr::Units),
        900 => (Cmd::Distance { incremental: false }, Gr::Distance),
        910 => (Cmd::Distance { incremental: true }, Gr::Distance),
        911 => (Cmd::ArcCentreIncremental, Gr::ArcDistance),
        940 => (Cmd::NoEffect, Gr::FeedMode),
        400 => (Cmd::NoEffect, Gr::CutterComp),
        490 => (Cmd::NoEffect, Gr::ToolLength),
        540 => (Cmd::WorkOffset54, Gr::WorkOffset),
        610 => (Cmd::ExactStop, Gr::PathControl),
        640 => (Cmd::Blending, Gr::PathControl),
        _ => return Err(describe_unsupported_g(c10)),
    })
}

fn describe_unsupported_g(c10: u32) -> Option<&'static str> {
    Some(match c10 {
        50..=53 => "spline",
        70 | 80 => "lathe diameter/radius mode",
        100 => "setting offsets and tables",
        150 | 160 => "polar coordinates",
        281 | 301 => "storing a home position",
        300 => "second home position",
        330 | 331 => "spindle-synchronised motion",
        382..=385 => "probing",
        410 | 411 | 420 | 421 => "cutter radius compensation",
        430..=432 => "tool length offset",
        500 | 510 => "scaling",
        550 | 560 | 570 | 580 | 590..=593 => "work offsets other than G54",
        611 => "exact path mode",
        680 | 690 => "coordinate rotation",
        730 | 760 => "canned cycle",
        c if (810..=890).contains(&c) && c.is_multiple_of(10) => "canned cycle",
        901 => "absolute arc centres",
        922 | 923 => "suspending G92 offsets",
        930 => "inverse-time feed",
        950 => "feed per revolution",
        960 | 970 => "spindle speed mode",
        980 | 990 => "canned cycle return mode",
        _ => return None,
    })
}

fn classify_m(c10: u32) -> Result<(Cmd, Group), Option<&'static str>> {
    Ok(match c10 {
        0 => (Cmd::Pause, Group::Stopping),
        20 | 300 => (Cmd::End, Group::Stopping),
        30 | 40 | 50 => (Cmd::Auxiliary, Group::Spindle),
        70 | 80 | 90 => (Cmd::Auxiliary, Group::Coolant),
        _ => {
            return Err(Some(match c10 {
                10 => "optional stop",
                60 => "tool change",
                600 => "pallet change pause",
                480..=530 => "override control",
                620..=680 => "digital/analog output",
                700..=730 => "modal state save/restore",
                1000..=1990 => "user-defined M-code",
                _ => return Err(None),
            }))
        }
    })
}

/// Index of a value-word letter in the per-line table.
fn slot(letter: char) -> usize {
    (letter as usize).saturating_sub('A' as usize).min(25)
}

/// The value words of one line, with use tracking.
struct Values<'w> {
    words: [Option<&'w Word>; 26],
    used: [bool; 26],
}

impl<'w> Values<'w> {
    fn get(&mut self, letter: char) -> Option<f64> {
        let i = slot(letter);
        let w = self.words[i]?;
        self.used[i] = true;
        Some(w.value)
    }

    fn word(&self, letter: char) -> Option<&'w Word> {
        self.words[slot(letter)]
    }

    fn has(&self, letter: char) -> bool {
        self.words[slot(letter)].is_some()
    }
}

pub(crate) struct Interp<'a> {
    name: &'a str,
    opts: &'a ParseOptions,
    /// Current machine position (mm).
    pos: [f64; 3],
    motion: Option<Motion>,
    plane: Plane,
    inches: bool,
    incremental: bool,
    feed_mm_min: Option<f64>,
    g92_mm: [f64; 3],
    blend: Option<Blend>,
    end_line: Option<u32>,
    moves: Vec<Move>,
    ignored: Vec<Ignored>,
    bounds: [[f64; 2]; 3],
}

impl<'a> Interp<'a> {
    pub(crate) fn new(name: &'a str, opts: &'a ParseOptions) -> Self {
        Self {
            name,
            opts,
            pos: opts.start_mm,
            motion: None,
            plane: Plane::XY,
            inches: false,
            incremental: false,
            feed_mm_min: None,
            g92_mm: [0.0; 3],
            blend: None,
            end_line: None,
            moves: Vec::new(),
            ignored: Vec::new(),
            bounds: opts.start_mm.map(|p| [p, p]),
        }
    }

    pub(crate) fn finish(self) -> Program {
        Program {
            name: self.name.to_string(),
            start_mm: self.opts.start_mm,
            moves: self.moves,
            ignored: self.ignored,
            bounds_mm: self.bounds,
            end_line: self.end_line,
        }
    }

    fn error(&self, line: u32, kind: ErrorKind, message: String) -> Error {
        Error {
            file: self.name.to_string(),
            line: Some(line),
            kind,
            message,
        }
    }

    fn note_ignored(&mut self, word: String, line: u32) {
        match self.ignored.iter_mut().find(|i| i.word == word) {
            Some(i) => i.count = i.count.saturating_add(1),
            None => self.ignored.push(Ignored {
                word,
                first_line: line,
                count: 1,
            }),
        }
    }

    fn unit_mm(&self) -> f64 {
        if self.inches {
            MM_PER_INCH
        } else {
            1.0
        }
    }

    /// Interprets one block.
    pub(crate) fn block(&mut self, line: u32, words: &[Word]) -> Result<(), Error> {
        // 1. Classify every G/M code: anything unsupported rejects the line first.
        let mut cmds: Vec<(Cmd, Group, String)> = Vec::new();
        for w in words.iter().filter(|w| matches!(w.letter, 'G' | 'M')) {
            let c10 = code10(w.value);
            let classified = match c10 {
                Some(c) if w.letter == 'G' => classify_g(c),
                Some(c) => classify_m(c),
                None => Err(None),
            };
            match classified {
                Ok((cmd, group)) => {
                    cmds.push((cmd, group, code_name(w.letter, c10.unwrap_or_default())))
                }
                Err(what) => {
                    let name = c10.map_or_else(|| w.text.clone(), |c| code_name(w.letter, c));
                    let what = what.map_or(name.clone(), |d| format!("{name} ({d})"));
                    return Err(self.error(
                        line,
                        ErrorKind::Unsupported,
                        format!("{what} is not supported"),
                    ));
                }
            }
        }
        if self.end_line.is_some() {
            return Ok(());
        }

        // 2. Value words: each at most once.
        let mut values = Values {
            words: [None; 26],
            used: [false; 26],
        };
        for w in words.iter().filter(|w| !matches!(w.letter, 'G' | 'M')) {
            let i = slot(w.letter);
            if let Some(first) = values.words[i] {
                return Err(self.error(
                    line,
                    ErrorKind::RepeatedWord,
                    format!(
                        "{} appears twice on one line ({} and {})",
                        w.letter, first.text, w.text
                    ),
                ));
            }
            values.words[i] = Some(w);
        }

        // 3. At most one command per modal group.
        for (i, (_, group, name)) in cmds.iter().enumerate() {
            if let Some((_, _, other)) = cmds.iter().skip(i + 1).find(|(_, g, _)| g == group) {
                return Err(self.error(
                    line,
                    ErrorKind::ModalConflict,
                    format!(
                        "{name} and {other} on one line: both are in the {} group",
                        group.name()
                    ),
                ));
            }
        }
        let has = |c: Cmd| cmds.iter().any(|(k, _, _)| *k == c);
        let in_group = |g: Group| {
            cmds.iter()
                .find(|(_, k, _)| *k == g)
                .map(|(c, _, n)| (*c, n.clone()))
        };

        // 4. Ignored words, once each.
        for (cmd, _, name) in &cmds {
            if matches!(cmd, Cmd::NoEffect | Cmd::Auxiliary | Cmd::Motion(None)) {
                self.note_ignored(name.clone(), line);
            }
        }
        for letter in ['S', 'T'] {
            if values.get(letter).is_some() {
                self.note_ignored(letter.to_string(), line);
            }
        }
        if let Some(n) = values.get('N') {
            if !(n >= 0.0 && n.fract() == 0.0) {
                let text = values.word('N').map(|w| w.text.clone()).unwrap_or_default();
                return Err(self.error(
                    line,
                    ErrorKind::Syntax,
                    format!("line number {text} is not a whole number ≥ 0"),
                ));
            }
        }

        // 5. Execute in RS274NGC order. Units first: every length on the line is in them.
        if let Some((Cmd::Units { inches }, _)) = in_group(Group::Units) {
            self.inches = inches;
        }
        let k = self.unit_mm();
        if let Some(f) = values.get('F') {
            if !(f > 0.0) {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!("F{f} is not a usable feed rate: it must be greater than zero"),
                ));
            }
            self.feed_mm_min = Some(f * k);
        }
        // Which command on the line owns the P word (G4, G64, or an arc's turns).
        let mut p_owner: Option<&'static str> = None;
        let mut claim_p = |owner: &'static str, this: &Self| -> Result<(), Error> {
            match p_owner.replace(owner) {
                Some(prev) => Err(this.error(
                    line,
                    ErrorKind::Invalid,
                    format!("P is used by both {prev} and {owner} on one line"),
                )),
                None => Ok(()),
            }
        };
        if has(Cmd::Dwell) {
            claim_p("G4", self)?;
            let Some(s) = values.get('P') else {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    "G4 without P (the dwell time in seconds)".into(),
                ));
            };
            if !(s >= 0.0) {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!("G4 P{s}: the dwell time must not be negative"),
                ));
            }
            self.push(line, MoveKind::Dwell { s });
        }
        if let Some((Cmd::Plane(p), _)) = in_group(Group::Plane) {
            self.plane = p;
        }
        if let Some((Cmd::Distance { incremental }, _)) = in_group(Group::Distance) {
            self.incremental = incremental;
        }
        match in_group(Group::PathControl) {
            Some((Cmd::ExactStop, _)) => self.set_blend(line, Blend::ExactStop),
            Some((Cmd::Blending, _)) => {
                let blend = if values.has('P') {
                    claim_p("G64", self)?;
                    let p = values.get('P').unwrap_or_default();
                    if !(p >= 0.0) {
                        return Err(self.error(
                            line,
                            ErrorKind::Invalid,
                            format!("G64 P{p}: the path tolerance must not be negative"),
                        ));
                    }
                    Blend::Tolerance { mm: p * k }
                } else {
                    Blend::MachineDefault
                };
                self.set_blend(line, blend);
            }
            _ => {}
        }

        // Non-modal commands and motion share the axis words.
        let axes = [values.get('X'), values.get('Y'), values.get('Z')];
        let has_axes = axes.iter().any(Option::is_some);
        let explicit_motion = in_group(Group::Motion);
        if let Some((Cmd::Motion(m), _)) = explicit_motion {
            self.motion = m;
        }
        let nonmodal = in_group(Group::NonModal);
        if let (Some((Cmd::Home | Cmd::SetOffset, name)), Some((_, motion_name))) =
            (&nonmodal, &explicit_motion)
        {
            return Err(self.error(
                line,
                ErrorKind::ModalConflict,
                format!("{name} and {motion_name} on one line: both would use the axis words"),
            ));
        }
        match nonmodal.map(|(c, _)| c) {
            Some(Cmd::Home) => self.home(line, axes),
            Some(Cmd::SetOffset) => {
                if !has_axes {
                    return Err(self.error(
                        line,
                        ErrorKind::Invalid,
                        "G92 without axis words: name the axes to set".into(),
                    ));
                }
                for (a, v) in axes.iter().enumerate() {
                    if let Some(v) = v {
                        self.g92_mm[a] = self.pos[a] - self.opts.g54_offset_mm[a] - v * k;
                    }
                }
            }
            Some(Cmd::ClearOffset) => {
                self.g92_mm = [0.0; 3];
                if has_axes {
                    return Err(self.unused_axes(line, &values));
                }
            }
            Some(Cmd::MachineCoords) => {
                if has_axes {
                    if self.incremental {
                        return Err(self.error(
                            line,
                            ErrorKind::Unsupported,
                            "G53 in incremental distance mode (G91) is not supported".into(),
                        ));
                    }
                    if !matches!(self.motion, Some(Motion::Rapid | Motion::Linear)) {
                        return Err(self.error(
                            line,
                            ErrorKind::Invalid,
                            format!(
                                "G53 needs G0 or G1 in effect (in effect: {})",
                                self.motion.map_or("no motion mode", Motion::code)
                            ),
                        ));
                    }
                    self.motion_block(line, axes, true, &mut values, &mut claim_p)?;
                }
            }
            _ => {
                if has_axes {
                    self.motion_block(line, axes, false, &mut values, &mut claim_p)?;
                }
            }
        }

        // 6. Stop commands last.
        match in_group(Group::Stopping) {
            Some((Cmd::Pause, _)) => self.push(line, MoveKind::Pause),
            Some((Cmd::End, _)) => self.end_line = Some(line),
            _ => {}
        }

        // 7. Every value word must have been used by something on the line.
        for (i, w) in values.words.iter().enumerate() {
            if let (Some(w), false) = (w, values.used[i]) {
                return Err(self.error(
                    line,
                    ErrorKind::UnusedWord,
                    format!("{} is not used by any command on this line", w.text),
                ));
            }
        }
        Ok(())
    }

    fn unused_axes(&self, line: u32, values: &Values<'_>) -> Error {
        let text = ['X', 'Y', 'Z']
            .iter()
            .find_map(|&l| values.word(l))
            .map(|w| w.text.clone())
            .unwrap_or_default();
        self.error(
            line,
            ErrorKind::UnusedWord,
            format!("{text} is not used by any command on this line"),
        )
    }

    fn set_blend(&mut self, line: u32, blend: Blend) {
        if self.blend != Some(blend) {
            self.blend = Some(blend);
            self.push(line, MoveKind::SetBlend(blend));
        }
    }

    /// Appends a move from the current position; skips zero-length straight moves.
    fn push(&mut self, line: u32, kind: MoveKind) {
        let m = Move {
            line,
            from: self.pos,
            kind,
        };
        if matches!(kind, MoveKind::Rapid { .. } | MoveKind::Line { .. }) {
            let to = m.to();
            let d2: f64 = (0..3).map(|a| (to[a] - self.pos[a]).powi(2)).sum();
            if d2.sqrt() <= ZERO_LENGTH_MM {
                return;
            }
        }
        let ext = m.extent_mm();
        for (b, e) in self.bounds.iter_mut().zip(ext) {
            b[0] = b[0].min(e[0]);
            b[1] = b[1].max(e[1]);
        }
        self.pos = m.to();
        self.moves.push(m);
    }

    /// End point of a move from axis words (program units), in machine coordinates.
    fn target(&self, axes: [Option<f64>; 3], machine: bool) -> [f64; 3] {
        let k = self.unit_mm();
        let mut t = self.pos;
        for (a, v) in axes.iter().enumerate() {
            if let Some(v) = v {
                t[a] = if machine {
                    v * k
                } else if self.incremental {
                    self.pos[a] + v * k
                } else {
                    v * k + self.opts.g54_offset_mm[a] + self.g92_mm[a]
                };
            }
        }
        t
    }

    /// G28: rapid to the intermediate point (if axis words), then home: all axes without
    /// axis words, only the named ones with.
    fn home(&mut self, line: u32, axes: [Option<f64>; 3]) {
        let home = self.opts.g28_position_mm;
        if axes.iter().any(Option::is_some) {
            let mid = self.target(axes, false);
            self.push(line, MoveKind::Rapid { to: mid });
            let mut end = self.pos;
            for (a, v) in axes.iter().enumerate() {
                if v.is_some() {
                    end[a] = home[a];
                }
            }
            self.push(line, MoveKind::Rapid { to: end });
        } else {
            self.push(line, MoveKind::Rapid { to: home });
        }
    }

    fn feed_mm_s(&self, line: u32, motion: Motion) -> Result<f64, Error> {
        self.feed_mm_min.map(|f| f / 60.0).ok_or_else(|| {
            self.error(
                line,
                ErrorKind::NoFeed,
                format!("{} without a feed rate (F)", motion.code()),
            )
        })
    }

    /// Motion in the modal (or just programmed) mode to the axis words.
    fn motion_block(
        &mut self,
        line: u32,
        axes: [Option<f64>; 3],
        machine: bool,
        values: &mut Values<'_>,
        claim_p: &mut impl FnMut(&'static str, &Self) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let Some(motion) = self.motion else {
            let text = ['X', 'Y', 'Z']
                .iter()
                .find_map(|&l| values.word(l))
                .map(|w| w.text.clone())
                .unwrap_or_default();
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!("{text} without a motion command: no G0/G1/G2/G3 is in effect"),
            ));
        };
        let to = self.target(axes, machine);
        match motion {
            Motion::Rapid => self.push(line, MoveKind::Rapid { to }),
            Motion::Linear => {
                let feed_mm_s = self.feed_mm_s(line, motion)?;
                self.push(line, MoveKind::Line { to, feed_mm_s });
            }
            Motion::Cw | Motion::Ccw => {
                let feed_mm_s = self.feed_mm_s(line, motion)?;
                let code = motion.code();
                let plane = self.plane;
                let [a0, a1, n] = plane.axes();
                let offset_letter = |a: usize| ['I', 'J', 'K'].get(a).copied().unwrap_or('I');
                if let Some(w) = values.word(offset_letter(n)) {
                    return Err(self.error(
                        line,
                        ErrorKind::UnusedWord,
                        format!(
                            "{} is not used by an arc in the {} plane",
                            w.text,
                            plane.name()
                        ),
                    ));
                }
                let k = self.unit_mm();
                let o0 = values.get(offset_letter(a0));
                let o1 = values.get(offset_letter(a1));
                let r = values.get('R');
                let form = match (r, o0.is_some() || o1.is_some()) {
                    (Some(_), true) => {
                        return Err(self.error(
                            line,
                            ErrorKind::Arc,
                            format!("{code} with both R and I/J/K: give one of them"),
                        ))
                    }
                    (Some(r), false) => CentreForm::Radius(r * k),
                    (None, true) => CentreForm::Offsets([
                        o0.unwrap_or_default() * k,
                        o1.unwrap_or_default() * k,
                    ]),
                    (None, false) => {
                        return Err(self.error(
                            line,
                            ErrorKind::Arc,
                            format!("{code} without I/J/K or R: the arc centre is not defined"),
                        ))
                    }
                };
                let turns = if values.has('P') {
                    claim_p(code, self)?;
                    let p = values.get('P').unwrap_or_default();
                    if !(p >= 1.0 && p.fract() == 0.0) {
                        return Err(self.error(
                            line,
                            ErrorKind::Invalid,
                            format!("{code} P{p}: the number of turns must be a whole number ≥ 1"),
                        ));
                    }
                    p as u32
                } else {
                    1
                };
                let clockwise = motion == Motion::Cw;
                let resolved = arc::resolve(
                    self.pos,
                    to,
                    plane,
                    clockwise,
                    form,
                    turns,
                    self.opts.arc_tolerance_mm,
                    self.opts.arc_tolerance_rel,
                )
                .map_err(|m| self.error(line, ErrorKind::Arc, m))?;
                self.push(
                    line,
                    MoveKind::Arc {
                        to,
                        center: resolved.center,
                        plane,
                        clockwise,
                        turns,
                        sweep_rad: resolved.sweep_rad,
                        feed_mm_s,
                    },
                );
            }
        }
        Ok(())
    }
}
