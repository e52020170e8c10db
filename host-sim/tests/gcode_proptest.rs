//! The G-code front end never panics and never emits a non-finite number, whatever the
//! input: random bytes, random G-code-like text, random well-formed programs.

// Axis loops index several arrays at once; ranges read clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

use host_sim::gcode::{check_travel, parse_str, MoveKind, Program, Travel};
use proptest::prelude::*;

/// Every number in the program is finite and every move lies within the bounds.
fn assert_sane(p: &Program) -> Result<(), TestCaseError> {
    let finite = |v: [f64; 3]| v.iter().all(|x| x.is_finite());
    for m in &p.moves {
        prop_assert!(finite(m.from) && finite(m.to()), "{m:?}");
        match m.kind {
            MoveKind::Line { feed_mm_s, .. } => {
                prop_assert!(feed_mm_s > 0.0 && feed_mm_s.is_finite())
            }
            MoveKind::Arc {
                center,
                sweep_rad,
                feed_mm_s,
                turns,
                ..
            } => {
                prop_assert!(finite(center) && sweep_rad > 0.0 && sweep_rad.is_finite());
                prop_assert!(feed_mm_s > 0.0 && turns >= 1);
            }
            MoveKind::Dwell { s } => prop_assert!(s >= 0.0 && s.is_finite()),
            _ => {}
        }
        let e = m.extent_mm();
        for a in 0..3 {
            prop_assert!(p.bounds_mm[a][0] <= e[a][0] && e[a][1] <= p.bounds_mm[a][1]);
        }
    }
    let travel = Travel::new([[-150.0, 150.0], [-150.0, 150.0], [-50.0, 50.0]]).unwrap();
    let _ = check_travel(p, &travel);
    Ok(())
}

/// One random word, mostly from the accepted vocabulary, with numbers of every shape.
fn word() -> impl Strategy<Value = String> {
    let letter = prop::sample::select(vec![
        "G", "M", "X", "Y", "Z", "I", "J", "K", "R", "F", "P", "N", "S", "T", "O", "A", "#", "[",
        "(", ";", "/", "%", "H", "L", "Q",
    ]);
    let number = prop_oneof![
        (0u32..100).prop_map(|n| n.to_string()),
        prop::sample::select(vec![
            "0", "1", "2", "3", "4", "17", "18", "19", "20", "21", "28", "53", "54", "61", "64",
            "80", "90", "91", "92", "92.1", "30", "10", "43", "43.1", "49", "52", "55", "59.3",
            "61.1", "90.1", "93", "94"
        ])
        .prop_map(str::to_string),
        (-1000.0f64..1000.0).prop_map(|v| format!("{v:.4}")),
        "[-+.0-9e]{0,12}",
        Just(String::new()),
    ];
    (letter, number, prop::bool::ANY)
        .prop_map(|(l, n, space)| format!("{l}{}{n}", if space { " " } else { "" }))
}

fn program() -> impl Strategy<Value = String> {
    prop::collection::vec(
        prop::collection::vec(word(), 0..6).prop_map(|w| w.join(" ")),
        0..25,
    )
    .prop_map(|lines| lines.join("\n"))
}

/// A well-formed program of moves (rapids, feeds, incremental arcs by I/J/K and by R in
/// all three planes, helices, unit/distance/offset switches, coordinate systems, G10,
/// G52, tool length offsets, inverse time, path control) that mostly parses, so the
/// geometry paths are exercised: arc ends are put on the circle (6 decimals), so every
/// such program must be accepted.
fn valid_program() -> impl Strategy<Value = String> {
    let coord = || (-60.0f64..60.0).prop_map(|v| format!("{v:.3}"));
    // (G, first, second, normal axis letters, first and second offset letters)
    let planes = prop::sample::select(vec![
        ("G17", 'X', 'Y', 'Z', 'I', 'J'),
        ("G18", 'Z', 'X', 'Y', 'K', 'I'),
        ("G19", 'Y', 'Z', 'X', 'J', 'K'),
    ]);
    let ijk_arc = (
        planes.clone(),
        -30.0f64..30.0,
        0.5f64..30.0,
        -3.2f64..3.2,
        -5.0f64..5.0,
        any::<bool>(),
        1u32..3,
    )
        .prop_map(|((g, a, b, n, oa, ob), i, j, ang, dn, cw, turns)| {
            let r = i.hypot(j);
            let (du, dv) = (i + r * ang.cos(), j + r * ang.sin());
            format!(
                "G91 {g} G{} {a}{du:.6} {b}{dv:.6} {n}{dn:.3} {oa}{i:.6} {ob}{j:.6} P{turns} F500",
                if cw { 2 } else { 3 }
            )
        });
    let r_arc = (
        planes,
        0.5f64..40.0,
        0.01f64..1.0,
        -3.2f64..3.2,
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(|((g, a, b, ..), r, frac, dir, neg, cw)| {
            let chord = 2.0 * r * frac;
            let (du, dv) = (chord * dir.cos(), chord * dir.sin());
            let r = if neg { -r } else { r };
            format!(
                "G91 {g} G{} {a}{du:.6} {b}{dv:.6} R{r:.6} F500",
                if cw { 2 } else { 3 }
            )
        });
    let line = prop_oneof![
        (coord(), coord(), coord()).prop_map(|(x, y, z)| format!("G90 G0 X{x} Y{y} Z{z}")),
        (coord(), coord()).prop_map(|(x, y)| format!("G90 G1 X{x} Y{y} F900")),
        ijk_arc,
        r_arc,
        prop::sample::select(vec![
            "G20",
            "G21",
            "G92 X0 Y0",
            "G92.1",
            "G28",
            "G61",
            "G64 P0.01",
            "M0",
            "G4 P0.5",
            "G90 G53 G0 Z0",
            "G55",
            "G59.3",
            "G54",
            "G10 L2 P3 X1 Y-2",
            "G10 L20 P0 Z0",
            "G52 X1",
            "G52 X0 Y0 Z0",
            "G43.1 Z1.5",
            "G49",
            "G61.1",
            "G64 P0.01 Q0.02",
            "G93",
            "G94",
        ])
        .prop_map(str::to_string),
    ];
    prop::collection::vec(line, 1..30).prop_map(|l| l.join("\n"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(p) = parse_str("fuzz.nc", &text) {
            assert_sane(&p)?;
        }
    }

    #[test]
    fn random_gcode_like_text_never_panics(text in program()) {
        match parse_str("fuzz.nc", &text) {
            Ok(p) => assert_sane(&p)?,
            Err(e) => {
                let s = e.to_string();
                prop_assert!(s.starts_with("fuzz.nc:"), "{s}");
            }
        }
    }

    #[test]
    fn well_formed_programs_are_accepted_and_sane(text in valid_program()) {
        let p = parse_str("fuzz.nc", &text).map_err(|e| TestCaseError::fail(e.to_string()))?;
        assert_sane(&p)?;
    }

    #[test]
    fn any_unicode_string_never_panics(text in "\\PC{0,300}") {
        let _ = parse_str("fuzz.nc", &text);
    }
}
