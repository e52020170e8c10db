//! The generated benchmark programs (`host_sim::bench_programs`): each parses, stays inside
//! the default machine's travel from where the machine starts, has the moves and the path
//! length its documentation states, and is the same text every time it is generated.

use std::f64::consts::TAU;

use host_sim::bench_programs::{self as bp, Direction};
use host_sim::gcode::program::travel_of;
use host_sim::gcode::{check_travel, parse_str, MoveKind, Program, Travel};
use host_sim::sim_gantry::machine_and_planner;

/// The travel of the default machine of `cargo sim gcode` (the built-in gcode.toml).
fn default_travel() -> Travel {
    let (run, _) = machine_and_planner(None).unwrap();
    travel_of(&run).unwrap()
}

fn parse(name: &str, text: &str) -> Program {
    let p = parse_str(name, text).unwrap_or_else(|e| panic!("{e}"));
    check_travel(&p, &default_travel()).unwrap_or_else(|e| panic!("{e}"));
    assert!(p.end_line.is_some(), "{name} has no M30");
    assert!(p.ignored.is_empty(), "{name} ignores {:?}", p.ignored);
    p
}

/// Moves of a program by kind: rapids, lines, arcs; and its whole path (mm).
#[derive(Debug, PartialEq)]
struct Counts {
    rapids: usize,
    lines: usize,
    arcs: usize,
}

fn counts(p: &Program) -> (Counts, f64) {
    let mut c = Counts {
        rapids: 0,
        lines: 0,
        arcs: 0,
    };
    for m in &p.moves {
        match m.kind {
            MoveKind::Rapid { .. } => c.rapids += 1,
            MoveKind::Line { .. } => c.lines += 1,
            MoveKind::Arc { .. } => c.arcs += 1,
            _ => {}
        }
    }
    (c, p.moves.iter().map(|m| m.length_mm()).sum())
}

/// What each program's documentation states: (name, counts, path mm, relative tolerance
/// of the path).
fn documented() -> Vec<(&'static str, Counts, f64, f64)> {
    let circle = bp::CIRCLE_RADIUS_MM + TAU * bp::CIRCLE_RADIUS_MM;
    let collinear = 1.5 * bp::COLLINEAR_MOVES as f64 * bp::COLLINEAR_STEP_MM;
    let c = |rapids, lines, arcs| Counts {
        rapids,
        lines,
        arcs,
    };
    vec![
        ("circle_chords", c(1, bp::CIRCLE_CHORDS, 0), circle, 1e-4),
        (
            "collinear_tiny",
            c(1, bp::COLLINEAR_MOVES, 0),
            collinear,
            1e-9,
        ),
        (
            "surfacing_3d",
            c(3, bp::SURFACING_FEED_MOVES, 0),
            bp::SURFACING_PATH_MM,
            1e-3,
        ),
        (
            "spiral_arcs",
            c(3, 2, 2 * bp::SPIRAL_ARCS_PER_SPIRAL),
            bp::SPIRAL_PATH_MM,
            1e-3,
        ),
        (
            "zigzag",
            c(3, 1 + bp::ZIGZAG_MOVES, 0),
            bp::ZIGZAG_PATH_MM,
            1e-3,
        ),
        (
            "dense_curve_3d",
            c(3, 1 + bp::DENSE_CURVE_CHORDS, 0),
            bp::DENSE_CURVE_PATH_MM,
            1e-3,
        ),
    ]
}

#[test]
fn the_default_travel_is_the_one_the_programs_are_written_for() {
    assert_eq!(default_travel().limits_mm(), bp::DEFAULT_TRAVEL_MM);
}

#[test]
fn every_program_parses_stays_in_the_travel_and_has_its_documented_counts() {
    let all = bp::all();
    let doc = documented();
    assert_eq!(
        all.iter().map(|(n, _)| *n).collect::<Vec<_>>(),
        doc.iter().map(|(n, ..)| *n).collect::<Vec<_>>()
    );
    for ((name, text), (_, want, path_mm, rel)) in all.iter().zip(doc) {
        let p = parse(name, text);
        let (got, got_mm) = counts(&p);
        println!(
            "{name}: {got:?}, {got_mm:.3} mm, {} lines",
            text.lines().count()
        );
        assert_eq!(got, want, "{name}");
        assert!(
            (got_mm - path_mm).abs() <= rel * path_mm,
            "{name}: {got_mm} mm, documented {path_mm}"
        );
        // every program starts where the machine starts
        assert_eq!(p.start_mm, [0.0; 3], "{name}");
    }
}

#[test]
fn generating_twice_gives_the_same_text() {
    assert_eq!(bp::all(), bp::all());
    assert_eq!(bp::huge(), bp::huge());
    for (_, len, dir) in bp::rest_to_rest_cases() {
        assert_eq!(bp::rest_to_rest(len, dir), bp::rest_to_rest(len, dir));
    }
}

/// Feed moves' lengths (mm) of a program, with the index of the move.
fn feed_lengths(p: &Program) -> Vec<f64> {
    p.moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Line { .. }))
        .map(|m| m.length_mm())
        .collect()
}

fn text_of(name: &str) -> String {
    bp::all()
        .into_iter()
        .find(|(n, _)| *n == name)
        .map(|(_, t)| t)
        .unwrap()
}

#[test]
fn the_programs_have_the_moves_their_docs_promise() {
    // circle: every chord on the circle, at F100000
    let p = parse("circle_chords", &text_of("circle_chords"));
    for m in &p.moves {
        if let MoveKind::Line { to, feed_mm_s } = m.kind {
            assert!((to[0].hypot(to[1]) - bp::CIRCLE_RADIUS_MM).abs() < 1e-4);
            assert!((feed_mm_s - bp::CIRCLE_FEED_MM_MIN / 60.0).abs() < 1e-9);
        }
    }
    // collinear: every move exactly 0.0254 mm along X
    let p = parse("collinear_tiny", &text_of("collinear_tiny"));
    for l in feed_lengths(&p) {
        assert!((l - bp::COLLINEAR_STEP_MM).abs() < 1e-9, "{l}");
    }
    // surfacing: chords whose X step is within the bounds, but the last of each pass
    // (the remainder to the pass's end: 0.5-1.5 of the step before it); links across
    let p = parse("surfacing_3d", &text_of("surfacing_3d"));
    let [lo, hi] = bp::SURFACING_CHORD_MM;
    // inch rounding moves a point by up to 1.27 µm per axis
    let slack = 3e-3;
    let lines: Vec<&host_sim::gcode::Move> = p
        .moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Line { .. }))
        .skip(1)
        .collect();
    let dx = |m: &host_sim::gcode::Move| (m.to()[0] - m.from[0]).abs();
    let mut links = 0;
    for (i, m) in lines.iter().enumerate() {
        let last_of_pass = lines.get(i + 1).is_none_or(|n| dx(n) < slack);
        if dx(m) < slack {
            links += 1;
            let dy = m.to()[1] - m.from[1];
            assert!((dy - bp::SURFACING_STEPOVER_MM).abs() < slack, "link {dy}");
        } else if last_of_pass {
            assert!(
                (0.5 * lo - slack..=1.5 * hi + slack).contains(&dx(m)),
                "last {}",
                dx(m)
            );
        } else {
            assert!(
                (lo - slack..=hi + slack).contains(&dx(m)),
                "chord {}",
                dx(m)
            );
        }
    }
    assert_eq!(links, bp::SURFACING_PASSES - 1);
    // spiral: every arc a quarter turn whose ends agree with its centre
    let p = parse("spiral_arcs", &text_of("spiral_arcs"));
    let mut radii = Vec::new();
    for m in &p.moves {
        if let MoveKind::Arc {
            to,
            center,
            sweep_rad,
            ..
        } = m.kind
        {
            let r0 = (m.from[0] - center[0]).hypot(m.from[1] - center[1]);
            let r1 = (to[0] - center[0]).hypot(to[1] - center[1]);
            assert!(
                (r0 - r1).abs() <= bp::SPIRAL_RADIUS_MISMATCH_MAX_MM,
                "{r0} {r1}"
            );
            // a quarter turn about the spiral's axis; about the arc's own centre a little more
            assert!((sweep_rad - TAU / 4.0).abs() < 0.05, "{sweep_rad}");
            radii.push(r0);
        }
    }
    let (rmin, rmax) = radii
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), &r| (a.min(r), b.max(r)));
    assert!(
        rmin > bp::SPIRAL_INNER_MM && rmin < bp::SPIRAL_INNER_MM + 1.0,
        "{rmin}"
    );
    assert!(
        rmax < bp::SPIRAL_OUTER_MM && rmax > bp::SPIRAL_OUTER_MM - 1.0,
        "{rmax}"
    );
    // zigzag: moves of 0.5-3 mm, corners within a row of 60-150°
    let p = parse("zigzag", &text_of("zigzag"));
    let zig: Vec<&host_sim::gcode::Move> = p
        .moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Line { .. }))
        .skip(1)
        .collect();
    for m in &zig {
        let l = m.length_mm();
        assert!((0.5 - 1e-3..=3.0 + 1e-3).contains(&l), "{l}");
    }
    let dir = |m: &host_sim::gcode::Move| {
        let t = m.to();
        [t[0] - m.from[0], t[1] - m.from[1]]
    };
    let mut row_corners = 0;
    for w in zig.windows(2) {
        let (a, b) = (dir(w[0]), dir(w[1]));
        // row links go straight down −Y; the corners they make are not the row's
        if a[0].abs() < 1e-9 || b[0].abs() < 1e-9 {
            continue;
        }
        let cos = (a[0] * b[0] + a[1] * b[1]) / (a[0].hypot(a[1]) * b[0].hypot(b[1]));
        let turn = cos.clamp(-1.0, 1.0).acos().to_degrees();
        assert!((59.9..=150.1).contains(&turn), "corner {turn}°");
        row_corners += 1;
    }
    assert!(row_corners > 900, "{row_corners}");
    // dense curve: chords of 0.05-0.2 mm
    let p = parse("dense_curve_3d", &text_of("dense_curve_3d"));
    for l in feed_lengths(&p).iter().skip(1) {
        assert!((0.05..=0.2).contains(l), "{l}");
    }
}

#[test]
fn huge_is_a_170000_line_program_inside_the_travel() {
    let text = bp::huge();
    assert_eq!(text.lines().count(), bp::HUGE_LINES);
    let p = parse("huge", &text);
    let (c, path_mm) = counts(&p);
    assert_eq!(
        c,
        Counts {
            rapids: 3,
            lines: bp::HUGE_FEED_MOVES,
            arcs: 0
        }
    );
    assert!(
        (path_mm - bp::HUGE_PATH_MM).abs() <= 1e-3 * bp::HUGE_PATH_MM,
        "{path_mm}"
    );
}

#[test]
fn rest_to_rest_lines_are_one_g61_line_from_the_origin() {
    let cases = bp::rest_to_rest_cases();
    let mut left_out = Vec::new();
    for dir in Direction::ALL {
        for len in bp::REST_TO_REST_LENGTHS_MM {
            if !cases.iter().any(|(_, l, d)| *l == len && *d == dir) {
                left_out.push(bp::rest_to_rest_name(len, dir));
            }
        }
    }
    // only the lines that would leave the travel from the origin are left out
    assert_eq!(
        left_out,
        ["r2r_x_300", "r2r_xy_300", "r2r_xyz_100", "r2r_xyz_300"]
    );
    assert_eq!(cases.len(), 20);
    for (name, len, dir) in cases {
        let p = parse(&name, &bp::rest_to_rest(len, dir));
        let (c, path_mm) = counts(&p);
        assert_eq!(
            c,
            Counts {
                rapids: 0,
                lines: 1,
                arcs: 0
            },
            "{name}"
        );
        // the end point rounded to 4 decimals
        assert!((path_mm - len).abs() < 1e-4, "{name}: {path_mm}");
        let to = p.moves.last().unwrap().to();
        let u = dir.unit();
        for a in 0..3 {
            assert!((to[a] - u[a] * len).abs() <= 0.5e-4 + 1e-12, "{name}");
        }
    }
    // the one left out along X is refused by the travel check, not silently clipped
    let p = parse_str("r2r_x_300", &bp::rest_to_rest(300.0, Direction::X)).unwrap();
    assert!(check_travel(&p, &default_travel()).is_err());
}
