//! The words of G10 (L1 a tool of the table, L2 / L20 a coordinate system's origin) and of
//! the tool length offset (G43 H, G43.1 Z, G49), read into the interpreter's
//! [`super::offsets::Frames`] with LinuxCNC's rules. Values are absolute whatever the
//! distance mode (G91 has no effect on G10, as in LinuxCNC) and in program units.

use super::codes::ToolLength;
use super::interp::{system_code, Interp, POwner, Values};
use super::{
    Error, ErrorKind, AXIS_NAMES, MAX_TOOL_DIAMETER_MM, MAX_TOOL_LENGTH_MM, MAX_WORK_OFFSET_MM,
    WORK_SYSTEMS,
};

/// `v` as a whole number within `lo..=hi`.
fn whole(v: f64, lo: usize, hi: usize) -> Option<usize> {
    (v.fract() == 0.0 && v >= lo as f64 && v <= hi as f64).then_some(v as usize)
}

/// "tools 1 to 8", or that the table is empty, for messages.
fn table_size(n: usize) -> String {
    if n == 0 {
        "the tool table is empty".into()
    } else {
        format!("the tool table has tools 1 to {n}")
    }
}

impl Interp<'_> {
    /// G43 H<n> (tool n's length; H0 none), G43.1 Z<len> (that length), G49 (none).
    pub(super) fn tool_length(
        &mut self,
        line: u32,
        cmd: ToolLength,
        name: &str,
        values: &mut Values<'_>,
    ) -> Result<(), Error> {
        match cmd {
            ToolLength::Cancel => self.frames.tool_length_mm = 0.0,
            ToolLength::Table => {
                let Some(h) = values.get('H') else {
                    return Err(self.error(
                        line,
                        ErrorKind::Invalid,
                        format!(
                            "{name} without H: name the tool (G43 H<n>; H0: no offset): no tool is \
                             loaded, M6 is not supported"
                        ),
                    ));
                };
                let text = values.word('H').map(|w| w.text.clone()).unwrap_or_default();
                let Some(n) = whole(h, 0, usize::MAX) else {
                    return Err(self.error(
                        line,
                        ErrorKind::Invalid,
                        format!(
                            "{name} {text}: the tool must be a whole number ≥ 0 (H0: no offset)"
                        ),
                    ));
                };
                self.frames.tool_length_mm = if n == 0 {
                    0.0
                } else {
                    let tools = self.frames.tools.len();
                    self.frames.tool(n).map(|t| t.length_mm).ok_or_else(|| {
                        self.error(
                            line,
                            ErrorKind::Invalid,
                            format!(
                                "{name} {text}: tool {n} is not in the tool table ({})",
                                table_size(tools)
                            ),
                        )
                    })?
                };
            }
            ToolLength::Dynamic => {
                if let Some(w) = values.word('X').or_else(|| values.word('Y')) {
                    return Err(self.error(
                        line,
                        ErrorKind::Unsupported,
                        format!(
                            "{name} {} (a tool offset across the spindle) is not supported",
                            w.text
                        ),
                    ));
                }
                let Some(z) = values.get('Z') else {
                    return Err(self.error(
                        line,
                        ErrorKind::Invalid,
                        format!("{name} without Z: give the tool length offset ({name} Z<length>)"),
                    ));
                };
                self.frames.tool_length_mm = z * self.unit_mm();
            }
        }
        Ok(())
    }

    /// G10 L1 / L2 / L20 with the line's axis words (program units).
    pub(super) fn g10(
        &mut self,
        line: u32,
        axes: [Option<f64>; 3],
        values: &mut Values<'_>,
        p: &mut POwner,
    ) -> Result<(), Error> {
        let Some(l) = values.get('L') else {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                "G10 without L: give L2 or L20 (a coordinate system's origin) or L1 (a tool)"
                    .into(),
            ));
        };
        let l_text = values.word('L').map(|w| w.text.clone()).unwrap_or_default();
        match whole(l, 0, 20) {
            Some(2) => self.g10_work(line, false, axes, values, p),
            Some(20) => self.g10_work(line, true, axes, values, p),
            Some(1) => self.g10_tool(line, axes, values, p),
            Some(0) => Err(self.error(
                line,
                ErrorKind::Unsupported,
                "G10 L0 (reloading the tool table) is not supported".into(),
            )),
            Some(10 | 11) => Err(self.error(
                line,
                ErrorKind::Unsupported,
                format!("G10 {l_text} (setting a tool from the current position) is not supported"),
            )),
            _ => Err(self.error(
                line,
                ErrorKind::Invalid,
                format!(
                    "G10 {l_text}: L must be 1 (a tool), 2 or 20 (a coordinate system's origin)"
                ),
            )),
        }
    }

    /// G10 L2 P<cs> (the origin of the named axes) / G10 L20 P<cs> (the origin that makes
    /// the current point the given coordinates).
    fn g10_work(
        &mut self,
        line: u32,
        here: bool,
        axes: [Option<f64>; 3],
        values: &mut Values<'_>,
        p: &mut POwner,
    ) -> Result<(), Error> {
        let l = if here { "L20" } else { "L2" };
        if let Some(w) = values.word('R') {
            return Err(self.error(
                line,
                ErrorKind::Unsupported,
                format!(
                    "G10 {l} {} (coordinate system rotation) is not supported",
                    w.text
                ),
            ));
        }
        p.claim("G10", self, line)?;
        let which = "P1 = G54 .. P9 = G59.3, P0 = the one in effect";
        let Some(pv) = values.get('P') else {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!("G10 {l} without P: name the coordinate system ({which})"),
            ));
        };
        let p_text = values.word('P').map(|w| w.text.clone()).unwrap_or_default();
        let Some(pn) = whole(pv, 0, WORK_SYSTEMS) else {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!(
                    "G10 {l} {p_text}: the coordinate system must be a whole number from 0 to \
                     {WORK_SYSTEMS} ({which})"
                ),
            ));
        };
        let system = if pn == 0 { self.frames.active } else { pn - 1 };
        let k = self.unit_mm();
        let given = axes.map(|v| v.map(|v| v * k));
        let origin = if here {
            self.frames.work_here(self.pos, given)
        } else {
            given
        };
        for (a, v) in origin.iter().enumerate() {
            if let Some(v) = v {
                if !(v.abs() <= MAX_WORK_OFFSET_MM) {
                    return Err(self.error(
                        line,
                        ErrorKind::Invalid,
                        format!(
                            "G10 {l} {p_text}: the {} origin's {} would be {v:.3} mm from machine \
                             zero, beyond the ±{MAX_WORK_OFFSET_MM} mm a work offset may be",
                            system_code(system),
                            AXIS_NAMES.get(a).copied().unwrap_or('?'),
                        ),
                    ));
                }
            }
        }
        self.frames.set_work(system, origin);
        Ok(())
    }

    /// G10 L1 P<tool> [Z<length>] [R<radius>]: the tool table entry.
    fn g10_tool(
        &mut self,
        line: u32,
        axes: [Option<f64>; 3],
        values: &mut Values<'_>,
        p: &mut POwner,
    ) -> Result<(), Error> {
        if let Some(w) = [0, 1]
            .iter()
            .filter(|&&a| axes[a].is_some())
            .find_map(|&a| values.word(AXIS_NAMES.get(a).copied().unwrap_or('X')))
        {
            return Err(self.error(
                line,
                ErrorKind::Unsupported,
                format!(
                    "G10 L1 {} (a tool offset across the spindle) is not supported",
                    w.text
                ),
            ));
        }
        p.claim("G10", self, line)?;
        let tools = self.frames.tools.len();
        let Some(pv) = values.get('P') else {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!("G10 L1 without P: name the tool ({})", table_size(tools)),
            ));
        };
        let p_text = values.word('P').map(|w| w.text.clone()).unwrap_or_default();
        let Some(n) = whole(pv, 1, tools) else {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!(
                    "G10 L1 {p_text}: the tool must be a whole number in the table ({})",
                    table_size(tools)
                ),
            ));
        };
        let k = self.unit_mm();
        let r = values.get('R');
        let length = axes[2].map(|z| z * k);
        if length.is_none() && r.is_none() {
            return Err(self.error(
                line,
                ErrorKind::Invalid,
                format!("G10 L1 {p_text} without Z or R has no effect"),
            ));
        }
        if let Some(len) = length {
            if !(len.abs() <= MAX_TOOL_LENGTH_MM) {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!(
                        "G10 L1 {p_text}: the tool length {len:.3} mm is beyond the \
                         ±{MAX_TOOL_LENGTH_MM} mm a tool may have"
                    ),
                ));
            }
        }
        let diameter = match r {
            Some(r) if !(r >= 0.0) => {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!("G10 L1 {p_text} R{r}: the tool radius must not be negative"),
                ))
            }
            Some(r) if !(2.0 * r * k <= MAX_TOOL_DIAMETER_MM) => {
                return Err(self.error(
                    line,
                    ErrorKind::Invalid,
                    format!(
                        "G10 L1 {p_text} R{r}: the diameter {:.3} mm is beyond the \
                         {MAX_TOOL_DIAMETER_MM} mm a tool may have",
                        2.0 * r * k
                    ),
                ))
            }
            Some(r) => Some(2.0 * r * k),
            None => None,
        };
        if let Some(t) = self.frames.tool_mut(n) {
            if let Some(len) = length {
                t.length_mm = len;
            }
            if let Some(d) = diameter {
                t.diameter_mm = d;
            }
        }
        Ok(())
    }
}
