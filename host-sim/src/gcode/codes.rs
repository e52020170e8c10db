//! The G and M codes the interpreter knows: what each one is ([`Cmd`]), its RS274NGC
//! modal group ([`Group`], two of one group on a line are a conflict), and for the codes
//! it does not support, what they are (for the "is not supported" message).

use super::Plane;

/// Modal motion mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum MotionMode {
    Rapid,
    Linear,
    Cw,
    Ccw,
}

impl MotionMode {
    pub(super) fn code(self) -> &'static str {
        match self {
            MotionMode::Rapid => "G0",
            MotionMode::Linear => "G1",
            MotionMode::Cw => "G2",
            MotionMode::Ccw => "G3",
        }
    }
}

/// Tool length offset commands (modal group 8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ToolLength {
    /// G43 H<n>: tool n's length from the table.
    Table,
    /// G43.1 Z<len>: the given length.
    Dynamic,
    /// G49: none.
    Cancel,
}

/// A supported G or M command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Cmd {
    /// G0–G3; `None` is G80 (motion cancel).
    Motion(Option<MotionMode>),
    Plane(Plane),
    Distance {
        incremental: bool,
    },
    /// G90.1 (absolute) / G91.1 (incremental, the default) arc centres.
    ArcCentre {
        absolute: bool,
    },
    Units {
        inches: bool,
    },
    /// G93 (inverse time) / G94 (units per minute, the default).
    FeedMode {
        inverse_time: bool,
    },
    /// G40: accepted, ignored (cutter compensation is never on).
    NoEffect,
    ToolLength(ToolLength),
    /// G54 .. G59.3: the coordinate system of that index.
    WorkSystem(usize),
    /// G61.
    ExactPath,
    /// G61.1.
    ExactStop,
    /// G64.
    Blending,
    Dwell,
    /// G10 (L1, L2, L20).
    SetTable,
    Home,
    /// G52.
    LocalOffset,
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
pub(super) enum Group {
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
    pub(super) fn name(self) -> &'static str {
        match self {
            Group::NonModal => "non-modal (G4, G10, G28, G52, G53, G92)",
            Group::Motion => "motion (G0, G1, G2, G3, G80)",
            Group::Plane => "plane (G17, G18, G19)",
            Group::Distance => "distance mode (G90, G91)",
            Group::ArcDistance => "arc distance mode (G90.1, G91.1)",
            Group::FeedMode => "feed rate mode (G93, G94)",
            Group::Units => "units (G20, G21)",
            Group::CutterComp => "cutter compensation (G40)",
            Group::ToolLength => "tool length offset (G43, G43.1, G49)",
            Group::WorkOffset => "coordinate system (G54 … G59.3)",
            Group::PathControl => "path control (G61, G61.1, G64)",
            Group::Stopping => "stopping (M0, M2, M30)",
            Group::Spindle => "spindle (M3, M4, M5)",
            Group::Coolant => "coolant (M7, M8, M9)",
        }
    }
}

/// A G/M number ×10 (`G91.1` → 911), if it has at most one decimal.
pub(super) fn code10(value: f64) -> Option<u32> {
    let x = value * 10.0;
    let r = x.round();
    ((0.0..=1e9).contains(&r) && (x - r).abs() <= 1e-6).then_some(r as u32)
}

/// `G91.1`, `M3`: the code as RS274NGC names it.
pub(super) fn code_name(letter: char, c10: u32) -> String {
    if c10.is_multiple_of(10) {
        format!("{letter}{}", c10 / 10)
    } else {
        format!("{letter}{}.{}", c10 / 10, c10 % 10)
    }
}

pub(super) fn classify_g(c10: u32) -> Result<(Cmd, Group), Option<&'static str>> {
    use Group as Gr;
    Ok(match c10 {
        0 => (Cmd::Motion(Some(MotionMode::Rapid)), Gr::Motion),
        10 => (Cmd::Motion(Some(MotionMode::Linear)), Gr::Motion),
        20 => (Cmd::Motion(Some(MotionMode::Cw)), Gr::Motion),
        30 => (Cmd::Motion(Some(MotionMode::Ccw)), Gr::Motion),
        800 => (Cmd::Motion(None), Gr::Motion),
        40 => (Cmd::Dwell, Gr::NonModal),
        100 => (Cmd::SetTable, Gr::NonModal),
        280 => (Cmd::Home, Gr::NonModal),
        520 => (Cmd::LocalOffset, Gr::NonModal),
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
        901 => (Cmd::ArcCentre { absolute: true }, Gr::ArcDistance),
        911 => (Cmd::ArcCentre { absolute: false }, Gr::ArcDistance),
        930 => (Cmd::FeedMode { inverse_time: true }, Gr::FeedMode),
        940 => (
            Cmd::FeedMode {
                inverse_time: false,
            },
            Gr::FeedMode,
        ),
        400 => (Cmd::NoEffect, Gr::CutterComp),
        430 => (Cmd::ToolLength(ToolLength::Table), Gr::ToolLength),
        431 => (Cmd::ToolLength(ToolLength::Dynamic), Gr::ToolLength),
        490 => (Cmd::ToolLength(ToolLength::Cancel), Gr::ToolLength),
        540 => (Cmd::WorkSystem(0), Gr::WorkOffset),
        550 => (Cmd::WorkSystem(1), Gr::WorkOffset),
        560 => (Cmd::WorkSystem(2), Gr::WorkOffset),
        570 => (Cmd::WorkSystem(3), Gr::WorkOffset),
        580 => (Cmd::WorkSystem(4), Gr::WorkOffset),
        590 => (Cmd::WorkSystem(5), Gr::WorkOffset),
        591 => (Cmd::WorkSystem(6), Gr::WorkOffset),
        592 => (Cmd::WorkSystem(7), Gr::WorkOffset),
        593 => (Cmd::WorkSystem(8), Gr::WorkOffset),
        610 => (Cmd::ExactPath, Gr::PathControl),
        611 => (Cmd::ExactStop, Gr::PathControl),
        640 => (Cmd::Blending, Gr::PathControl),
        _ => return Err(describe_unsupported_g(c10)),
    })
}

fn describe_unsupported_g(c10: u32) -> Option<&'static str> {
    Some(match c10 {
        50..=53 => "spline",
        70 | 80 => "lathe diameter/radius mode",
        150 | 160 => "polar coordinates",
        281 | 301 => "storing a home position",
        300 => "second home position",
        330 | 331 => "spindle-synchronised motion",
        382..=385 => "probing",
        410 | 411 | 420 | 421 => "cutter radius compensation",
        432 => "adding tool length offsets",
        500 | 510 => "scaling",
        680 | 690 => "coordinate rotation",
        730 | 760 => "canned cycle",
        c if (810..=890).contains(&c) && c.is_multiple_of(10) => "canned cycle",
        922 | 923 => "suspending G92 offsets",
        950 => "feed per revolution",
        960 | 970 => "spindle speed mode",
        980 | 990 => "canned cycle return mode",
        _ => return None,
    })
}

pub(super) fn classify_m(c10: u32) -> Result<(Cmd, Group), Option<&'static str>> {
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
