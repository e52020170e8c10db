//! Modal interpreter: executes one tokenized block at a time in RS274NGC order (feed mode,
//! feed, dwell, plane, units, tool length offset, coordinate system, path control,
//! distance modes, G10/G28/G52/G53/G92, motion, stop) and appends [`Move`]s in machine
//! coordinates. The codes and their groups are [`super::codes`]; the coordinate frames
//! (work offsets, G92/G52, tool length) are [`super::offsets::Frames`]; G10 and G43 are
//! read in [`super::setup`].

use super::arc::{self, CentreForm};
use super::codes::{classify_g, classify_m, code10, code_name, Cmd, Group, MotionMode, ToolLength};
use super::lexer::Word;
use super::offsets::{Frames, WORK_SYSTEM_CODES};
use super::{
    Blend, Error, ErrorKind, Ignored, Move, MoveKind, ParseOptions, Plane, Program, MM_PER_INCH,
    ZERO_LENGTH_MM,
};

/// Index of a value-word letter in the per-line table.
fn slot(letter: char) -> usize {
    (letter as usize).saturating_sub('A' as usize).min(25)
}

/// The value words of one line, with use tracking.
pub(super) struct Values<'w> {
    words: [Option<&'w Word>; 26],
    used: [bool; 26],
}

impl<'w> Values<'w> {
    /// The value of `letter`'s word, marking it used.
    pub(super) fn get(&mut self, letter: char) -> Option<f64> {
        let i = slot(letter);
        let w = self.words[i]?;
        self.used[i] = true;
        Some(w.value)
    }

    /// The word as written (for messages), without marking it used.
    pub(super) fn word(&self, letter: char) -> Option<&'w Word> {
        self.words[slot(letter)]
    }

    pub(super) fn has(&self, letter: char) -> bool {
        self.words[slot(letter)].is_some()
    }

    /// The text of the first of `letters` on the line (`"X5"`), or empty.
    pub(super) fn first_text(&self, letters: &[char]) -> String {
        letters
            .iter()
            .find_map(|&l| self.word(l))
            .map(|w| w.text.clone())
            .unwrap_or_default()
    }
}

/// Which command on the line owns the P word (G4, G10, G64, or an arc's turns).
pub(super) struct POwner {
    owner: Option<&'static str>,
}

impl POwner {
    /// `owner` takes P; an error if another command on the line already did.
    pub(super) fn claim(
        &mut self,
        owner: &'static str,
        interp: &Interp<'_>,
        line: u32,
    ) -> Result<(), Error> {
        match self.owner.replace(owner) {
            Some(prev) => Err(interp.error(
                line,
                ErrorKind::Invalid,
                format!("P is used by both {prev} and {owner} on one line"),
            )),
            None => Ok(()),
        }
    }
}

pub(crate) struct Interp<'a> {
    pub(super) name: &'a str,
    pub(super) opts: &'a ParseOptions,
    /// Current machine position (mm).
    pub(super) pos: [f64; 3],
    pub(super) motion: Option<MotionMode>,
    pub(super) plane: Plane,
    pub(super) inches: bool,
    pub(super) incremental: bool,
    /// G90.1: I/J/K are absolute coordinates.
    pub(super) arc_absolute: bool,
    /// G93 inverse-time feed mode.
    pub(super) inverse_time: bool,
    /// The modal feed in units per minute mode (mm/min); `None` until an F, and again
    /// after G93 → G94 (LinuxCNC wants a new F then).
    pub(super) feed_mm_min: Option<f64>,
    /// A G93 → G94 switch cleared the feed (for the message of the move without F).
    pub(super) feed_cleared_by_g94: bool,
    /// Work offsets, G92/G52, tool length.
    pub(super) frames: Frames,
    pub(super) blend: Option<Blend>,
    pub(super) end_line: Option<u32>,
    pub(super) moves: Vec<Move>,
    pub(super) ignored: Vec<Ignored>,
    pub(super) bounds: [[f64; 2]; 3],
    /// The finest step the program's axis words are written in, mm (∞: none seen).
    pub(super) resolution_mm: f64,
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
            arc_absolute: false,
            inverse_time: false,
            feed_mm_min: None,
            feed_cleared_by_g94: false,
            frames: Frames::new(opts.work_offsets_mm, opts.tools.clone()),
            blend: None,
            end_line: None,
            moves: Vec::new(),
            ignored: Vec::new(),
            bounds: opts.start_mm.map(|p| [p, p]),
            resolution_mm: f64::INFINITY,
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
            work_offsets_mm: self.frames.work_mm,
            tools: self.frames.tools,
            coordinate_resolution_mm: if self.resolution_mm.is_finite() {
                self.resolution_mm
            } else {
                0.0
            },
        }
    }

    pub(super) fn error(&self, line: u32, kind: ErrorKind, message: String) -> Error {
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

    pub(super) fn unit_mm(&self) -> f64 {
        if self.inches {
            MM_PER_INCH
        } else {
            1.0
        }
    }

    /// Interprets one block.
    pub(crate) fn block(&mut self, line: u32, words: &[Word]) -> Result<(), Error> {
        // 1. Classify every G/M code: anything unsupported rejects the line first.
        let cmds = self.classify(line, words)?;
        if self.end_line.is_some() {
            return Ok(());
        }

        // 2. Value words: each at most once.
        let mut values = self.value_words(line, words)?;

        // 3. At most one command per modal group.
        self.check_modal_groups(line, &cmds)?;
        let has = |c: Cmd| cmds.iter().any(|(k, _, _)| *k == c);
        let group = |g: Group| in_group(&cmds, g);

        // 4. Ignored words, once each.
        self.note_ignored_words(line, &cmds, &mut values)?;

        // 5. Who uses the axis words: at most one of G43.1, G10/G28/G52/G92 and an
        //    explicit motion command (a modal motion yields to the others).
        let explicit_motion = group(Group::Motion);
        let nonmodal = group(Group::NonModal);
        self.check_axis_users(line, &cmds)?;

        // 6. Execute in RS274NGC order. Units first: every length on the line is in them.
        if let Some((Cmd::Units { inches }, _)) = group(Group::Units) {
            self.inches = inches;
        }
        let k = self.unit_mm();
        if let Some((Cmd::FeedMode { inverse_time }, _)) = group(Group::FeedMode) {
            if self.inverse_time && !inverse_time {
                // G93 → G94: the F in force was a time, not a speed (LinuxCNC)
                self.feed_mm_min = None;
                self.feed_cleared_by_g94 = true;
            }
            self.inverse_time = inverse_time;
        }
        // In G93 an F belongs to its line only: the moves on it take 1/F minutes.
        let inverse_f = self.feed_word(line, &mut values, k)?;
        let mut p = POwner { owner: None };
        if has(Cmd::Dwell) {
            self.dwell(line, &mut values, &mut p)?;
        }
        if let Some((Cmd::Plane(pl), _)) = group(Group::Plane) {
            self.plane = pl;
        }
        if let Some((Cmd::ToolLength(t), name)) = group(Group::ToolLength) {
            self.tool_length(line, t, &name, &mut values)?;
        }
        if let Some((Cmd::WorkSystem(i), _)) = group(Group::WorkOffset) {
            self.frames.active = i;
        }
        match group(Group::PathControl) {
            Some((Cmd::ExactPath, _)) => self.set_blend(line, Blend::ExactPath),
            Some((Cmd::ExactStop, _)) => self.set_blend(line, Blend::ExactStop),
            Some((Cmd::Blending, _)) => {
                let blend = self.g64(line, &mut values, &mut p)?;
                self.set_blend(line, blend);
            }
            _ => {}
        }
        if let Some((Cmd::Distance { incremental }, _)) = group(Group::Distance) {
            self.incremental = incremental;
        }
        if let Some((Cmd::ArcCentre { absolute }, _)) = group(Group::ArcDistance) {
            self.arc_absolute = absolute;
        }

        // Non-modal commands and motion share the axis words (a G43.1 took them above).
        self.note_resolution(&values);
        let axes = [values.get('X'), values.get('Y'), values.get('Z')];
        let has_axes = axes.iter().any(Option::is_some);
        if let Some((Cmd::Motion(m), _)) = explicit_motion {
            self.motion = m;
        }
        let dynamic_tool = has(Cmd::ToolLength(ToolLength::Dynamic));
        let nonmodal = nonmodal.map(|(c, _)| c);
        let axes_used = NonModalAxes {
            axes,
            has_axes,
            dynamic_tool,
            inverse_f,
            k,
        };
        self.nonmodal_or_motion(line, nonmodal, axes_used, &mut values, &mut p)?;

        // 7. Stop commands last.
        match group(Group::Stopping) {
            Some((Cmd::Pause, _)) => self.push(line, MoveKind::Pause),
            Some((Cmd::End, _)) => self.end_line = Some(line),
            _ => {}
        }

        // 8. Every value word must have been used by something on the line.
        self.check_all_used(line, &values)
    }

    /// Every G and M code of the line, classified with its modal group and name; an
    /// unsupported one rejects the line.
    fn classify(&self, line: u32, words: &[Word]) -> Result<Vec<(Cmd, Group, String)>, Error> {
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
        Ok(cmds)
    }

    /// The line's value words (all but G and M), each letter at most once.
    fn value_words<'w>(&self, line: u32, words: &'w [Word]) -> Result<Values<'w>, Error> {
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

        Ok(values)
    }

    /// At most one command per modal group.
    fn check_modal_groups(&self, line: u32, cmds: &[(Cmd, Group, String)]) -> Result<(), Error> {
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
        Ok(())
    }

    /// Words accepted but ignored, noted once each; a line number must be whole.
    fn note_ignored_words(
        &mut self,
        line: u32,
        cmds: &[(Cmd, Group, String)],
        values: &mut Values<'_>,
    ) -> Result<(), Error> {
        for (cmd, _, name) in cmds {
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
        Ok(())
    }

    /// At most one of G43.1, G10/G28/G52/G92 and an explicit motion command uses the axis
    /// words.
    fn check_axis_users(&self, line: u32, cmds: &[(Cmd, Group, String)]) -> Result<(), Error> {
        let explicit_motion = in_group(cmds, Group::Motion);
        let nonmodal = in_group(cmds, Group::NonModal);
        let axis_users: Vec<String> = [
            in_group(cmds, Group::ToolLength)
                .filter(|(c, _)| *c == Cmd::ToolLength(ToolLength::Dynamic))
                .map(|(_, n)| n),
            nonmodal
                .as_ref()
                .filter(|(c, _)| {
                    matches!(
                        c,
                        Cmd::Home | Cmd::SetOffset | Cmd::LocalOffset | Cmd::SetTable
                    )
                })
                .map(|(_, n)| n.clone()),
            explicit_motion
                .as_ref()
                .filter(|(c, _)| matches!(c, Cmd::Motion(Some(_))))
                .map(|(_, n)| n.clone()),
        ]
        .into_iter()
        .flatten()
        .collect();
        if let [first, second, ..] = axis_users.as_slice() {
            return Err(self.error(
                line,
                ErrorKind::ModalConflict,
                format!("{first} and {second} on one line: both would use the axis words"),
            ));
        }

        Ok(())
    }

    /// The F word: a feed in force (G94), or the line's inverse time (G93, returned).
    fn feed_word(
        &mut self,
        line: u32,
        values: &mut Values<'_>,
        k: f64,
    ) -> Result<Option<f64>, Error> {
        let mut inverse_f: Option<f64> = None;
        if let Some(f) = values.get('F') {
            if !(f > 0.0) {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!("F{f} is not a usable feed rate: it must be greater than zero"),
                ));
            }
            if !self.inverse_time && f * k < super::MIN_FEED_MM_MIN {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!(
                        "F{f} is below the slowest feed, {} mm/min",
                        super::MIN_FEED_MM_MIN
                    ),
                ));
            }
            if self.inverse_time {
                inverse_f = Some(f);
            } else {
                self.feed_mm_min = Some(f * k);
                self.feed_cleared_by_g94 = false;
            }
        }
        Ok(inverse_f)
    }

    /// G4: a dwell of P seconds.
    fn dwell(&mut self, line: u32, values: &mut Values<'_>, p: &mut POwner) -> Result<(), Error> {
        p.claim("G4", self, line)?;
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
        if s > super::MAX_DWELL_S {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!(
                    "G4 P{s}: the dwell is longer than {} s (use a feed hold to wait longer)",
                    super::MAX_DWELL_S
                ),
            ));
        }
        self.push(line, MoveKind::Dwell { s });
        Ok(())
    }

    /// The step the line's axis words are written in: how far a CAM post's rounding moved
    /// the points (the most decimals seen, as posts drop trailing zeros).
    fn note_resolution(&mut self, values: &Values<'_>) {
        for w in ['X', 'Y', 'Z'].iter().filter_map(|&l| values.word(l)) {
            let decimals = w.text.split_once('.').map_or(0, |(_, f)| {
                f.chars().take_while(char::is_ascii_digit).count()
            });
            let step = 10f64.powi(-(decimals.min(12) as i32)) * self.unit_mm();
            self.resolution_mm = self.resolution_mm.min(step);
        }
    }

    /// The non-modal command that takes the axis words (G28, G10, G52, G92, G92.1, G53),
    /// or else the motion in force.
    fn nonmodal_or_motion(
        &mut self,
        line: u32,
        nonmodal: Option<Cmd>,
        a: NonModalAxes,
        values: &mut Values<'_>,
        p: &mut POwner,
    ) -> Result<(), Error> {
        let NonModalAxes {
            axes,
            has_axes,
            dynamic_tool,
            inverse_f,
            k,
        } = a;
        match nonmodal {
            Some(Cmd::Home) => self.home(line, axes),
            Some(Cmd::SetTable) => self.g10(line, axes, values, p)?,
            Some(Cmd::LocalOffset) => self.frames.set_g52(axes.map(|v| v.map(|v| v * k))),
            Some(Cmd::SetOffset) => {
                if !has_axes {
                    return Err(self.error(
                        line,
                        ErrorKind::Invalid,
                        "G92 without axis words: name the axes to set".into(),
                    ));
                }
                self.frames
                    .set_g92(self.pos, axes.map(|v| v.map(|v| v * k)));
            }
            Some(Cmd::ClearOffset) => {
                self.frames.clear_g92();
                if has_axes && !dynamic_tool {
                    return Err(self.unused_axes(line, values));
                }
            }
            Some(Cmd::MachineCoords) => {
                if has_axes && !dynamic_tool {
                    if self.incremental {
                        return Err(self.error(
                            line,
                            ErrorKind::Unsupported,
                            "G53 in incremental distance mode (G91) is not supported".into(),
                        ));
                    }
                    if !matches!(self.motion, Some(MotionMode::Rapid | MotionMode::Linear)) {
                        return Err(self.error(
                            line,
                            ErrorKind::Invalid,
                            format!(
                                "G53 needs G0 or G1 in effect (in effect: {})",
                                self.motion.map_or("no motion mode", MotionMode::code)
                            ),
                        ));
                    }
                    self.motion_block(line, axes, true, inverse_f, values, p)?;
                }
            }
            _ => {
                if has_axes && !dynamic_tool {
                    self.motion_block(line, axes, false, inverse_f, values, p)?;
                }
            }
        }

        Ok(())
    }

    /// Every value word was used by something on the line.
    fn check_all_used(&self, line: u32, values: &Values<'_>) -> Result<(), Error> {
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
        let text = values.first_text(&['X', 'Y', 'Z']);
        self.error(
            line,
            ErrorKind::UnusedWord,
            format!("{text} is not used by any command on this line"),
        )
    }

    /// G64 [P [Q]]: LinuxCNC's blending tolerance P and naive-CAM tolerance Q (Q defaults
    /// to P; Q without P is an error).
    fn g64(&self, line: u32, values: &mut Values<'_>, p: &mut POwner) -> Result<Blend, Error> {
        let k = self.unit_mm();
        if !values.has('P') {
            if let Some(q) = values.word('Q') {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!(
                        "G64 {} without P: the naive-CAM tolerance Q needs a path tolerance P \
                         (G64 P- Q-)",
                        q.text
                    ),
                ));
            }
            return Ok(Blend::MachineDefault);
        }
        p.claim("G64", self, line)?;
        let tol = values.get('P').unwrap_or_default();
        if !(tol >= 0.0) {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!("G64 P{tol}: the path tolerance must not be negative"),
            ));
        }
        let q = values.get('Q').unwrap_or(tol);
        if !(q >= 0.0) {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!("G64 Q{q}: the naive-CAM tolerance must not be negative"),
            ));
        }
        Ok(Blend::Tolerance {
            mm: tol * k,
            naive_cam_mm: q * k,
        })
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
        if matches!(kind, MoveKind::Rapid { .. } | MoveKind::Line { .. })
            && m.length_mm() <= ZERO_LENGTH_MM
        {
            return;
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
    pub(super) fn target(&self, axes: [Option<f64>; 3], machine: bool) -> [f64; 3] {
        let k = self.unit_mm();
        let mut t = self.pos;
        for (a, v) in axes.iter().enumerate() {
            if let Some(v) = v {
                t[a] = if machine {
                    v * k
                } else if self.incremental {
                    self.pos[a] + v * k
                } else {
                    v * k + self.frames.origin_mm(a)
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

    /// Path speed (mm/s) of a feed move of `length_mm`: the modal F (G94), or, in G93, the
    /// line's own F as an inverse time (the move takes 1/F minutes).
    fn feed_mm_s(
        &self,
        line: u32,
        motion: MotionMode,
        inverse_f: Option<f64>,
        length_mm: f64,
    ) -> Result<f64, Error> {
        let code = motion.code();
        if self.inverse_time {
            return inverse_f.map(|f| length_mm * f / 60.0).ok_or_else(|| {
                self.error(
                    line,
                    ErrorKind::NoFeed,
                    format!(
                        "{code} in inverse-time feed mode (G93) without F: every G1, G2 and G3 \
                         needs its own F"
                    ),
                )
            });
        }
        self.feed_mm_min.map(|f| f / 60.0).ok_or_else(|| {
            let why = if self.feed_cleared_by_g94 {
                ": after G93, G94 needs a new F"
            } else {
                ""
            };
            self.error(
                line,
                ErrorKind::NoFeed,
                format!("{code} without a feed rate (F){why}"),
            )
        })
    }

    /// Motion in the modal (or just programmed) mode to the axis words.
    fn motion_block(
        &mut self,
        line: u32,
        axes: [Option<f64>; 3],
        machine: bool,
        inverse_f: Option<f64>,
        values: &mut Values<'_>,
        p: &mut POwner,
    ) -> Result<(), Error> {
        let Some(motion) = self.motion else {
            let text = values.first_text(&['X', 'Y', 'Z']);
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!("{text} without a motion command: no G0/G1/G2/G3 is in effect"),
            ));
        };
        let to = self.target(axes, machine);
        match motion {
            MotionMode::Rapid => self.push(line, MoveKind::Rapid { to }),
            MotionMode::Linear => {
                let length: f64 = (0..3)
                    .map(|a| (to[a] - self.pos[a]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let feed_mm_s = self.feed_mm_s(line, motion, inverse_f, length)?;
                self.push(line, MoveKind::Line { to, feed_mm_s });
            }
            MotionMode::Cw | MotionMode::Ccw => self.arc(line, motion, to, inverse_f, values, p)?,
        }
        Ok(())
    }

    /// G2/G3 to `to` (machine mm): centre by I/J/K (incremental from the start, or
    /// absolute in the current coordinate system under G90.1) or by R.
    fn arc(
        &mut self,
        line: u32,
        motion: MotionMode,
        to: [f64; 3],
        inverse_f: Option<f64>,
        values: &mut Values<'_>,
        p: &mut POwner,
    ) -> Result<(), Error> {
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
            (None, true) if self.arc_absolute => {
                let (Some(c0), Some(c1)) = (o0, o1) else {
                    return Err(self.error(
                        line,
                        ErrorKind::Arc,
                        format!(
                            "{code} with absolute arc centres (G90.1) needs both {} and {}",
                            offset_letter(a0),
                            offset_letter(a1)
                        ),
                    ));
                };
                // the centre in the current coordinate system (offsets and, on Z, the tool
                // length applied), as offsets from the start
                CentreForm::Offsets([
                    c0 * k + self.frames.origin_mm(a0) - self.pos[a0],
                    c1 * k + self.frames.origin_mm(a1) - self.pos[a1],
                ])
            }
            (None, true) => {
                CentreForm::Offsets([o0.unwrap_or_default() * k, o1.unwrap_or_default() * k])
            }
            (None, false) => {
                return Err(self.error(
                    line,
                    ErrorKind::Arc,
                    format!("{code} without I/J/K or R: the arc centre is not defined"),
                ))
            }
        };
        let turns = if values.has('P') {
            p.claim(code, self, line)?;
            let t = values.get('P').unwrap_or_default();
            if !(t >= 1.0 && t.fract() == 0.0) {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!("{code} P{t}: the number of turns must be a whole number ≥ 1"),
                ));
            }
            if t > f64::from(super::MAX_ARC_TURNS) {
                return Err(self.error(
                    line,
                    ErrorKind::Arc,
                    format!(
                        "{code} P{t}: at most {} turns in one arc",
                        super::MAX_ARC_TURNS
                    ),
                ));
            }
            t as u32
        } else {
            1
        };
        let clockwise = motion == MotionMode::Cw;
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
        let [a0, a1, _] = plane.axes();
        let radius = (self.pos[a0] - resolved.center[a0]).hypot(self.pos[a1] - resolved.center[a1]);
        if radius > super::MAX_ARC_RADIUS_MM {
            return Err(self.error(
                line,
                ErrorKind::Arc,
                format!(
                    "{code}: the arc's radius {radius:.1} mm is above {} mm (program a line)",
                    super::MAX_ARC_RADIUS_MM
                ),
            ));
        }
        let length = arc::arc_length_mm(self.pos, to, resolved.center, plane, resolved.sweep_rad);
        let feed_mm_s = self.feed_mm_s(line, motion, inverse_f, length)?;
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
        Ok(())
    }
}

/// The G-code of coordinate system `i` (`G59.1`), for messages.
pub(super) fn system_code(i: usize) -> &'static str {
    WORK_SYSTEM_CODES.get(i).copied().unwrap_or("G54")
}

/// The command of `cmds` in group `g`, and its name.
fn in_group(cmds: &[(Cmd, Group, String)], g: Group) -> Option<(Cmd, String)> {
    cmds.iter()
        .find(|(_, k, _)| *k == g)
        .map(|(c, _, n)| (*c, n.clone()))
}

/// What the non-modal command or the motion of a line gets: its axis words (in the
/// program's units), whether it has any, whether a G43.1 took them, the line's inverse
/// time feed (G93) and the length unit, mm.
#[derive(Clone, Copy)]
struct NonModalAxes {
    axes: [Option<f64>; 3],
    has_axes: bool,
    dynamic_tool: bool,
    inverse_f: Option<f64>,
    k: f64,
}
