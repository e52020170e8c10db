//! G-code front end: every supported construct with its numbers, every class of rejection
//! with its exact message.

use std::f64::consts::{PI, TAU};

use host_sim::gcode::{
    parse_file, parse_str, parse_str_with, Blend, ErrorKind, Ignored, Move, MoveKind, ParseOptions,
    Plane, Program, WorkOffsets, MAX_FILE_BYTES, WORK_SYSTEMS,
};

/// Work offsets with G54 at `g54` (machine mm), every other system at machine zero.
fn g54(g54: [f64; 3]) -> WorkOffsets {
    let mut w = [[0.0; 3]; WORK_SYSTEMS];
    w[0] = g54;
    w
}

fn ok(text: &str) -> Program {
    parse_str("prog.nc", text).unwrap_or_else(|e| panic!("{e}"))
}

fn err(text: &str) -> String {
    match parse_str("prog.nc", text) {
        Ok(p) => panic!("accepted: {:?}", p.moves),
        Err(e) => e.to_string(),
    }
}

fn kind(text: &str) -> ErrorKind {
    parse_str("prog.nc", text).map(|_| ()).unwrap_err().kind
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

fn arc(m: &Move) -> ([f64; 3], [f64; 3], Plane, bool, u32, f64, f64) {
    match m.kind {
        MoveKind::Arc {
            to,
            center,
            plane,
            clockwise,
            turns,
            sweep_rad,
            feed_mm_s,
        } => (to, center, plane, clockwise, turns, sweep_rad, feed_mm_s),
        k => panic!("not an arc: {k:?}"),
    }
}

#[test]
fn rapid_and_feed_moves_in_mm_and_mm_per_s() {
    let p = ok("G21 G90\nG0 X10 Y5\nG1 Z-2 F600\nX20\n");
    assert_eq!(p.moves.len(), 3);
    assert_eq!(
        p.moves[0],
        Move {
            line: 2,
            from: [0.0; 3],
            kind: MoveKind::Rapid {
                to: [10.0, 5.0, 0.0]
            }
        }
    );
    assert_eq!(
        p.moves[1].kind,
        MoveKind::Line {
            to: [10.0, 5.0, -2.0],
            feed_mm_s: 10.0
        }
    );
    // Modal G1 and F carry over.
    assert_eq!(
        p.moves[2],
        Move {
            line: 4,
            from: [10.0, 5.0, -2.0],
            kind: MoveKind::Line {
                to: [20.0, 5.0, -2.0],
                feed_mm_s: 10.0
            }
        }
    );
    assert_eq!(p.bounds_mm, [[0.0, 20.0], [0.0, 5.0], [-2.0, 0.0]]);
    assert_eq!(p.end_line, None);
}

#[test]
fn inches_convert_to_mm_and_feed_to_mm_per_s() {
    let p = ok("G20 G90\nG1 X1 Y-0.5 F10\nG21\nX2\n");
    // 1 in = 25.4 mm; 10 in/min = 254 mm/min = 4.2333 mm/s.
    assert_eq!(
        p.moves[0].kind,
        MoveKind::Line {
            to: [25.4, -12.7, 0.0],
            feed_mm_s: 254.0 / 60.0
        }
    );
    // After G21 the feed stays what it was converted to; X2 is now 2 mm.
    assert_eq!(
        p.moves[1].kind,
        MoveKind::Line {
            to: [2.0, -12.7, 0.0],
            feed_mm_s: 254.0 / 60.0
        }
    );
    // Units on the same line apply to every value on it, F included (grbl).
    let p = ok("G1 G20 X1 F1");
    assert_eq!(
        p.moves[0].kind,
        MoveKind::Line {
            to: [25.4, 0.0, 0.0],
            feed_mm_s: 25.4 / 60.0
        }
    );
}

#[test]
fn incremental_moves_and_arcs() {
    let p = ok("G91 G0 X10 Y10\nX5\nG1 Z-1 F60\nG2 X10 Y0 I5 J0\n");
    assert_eq!(
        ends(&p),
        [
            [10.0, 10.0, 0.0],
            [15.0, 10.0, 0.0],
            [15.0, 10.0, -1.0],
            [25.0, 10.0, -1.0]
        ]
    );
    let (to, center, plane, cw, turns, sweep, feed) = arc(&p.moves[3]);
    assert_eq!(
        (to, center, plane, cw, turns),
        ([25.0, 10.0, -1.0], [20.0, 10.0, -1.0], Plane::XY, true, 1)
    );
    assert!((sweep - PI).abs() < 1e-12);
    assert_eq!(feed, 1.0);
}

#[test]
fn work_offset_g54_and_start_point() {
    let opts = ParseOptions {
        start_mm: [1.0, 2.0, 3.0],
        work_offsets_mm: g54([100.0, 50.0, -10.0]),
        ..ParseOptions::default()
    };
    let p = parse_str_with("prog.nc", "G54 G0 X10\nG91 Y1\n", &opts).unwrap();
    assert_eq!(p.start_mm, [1.0, 2.0, 3.0]);
    assert_eq!(
        p.moves[0],
        Move {
            line: 1,
            from: [1.0, 2.0, 3.0],
            kind: MoveKind::Rapid {
                to: [110.0, 2.0, 3.0]
            }
        }
    );
    assert_eq!(p.moves[1].to(), [110.0, 3.0, 3.0]);
}

#[test]
fn g92_makes_the_current_point_the_given_coordinates() {
    let opts = ParseOptions {
        work_offsets_mm: g54([5.0, 0.0, 0.0]),
        ..ParseOptions::default()
    };
    let text = "G0 X10 Y10\nG92 X0 Y0\nG0 X5\nG91 G92 X100\nG90 G0 X101\nG92.1\nG0 X0\n";
    let p = parse_str_with("prog.nc", text, &opts).unwrap();
    // Machine (15, 10); G92 makes it (0, 0); X5 is machine 20. G92 values are absolute even
    // under G91: the point (20) becomes X100, so X101 is machine 21. G92.1 clears: X0 = 5.
    assert_eq!(
        ends(&p),
        [
            [15.0, 10.0, 0.0],
            [20.0, 10.0, 0.0],
            [21.0, 10.0, 0.0],
            [5.0, 10.0, 0.0]
        ]
    );
    assert_eq!(
        err("G92"),
        "prog.nc:1: G92 without axis words: name the axes to set"
    );
}

#[test]
fn g53_is_machine_coordinates_for_one_line() {
    let opts = ParseOptions {
        work_offsets_mm: g54([100.0, 100.0, 0.0]),
        ..ParseOptions::default()
    };
    let p = parse_str_with(
        "prog.nc",
        "G0 X0 Y0\nG92 X1\nG53 G0 X-5 Z-1\nX0\nG53 G1 Y3 F60\n",
        &opts,
    )
    .unwrap();
    // After G92 X1 at machine 100, work X0 is machine 99.
    assert_eq!(
        ends(&p),
        [
            [100.0, 100.0, 0.0],
            [-5.0, 100.0, -1.0],
            [99.0, 100.0, -1.0],
            [99.0, 3.0, -1.0]
        ]
    );
    assert_eq!(
        err("G91\nG53 G0 X1"),
        "prog.nc:2: G53 in incremental distance mode (G91) is not supported"
    );
    assert_eq!(
        err("G2 X0 Y0 I1 F100\nG53 X1"),
        "prog.nc:2: G53 needs G0 or G1 in effect (in effect: G2)"
    );
    assert_eq!(
        err("G53 X1"),
        "prog.nc:1: G53 needs G0 or G1 in effect (in effect: no motion mode)"
    );
}

#[test]
fn g28_returns_home_via_the_intermediate_point() {
    let opts = ParseOptions {
        g28_position_mm: [0.0, 0.0, 10.0],
        ..ParseOptions::default()
    };
    let p = parse_str_with("prog.nc", "G0 X10 Y20 Z-5\nG28\n", &opts).unwrap();
    assert_eq!(
        p.moves[1],
        Move {
            line: 2,
            from: [10.0, 20.0, -5.0],
            kind: MoveKind::Rapid {
                to: [0.0, 0.0, 10.0]
            }
        }
    );
    // The CAM idiom: G28 G91 Z0 = lift Z straight home, X and Y stay.
    let p = parse_str_with("prog.nc", "G0 X10 Y20 Z-5\nG28 G91 Z0\n", &opts).unwrap();
    assert_eq!(ends(&p), [[10.0, 20.0, -5.0], [10.0, 20.0, 10.0]]);
    // Absolute intermediate point, then only the named axes go home.
    let p = parse_str_with("prog.nc", "G0 X10 Y20 Z-5\nG28 X30 Z0\n", &opts).unwrap();
    assert_eq!(
        ends(&p),
        [[10.0, 20.0, -5.0], [30.0, 20.0, 0.0], [0.0, 20.0, 10.0]]
    );
    assert!(p.moves.iter().skip(1).all(|m| m.line == 2));
    assert_eq!(
        err("G28 G0 X1"),
        "prog.nc:1: G28 and G0 on one line: both would use the axis words"
    );
}

#[test]
fn r_arcs_both_signs() {
    // 20 mm chord, R20: the 60° arc; R-20: the 300° arc. Centre 17.32 mm off the chord.
    let h = 300f64.sqrt();
    let p = ok("G0 X0 Y0\nG2 X20 R20 F600\nG3 X0 Y0 R-20\nG3 X20 R20\nG2 X0 R-20\n");
    let expect = [
        (true, -h, PI / 3.0),
        (false, h, 5.0 * PI / 3.0),
        (false, h, PI / 3.0),
        (true, -h, 5.0 * PI / 3.0),
    ];
    // Starting point alternates: (0,0) → (20,0) → (0,0) → (20,0) → (0,0).
    for (m, (cw, cy, sweep)) in p.moves.iter().zip(expect) {
        let (_, center, _, clockwise, _, s, _) = arc(m);
        assert_eq!(clockwise, cw, "line {}", m.line);
        assert!(
            (center[0] - 10.0).abs() < 1e-9 && (center[1] - cy).abs() < 1e-9,
            "line {}: {center:?}",
            m.line
        );
        assert!((s - sweep).abs() < 1e-9, "line {}: {s}", m.line);
    }
    // Both radii equal R by construction.
    for m in &p.moves {
        let (to, c, ..) = arc(m);
        assert!(((m.from[0] - c[0]).hypot(m.from[1] - c[1]) - 20.0).abs() < 1e-9);
        assert!(((to[0] - c[0]).hypot(to[1] - c[1]) - 20.0).abs() < 1e-9);
    }
}

#[test]
fn full_circles_turns_and_helix() {
    let p = ok("G0 X10\nG3 X10 Y0 I-10 J0 F600\nG2 I-10 Z-3 P3\n");
    let (to, center, _, cw, turns, sweep, _) = arc(&p.moves[1]);
    assert_eq!(
        (to, center, cw, turns),
        ([10.0, 0.0, 0.0], [0.0; 3], false, 1)
    );
    assert!((sweep - TAU).abs() < 1e-12);
    // Only Z given: in-plane end = start, a full helical circle; P3 = three turns.
    let (to, center, _, cw, turns, sweep, _) = arc(&p.moves[2]);
    assert_eq!(
        (to, center, cw, turns),
        ([10.0, 0.0, -3.0], [0.0; 3], true, 3)
    );
    assert!((sweep - 3.0 * TAU).abs() < 1e-12);
    assert_eq!(p.bounds_mm, [[-10.0, 10.0], [-10.0, 10.0], [-3.0, 0.0]]);
    assert_eq!(
        err("G0 X10\nG2 I-10 Z-1 P0 F60"),
        "prog.nc:2: G2 P0: the number of turns must be a whole number ≥ 1"
    );
}

#[test]
fn helical_partial_arc() {
    let p = ok("G0 X10\nG3 X0 Y10 Z-2 I-10 F120\n");
    let (to, center, plane, cw, _, sweep, feed) = arc(&p.moves[1]);
    assert_eq!(
        (to, center, plane, cw, feed),
        ([0.0, 10.0, -2.0], [0.0, 0.0, 0.0], Plane::XY, false, 2.0)
    );
    assert!((sweep - PI / 2.0).abs() < 1e-12);
}

#[test]
fn arcs_in_g18_and_g19() {
    // G18: axes (Z, X), clockwise seen from +Y. From X10 to Z10 about the origin is a
    // clockwise quarter.
    let p = ok("G18 G0 X10\nG2 X0 Z10 I-10 K0 F60\n");
    let (to, center, plane, _, _, sweep, _) = arc(&p.moves[1]);
    assert_eq!((to, center, plane), ([0.0, 0.0, 10.0], [0.0; 3], Plane::ZX));
    assert!((sweep - PI / 2.0).abs() < 1e-12);
    // The same end counter-clockwise is three quarters.
    let p = ok("G18 G0 X10\nG3 X0 Z10 I-10 F60\n");
    assert!((arc(&p.moves[1]).5 - 1.5 * PI).abs() < 1e-12);
    // G19: axes (Y, Z), clockwise seen from +X: from Y10 to Z-10 is clockwise, a quarter;
    // X is the helix axis.
    let p = ok("G19 G0 Y10\nG2 Y0 Z-10 X5 J-10 F60\n");
    let (to, center, plane, ..) = arc(&p.moves[1]);
    assert_eq!(
        (to, center, plane),
        ([5.0, 0.0, -10.0], [0.0; 3], Plane::YZ)
    );
    assert!((arc(&p.moves[1]).5 - PI / 2.0).abs() < 1e-12);
    // Offsets outside the plane are errors.
    assert_eq!(
        err("G0 X10\nG2 X-10 I-10 K1 F60"),
        "prog.nc:2: K1 is not used by an arc in the G17 (XY) plane"
    );
    assert_eq!(
        err("G18 G0 X10\nG2 X-10 I-10 J0 F60"),
        "prog.nc:2: J0 is not used by an arc in the G18 (ZX) plane"
    );
}

#[test]
fn arc_errors() {
    // End point 0.031 mm off a 10 mm circle: tolerance max(0.005, 0.1 % of 10) = 0.010.
    assert_eq!(
        err("G0 X10\nG2 X-10.031 Y0 I-10 F60"),
        "prog.nc:2: arc end point is 0.0310 mm off the circle (radius 10.0000 mm at the start, \
         10.0310 mm at the end; tolerance 0.0100 mm)"
    );
    // Within tolerance: accepted, centre kept, the radius mismatch left to the planner.
    let p = ok("G0 X10\nG2 X-10.009 Y0 I-10 F60");
    assert_eq!(arc(&p.moves[1]).1, [0.0; 3]);
    assert_eq!(
        err("G2 X10 I0 J0 F60"),
        "prog.nc:1: arc radius is zero: the I/J/K offsets put the centre on the start point"
    );
    assert_eq!(err("G2 X10 R0 F60"), "prog.nc:1: arc radius is zero (R0)");
    assert_eq!(
        err("G2 X12 R5 F60"),
        "prog.nc:1: R-form arc cannot reach its end point: the end is 12.0000 mm from the start, more than 2 × |R| = 10.0000 mm"
    );
    // A chord just within tolerance of the diameter is a half circle.
    let p = ok("G2 X10.004 R5 F60");
    assert!((arc(&p.moves[0]).5 - PI).abs() < 1e-9);
    assert_eq!(
        err("G2 X0 Z1 R5 F60"),
        "prog.nc:1: R-form arc ends where it starts: a full circle needs I/J/K, not R"
    );
    assert_eq!(
        err("G2 X10 R5 I5 F60"),
        "prog.nc:1: G2 with both R and I/J/K: give one of them"
    );
    assert_eq!(
        err("G3 X10 F60"),
        "prog.nc:1: G3 without I/J/K or R: the arc centre is not defined"
    );
    assert_eq!(kind("G3 X10 F60"), ErrorKind::Arc);
}

#[test]
fn missing_feed() {
    assert_eq!(
        err("G21\nG0 X1\nG1 X2\n"),
        "prog.nc:3: G1 without a feed rate (F)"
    );
    assert_eq!(err("G2 X2 I1"), "prog.nc:1: G2 without a feed rate (F)");
    assert_eq!(kind("G1 X2"), ErrorKind::NoFeed);
    assert_eq!(
        err("G1 X1 F0"),
        "prog.nc:1: F0 is not a usable feed rate: it must be greater than zero"
    );
    assert_eq!(
        err("G1 X1 F-5"),
        "prog.nc:1: F-5 is not a usable feed rate: it must be greater than zero"
    );
    // F on an earlier rapid line is modal.
    assert_eq!(
        ok("G0 X1 F120\nG1 X2").moves[1].kind,
        MoveKind::Line {
            to: [2.0, 0.0, 0.0],
            feed_mm_s: 2.0
        }
    );
}

#[test]
fn modal_group_conflicts_and_repeated_words() {
    assert_eq!(
        err("G0 G1 X1"),
        "prog.nc:1: G0 and G1 on one line: both are in the motion (G0, G1, G2, G3, G80) group"
    );
    assert_eq!(
        err("G90 G91"),
        "prog.nc:1: G90 and G91 on one line: both are in the distance mode (G90, G91) group"
    );
    assert_eq!(
        err("G20 G21"),
        "prog.nc:1: G20 and G21 on one line: both are in the units (G20, G21) group"
    );
    assert_eq!(
        err("G17 G18"),
        "prog.nc:1: G17 and G18 on one line: both are in the plane (G17, G18, G19) group"
    );
    assert_eq!(
        err("G4 P1 G92 X0"),
        "prog.nc:1: G4 and G92 on one line: both are in the non-modal (G4, G10, G28, G52, G53, G92) group"
    );
    assert_eq!(
        err("M3 M5"),
        "prog.nc:1: M3 and M5 on one line: both are in the spindle (M3, M4, M5) group"
    );
    assert_eq!(
        err("G1 G1 X1 F1"),
        "prog.nc:1: G1 and G1 on one line: both are in the motion (G0, G1, G2, G3, G80) group"
    );
    assert_eq!(kind("G0 G1 X1"), ErrorKind::ModalConflict);
    assert_eq!(
        err("G0 X1 X2"),
        "prog.nc:1: X appears twice on one line (X1 and X2)"
    );
    assert_eq!(kind("G0 X1 X2"), ErrorKind::RepeatedWord);
    assert_eq!(
        err("G4 G64 P0.1"),
        "prog.nc:1: P is used by both G4 and G64 on one line"
    );
}

#[test]
fn unused_words_and_missing_motion() {
    assert_eq!(
        err("G0 X1 I5"),
        "prog.nc:1: I5 is not used by any command on this line"
    );
    assert_eq!(
        err("G1 X1 F10 P2"),
        "prog.nc:1: P2 is not used by any command on this line"
    );
    assert_eq!(
        err("R5"),
        "prog.nc:1: R5 is not used by any command on this line"
    );
    assert_eq!(kind("G0 X1 I5"), ErrorKind::UnusedWord);
    assert_eq!(
        err("G90\nX10"),
        "prog.nc:2: X10 without a motion command: no G0/G1/G2/G3 is in effect"
    );
    assert_eq!(
        err("G0 X1\nG80\nY1"),
        "prog.nc:3: Y1 without a motion command: no G0/G1/G2/G3 is in effect"
    );
    assert_eq!(
        err("G92.1 X1"),
        "prog.nc:1: X1 is not used by any command on this line"
    );
    // A motion code alone only sets the mode.
    assert!(ok("G1\nG2\nG0").moves.is_empty());
}

#[test]
fn unsupported_constructs() {
    let cases = [
        ("G81 X1 Y1 Z-1 R1", "G81 (canned cycle)"),
        ("G83 X1", "G83 (canned cycle)"),
        ("G73 X1", "G73 (canned cycle)"),
        ("G98", "G98 (canned cycle return mode)"),
        ("G33 Z-10 K1", "G33 (spindle-synchronised motion)"),
        ("G38.2 Z-10 F10", "G38.2 (probing)"),
        ("G95", "G95 (feed per revolution)"),
        ("G10 L2 R30 P1", "G10 L2 R30 (coordinate system rotation)"),
        (
            "G10 L10 P1 Z0",
            "G10 L10 (setting a tool from the current position)",
        ),
        ("G10 L0", "G10 L0 (reloading the tool table)"),
        ("G28.1", "G28.1 (storing a home position)"),
        ("G30", "G30 (second home position)"),
        ("G41", "G41 (cutter radius compensation)"),
        ("G42.1", "G42.1 (cutter radius compensation)"),
        ("G43.2 H1", "G43.2 (adding tool length offsets)"),
        ("G43.1 X1", "G43.1 X1 (a tool offset across the spindle)"),
        ("G92.2", "G92.2 (suspending G92 offsets)"),
        ("G5 X1", "G5 (spline)"),
        ("G12", "G12"),
        ("G1.25 X1", "G1.25"),
        ("G-1", "G-1"),
        ("M1", "M1 (optional stop)"),
        ("T1 M6", "M6 (tool change)"),
        ("M98 P100", "M98"),
        ("M62 P1", "M62 (digital/analog output)"),
        ("O100 sub", "O-word (program number or subroutine)"),
        ("#1 = 5", "parameter #1"),
        ("G1 X#<depth> F10", "parameter #<depth>"),
        ("G1 X[2*3] F10", "expression [2*3]"),
        ("/G0 X1", "block delete (/)"),
        ("G1 A10 F10", "A word (rotary axis)"),
        ("G1 X1 E0.5 F10", "E word (extruder axis of 3D printers)"),
        ("G81 Q1", "G81 (canned cycle)"),
        ("G92.3", "G92.3 (suspending G92 offsets)"),
        ("G41 D1", "D word (cutter compensation register)"),
    ];
    for (line, what) in cases {
        let text = format!("G21\n{line}\n");
        let e = parse_str("prog.nc", &text).map(|_| ()).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("prog.nc:2: {what} is not supported"),
            "{line}"
        );
        assert_eq!(e.kind, ErrorKind::Unsupported);
        assert_eq!(e.line, Some(2));
    }
    // Unsupported wins over an error earlier on the same line, and rejects before any
    // motion: the good moves before it do not come back.
    assert_eq!(
        err("G0 X1\nG0 G1 G81 X1\n"),
        "prog.nc:2: G81 (canned cycle) is not supported"
    );
}

#[test]
fn ignored_words_are_reported_once() {
    // (G49 and G94 are real now: the modes a program starts in, not reported)
    let p = ok("G21 G40 G49 G80 G94\nT1\nM3 S12000\nG0 X1\nM8\nS10000 M4\nM7\nM9\nM5\nT2\n");
    let word = |w: &str, first_line: u32, count: u32| Ignored {
        word: w.into(),
        first_line,
        count,
    };
    assert_eq!(
        p.ignored,
        [
            word("G40", 1, 1),
            word("G80", 1, 1),
            word("T", 2, 2),
            word("M3", 3, 1),
            word("S", 3, 2),
            word("M8", 5, 1),
            word("M4", 6, 1),
            word("M7", 7, 1),
            word("M9", 8, 1),
            word("M5", 9, 1),
        ]
    );
    assert_eq!(p.moves.len(), 1);
}

#[test]
fn dwell_pause_end_and_after_end() {
    let p = ok("G4 P1.5\nG0 X1\nM0\nG0 X2 M2\nG0 X3\n");
    let kinds: Vec<MoveKind> = p.moves.iter().map(|m| m.kind).collect();
    assert_eq!(
        kinds,
        [
            MoveKind::Dwell { s: 1.5 },
            MoveKind::Rapid {
                to: [1.0, 0.0, 0.0]
            },
            MoveKind::Pause,
            MoveKind::Rapid {
                to: [2.0, 0.0, 0.0]
            },
        ]
    );
    assert_eq!(p.moves[2].from, [1.0, 0.0, 0.0]);
    assert_eq!(p.end_line, Some(4));
    // After the end nothing is interpreted (no motion mode is needed, no conflict is
    // checked), but unsupported words and syntax errors still reject the file.
    assert_eq!(ok("M30\nX5 G0 G1\nS5").ignored, []);
    assert_eq!(
        err("M30\nG81 X1"),
        "prog.nc:2: G81 (canned cycle) is not supported"
    );
    assert_eq!(
        err("M30\n(open"),
        "prog.nc:2: comment is not closed: missing ')'"
    );
    assert_eq!(
        err("G4"),
        "prog.nc:1: G4 without P (the dwell time in seconds)"
    );
    assert_eq!(
        err("G4 P-1"),
        "prog.nc:1: G4 P-1: the dwell time must not be negative"
    );
    assert_eq!(
        err("M0 M2"),
        "prog.nc:1: M0 and M2 on one line: both are in the stopping (M0, M2, M30) group"
    );
}

#[test]
fn path_control_emits_blend_changes() {
    let p = ok("G61\nG0 X1\nG64 P0.02\nG64 P0.02\nG20 G64 P0.001\nG64\nG61 G0 X2\n");
    let blends: Vec<(u32, Blend)> = p
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::SetBlend(b) => Some((m.line, b)),
            _ => None,
        })
        .collect();
    assert_eq!(blends.len(), 5);
    assert_eq!(blends[0], (1, Blend::ExactPath));
    // without Q, the naive-CAM tolerance is P (LinuxCNC)
    assert_eq!(
        blends[1],
        (
            3,
            Blend::Tolerance {
                mm: 0.02,
                naive_cam_mm: 0.02
            }
        )
    );
    match blends[2] {
        (5, Blend::Tolerance { mm, naive_cam_mm }) => {
            assert!((mm - 0.0254).abs() < 1e-15 && mm == naive_cam_mm)
        }
        b => panic!("{b:?}"),
    }
    assert_eq!(blends[3], (6, Blend::MachineDefault));
    assert_eq!(blends[4], (7, Blend::ExactPath));
    // G61 on line 7 with the move: the blend change comes before the move.
    assert_eq!(
        p.moves.last().unwrap().kind,
        MoveKind::Rapid {
            to: [50.8, 0.0, 0.0]
        }
    );
    assert_eq!(
        err("G64 P-1"),
        "prog.nc:1: G64 P-1: the path tolerance must not be negative"
    );
}

#[test]
fn zero_length_moves_are_skipped() {
    let p = ok("G0 X0 Y0 Z0\nG91 G1 X0 F100\nG90 G0 X1\nX1\nG91 X0.1\nX0.2\nG90 X1.3\n");
    // Line 7 is 1.3 vs 1 + 0.1 + 0.2 = 1.3000000000000003: float noise, skipped.
    assert_eq!(
        p.moves.iter().map(|m| m.line).collect::<Vec<_>>(),
        [3, 5, 6]
    );
}

#[test]
fn syntax_comments_line_numbers_and_case() {
    let text = "%\n(header comment)\nn10 g0 x1 (inline) y2 ; tail\nN20 G1 X 3 F 60\n\r\n%\n";
    let p = ok(text);
    assert_eq!(p.moves.len(), 2);
    // N words are ignored: lines are file lines.
    assert_eq!((p.moves[0].line, p.moves[1].line), (3, 4));
    assert_eq!(p.moves[1].to(), [3.0, 2.0, 0.0]);
    assert_eq!(
        err("G0 X1\nN1.5 G0 X2"),
        "prog.nc:2: line number N1.5 is not a whole number ≥ 0"
    );
    assert_eq!(err("G0 X1\nG0 X1.2.3"), "prog.nc:2: bad number X1.2.3");
    assert_eq!(err("G0 X"), "prog.nc:1: X has no number after the letter");
    assert_eq!(
        err("G0 X1 5"),
        "prog.nc:1: number 5 has no letter before it"
    );
    assert_eq!(err("G0 X1 *12"), "prog.nc:1: unexpected character '*'");
    assert_eq!(
        err("G0 X1e5"),
        "prog.nc:1: E word (extruder axis of 3D printers) is not supported"
    );
    assert_eq!(
        err("(a (b))"),
        "prog.nc:1: '(' inside a comment: comments do not nest"
    );
    assert_eq!(
        err("G0 X1 (no end\nG0 X2)"),
        "prog.nc:1: comment is not closed: missing ')'"
    );
    assert_eq!(
        err("G0 X1 %"),
        "prog.nc:1: '%' must stand alone at the start of its line"
    );
    assert_eq!(
        err("G0 X123456789"),
        "prog.nc:1: X123456789 is out of range (magnitude at most 1e7)"
    );
    assert_eq!(kind("G0 X1.2.3"), ErrorKind::Syntax);
    // A UTF-8 byte-order mark is skipped; comments may hold any text.
    assert_eq!(ok("\u{feff}G0 X1 (Ø 6 mm, 12 000 min⁻¹)").moves.len(), 1);
    assert_eq!(err("G0 X1 é"), "prog.nc:1: unexpected character 'é'");
}

#[test]
fn line_length_limit() {
    let pad = |n: usize| format!("G0 X1 ({})", "a".repeat(n - 8));
    assert_eq!(pad(256).chars().count(), 256);
    assert_eq!(ok(&pad(256)).moves.len(), 1);
    assert_eq!(
        err(&format!("G0\n{}", pad(257))),
        "prog.nc:2: line is too long: 257 characters (at most 256)"
    );
    assert_eq!(kind(&pad(257)), ErrorKind::LineTooLong);
}

#[test]
fn options_are_validated() {
    let bad = ParseOptions {
        start_mm: [f64::NAN, 0.0, 0.0],
        ..ParseOptions::default()
    };
    let e = parse_str_with("prog.nc", "G0 X1", &bad).unwrap_err();
    assert_eq!((e.kind, e.line), (ErrorKind::Options, None));
    assert!(
        e.to_string()
            .starts_with("prog.nc: option start_mm must be finite"),
        "{e}"
    );
    let bad = ParseOptions {
        arc_tolerance_mm: 0.0,
        ..ParseOptions::default()
    };
    assert_eq!(
        parse_str_with("prog.nc", "", &bad).unwrap_err().kind,
        ErrorKind::Options
    );
}

#[test]
fn files_size_cap_encoding_and_missing() {
    let dir = std::env::temp_dir().join(format!("gantry-gcode-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let good = dir.join("good.nc");
    std::fs::write(&good, "G0 X1\n").unwrap();
    let p = parse_file(&good).unwrap();
    assert_eq!(
        (p.name.as_str(), p.moves.len()),
        (good.to_str().unwrap(), 1)
    );

    let big = dir.join("big.nc");
    let f = std::fs::File::create(&big).unwrap();
    f.set_len(MAX_FILE_BYTES + 1).unwrap();
    let e = parse_file(&big).unwrap_err();
    assert_eq!(e.kind, ErrorKind::TooLarge);
    assert_eq!(
        e.to_string(),
        format!("{}: file is larger than the 16 MiB limit", big.display())
    );

    let latin1 = dir.join("latin1.nc");
    std::fs::write(&latin1, b"G0 X1\n(caf\xe9)\n").unwrap();
    let e = parse_file(&latin1).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}:2: not UTF-8 text (invalid byte at offset 10)",
            latin1.display()
        )
    );

    let e = parse_file(&dir.join("missing.nc")).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Io);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// What the planner would refuse or run off the path, and absurd values, are `FILE:LINE`
/// errors of the front end, before any motion: more arc turns than the planner queues, a
/// radius beyond its f32 precision, a dwell of days, a feed of nanometres a minute.
#[test]
fn limits_the_planner_enforces_are_checked_before_any_motion() {
    let e = err("G21 G90 G17\nG1 X1 F600\nG2 X1 Y0 I5 J0 P2000\n");
    assert!(e.contains(":3:") && e.contains("at most 16 turns"), "{e}");
    // 16 turns are what one arc may have (the planner's pieces)
    ok("G21 G90 G17\nG1 X1 F600\nG2 X1 Y0 I5 J0 P16\n");
    let e = err("G21 G90 G17\nG1 X1 F600\nG2 X10 R9999999\n");
    assert!(e.contains(":3:") && e.contains("above 10000 mm"), "{e}");
    let e = err("G21 G90 G17\nG1 X1 F600\nG3 X1 Y0 I-20000 J0\n");
    assert!(e.contains(":3:") && e.contains("radius 20000.0 mm"), "{e}");
    ok("G21 G90 G17\nG1 X1 F600\nG3 X1 Y0 I-9000 J0\n");
    let e = err("G21 G90\nG4 P10000000\n");
    assert!(e.contains(":2:") && e.contains("longer than 3600 s"), "{e}");
    ok("G21 G90\nG4 P3600\n");
    let e = err("G21 G90\nG1 X1 F0.000001\n");
    assert!(e.contains(":2:") && e.contains("slowest feed"), "{e}");
    // in inches too: 0.0001 in/min = 0.00254 mm/min
    let e = err("G20 G90\nG1 X1 F0.0001\n");
    assert!(e.contains(":2:") && e.contains("slowest feed"), "{e}");
    ok("G21 G90\nG1 X1 F0.01\n");
}
