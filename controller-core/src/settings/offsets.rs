//! The work coordinate systems (G54..G59.3) and the tool table: settings of the machine
//! that no servo parameter depends on. The host's G-code interpreter reads them when it
//! parses a program (a work origin and a tool length shift the programmed coordinates to
//! machine coordinates) and writes back what a program's G10 changed, as LinuxCNC keeps
//! them in its parameter file. They are kept here so that they live with the machine (and
//! its flash) rather than with whichever host last talked to it.
//!
//! Keys: `work.<cs>.{x,y,z}_mm` for the nine systems `cs` = `g54`, `g55`, `g56`, `g57`,
//! `g58`, `g59`, `g59_1`, `g59_2`, `g59_3` (the G-code with its dot written `_`), and
//! `tool.<n>.{length_mm,diameter_mm}` for tools `n` = 1..=[`TOOL_COUNT`]. The fields are
//! named so that the serde form (TOML export, the registry test) has the keys' segments;
//! [`WorkOffsets::get`] and [`ToolTable::get`] index them as the interpreter counts them.

/// Work coordinate systems: G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3.
pub const WORK_SYSTEMS: usize = 9;

/// Tools in the tool table (`H1` .. `H8`). Sized against the RAM a settings tree costs:
/// the tree is copied into every slot of the link's queues (about 50 copies), so each tool
/// (8 bytes) costs about 400 bytes of the board's RAM; 8 tools cover a manual-change
/// router's set (the firmware's size notes, firmware/README-firmware.md).
pub const TOOL_COUNT: usize = 8;

/// One coordinate system: the machine position of its origin (G10 L2 values), mm.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct WorkOffset {
    pub x_mm: f32,
    pub y_mm: f32,
    pub z_mm: f32,
}

impl WorkOffset {
    /// The origin at machine zero.
    pub const ZERO: Self = Self {
        x_mm: 0.0,
        y_mm: 0.0,
        z_mm: 0.0,
    };

    /// `[x, y, z]`, mm.
    pub const fn to_array(&self) -> [f32; 3] {
        [self.x_mm, self.y_mm, self.z_mm]
    }

    /// From `[x, y, z]`, mm.
    pub const fn from_array(v: [f32; 3]) -> Self {
        Self {
            x_mm: v[0],
            y_mm: v[1],
            z_mm: v[2],
        }
    }
}

/// The nine work coordinate systems, one field per G-code (G59.1 is `g59_1`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct WorkOffsets {
    pub g54: WorkOffset,
    pub g55: WorkOffset,
    pub g56: WorkOffset,
    pub g57: WorkOffset,
    pub g58: WorkOffset,
    pub g59: WorkOffset,
    pub g59_1: WorkOffset,
    pub g59_2: WorkOffset,
    pub g59_3: WorkOffset,
}

impl WorkOffsets {
    /// Every origin at machine zero (the factory value, and LinuxCNC's empty parameter file).
    pub const ZERO: Self = Self {
        g54: WorkOffset::ZERO,
        g55: WorkOffset::ZERO,
        g56: WorkOffset::ZERO,
        g57: WorkOffset::ZERO,
        g58: WorkOffset::ZERO,
        g59: WorkOffset::ZERO,
        g59_1: WorkOffset::ZERO,
        g59_2: WorkOffset::ZERO,
        g59_3: WorkOffset::ZERO,
    };

    /// The key segments of the systems, in G-code order (index 0 = G54).
    pub const NAMES: [&'static str; WORK_SYSTEMS] = [
        "g54", "g55", "g56", "g57", "g58", "g59", "g59_1", "g59_2", "g59_3",
    ];

    /// System `i` (0 = G54 .. 8 = G59.3).
    pub const fn get(&self, i: usize) -> Option<&WorkOffset> {
        Some(match i {
            0 => &self.g54,
            1 => &self.g55,
            2 => &self.g56,
            3 => &self.g57,
            4 => &self.g58,
            5 => &self.g59,
            6 => &self.g59_1,
            7 => &self.g59_2,
            8 => &self.g59_3,
            _ => return None,
        })
    }

    /// System `i`, to change it.
    pub fn get_mut(&mut self, i: usize) -> Option<&mut WorkOffset> {
        Some(match i {
            0 => &mut self.g54,
            1 => &mut self.g55,
            2 => &mut self.g56,
            3 => &mut self.g57,
            4 => &mut self.g58,
            5 => &mut self.g59,
            6 => &mut self.g59_1,
            7 => &mut self.g59_2,
            8 => &mut self.g59_3,
            _ => return None,
        })
    }

    /// Every system's origin `[x, y, z]`, mm, in G-code order.
    pub fn to_array(&self) -> [[f32; 3]; WORK_SYSTEMS] {
        core::array::from_fn(|i| self.get(i).map_or([0.0; 3], WorkOffset::to_array))
    }
}

/// One tool of the tool table.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ToolSettings {
    /// Tool length offset (G43 H), mm: LinuxCNC's sign, positive for a tool longer than
    /// the reference one, so that G43 raises the spindle by it (machine Z = programmed Z +
    /// length).
    pub length_mm: f32,
    /// Cutter diameter, mm (kept for the tool table; cutter compensation is not supported).
    pub diameter_mm: f32,
}

impl ToolSettings {
    /// An entry nobody measured: no length offset, no diameter.
    pub const EMPTY: Self = Self {
        length_mm: 0.0,
        diameter_mm: 0.0,
    };
}

/// The tool table, tools 1..=[`TOOL_COUNT`] (the serde names are the tool numbers).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ToolTable {
    #[cfg_attr(feature = "serde", serde(rename = "1"))]
    pub t1: ToolSettings,
    #[cfg_attr(feature = "serde", serde(rename = "2"))]
    pub t2: ToolSettings,
    #[cfg_attr(feature = "serde", serde(rename = "3"))]
    pub t3: ToolSettings,
    #[cfg_attr(feature = "serde", serde(rename = "4"))]
    pub t4: ToolSettings,
    #[cfg_attr(feature = "serde", serde(rename = "5"))]
    pub t5: ToolSettings,
    #[cfg_attr(feature = "serde", serde(rename = "6"))]
    pub t6: ToolSettings,
    #[cfg_attr(feature = "serde", serde(rename = "7"))]
    pub t7: ToolSettings,
    #[cfg_attr(feature = "serde", serde(rename = "8"))]
    pub t8: ToolSettings,
}

impl ToolTable {
    /// Every tool without length or diameter (the factory value).
    pub const EMPTY: Self = Self {
        t1: ToolSettings::EMPTY,
        t2: ToolSettings::EMPTY,
        t3: ToolSettings::EMPTY,
        t4: ToolSettings::EMPTY,
        t5: ToolSettings::EMPTY,
        t6: ToolSettings::EMPTY,
        t7: ToolSettings::EMPTY,
        t8: ToolSettings::EMPTY,
    };

    /// Tool `number` (1..=[`TOOL_COUNT`]; 0 and beyond: `None`).
    pub const fn get(&self, number: usize) -> Option<&ToolSettings> {
        Some(match number {
            1 => &self.t1,
            2 => &self.t2,
            3 => &self.t3,
            4 => &self.t4,
            5 => &self.t5,
            6 => &self.t6,
            7 => &self.t7,
            8 => &self.t8,
            _ => return None,
        })
    }

    /// Tool `number`, to change it.
    pub fn get_mut(&mut self, number: usize) -> Option<&mut ToolSettings> {
        Some(match number {
            1 => &mut self.t1,
            2 => &mut self.t2,
            3 => &mut self.t3,
            4 => &mut self.t4,
            5 => &mut self.t5,
            6 => &mut self.t6,
            7 => &mut self.t7,
            8 => &mut self.t8,
            _ => return None,
        })
    }
}

// the table's fields and its accessors cover exactly the tools 1..=TOOL_COUNT
const _: () = assert!(ToolTable::EMPTY.get(TOOL_COUNT).is_some());
const _: () = assert!(ToolTable::EMPTY.get(TOOL_COUNT + 1).is_none());
const _: () = assert!(WorkOffsets::ZERO.get(WORK_SYSTEMS - 1).is_some());
const _: () = assert!(WorkOffsets::ZERO.get(WORK_SYSTEMS).is_none());

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn systems_and_tools_are_indexed_as_the_g_code_counts_them() {
        let mut w = WorkOffsets::ZERO;
        for i in 0..WORK_SYSTEMS {
            if let Some(o) = w.get_mut(i) {
                *o = WorkOffset::from_array([i as f32, 10.0 * i as f32, -(i as f32)]);
            }
        }
        assert_eq!(w.g54.to_array(), [0.0, 0.0, 0.0]);
        assert_eq!(w.g59.to_array(), [5.0, 50.0, -5.0]);
        assert_eq!(w.g59_3.to_array(), [8.0, 80.0, -8.0]);
        assert_eq!(w.to_array()[7], [7.0, 70.0, -7.0]);
        assert!(w.get_mut(WORK_SYSTEMS).is_none());

        let mut t = ToolTable::EMPTY;
        assert!(t.get(0).is_none() && t.get_mut(0).is_none());
        for n in 1..=TOOL_COUNT {
            if let Some(tool) = t.get_mut(n) {
                tool.length_mm = n as f32;
            }
        }
        assert_eq!((t.t1.length_mm, t.t8.length_mm), (1.0, 8.0));
        assert!(t.get_mut(TOOL_COUNT + 1).is_none());
    }
}
