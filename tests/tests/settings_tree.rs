//! The settings registry and the tree's serde form agree: every leaf of the tree has a key
//! of the same dotted name and every key a leaf (so the registry covers the whole tree, and
//! the CLI's keys are the export's names), and the TOML export (`gantry settings
//! export/import`) round-trips bit for bit.

use controller_core::settings::keys::keys;
use controller_core::settings::{Settings, FACTORY, PLACEHOLDER_MODELS};

fn with_models() -> Settings {
    let mut s = FACTORY;
    for (a, m) in s.axis.iter_mut().zip(PLACEHOLDER_MODELS) {
        a.model = Some(m);
    }
    s
}

fn leaves(prefix: &str, v: &serde_json::Value, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, v) in m {
                leaves(&format!("{prefix}{k}."), v, out);
            }
        }
        _ => out.push(prefix.trim_end_matches('.').to_string()),
    }
}

#[test]
fn every_field_has_a_key_and_every_key_a_field() {
    let json = serde_json::to_value(with_models()).unwrap();
    let mut fields = Vec::new();
    leaves("", &json, &mut fields);
    fields.sort();
    // `model.known` is the presence of the model, not a field of its own
    let mut names: Vec<String> = keys()
        .map(|k| k.name.to_string())
        .filter(|n| !n.ends_with(".model.known"))
        .collect();
    names.sort();
    assert_eq!(fields, names);
    // 109 before the work offsets (27), the tool table (16), `planner.servo_reserve` (1)
    // the brakes (3 × 3), `safety.arm_encoder_check` (1) and the motors' and encoders'
    // directions (3 × 2), the input shapers (3 × 3), the feed-forward (3 × 9) and the
    // output filters (3 × 4 stages × 5)
    assert_eq!(fields.len(), 109 + 27 + 16 + 1 + 9 + 1 + 6 + 9 + 27 + 60);
}

#[test]
fn toml_export_round_trips_bit_for_bit() {
    for s in [FACTORY, with_models()] {
        let text = toml::to_string(&s).unwrap();
        let back: Settings = toml::from_str(&text).unwrap();
        assert_eq!(back, s);
        for ((k, a), (_, b)) in s.list().zip(back.list()) {
            match (a, b) {
                (Some(a), Some(b)) => assert!(a.same(&b), "{}", k.name),
                (a, b) => assert_eq!(a.is_some(), b.is_some(), "{}", k.name),
            }
        }
    }
    // the export names the keys' segments
    let text = toml::to_string(&FACTORY).unwrap();
    assert!(text.contains("[axis.x.law]\nkind = \"dsmc\""), "{text}");
    // the tables by their keys' segments: work.g59_3.x_mm, tool.8.length_mm
    assert!(text.contains("[work.g59_3]\nx_mm = 0.0"), "{text}");
    assert!(text.contains("[tool.8]\nlength_mm = 0.0"), "{text}");
    // an unknown field is refused
    let bad = text.replace("following_error_mm", "following_error");
    assert!(toml::from_str::<Settings>(&bad).is_err());
}
