//! The shipped example programs (host-sim/programs/) parse, stay within ±150 mm X/Y and
//! ±50 mm Z of the work origin, and contain what their names promise.

use std::{
    f64::consts::{PI, TAU},
    path::PathBuf,
};

use host_sim::gcode::{check_travel, parse_file, samples, Blend, MoveKind, Plane, Program, Travel};

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("programs")
}

fn load(name: &str) -> Program {
    parse_file(&dir().join(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// The travel the examples must respect: ±150 mm X/Y, ±50 mm Z about the work origin
/// (machine zero here: default G54 offset 0, start at 0).
fn travel() -> Travel {
    Travel::new([[-150.0, 150.0], [-150.0, 150.0], [-50.0, 50.0]]).unwrap()
}

const SHIPPED: [&str; 4] = ["square.nc", "arcs.nc", "helix.nc", "dense_contour.nc"];

#[test]
fn every_shipped_program_parses_and_respects_the_travel() {
    let mut names: Vec<String> = std::fs::read_dir(dir())
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".nc"))
        .collect();
    names.sort();
    let mut expected: Vec<String> = SHIPPED.iter().map(|s| s.to_string()).collect();
    expected.sort();
    assert_eq!(names, expected, "a new program must be added to SHIPPED");
    for name in SHIPPED {
        let p = load(name);
        check_travel(&p, &travel()).unwrap_or_else(|e| panic!("{e}"));
        assert!(p.end_line.is_some(), "{name} has no M2/M30");
        assert!(p.moves.iter().all(|m| m.to().iter().all(|v| v.is_finite())));
    }
}

#[test]
fn square_is_a_40_mm_square_in_exact_path_mode() {
    let p = load("square.nc");
    // G61: exact path (tolerance 0; its corners are all 90°, so the machine stops at each)
    assert_eq!(
        p.moves.iter().find_map(|m| match m.kind {
            MoveKind::SetBlend(b) => Some(b),
            _ => None,
        }),
        Some(Blend::ExactPath)
    );
    let cut: Vec<[f64; 3]> = p
        .moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Line { .. }) && m.from[2] == -1.0)
        .map(|m| m.to())
        .collect();
    assert_eq!(
        cut,
        [
            [20.0, -20.0, -1.0],
            [20.0, 20.0, -1.0],
            [-20.0, 20.0, -1.0],
            [-20.0, -20.0, -1.0]
        ]
    );
    assert_eq!(p.bounds_mm, [[-20.0, 20.0], [-20.0, 20.0], [-1.0, 5.0]]);
}

#[test]
fn arcs_has_a_circle_r_arcs_of_both_signs_and_ijk_arcs() {
    let p = load("arcs.nc");
    let arcs: Vec<(f64, Plane)> = p
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Arc {
                sweep_rad, plane, ..
            } => Some((sweep_rad, plane)),
            _ => None,
        })
        .collect();
    let expect = [
        (TAU, Plane::XY),
        (PI / 3.0, Plane::XY),
        (5.0 * PI / 3.0, Plane::XY),
        (PI / 2.0, Plane::XY),
        (PI / 2.0, Plane::XY),
        (PI, Plane::ZX),
    ];
    assert_eq!(arcs.len(), expect.len());
    for ((s, pl), (es, epl)) in arcs.iter().zip(expect) {
        assert!(
            (s - es).abs() < 1e-9 && *pl == epl,
            "{s} {pl:?} vs {es} {epl:?}"
        );
    }
    // The G18 half circle reaches Z = -10.
    assert!((p.bounds_mm[2][0] + 10.0).abs() < 1e-9);
}

#[test]
fn helix_descends_five_turns() {
    let p = load("helix.nc");
    let turns: Vec<(f64, f64)> = p
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Arc { sweep_rad, to, .. } => Some((sweep_rad, to[2] - m.from[2])),
            _ => None,
        })
        .collect();
    assert_eq!(turns.len(), 6);
    for (i, (sweep, dz)) in turns.iter().enumerate() {
        assert!((sweep - TAU).abs() < 1e-12);
        assert_eq!(*dz, if i < 5 { -1.0 } else { 0.0 });
    }
}

#[test]
fn dense_contour_is_the_generator_output() {
    let text = std::fs::read_to_string(dir().join("dense_contour.nc")).unwrap();
    let generated = samples::dense_contour(
        samples::DENSE_CONTOUR_PASSES,
        samples::DENSE_CONTOUR_SEGMENTS_PER_PASS,
    );
    assert!(
        text == generated,
        "programs/dense_contour.nc differs from the generator: run \
         `cargo test -p host-sim --test sim_tests gcode_programs::regenerate_dense_contour -- --ignored`"
    );
    assert!(text.len() < 1024 * 1024, "{} bytes", text.len());
    let p = load("dense_contour.nc");
    let lines: Vec<f64> = p
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Line {
                to,
                feed_mm_s: 25.0,
            } => Some(
                (0..3)
                    .map(|a| (to[a] - m.from[a]).powi(2))
                    .sum::<f64>()
                    .sqrt(),
            ),
            _ => None,
        })
        .collect();
    assert!(lines.len() >= 5000, "{} contour segments", lines.len());
    // Short segments: 0.1–0.2 mm for 3000 per turn of a 49–71 mm radius outline.
    let (min, max) = lines
        .iter()
        .fold((f64::MAX, 0f64), |(lo, hi), &l| (lo.min(l), hi.max(l)));
    assert!(min > 0.05 && max < 0.25, "segment lengths {min}..{max} mm");
}

/// Rewrites programs/dense_contour.nc from the generator.
#[test]
#[ignore]
fn regenerate_dense_contour() {
    let text = samples::dense_contour(
        samples::DENSE_CONTOUR_PASSES,
        samples::DENSE_CONTOUR_SEGMENTS_PER_PASS,
    );
    std::fs::write(dir().join("dense_contour.nc"), text).unwrap();
}
