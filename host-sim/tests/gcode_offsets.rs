//! The LinuxCNC part of the front end, with numbers: work coordinate systems G54..G59.3,
//! G10 L1/L2/L20, G52 with G92, tool length offsets G43 H / G43.1 / G49, absolute arc
//! centres G90.1, inverse-time feed G93 / G94, G64 P Q, G61 / G61.1; every rejection with
//! its FILE:LINE and message.

use std::f64::consts::PI;

use host_sim::gcode::{
    check_travel, parse_str_with, Blend, ErrorKind, Move, MoveKind, ParseOptions, Program, Tool,
    Travel, WorkOffsets, WORK_SYSTEMS,
};

/// G54 at (100, 50, −10), G55 at (200, 0, −20), G56..G59.3 at (10·i, −5·i, i) for system i.
fn work() -> WorkOffsets {
    let mut w = [[0.0; 3]; WORK_SYSTEMS];
    for (i, o) in w.iter_mut().enumerate() {
        let i = i as f64;
        *o = [10.0 * i, -5.0 * i, i];
    }
    w[0] = [100.0, 50.0, -10.0];
    w[1] = [200.0, 0.0, -20.0];
    w
}

/// Eight tools: tool n is n × 10 mm long and n mm in diameter.
fn tools() -> Vec<Tool> {
    (1..=8)
        .map(|n| Tool {
            length_mm: 10.0 * f64::from(n),
            diameter_mm: f64::from(n),
        })
        .collect()
}

fn opts() -> ParseOptions {
    ParseOptions {
        work_offsets_mm: work(),
        tools: tools(),
        ..ParseOptions::default()
    }
}

fn ok(text: &str) -> Program {
    parse_str_with("prog.nc", text, &opts()).unwrap_or_else(|e| panic!("{e}"))
}

fn err(text: &str) -> String {
    match parse_str_with("prog.nc", text, &opts()) {
        Ok(p) => panic!("accepted: {:?}", p.moves),
        Err(e) => e.to_string(),
    }
}

fn kind(text: &str) -> ErrorKind {
    parse_str_with("prog.nc", text, &opts()).unwrap_err().kind
}

/// End points of the straight and arc moves.
fn ends(p: &Program) -> Vec<[f64; 3]> {
    p.moves
        .iter()
        .filter(|m| {
            matches!(
                m.kind,
                MoveKind::Rapid { .. } | MoveKind::Line { .. } | MoveKind::Arc { .. }
            )
        })
        .map(Move::to)
        .collect()
}

fn feeds(p: &Program) -> Vec<f64> {
    p.moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Line { feed_mm_s, .. } | MoveKind::Arc { feed_mm_s, .. } => Some(feed_mm_s),
            _ => None,
        })
        .collect()
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() < 1e-9)
}

#[test]
fn the_nine_coordinate_systems_shift_programmed_points_and_g54_is_the_start() {
    let text = "G0 X1 Y2 Z3\nG55 X1 Y2 Z3\nG56 X1\nG57 X1\nG58 X1\nG59 X1\nG59.1 X1\nG59.2 X1\n\
                G59.3 X1 Y2 Z3\nG53 X0 Y0 Z0\nX0\nG54 X0\n";
    let p = ok(text);
    assert_eq!(
        ends(&p),
        [
            // G54 in effect at the start: (1, 2, 3) + (100, 50, −10)
            [101.0, 52.0, -7.0],
            [201.0, 2.0, -17.0],
            // only X given: Y and Z stay where the machine is
            [21.0, 2.0, -17.0],
            [31.0, 2.0, -17.0],
            [41.0, 2.0, -17.0],
            [51.0, 2.0, -17.0],
            [61.0, 2.0, -17.0],
            [71.0, 2.0, -17.0],
            [81.0, -38.0, 11.0],
            // G53: machine coordinates for one line, G59.3 still in effect after it
            [0.0, 0.0, 0.0],
            [80.0, 0.0, 0.0],
            [100.0, 0.0, 0.0],
        ]
    );
    // nothing changed the systems
    assert_eq!(p.work_offsets_mm, work());
    assert!(p.work_offset_changes(&opts()).is_empty());
    assert_eq!(
        err("G54 G55"),
        "prog.nc:1: G54 and G55 on one line: both are in the coordinate system (G54 … G59.3) group"
    );
    assert_eq!(kind("G59.1 G59.2"), ErrorKind::ModalConflict);
}

#[test]
fn g10_l2_sets_a_systems_origin_and_the_axes_not_given_keep_theirs() {
    let p = ok("G10 L2 P2 X10 Y20\nG55 G0 X0 Y0 Z0\nG10 L2 P0 Z-5\nG0 Z1\n\
                G20 G91 G10 L2 P9 X1\nG21 G90 G59.3 G0 X0\n");
    assert_eq!(
        ends(&p),
        [
            // G55 was (200, 0, −20): X and Y replaced, Z kept
            [10.0, 20.0, -20.0],
            // P0 = the system in effect (G55), and it takes effect at once
            [10.0, 20.0, -4.0],
            // G59.3's X set in inches (1 in), G91 has no effect on G10
            [25.4, 20.0, -4.0],
        ]
    );
    let mut expected = work();
    expected[1] = [10.0, 20.0, -5.0];
    expected[8][0] = 25.4;
    assert_eq!(p.work_offsets_mm, expected);
    assert_eq!(
        p.work_offset_changes(&opts()),
        [(1, 0, 10.0), (1, 1, 20.0), (1, 2, -5.0), (8, 0, 25.4)]
    );
    // no axis words: nothing to set (LinuxCNC accepts it)
    assert_eq!(ok("G10 L2 P3").work_offsets_mm, work());
}

#[test]
fn g10_l20_makes_the_current_point_the_given_coordinates() {
    // machine (130, 90, ·) in G54; X0 Y0 there: G54's origin becomes (130, 90)
    let p = ok("G0 X30 Y40\nG10 L20 P1 X0 Y0\nG0 X5 Y-5\n");
    assert_eq!(p.work_offsets_mm[0], [130.0, 90.0, -10.0]);
    assert_eq!(ends(&p)[1], [135.0, 85.0, 0.0]);
    // with a G92 offset and a tool length offset in effect: the current point still gets
    // the given coordinates in the system it is set for (here G57, not the active one)
    let p = ok("G43 H2\nG0 X0 Y0 Z0\nG92 X1 Z1\nG10 L20 P4 X2 Z3\nG57 G0 X2 Z3\n");
    // machine after line 2: (100, 50, −10 + 20) = (100, 50, 10); G92 X1 Z1 there: an
    // offset of (−1, ·, −1); G57's origin = machine − G92 − tool − given:
    // X 100 + 1 − 2 = 99, Z 10 + 1 − 20 − 3 = −12 (Y not given: kept at −15)
    assert_eq!(p.work_offsets_mm[3], [99.0, -15.0, -12.0]);
    // G57 then puts X2 Z3 exactly where the machine was: no motion (a zero-length move)
    assert_eq!(ends(&p).len(), 1);
    assert_eq!(p.moves.last().map(Move::to), Some([100.0, 50.0, 10.0]));
}

#[test]
fn g10_l1_sets_a_tool_and_g43_takes_it_only_when_programmed_again() {
    let p = ok("G43 H1\nG0 Z5\nG10 L1 P1 Z50 R3\nG0 X0 Z1\nG43 H1\nG0 Z0\nG10 L1 P2 R0.5\n");
    assert_eq!(
        ends(&p),
        [
            // tool 1 was 10 mm: G54's Z −10 + 10 + 5
            [0.0, 0.0, 5.0],
            // the table changed, the offset in effect did not (LinuxCNC)
            [100.0, 0.0, 1.0],
            // G43 H1 again: 50 mm
            [100.0, 0.0, 40.0],
        ]
    );
    assert_eq!(
        p.tools[0],
        Tool {
            length_mm: 50.0,
            diameter_mm: 6.0
        }
    );
    // R alone: the diameter only
    assert_eq!(
        p.tools[1],
        Tool {
            length_mm: 20.0,
            diameter_mm: 1.0
        }
    );
    assert_eq!(p.tool_changes(&opts()), [(1, p.tools[0]), (2, p.tools[1])]);
    // inches
    let p = ok("G20 G10 L1 P3 Z1 R0.25\n");
    assert_eq!(
        p.tools[2],
        Tool {
            length_mm: 25.4,
            diameter_mm: 12.7
        }
    );
}

#[test]
fn tool_length_offsets_shift_z_by_the_length_in_linuxcncs_sign() {
    let text = "G0 X0 Y0 Z0\nG43 H3\nX5\nZ0\nG0 G43 Z15 H1\nG43 H0 Z0\nG43.1 Z-1.5\nZ0\n\
                G20 G43.1 Z1\nG0 Z0\nG21 G49\nZ0\nG43 H2\nG91 Z1\nG90 G53 Z0\n";
    let p = ok(text);
    let got = ends(&p);
    let want = [
        [100.0, 50.0, -10.0],
        // G43 moves nothing: X alone keeps the machine's Z
        [105.0, 50.0, -10.0],
        // the next Z is compensated: a 30 mm tool lifts the spindle by 30
        [105.0, 50.0, 20.0],
        // the CAM idiom: G43 with H and the Z on one line, the offset first
        [105.0, 50.0, 15.0],
        // H0: no offset
        [105.0, 50.0, -10.0],
        // G43.1: the given length
        [105.0, 50.0, -11.5],
        // in inches: 25.4 mm
        [105.0, 50.0, 15.4],
        // G49 cancels
        [105.0, 50.0, -10.0],
        // incremental Z after a new offset: an increment, no jump
        [105.0, 50.0, -9.0],
        // G53 is machine coordinates, the tool length not applied
        [105.0, 50.0, 0.0],
    ];
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        assert!(close(*g, w), "{got:?}");
    }
    // arcs in G18 and G19 see the length on their Z too, and on the centre
    let p = ok("G18 G43 H1\nG0 X0 Z0\nG90.1 G2 X0 Z20 I0 K10 F600\n");
    match p.moves.last().map(|m| m.kind) {
        Some(MoveKind::Arc { to, center, .. }) => {
            assert!(close(to, [100.0, 0.0, 20.0]), "{to:?}");
            assert!(close(center, [100.0, 0.0, 10.0]), "{center:?}");
        }
        k => panic!("{k:?}"),
    }
}

#[test]
fn g52_is_the_g92_offset_set_directly() {
    let text =
        "G52 X10 Y-5\nG0 X0 Y0 Z0\nG52 X0\nG0 X0 Y0\nG92 X0\nG52 Y0\nG0 X1 Y1\nG92.1\nG0 X0 Y0\n\
                G91 G52 Z2\nG90 G0 Z0\n";
    let p = ok(text);
    assert_eq!(
        ends(&p),
        [
            // G54 + (10, −5)
            [110.0, 45.0, -10.0],
            // G52 X0 cancels X only
            [100.0, 45.0, -10.0],
            // G92 X0 at machine X 100 (same register): offset X 0; G52 Y0 then clears Y:
            // X1 Y1 = machine (101, 51)
            [101.0, 51.0, -10.0],
            // G92.1 clears what G52 set too
            [100.0, 50.0, -10.0],
            // G52 values are absolute even under G91
            [100.0, 50.0, -8.0],
        ]
    );
    // no axis words: nothing (LinuxCNC accepts it)
    assert_eq!(ends(&ok("G52\nG0 X0")), [[100.0, 0.0, 0.0]]);
    assert_eq!(
        err("G52 X1 G0 Y1"),
        "prog.nc:1: G52 and G0 on one line: both would use the axis words"
    );
}

#[test]
fn absolute_arc_centres_are_coordinates_in_the_current_system() {
    // G90.1: I J are the centre in G54 (origin 100, 50); G91.1 back to offsets
    let p = ok("G0 X10 Y0\nG90.1 G3 X-10 Y0 I0 J0 F600\nG91.1 G3 X10 Y0 I10 J0\n");
    let arcs: Vec<([f64; 3], [f64; 3], f64)> = p
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Arc {
                to,
                center,
                sweep_rad,
                ..
            } => Some((to, center, sweep_rad)),
            _ => None,
        })
        .collect();
    assert_eq!(arcs.len(), 2);
    assert!(close(arcs[0].0, [90.0, 50.0, 0.0]) && close(arcs[0].1, [100.0, 50.0, 0.0]));
    assert!((arcs[0].2 - PI).abs() < 1e-12);
    assert!(close(arcs[1].0, [110.0, 50.0, 0.0]) && close(arcs[1].1, [100.0, 50.0, 0.0]));
    // with G92 / G52 and in inches the centre moves with the coordinate system
    let p = ok("G52 X1\nG20 G0 X1 Y0\nG90.1 G2 X-1 Y0 I0 J0 F10\n");
    match p.moves.last().map(|m| m.kind) {
        Some(MoveKind::Arc { center, .. }) => assert!(close(center, [101.0, 50.0, 0.0])),
        k => panic!("{k:?}"),
    }
    assert_eq!(
        err("G90.1\nG0 X10\nG2 X-10 I0 F600"),
        "prog.nc:3: G2 with absolute arc centres (G90.1) needs both I and J"
    );
    assert_eq!(
        err("G18 G90.1\nG0 X10\nG2 X-10 K0 F600"),
        "prog.nc:3: G2 with absolute arc centres (G90.1) needs both K and I"
    );
    // R arcs do not care
    assert_eq!(ok("G90.1\nG0 X0 Y0\nG2 X20 R10 F600").moves.len(), 2);
    assert_eq!(
        err("G90.1 G91.1"),
        "prog.nc:1: G90.1 and G91.1 on one line: both are in the arc distance mode (G90.1, G91.1) group"
    );
}

#[test]
fn inverse_time_feed_makes_each_move_take_one_over_f_minutes() {
    let text = "G93\nG1 X10 F2\nG3 X0 Y10 I-10 J0 F6\nG0 X50\nG3 X50 Y10 Z-3 I0 J-10 P1 F1\n\
                G20 G1 X1 F4\nG21 G94 F600 G1 X0\n";
    let p = parse_str_with("prog.nc", text, &ParseOptions::default()).unwrap();
    let f = feeds(&p);
    // 10 mm in 1/2 min: 20 mm/min
    assert!((f[0] - 10.0 * 2.0 / 60.0).abs() < 1e-12, "{f:?}");
    // a quarter circle of radius 10 (5π mm) in 1/6 min
    assert!((f[1] - 5.0 * PI * 6.0 / 60.0).abs() < 1e-12, "{f:?}");
    // a full helical turn of radius 10, 3 mm down: its whole length in 1 min
    let helix = (2.0 * PI * 10.0).hypot(3.0);
    match p.moves[3].kind {
        MoveKind::Arc { sweep_rad, .. } => assert!((sweep_rad - 2.0 * PI).abs() < 1e-12),
        k => panic!("{k:?}"),
    }
    assert!((f[2] - helix / 60.0).abs() < 1e-12, "{f:?}");
    // inches: the length is in mm, F is a count per minute (not converted)
    assert_eq!(p.moves[4].from, [50.0, 10.0, -3.0]);
    assert!((f[3] - (50.0 - 25.4) * 4.0 / 60.0).abs() < 1e-12, "{f:?}");
    // back in G94 with a new F on the same line
    assert_eq!(f[4], 10.0);
    // rapids are not affected
    assert!(matches!(p.moves[2].kind, MoveKind::Rapid { .. }));

    assert_eq!(
        err("G93\nG1 X10 F2\nX20"),
        "prog.nc:3: G1 in inverse-time feed mode (G93) without F: every G1, G2 and G3 needs its own F"
    );
    assert_eq!(kind("G93 G1 X1"), ErrorKind::NoFeed);
    // an F on a line without motion is not kept
    assert_eq!(
        err("G93\nF2\nG91 G2 X2 I1"),
        "prog.nc:3: G2 in inverse-time feed mode (G93) without F: every G1, G2 and G3 needs its own F"
    );
    // the F of G94 before G93 is gone after it (LinuxCNC: a new F after G94)
    assert_eq!(
        err("G1 X1 F600\nG93 G1 X2 F10\nG94\nG1 X3"),
        "prog.nc:4: G1 without a feed rate (F): after G93, G94 needs a new F"
    );
    // G94 in G94 keeps the feed
    assert_eq!(feeds(&ok("G1 X1 F600\nG94\nG1 X2")), [10.0, 10.0]);
    assert_eq!(
        err("G93 G94"),
        "prog.nc:1: G93 and G94 on one line: both are in the feed rate mode (G93, G94) group"
    );
}

#[test]
fn path_control_g61_exact_path_g61_1_exact_stop_and_g64_p_q() {
    let text =
        "G61\nG61.1\nG61\nG64 P0.02 Q0.05\nG64 P0.02\nG64 P0.01 Q0\nG20 G64 P0.001 Q0.002\nG64\n";
    let blends: Vec<(u32, Blend)> = ok(text)
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::SetBlend(b) => Some((m.line, b)),
            _ => None,
        })
        .collect();
    let tol = |mm, naive_cam_mm| Blend::Tolerance { mm, naive_cam_mm };
    assert_eq!(
        blends[..6],
        [
            (1, Blend::ExactPath),
            (2, Blend::ExactStop),
            (3, Blend::ExactPath),
            (4, tol(0.02, 0.05)),
            // Q defaults to P
            (5, tol(0.02, 0.02)),
            // Q0: no merging
            (6, tol(0.01, 0.0)),
        ]
    );
    match blends[6] {
        (7, Blend::Tolerance { mm, naive_cam_mm }) => {
            assert!((mm - 0.0254).abs() < 1e-15 && (naive_cam_mm - 0.0508).abs() < 1e-15)
        }
        b => panic!("{b:?}"),
    }
    assert_eq!(blends[7], (8, Blend::MachineDefault));
    assert_eq!(
        err("G64 Q0.1"),
        "prog.nc:1: G64 Q0.1 without P: the naive-CAM tolerance Q needs a path tolerance P (G64 P- Q-)"
    );
    assert_eq!(
        err("G64 P0.1 Q-1"),
        "prog.nc:1: G64 Q-1: the naive-CAM tolerance must not be negative"
    );
    assert_eq!(
        err("G61 G61.1"),
        "prog.nc:1: G61 and G61.1 on one line: both are in the path control (G61, G61.1, G64) group"
    );
    assert_eq!(
        err("G1 X1 Q1 F100"),
        "prog.nc:1: Q1 is not used by any command on this line"
    );
}

#[test]
fn g10_and_tool_length_errors_name_the_line_and_what_is_wrong() {
    let cases: [(&str, ErrorKind, &str); 24] = [
        (
            "G10 L2 P10 X0",
            ErrorKind::Invalid,
            "G10 L2 P10: the coordinate system must be a whole number from 0 to 9 (P1 = G54 .. P9 = G59.3, P0 = the one in effect)",
        ),
        (
            "G10 L20 P-1 X0",
            ErrorKind::Invalid,
            "G10 L20 P-1: the coordinate system must be a whole number from 0 to 9 (P1 = G54 .. P9 = G59.3, P0 = the one in effect)",
        ),
        (
            "G10 L2 P1.5 X0",
            ErrorKind::Invalid,
            "G10 L2 P1.5: the coordinate system must be a whole number from 0 to 9 (P1 = G54 .. P9 = G59.3, P0 = the one in effect)",
        ),
        (
            "G10 P1 X0",
            ErrorKind::Invalid,
            "G10 without L: give L2 or L20 (a coordinate system's origin) or L1 (a tool)",
        ),
        (
            "G10 L2 X0",
            ErrorKind::Invalid,
            "G10 L2 without P: name the coordinate system (P1 = G54 .. P9 = G59.3, P0 = the one in effect)",
        ),
        (
            "G10 L3 P1 X0",
            ErrorKind::Invalid,
            "G10 L3: L must be 1 (a tool), 2 or 20 (a coordinate system's origin)",
        ),
        (
            "G10 L2 P1 X20000",
            ErrorKind::Invalid,
            "G10 L2 P1: the G54 origin's X would be 20000.000 mm from machine zero, beyond the ±10000 mm a work offset may be",
        ),
        (
            "G10 L2 P1 R45",
            ErrorKind::Unsupported,
            "G10 L2 R45 (coordinate system rotation) is not supported",
        ),
        (
            "G10 L11 P1 Z0",
            ErrorKind::Unsupported,
            "G10 L11 (setting a tool from the current position) is not supported",
        ),
        (
            "G10 L1 P0 Z1",
            ErrorKind::Invalid,
            "G10 L1 P0: the tool must be a whole number in the table (the tool table has tools 1 to 8)",
        ),
        (
            "G10 L1 P9 Z1",
            ErrorKind::Invalid,
            "G10 L1 P9: the tool must be a whole number in the table (the tool table has tools 1 to 8)",
        ),
        (
            "G10 L1 Z1",
            ErrorKind::Invalid,
            "G10 L1 without P: name the tool (the tool table has tools 1 to 8)",
        ),
        (
            "G10 L1 P1",
            ErrorKind::Invalid,
            "G10 L1 P1 without Z or R has no effect",
        ),
        (
            "G10 L1 P1 R-1",
            ErrorKind::Invalid,
            "G10 L1 P1 R-1: the tool radius must not be negative",
        ),
        (
            "G10 L1 P1 Z2000",
            ErrorKind::Invalid,
            "G10 L1 P1: the tool length 2000.000 mm is beyond the ±1000 mm a tool may have",
        ),
        (
            "G10 L1 P1 X1",
            ErrorKind::Unsupported,
            "G10 L1 X1 (a tool offset across the spindle) is not supported",
        ),
        (
            "G43",
            ErrorKind::Invalid,
            "G43 without H: name the tool (G43 H<n>; H0: no offset): no tool is loaded, M6 is not supported",
        ),
        (
            "G43 H9",
            ErrorKind::Invalid,
            "G43 H9: tool 9 is not in the tool table (the tool table has tools 1 to 8)",
        ),
        (
            "G43 H-1",
            ErrorKind::Invalid,
            "G43 H-1: the tool must be a whole number ≥ 0 (H0: no offset)",
        ),
        (
            "G43 H1.5",
            ErrorKind::Invalid,
            "G43 H1.5: the tool must be a whole number ≥ 0 (H0: no offset)",
        ),
        (
            "G43.1",
            ErrorKind::Invalid,
            "G43.1 without Z: give the tool length offset (G43.1 Z<length>)",
        ),
        (
            "G43.1 Z1 G1 X1 F100",
            ErrorKind::ModalConflict,
            "G43.1 and G1 on one line: both would use the axis words",
        ),
        (
            "G10 L2 P1 Y0 G0 X1",
            ErrorKind::ModalConflict,
            "G10 and G0 on one line: both would use the axis words",
        ),
        ("G1 X1 H1 F100", ErrorKind::UnusedWord, "H1 is not used by any command on this line"),
    ];
    for (line, kind, message) in cases {
        let text = format!("G21 G0 X1\n{line}\nG0 X2\n");
        let e = parse_str_with("prog.nc", &text, &opts()).unwrap_err();
        assert_eq!(e.to_string(), format!("prog.nc:2: {message}"), "{line}");
        assert_eq!((e.kind, e.line), (kind, Some(2)), "{line}");
    }
    // L on a line without G10, a G43 with an empty table
    assert_eq!(
        err("G0 X1 L2"),
        "prog.nc:1: L2 is not used by any command on this line"
    );
    let e = parse_str_with("prog.nc", "G43 H1", &ParseOptions::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "prog.nc:1: G43 H1: tool 1 is not in the tool table (the tool table is empty)"
    );
    // a G43.1 line keeps the modal motion from using its Z
    let p = ok("G1 X0 F600\nG43.1 Z5\nZ0\n");
    assert_eq!(ends(&p), [[100.0, 0.0, 0.0], [100.0, 0.0, -5.0]]);
}

#[test]
fn the_travel_check_sees_machine_coordinates_with_offsets_and_tool_length() {
    let travel = Travel::new([[-150.0, 150.0], [-150.0, 150.0], [-50.0, 50.0]]).unwrap();
    let check = |text: &str| {
        let p = parse_str_with("prog.nc", text, &opts()).unwrap_or_else(|e| panic!("{e}"));
        check_travel(&p, &travel).map_err(|e| e.to_string())
    };
    // G54 X40 is machine 140: inside; G55 X-40 is machine 160: outside
    assert_eq!(check("G0 X40"), Ok(()));
    assert_eq!(
        check("G0 X40\nG55 X-40"),
        Err("prog.nc:2: X would leave the travel: 160.000 mm > +150.000 mm".into())
    );
    // a 60 mm tool (H6) at Z0 of G54 (−10): machine Z 50, the limit; Z1 leaves
    assert_eq!(check("G43 H6\nG0 Z0"), Ok(()));
    assert_eq!(
        check("G43 H6\nG0 Z0\nZ1"),
        Err("prog.nc:3: Z would leave the travel: 51.000 mm > +50.000 mm".into())
    );
    // G10 moving the origin under the program, and an absolute arc centre, both seen
    assert_eq!(
        check("G10 L2 P1 Y140\nG0 Y20"),
        Err("prog.nc:2: Y would leave the travel: 160.000 mm > +150.000 mm".into())
    );
    assert_eq!(
        check("G0 X-40 Y0\nG90.1 G2 X-40 Y0 I40 J0 F600"),
        Err("prog.nc:2: X would leave the travel: 220.000 mm > +150.000 mm".into())
    );
    // the same I as an offset from the start (G91.1): a circle about machine X 100, inside
    assert_eq!(check("G0 X-40 Y0\nG2 X-40 Y0 I40 J0 F600"), Ok(()));
}

#[test]
fn options_with_bad_offsets_or_tools_are_refused_without_a_line() {
    let mut o = opts();
    o.work_offsets_mm[4][1] = f64::NAN;
    let e = parse_str_with("prog.nc", "G0 X1", &o).unwrap_err();
    assert_eq!((e.kind, e.line), (ErrorKind::Options, None));
    assert!(
        e.to_string()
            .starts_with("prog.nc: option work_offsets_mm: the G58 origin must be finite"),
        "{e}"
    );
    let mut o = opts();
    o.tools[2].diameter_mm = -1.0;
    let e = parse_str_with("prog.nc", "G0 X1", &o).unwrap_err();
    assert!(
        e.to_string().starts_with("prog.nc: option tools: tool 3"),
        "{e}"
    );
    let mut o = opts();
    o.tools[0].length_mm = f64::INFINITY;
    assert_eq!(
        parse_str_with("prog.nc", "", &o).unwrap_err().kind,
        ErrorKind::Options
    );
}

#[test]
fn the_g10_limits_are_the_machines_settings_ranges_and_the_settings_reach_the_options() {
    use controller_core::settings::{keys::find, Range, FACTORY, TOOL_COUNT};
    use host_sim::gcode::{MAX_TOOL_DIAMETER_MM, MAX_TOOL_LENGTH_MM, MAX_WORK_OFFSET_MM};
    let range = |key: &str| match find(key).unwrap().range {
        Range::F32 { min, max } => (f64::from(min), f64::from(max)),
        r => panic!("{key}: {r:?}"),
    };
    assert_eq!(
        range("work.g59_3.z_mm"),
        (-MAX_WORK_OFFSET_MM, MAX_WORK_OFFSET_MM)
    );
    assert_eq!(
        range("tool.8.length_mm"),
        (-MAX_TOOL_LENGTH_MM, MAX_TOOL_LENGTH_MM)
    );
    assert_eq!(range("tool.1.diameter_mm"), (0.0, MAX_TOOL_DIAMETER_MM));
    assert_eq!(WORK_SYSTEMS, controller_core::settings::WORK_SYSTEMS);

    // a machine's settings as the interpreter's options: each value the decimal it was
    // written as (0.1, not 0.10000000149)
    let mut s = FACTORY;
    s.set_text("work.g55.x_mm", "0.1", 10_000).unwrap();
    s.set_text("work.g59_2.z_mm", "-12.345", 10_000).unwrap();
    s.set_text("tool.8.length_mm", "33.3", 10_000).unwrap();
    let o = host_sim::gcode::program::parse_options(&s, [1.0, 2.0, 3.0]);
    assert_eq!(o.start_mm, [1.0, 2.0, 3.0]);
    assert_eq!(o.work_offsets_mm[1], [0.1, 0.0, 0.0]);
    assert_eq!(o.work_offsets_mm[7], [0.0, 0.0, -12.345]);
    assert_eq!(o.tools.len(), TOOL_COUNT);
    assert_eq!(o.tools[7].length_mm, 33.3);
    let p = parse_str_with("prog.nc", "G55 G0 X1\nG43 H8 Z0\n", &o).unwrap();
    assert_eq!(ends(&p), [[1.1, 2.0, 3.0], [1.1, 2.0, 33.3]]);
}
