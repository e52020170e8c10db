//! Key registry tests: every key's get / text / parse / set round trip, errors that name
//! the key and its range and change nothing, whole-tree rejections, models entered through
//! keys, apply classes, and the doc table.

extern crate std;

use std::string::{String, ToString};
use std::vec::Vec;

use super::*;
use crate::config::ConfigError;
use crate::filter::MAX_STAGES;
use crate::law::LawConfig;
use crate::plant::AxisModel;
use crate::presets::board::BOARD_RATE_HZ;
use crate::presets::gantry::{dsmc_for, tuning_for, GANTRY_X, GANTRY_Y};
use crate::settings::{FACTORY, TOOL_COUNT, WORK_SYSTEMS};
use crate::sysid::tuning;

const RATE: u32 = BOARD_RATE_HZ;

/// Number of keys: 39 per axis, 9 per axis' feed-forward, 5 per axis' filter stage, 12
/// others, 3 per axis' input shaper, 3 per work coordinate system, 2 per tool.
const KEY_COUNT: usize =
    (39 + 9 + 5 * MAX_STAGES) * 3 + 12 + 3 * 3 + 3 * WORK_SYSTEMS + 2 * TOOL_COUNT;

/// The factory tree with every axis' model known (so every key has a value).
fn with_models() -> Settings {
    let mut s = FACTORY;
    for (a, m) in s.axis.iter_mut().zip(PLACEHOLDER_MODELS) {
        a.model = Some(m);
    }
    s
}

/// Every key's value, for bit-exact comparison of whole trees.
fn snapshot(s: &Settings) -> Vec<(&'static str, Option<Value>)> {
    s.list().map(|(k, v)| (k.name, v)).collect()
}

fn same_tree(a: &Settings, b: &Settings) -> bool {
    snapshot(a)
        .iter()
        .zip(snapshot(b))
        .all(|((ka, va), (kb, vb))| {
            *ka == kb
                && match (va, vb) {
                    (Some(x), Some(y)) => x.same(&y),
                    (None, None) => true,
                    _ => false,
                }
        })
}

#[test]
fn keys_are_unique_named_by_their_axis_and_counted() {
    let names: Vec<&str> = keys().map(|k| k.name).collect();
    assert_eq!(names.len(), KEY_COUNT);
    let mut sorted = names.clone();
    sorted.sort_unstable();
    sorted.dedup();
    assert_eq!(sorted.len(), KEY_COUNT, "duplicate key names");
    for k in keys() {
        match k.axis() {
            Some(a) => assert!(
                k.name.starts_with(&std::format!("axis.{}.", a.name())),
                "{}",
                k.name
            ),
            None => assert!(!k.name.starts_with("axis."), "{}", k.name),
        }
        assert!(!k.doc.is_empty() && !k.doc.contains('\n') && !k.doc.contains('|'));
        // a unit where the value has one
        if matches!(k.range, Range::F32 { .. }) && !k.name.contains("lambda") {
            assert!(
                // (dimensionless: damping ratio, tangential share, servo reserve, a
                // filter's quality, the Stribeck peak's ratio)
                !k.unit.is_empty()
                    || k.name.ends_with(".q")
                    || k.name.ends_with("stiction_ratio")
                    || k.name.ends_with("damping")
                    || k.name.ends_with("damping_ratio")
                    || k.name.ends_with("share")
                    || k.name.ends_with("reserve"),
                "{} has no unit",
                k.name
            );
        }
    }
    assert_eq!(
        find("axis.y.following_error_mm").map(|k| k.apply),
        Ok(Apply::Live)
    );
    assert_eq!(
        find("axis.z.law.kind").map(|k| k.apply),
        Ok(Apply::OutputsOff)
    );
}

#[test]
fn factory_values_lie_in_their_ranges() {
    assert_eq!(FACTORY.out_of_range(), None);
    assert_eq!(with_models().out_of_range(), None);
    assert_eq!(FACTORY.validate(RATE), Ok(()));
    // the unknown models have no value
    let unset: Vec<&str> = FACTORY
        .list()
        .filter(|(_, v)| v.is_none())
        .map(|(k, _)| k.name)
        .collect();
    assert_eq!(unset.len(), 3 * 4);
    assert!(unset.iter().all(|n| n.contains(".model.")));
}

#[test]
fn every_key_round_trips_through_get_text_parse_and_set() {
    let s0 = with_models();
    let mut s = s0;
    for k in keys() {
        let v = s.get(k.name).unwrap();
        let text = v.to_string();
        let parsed = k.parse(&text).unwrap();
        assert!(parsed.same(&v), "{}: {text} parsed as {parsed:?}", k.name);
        s.set(k.name, parsed, RATE)
            .unwrap_or_else(|e| panic!("{}: {e}", k.name));
        s.set_text(k.name, &text, RATE).unwrap();
        assert!(s.get(k.name).unwrap().same(&v));
    }
    assert!(same_tree(&s, &s0));
    assert_eq!(s, s0);
}

/// Candidate new values for a key at `v`, nearest first.
fn other_values(k: &Key, v: Value) -> Vec<Value> {
    match (k.range, v) {
        (Range::F32 { min, max }, Value::F32(x)) => {
            [x * 0.99, x * 1.01, x + 0.5, x - 0.5, min, max]
                .into_iter()
                .filter(|c| c.to_bits() != x.to_bits())
                .map(Value::F32)
                .collect()
        }
        (Range::U32 { min, max }, Value::U32(x)) => {
            [x.saturating_add(1), x.saturating_sub(1), min, max]
                .into_iter()
                .filter(|c| *c != x)
                .map(Value::U32)
                .collect()
        }
        (Range::Bool, Value::Bool(b)) => std::vec![Value::Bool(!b)],
        (Range::Choice(names), Value::Choice(c)) => names
            .iter()
            .filter(|n| **n != c)
            .map(|n| Value::Choice(n))
            .collect(),
        _ => panic!("{}: value {v:?} does not match its range", k.name),
    }
}

#[test]
fn every_key_changes_its_value_and_nothing_else() {
    let s0 = with_models();
    for k in keys() {
        let before = s0.get(k.name).unwrap();
        // a key that alone moves the home position beyond the other end of the travel
        // changes together with the switch position
        let companion = k
            .name
            .ends_with("homing.direction")
            .then(|| k.name.replace("direction", "switch_pos_mm"));
        let mut accepted = None;
        for candidate in other_values(&k, before) {
            let mut s = s0;
            let result = match &companion {
                Some(switch) => {
                    let Ok(Value::F32(pos)) = s0.get(switch) else {
                        panic!("{switch}")
                    };
                    // alone: refused
                    assert!(matches!(
                        s.set(k.name, candidate, RATE),
                        Err(SetError::Rejected { .. })
                    ));
                    s.set_all(&[(k.name, candidate), (switch, Value::F32(-pos))], RATE)
                }
                None => s.set(k.name, candidate, RATE),
            };
            match result {
                Ok(()) => {
                    accepted = Some((s, candidate));
                    break;
                }
                Err(e) => {
                    // a refused candidate changes nothing
                    assert!(same_tree(&s, &s0), "{}: {e}", k.name);
                    assert!(
                        matches!(e, SetError::Rejected { .. } | SetError::OutOfRange { .. }),
                        "{}: {e}",
                        k.name
                    );
                }
            }
        }
        let (s, v) = accepted.unwrap_or_else(|| panic!("{}: no other value accepted", k.name));
        assert!(s.get(k.name).unwrap().same(&v), "{}", k.name);
        for ((name, a), (_, b)) in snapshot(&s).into_iter().zip(snapshot(&s0)) {
            if name == k.name || Some(name) == companion.as_deref() {
                continue;
            }
            // forgetting a model also clears its four values
            let model_side_effect = k.name.ends_with("model.known")
                && name.starts_with(&k.name[..7])
                && name.contains(".model.");
            if model_side_effect {
                assert_eq!(a, None, "{name}");
                continue;
            }
            let unchanged = match (a, b) {
                (Some(x), Some(y)) => x.same(&y),
                (None, None) => true,
                _ => false,
            };
            assert!(unchanged, "setting {} changed {name}", k.name);
        }
    }
}

#[test]
fn out_of_range_values_name_the_key_and_range_and_change_nothing() {
    let s0 = with_models();
    for k in keys() {
        let bad: Vec<Value> = match k.range {
            Range::F32 { min, max } => std::vec![
                Value::F32(max * 2.0 + 1.0),
                Value::F32(min - (max - min) * 0.5 - 1.0),
                Value::F32(f32::NAN),
                Value::F32(f32::INFINITY),
            ],
            Range::U32 { min, max } => {
                let mut v = std::vec![Value::U32(max + 1)];
                if min > 0 {
                    v.push(Value::U32(min - 1));
                }
                v
            }
            Range::Bool => std::vec![],
            Range::Choice(_) => std::vec![Value::Choice("bogus")],
        };
        for v in bad {
            let mut s = s0;
            let e = s.set(k.name, v, RATE).unwrap_err();
            let SetError::OutOfRange {
                key,
                value,
                range,
                unit,
            } = e.clone()
            else {
                panic!("{}: {e:?}", k.name)
            };
            assert!(key == k.name && value.same(&v) && range == k.range && unit == k.unit);
            let text = e.to_string();
            assert!(
                text.contains(k.name) && text.contains(&k.range.to_string()),
                "{text}"
            );
            assert!(same_tree(&s, &s0), "{}", k.name);
        }
    }
    let mut s = FACTORY;
    let e = s
        .set("axis.x.following_error_mm", Value::F32(500.0), RATE)
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "axis.x.following_error_mm: 500 is outside the allowed range [0.001, 100] mm"
    );
}

#[test]
fn wrong_types_and_unknown_keys_are_refused_and_change_nothing() {
    let s0 = with_models();
    for k in keys() {
        let wrong = match k.range {
            Range::F32 { .. } => Value::U32(1),
            Range::U32 { .. } => Value::F32(100.0),
            Range::Bool => Value::F32(1.0),
            Range::Choice(_) => Value::Bool(true),
        };
        let mut s = s0;
        assert_eq!(
            s.set(k.name, wrong, RATE),
            Err(SetError::WrongType {
                key: k.name,
                range: k.range
            })
        );
        // text of the wrong type
        let e = s.set_text(k.name, "not-a-value", RATE).unwrap_err();
        assert_eq!(
            e,
            SetError::WrongType {
                key: k.name,
                range: k.range
            }
        );
        assert!(e.to_string().starts_with(k.name));
        assert!(same_tree(&s, &s0));
    }
    let mut s = s0;
    for bad in [
        "axis.w.vel_max_mm_s",
        "axis.x",
        "",
        "link.watchdog",
        "axis.x.model",
    ] {
        let e = s.set(bad, Value::F32(1.0), RATE).unwrap_err();
        assert_eq!(e, SetError::Unknown(KeyText::new(bad)));
        assert_eq!(e.to_string(), std::format!("unknown key `{bad}`"));
        assert!(matches!(s.get(bad), Err(KeyError::Unknown(_))));
    }
    // a long unknown key is repeated back cut to KEY_TEXT_MAX bytes
    let long = "axis.x.".repeat(20);
    let e = s.set(&long, Value::F32(1.0), RATE).unwrap_err();
    let text = e.to_string();
    assert!(
        text.len() <= KEY_TEXT_MAX + "unknown key ``".len(),
        "{text}"
    );
    assert!(text.ends_with("…`"));
    assert!(same_tree(&s, &s0));
}

#[test]
fn shaper_keys_are_validated_with_the_tree_and_their_deviation_with_the_planner() {
    let mut s = FACTORY;
    assert_eq!(s.shaper.shapers(), crate::motion::shaper::AxisShapers::NONE);
    s.set_text("shaper.y.freq_hz", "35", RATE).unwrap();
    // ZVD lasts one damped period, 287 periods at 35 Hz: longer than the board's history
    let e = s.set_text("shaper.y.kind", "zvd", RATE).unwrap_err();
    let SetError::Rejected { error, .. } = &e else {
        panic!("{e}")
    };
    match error {
        ServoConfigError::Shaper(ConfigError::OutOfRange(name)) => {
            assert!(name.starts_with("shaper.y (zvd) longer"), "{name}")
        }
        other => panic!("{other:?}"),
    }
    assert!(
        e.to_string()
            .starts_with("shaper.y.kind = zvd rejected: parameter `shaper.y (zvd) longer"),
        "{e}"
    );
    assert_eq!(s.shaper.y.kind, None, "a refused change changes nothing");
    s.set_text("shaper.y.kind", "zv", RATE).unwrap();
    assert_eq!(
        s.shaper.shapers().y,
        Some(crate::motion::shaper::ShaperConfig::new(
            crate::motion::shaper::ShaperKind::Zv,
            35.0
        ))
    );
    assert_eq!(FACTORY.change_class(&s), Some(Apply::OutputsOff));
    // above 1/100 of the control rate
    let e = s.set_text("shaper.y.freq_hz", "150", RATE).unwrap_err();
    assert!(
        e.to_string()
            .contains("shaper.y.freq_hz (<= 1/100 of the control rate)"),
        "{e}"
    );
    // no path tolerance left for the shaper's deviation
    let e = s.set_text("planner.tolerance_mm", "0", RATE).unwrap_err();
    let SetError::Rejected { error, .. } = &e else {
        panic!("{e}")
    };
    assert_eq!(
        *error,
        ServoConfigError::ShaperTolerance(crate::motion::shaper::ShapedPlannerError::NoTolerance)
    );
    assert!(
        e.to_string()
            .contains("planner.tolerance_mm must be > 0 with input shaping"),
        "{e}"
    );
    // "none" switches it off again, keeping the mode's values
    s.set_text("shaper.y.kind", "none", RATE).unwrap();
    assert_eq!(s.shaper.y.freq_hz, 35.0);
    s.set_text("planner.tolerance_mm", "0", RATE).unwrap();
}

#[test]
fn values_valid_alone_but_rejected_by_the_servo_are_refused_with_its_reason() {
    let s0 = FACTORY;
    let cases: [(&str, Value, ServoConfigError); 5] = [
        (
            "axis.x.following_error_mm",
            Value::F32(0.05),
            ServoConfigError::Servo(ConfigError::OutOfRange(
                "safety.ferror_mm (>= min_ferror_mm)",
            )),
        ),
        (
            "axis.y.travel.min_mm",
            Value::F32(200.0),
            ServoConfigError::Servo(ConfigError::OutOfRange("travel.y (min_mm < max_mm)")),
        ),
        (
            "axis.z.homing.switch_pos_mm",
            Value::F32(60.0),
            ServoConfigError::Servo(ConfigError::OutOfRange(
                "homing: switch_pos_mm -/+ pulloff_mm must lie inside the travel",
            )),
        ),
        (
            "axis.x.homing.locate_mm_s",
            Value::F32(30.0),
            ServoConfigError::Servo(ConfigError::OutOfRange(
                "homing.locate_mm_s (at most seek_mm_s)",
            )),
        ),
        (
            "estimator.pll_bandwidth_rad_s",
            Value::F32(9000.0),
            ServoConfigError::Servo(ConfigError::Unstable(
                "pll (bandwidth_rad_s too high for the control rate)",
            )),
        ),
    ];
    for (key, value, expected) in cases {
        let mut s = s0;
        let e = s.set(key, value, RATE).unwrap_err();
        let SetError::Rejected {
            key: k,
            value: v,
            error,
        } = &e
        else {
            panic!("{key}: {e}")
        };
        assert_eq!((*k, *v), (key, value));
        // the servo's own text is part of the message
        match (error, &expected) {
            (
                ServoConfigError::Servo(ConfigError::Unstable(_)),
                ServoConfigError::Servo(ConfigError::Unstable(_)),
            ) => {}
            _ => assert_eq!(*error, expected, "{key}"),
        }
        let text = e.to_string();
        assert!(
            text.contains(&error.to_string()) && text.starts_with(key),
            "{text}"
        );
        assert!(same_tree(&s, &s0), "{key}");
    }
    // a model whose forward friction is below its backward friction is not dissipative
    let mut s = with_models();
    let e = s
        .set("axis.y.model.coulomb_pos_mnm", Value::F32(-60.0), RATE)
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "axis.y.model.coulomb_pos_mnm = -60 rejected: axis.y.model: parameter \
         `coulomb_pos_mnm - coulomb_neg_mnm` must not be negative"
    );
}

#[test]
fn a_model_entered_through_keys_arms_and_gives_the_presets_dsmc_bit_for_bit() {
    let mut s = FACTORY;
    // no model yet: its values cannot be read or set
    assert_eq!(
        s.get("axis.x.model.inertia"),
        Err(KeyError::NoModel {
            key: "axis.x.model.inertia"
        })
    );
    assert_eq!(
        s.set("axis.x.model.inertia", Value::F32(0.064), RATE),
        Err(SetError::NoModel {
            key: "axis.x.model.inertia"
        })
    );
    assert_eq!(FACTORY.servo_config(RATE).unwrap().model_known, [false; 3]);

    // Y first gets a foreign model, then X and Y the presets', value by value
    s.set_text("axis.y.model.known", "true", RATE).unwrap();
    s.set_text("axis.y.model.inertia", "0.3", RATE).unwrap();
    for (axis, p) in [("x", &GANTRY_X), ("y", &GANTRY_Y)] {
        s.set(
            &std::format!("axis.{axis}.model.known"),
            Value::Bool(true),
            RATE,
        )
        .unwrap();
        for (field, v) in [
            ("inertia", p.inertia),
            ("viscous", p.viscous),
            ("coulomb_pos_mnm", p.coulomb_pos_mnm),
            ("coulomb_neg_mnm", p.coulomb_neg_mnm),
        ] {
            let key = std::format!("axis.{axis}.model.{field}");
            s.set_text(&key, &v.to_string(), RATE).unwrap();
            assert_eq!(s.get(&key).map(|v| v.to_string()), Ok(v.to_string()));
        }
    }
    let c = s.servo_config(RATE).unwrap();
    assert_eq!(c.model_known, [true, true, false]);
    for (law, p) in c.controller.laws.iter().zip([&GANTRY_X, &GANTRY_Y]) {
        let LawConfig::Smc(got) = law else {
            panic!("{law:?}")
        };
        let want = dsmc_for(p);
        assert_eq!(*got, want);
        // bit for bit, field by field of what the law computes from the model
        assert_eq!(got.plant.a.to_bits(), want.plant.a.to_bits());
        assert_eq!(got.plant.k.to_bits(), want.plant.k.to_bits());
        assert_eq!(got.k4.to_bits(), want.k4.to_bits());
        assert_eq!(got.integral_limit.to_bits(), want.integral_limit.to_bits());
        assert_eq!(got.u_max.to_bits(), want.u_max.to_bits());
    }

    // another law on X takes the same model
    s.set_text("axis.x.law.kind", "dob_smc", RATE).unwrap();
    let c = s.servo_config(RATE).unwrap();
    assert_eq!(
        c.controller.laws[0],
        LawConfig::DobSmc(tuning::dob_smc(
            &AxisModel::from_physical(&GANTRY_X),
            &tuning_for(&GANTRY_X)
        ))
    );

    // forgetting a model: unknown again, its values gone
    s.set_text("axis.y.model.known", "false", RATE).unwrap();
    assert_eq!(s.axis[1].model, None);
    assert_eq!(
        s.servo_config(RATE).unwrap().model_known,
        [true, false, false]
    );
}

#[test]
fn text_from_the_cli_parses_by_the_keys_type() {
    let mut s = FACTORY;
    s.set_text("axis.x.min_ferror_mm", " 0.05 ", RATE).unwrap();
    assert_eq!(s.axis[0].min_ferror_mm, 0.05);
    s.set_text("axis.z.homing.use_index", "true", RATE).unwrap();
    assert!(s.axis[2].homing.use_index);
    s.set_text("axis.y.law.kind", "adaptive_smc", RATE).unwrap();
    assert_eq!(s.axis[1].law.kind, LawKind::AdaptiveSmc);
    s.set_text("coupling.kind", "none", RATE).unwrap();
    assert_eq!(s.coupling.kind, CouplingKind::None);
    s.set_text("link.watchdog_ms", "250", RATE).unwrap();
    assert_eq!(s.link.watchdog_ms, 250);
    // the switch moves to the other end with its direction, in one change
    let max = find("axis.x.homing.direction")
        .unwrap()
        .parse("max")
        .unwrap();
    s.set_all(
        &[
            ("axis.x.homing.direction", max),
            ("axis.x.homing.switch_pos_mm", Value::F32(151.0)),
        ],
        RATE,
    )
    .unwrap();
    assert_eq!(s.axis[0].homing.direction, HomeDirection::Max);
    assert_eq!(s.axis[0].homing.switch_pos_mm, 151.0);
    // case matters, integers are not floats
    for (key, text) in [
        ("axis.y.law.kind", "DSMC"),
        ("axis.x.homing.enabled", "1"),
        ("link.watchdog_ms", "250.0"),
        ("axis.x.vel_max_mm_s", ""),
    ] {
        let before = s;
        assert!(matches!(
            s.set_text(key, text, RATE),
            Err(SetError::WrongType { .. })
        ));
        assert_eq!(s, before);
    }
}

#[test]
fn change_classes() {
    let s0 = FACTORY;
    assert_eq!(s0.change_class(&s0), None);
    let mut live = s0;
    live.set_text("axis.x.jog.speed_max_mm_s", "20", RATE)
        .unwrap();
    live.set_text("axis.y.following_error_mm", "2", RATE)
        .unwrap();
    live.set_text("link.watchdog_ms", "1000", RATE).unwrap();
    assert_eq!(s0.change_class(&live), Some(Apply::Live));
    let mut off = live;
    off.set_text("axis.z.law.kind", "pid", RATE).unwrap();
    assert_eq!(s0.change_class(&off), Some(Apply::OutputsOff));
    let mut model = s0;
    model.set_text("axis.x.model.known", "true", RATE).unwrap();
    assert_eq!(s0.change_class(&model), Some(Apply::OutputsOff));
    // every live key is a limit, a jog value, the link or identification's next run
    for k in keys().filter(|k| k.apply == Apply::Live) {
        assert!(
            [
                "ferror_mm",
                "following_error_mm",
                ".jog.",
                "jog.timeout_s",
                "link.",
                "identify."
            ]
            .iter()
            .any(|p| k.name.contains(p)),
            "{}",
            k.name
        );
    }
}

#[test]
fn work_offsets_and_tools_are_keys_taken_at_any_time() {
    assert_eq!(KEY_COUNT, 268);
    let names: Vec<&str> = keys().map(|k| k.name).collect();
    // the tables come last, row by row: G54's three coordinates, ..., then the tools
    let work = names.iter().position(|n| *n == "work.g54.x_mm").unwrap();
    assert_eq!(
        names[work..work + 6],
        [
            "work.g54.x_mm",
            "work.g54.y_mm",
            "work.g54.z_mm",
            "work.g55.x_mm",
            "work.g55.y_mm",
            "work.g55.z_mm"
        ]
    );
    assert_eq!(names[work + 26], "work.g59_3.z_mm");
    assert_eq!(
        names[work + 27..],
        [
            "tool.1.length_mm",
            "tool.1.diameter_mm",
            "tool.2.length_mm",
            "tool.2.diameter_mm",
            "tool.3.length_mm",
            "tool.3.diameter_mm",
            "tool.4.length_mm",
            "tool.4.diameter_mm",
            "tool.5.length_mm",
            "tool.5.diameter_mm",
            "tool.6.length_mm",
            "tool.6.diameter_mm",
            "tool.7.length_mm",
            "tool.7.diameter_mm",
            "tool.8.length_mm",
            "tool.8.diameter_mm"
        ]
    );
    for k in keys().filter(|k| k.name.starts_with("work.") || k.name.starts_with("tool.")) {
        assert_eq!((k.apply, k.unit), (Apply::Anytime, "mm"), "{}", k.name);
        assert_eq!(k.axis(), None);
    }
    assert_eq!(
        find("work.g55.x_mm").map(|k| k.range),
        Ok(Range::F32 {
            min: -10_000.0,
            max: 10_000.0
        })
    );
    assert_eq!(
        find("tool.8.length_mm").map(|k| k.range),
        Ok(Range::F32 {
            min: -1_000.0,
            max: 1_000.0
        })
    );
    assert_eq!(
        find("tool.1.diameter_mm").map(|k| k.range),
        Ok(Range::F32 {
            min: 0.0,
            max: 1_000.0
        })
    );
    assert!(find("tool.0.length_mm").is_err() && find("tool.9.length_mm").is_err());
    assert!(find("work.g59_4.x_mm").is_err() && find("work.g53.x_mm").is_err());

    // set through the keys, read back from the tree's fields
    let mut s = FACTORY;
    s.set_text("work.g55.x_mm", "120.5", RATE).unwrap();
    s.set_text("work.g59_3.z_mm", "-42.25", RATE).unwrap();
    s.set_text("tool.3.length_mm", "37.5", RATE).unwrap();
    s.set_text("tool.8.diameter_mm", "6", RATE).unwrap();
    assert_eq!(s.work.g55.to_array(), [120.5, 0.0, 0.0]);
    assert_eq!(s.work.g59_3.to_array(), [0.0, 0.0, -42.25]);
    assert_eq!(s.work.to_array()[1], [120.5, 0.0, 0.0]);
    assert_eq!((s.tool.t3.length_mm, s.tool.t3.diameter_mm), (37.5, 0.0));
    assert_eq!(s.tool.t8.diameter_mm, 6.0);
    assert_eq!(s.get("tool.3.length_mm"), Ok(Value::F32(37.5)));
    // out of range: named, nothing changed
    let before = s;
    assert_eq!(
        s.set_text("work.g54.y_mm", "20000", RATE)
            .unwrap_err()
            .to_string(),
        "work.g54.y_mm: 20000 is outside the allowed range [-10000, 10000] mm"
    );
    assert_eq!(
        s.set_text("tool.2.diameter_mm", "-1", RATE)
            .unwrap_err()
            .to_string(),
        "tool.2.diameter_mm: -1 is outside the allowed range [0, 1000] mm"
    );
    assert!(s
        .set("tool.2.length_mm", Value::F32(f32::NAN), RATE)
        .is_err());
    assert_eq!(s, before);
    // no servo parameter changes: the machine takes it without a reconfiguration, armed
    // or moving (the supervisor applies class None at once)
    assert_eq!(FACTORY.change_class(&s), None);
    let mut both = s;
    both.set_text("axis.x.jog.speed_max_mm_s", "20", RATE)
        .unwrap();
    assert_eq!(FACTORY.change_class(&both), Some(Apply::Live));
    // the servo configuration does not depend on them
    assert_eq!(s.servo_config(RATE), FACTORY.servo_config(RATE));
}

#[test]
fn docs_settings_md_key_table_is_current() {
    const BEGIN: &str = "<!-- keys:begin (generated from settings::keys, see the test docs_settings_md_key_table_is_current) -->\n";
    const END: &str = "<!-- keys:end -->";
    let mut table = String::new();
    write_markdown_table(&mut table, &FACTORY).unwrap();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/settings.md");
    let doc = std::fs::read_to_string(path).unwrap();
    let start = doc.find(BEGIN).expect("docs/settings.md: begin marker") + BEGIN.len();
    let end = doc.find(END).expect("docs/settings.md: end marker");
    if doc.get(start..end) != Some(table.as_str()) {
        if std::env::var_os("GANTRY_UPDATE_DOCS").is_some() {
            let updated = std::format!("{}{table}{}", &doc[..start], &doc[end..]);
            std::fs::write(path, updated).unwrap();
        } else {
            panic!(
                "docs/settings.md's key table is stale: run \
                 `GANTRY_UPDATE_DOCS=1 cargo test -p controller-core docs_settings_md` and commit it"
            );
        }
    }
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn value() -> impl Strategy<Value = Value> {
        prop_oneof![
            any::<f32>().prop_map(Value::F32),
            (-1e4f32..1e4).prop_map(Value::F32),
            any::<u32>().prop_map(Value::U32),
            (0u32..70_000).prop_map(Value::U32),
            any::<bool>().prop_map(Value::Bool),
            prop::sample::select(std::vec![
                "pid", "dsmc", "contour", "none", "min", "max", "x"
            ])
            .prop_map(Value::Choice),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Any value on any key: accepted values are read back and leave a valid tree;
        /// refused ones change nothing.
        #[test]
        fn any_value_on_any_key(i in 0..KEY_COUNT, v in value(), models in any::<bool>()) {
            let s0 = if models { with_models() } else { FACTORY };
            let k = keys().nth(i).unwrap();
            let mut s = s0;
            match s.set(k.name, v, RATE) {
                Ok(()) => {
                    prop_assert!(s.get(k.name).unwrap().same(&v) || k.name.ends_with("model.known"));
                    prop_assert_eq!(s.validate(RATE), Ok(()));
                }
                Err(e) => {
                    prop_assert!(same_tree(&s, &s0));
                    prop_assert!(e.to_string().contains(k.name));
                }
            }
        }

        /// Any text on any key name (known or not) never panics; refusals change nothing.
        #[test]
        fn any_text_on_any_key(key in "(axis\\.[xyzw]\\.)?[a-z_.]{0,30}", i in 0..KEY_COUNT, text in "\\PC{0,24}") {
            let s0 = FACTORY;
            for name in [key.as_str(), keys().nth(i).unwrap().name] {
                let mut s = s0;
                if s.set_text(name, &text, RATE).is_err() {
                    prop_assert!(same_tree(&s, &s0));
                }
            }
        }
    }
}

#[test]
fn feedforward_and_filter_keys_reach_the_servo_configuration_validated_at_the_rate() {
    use crate::filter::{AxisFilterConfig, FilterConfig};
    use crate::motion::feedforward::FeedForwardConfig;
    // the factory's: none on every axis, exactly the board's factory configuration
    let c = FACTORY.servo_config(RATE).unwrap();
    assert_eq!(c.feedforward, [FeedForwardConfig::NONE; 3]);
    assert_eq!(c.filters, [AxisFilterConfig::NONE; 3]);

    // the flexible gantry's Y (host-sim/comp/gantry_flexible/feedforward.toml), a 35 Hz
    // notch in stage 2 and a low-pass in stage 4 (stages 1 and 3 off: skipped)
    let mut s = FACTORY;
    for (k, v) in [
        ("axis.y.feedforward.coulomb_pos_mnm", "60"),
        ("axis.y.feedforward.coulomb_neg_mnm", "-50"),
        ("axis.y.feedforward.stiction_ratio", "1.3"),
        ("axis.y.feedforward.compliance_s2", "2.323e-5"),
        ("axis.y.filter.stage2.kind", "notch"),
        ("axis.y.filter.stage2.freq_hz", "35"),
        ("axis.y.filter.stage2.width_hz", "10"),
        ("axis.y.filter.stage2.depth_db", "20"),
        ("axis.y.filter.stage4.kind", "low_pass"),
        ("axis.y.filter.stage4.freq_hz", "800"),
    ] {
        s.set_text(k, v, RATE)
            .unwrap_or_else(|e| panic!("{k}: {e}"));
        assert_eq!(FACTORY.change_class(&s), Some(Apply::OutputsOff), "{k}");
    }
    let c = s.servo_config(RATE).unwrap();
    assert_eq!(
        c.feedforward[1],
        FeedForwardConfig {
            coulomb_pos_mnm: 60.0,
            coulomb_neg_mnm: -50.0,
            stiction_ratio: 1.3,
            compliance_s2: 2.323e-5,
            ..FeedForwardConfig::NONE
        }
    );
    assert_eq!(
        c.filters[1].stages(),
        [
            FilterConfig::Notch {
                freq_hz: 35.0,
                width_hz: 10.0,
                depth_db: 20.0
            },
            FilterConfig::low_pass(800.0)
        ]
    );
    assert_eq!(c.feedforward[0], FeedForwardConfig::NONE);
    assert_eq!(c.filters[0], AxisFilterConfig::NONE);
    // the servo runs what the keys say: the filtered servo is built from them
    assert!(crate::servo::Servo::<f32>::new(&c, [0; 3], [0; 3]).is_ok());

    // a low-pass at 0.45 of the rate or above is refused with the tree, naming the axis
    // and the stage, and changes nothing
    let before = s;
    let e = s
        .set_text("axis.y.filter.stage4.freq_hz", "4500", RATE)
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "axis.y.filter.stage4.freq_hz = 4500 rejected: axis.y.filter.stage4: parameter \
         `low_pass.cutoff_hz` is out of its allowed range (frequencies lie from 1/10000 to \
         0.45 of the control rate)"
    );
    assert!(same_tree(&s, &before));
    // at 20 kHz it is within 0.45 of the rate
    s.set_text("axis.y.filter.stage4.freq_hz", "4500", 20_000)
        .unwrap();
    // a key's own range: a notch deeper than the design's 60 dB, a positive Coulomb
    // torque for the backward direction
    assert!(matches!(
        s.set_text("axis.y.filter.stage2.depth_db", "61", RATE),
        Err(SetError::OutOfRange { .. })
    ));
    assert!(matches!(
        s.set_text("axis.x.feedforward.coulomb_neg_mnm", "5", RATE),
        Err(SetError::OutOfRange { .. })
    ));
    // a stage switched off again leaves the others
    s.set_text("axis.y.filter.stage2.kind", "none", 20_000)
        .unwrap();
    assert_eq!(
        s.servo_config(20_000).unwrap().filters[1].stages(),
        [FilterConfig::low_pass(4500.0)]
    );
}
