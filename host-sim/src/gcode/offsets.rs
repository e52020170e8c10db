//! The interpreter's coordinate frames (RS274NGC / LinuxCNC): a programmed point is
//! shifted to machine coordinates by the active work coordinate system's origin (G54 ..
//! G59.3, set by G10 L2 / L20), the G92 / G52 offset (one shared register, as LinuxCNC's)
//! and, on Z, the tool length offset in effect (G43 H, G43.1; G49 cancels):
//!
//! ```text
//! machine = programmed + work[active] + g92 + (tool length on Z)
//! ```
//!
//! Everything here is in mm; the interpreter converts program units before it calls in.

/// Coordinate systems G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3 (LinuxCNC's 1..9).
pub const WORK_SYSTEMS: usize = 9;

/// The G-code that selects each system, by index (0 = G54).
pub const WORK_SYSTEM_CODES: [&str; WORK_SYSTEMS] = [
    "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
];

/// The origins of the nine systems in machine coordinates (mm), `[system][axis]`.
pub type WorkOffsets = [[f64; 3]; WORK_SYSTEMS];

/// Largest magnitude of a work origin G10 may set (mm): the machine's settings range of
/// `work.<cs>.*_mm` (controller-core's key registry; a test keeps them equal), so that a
/// program's G10 can always be written back.
pub const MAX_WORK_OFFSET_MM: f64 = 10_000.0;
/// Largest magnitude of a tool length G10 L1 may set (mm): `tool.<n>.length_mm`'s range.
pub const MAX_TOOL_LENGTH_MM: f64 = 1_000.0;
/// Largest cutter diameter G10 L1 R may set (mm): `tool.<n>.diameter_mm`'s range.
pub const MAX_TOOL_DIAMETER_MM: f64 = 1_000.0;

/// One entry of the tool table (tool `n` is entry `n − 1`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Tool {
    /// Tool length offset G43 applies to Z (mm), LinuxCNC's sign: machine Z = programmed
    /// Z + length.
    pub length_mm: f64,
    /// Cutter diameter (mm), kept for the table (no cutter compensation).
    pub diameter_mm: f64,
}

/// The offsets in effect while a program is interpreted.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Frames {
    /// The systems' origins, as G10 leaves them.
    pub work_mm: WorkOffsets,
    /// Index of the active system (0 = G54).
    pub active: usize,
    /// The G92 / G52 offset (mm, added after the work origin).
    pub g92_mm: [f64; 3],
    /// The tool length offset in effect on Z (mm; 0 without G43).
    pub tool_length_mm: f64,
    /// The tool table, as G10 L1 leaves it.
    pub tools: Vec<Tool>,
}

impl Frames {
    /// At program start: G54, no G92 / G52 offset, no tool length offset.
    pub fn new(work_mm: WorkOffsets, tools: Vec<Tool>) -> Self {
        Self {
            work_mm,
            active: 0,
            g92_mm: [0.0; 3],
            tool_length_mm: 0.0,
            tools,
        }
    }

    /// Machine minus programmed coordinate on `axis` (0 = X, 1 = Y, 2 = Z).
    pub fn origin_mm(&self, axis: usize) -> f64 {
        let work = self
            .work_mm
            .get(self.active)
            .and_then(|w| w.get(axis))
            .copied()
            .unwrap_or(0.0);
        let g92 = self.g92_mm.get(axis).copied().unwrap_or(0.0);
        work + g92 + self.tool_on(axis)
    }

    /// The tool length offset's share on `axis` (it acts on Z only).
    fn tool_on(&self, axis: usize) -> f64 {
        if axis == 2 {
            self.tool_length_mm
        } else {
            0.0
        }
    }

    /// G92: the G92 offset of the given axes such that the machine position `pos_mm` gets
    /// the programmed coordinates `axes_mm`; the other axes keep theirs (LinuxCNC).
    pub fn set_g92(&mut self, pos_mm: [f64; 3], axes_mm: [Option<f64>; 3]) {
        for (a, v) in axes_mm.iter().enumerate() {
            if let Some(v) = v {
                let work = self.work_mm[self.active][a];
                self.g92_mm[a] = pos_mm[a] - work - self.tool_on(a) - v;
            }
        }
    }

    /// G52: the given axes' offset (the same register as G92) is the given value; `G52 X0
    /// Y0 Z0` cancels it.
    pub fn set_g52(&mut self, axes_mm: [Option<f64>; 3]) {
        for (a, v) in axes_mm.iter().enumerate() {
            if let Some(v) = v {
                self.g92_mm[a] = *v;
            }
        }
    }

    /// G92.1: no G92 / G52 offset.
    pub fn clear_g92(&mut self) {
        self.g92_mm = [0.0; 3];
    }

    /// G10 L2: the given axes of `system`'s origin; the others keep theirs.
    pub fn set_work(&mut self, system: usize, axes_mm: [Option<f64>; 3]) {
        if let Some(w) = self.work_mm.get_mut(system) {
            for (a, v) in axes_mm.iter().enumerate() {
                if let Some(v) = v {
                    w[a] = *v;
                }
            }
        }
    }

    /// G10 L20: the origin a system needs on the given axes such that the machine position
    /// `pos_mm` has the given coordinates in it, with the G92 / G52 offset and the tool
    /// length offset in effect (as LinuxCNC computes it: the same for every system); the
    /// result, not yet stored.
    pub fn work_here(&self, pos_mm: [f64; 3], axes_mm: [Option<f64>; 3]) -> [Option<f64>; 3] {
        let mut out = [None; 3];
        for (a, v) in axes_mm.iter().enumerate() {
            if let Some(v) = v {
                out[a] = Some(pos_mm[a] - self.g92_mm[a] - self.tool_on(a) - v);
            }
        }
        out
    }

    /// Tool `number` (1-based) of the table.
    pub fn tool(&self, number: usize) -> Option<Tool> {
        number
            .checked_sub(1)
            .and_then(|i| self.tools.get(i))
            .copied()
    }

    /// Tool `number` (1-based), to change it.
    pub fn tool_mut(&mut self, number: usize) -> Option<&mut Tool> {
        number.checked_sub(1).and_then(|i| self.tools.get_mut(i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames() -> Frames {
        let mut work = [[0.0; 3]; WORK_SYSTEMS];
        work[0] = [100.0, 50.0, -10.0];
        work[1] = [200.0, 0.0, -20.0];
        Frames::new(
            work,
            vec![Tool {
                length_mm: 30.0,
                diameter_mm: 6.0,
            }],
        )
    }

    #[test]
    fn machine_is_program_plus_origin_g92_and_tool_length() {
        let mut f = frames();
        assert_eq!([0, 1, 2].map(|a| f.origin_mm(a)), [100.0, 50.0, -10.0]);
        f.active = 1;
        f.tool_length_mm = 30.0;
        f.set_g52([Some(5.0), None, Some(1.0)]);
        assert_eq!([0, 1, 2].map(|a| f.origin_mm(a)), [205.0, 0.0, 11.0]);
        // G92 makes machine (210, 3, 20) the point (0, 0, 0) of G55 with the tool
        f.set_g92([210.0, 3.0, 20.0], [Some(0.0), Some(0.0), Some(0.0)]);
        assert_eq!(f.g92_mm, [10.0, 3.0, 10.0]);
        assert_eq!([0, 1, 2].map(|a| f.origin_mm(a)), [210.0, 3.0, 20.0]);
        f.clear_g92();
        assert_eq!(f.g92_mm, [0.0; 3]);
    }

    #[test]
    fn g10_l20_makes_the_current_point_the_given_coordinates() {
        let mut f = frames();
        f.tool_length_mm = 30.0;
        f.g92_mm = [1.0, 2.0, 3.0];
        // machine (150, 60, 40) is to become X0 Z5 of G56 (system 2)
        let new = f.work_here([150.0, 60.0, 40.0], [Some(0.0), None, Some(5.0)]);
        assert_eq!(new, [Some(149.0), None, Some(2.0)]);
        f.set_work(2, new);
        assert_eq!(f.work_mm[2], [149.0, 0.0, 2.0]);
        f.active = 2;
        // back in program coordinates: X = 150 − 149 − 1 = 0, Z = 40 − 2 − 3 − 30 = 5
        assert_eq!(150.0 - f.origin_mm(0), 0.0);
        assert_eq!(40.0 - f.origin_mm(2), 5.0);
    }

    #[test]
    fn tools_are_numbered_from_one() {
        let mut f = frames();
        assert_eq!(f.tool(0), None);
        assert_eq!(f.tool(1).map(|t| t.length_mm), Some(30.0));
        assert_eq!(f.tool(2), None);
        if let Some(t) = f.tool_mut(1) {
            t.diameter_mm = 8.0;
        }
        assert_eq!(f.tools[0].diameter_mm, 8.0);
        assert!(f.tool_mut(0).is_none());
    }
}
