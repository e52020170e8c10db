//! Edge noise does not trip the fault checks told of it: 10 simulated minutes of the
//! physical gantry with 2 counts of edge noise on every encoder
//! (host-sim/scenarios/encoder_noise.toml) — holding, exact stops, fast moves, reversals —
//! and not one fault. The same checks without the noise allowance do trip (so the
//! scenario's noise reaches them), and told of the noise they still find a stuck encoder.

use controller_core::servo::Command;
use controller_core::sim::run::SimRun;
use gantry_scenario::Resolved;
use std::path::Path;

fn runs(overrides: &str) -> Vec<Resolved> {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/encoder_noise.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let dir = path.parent().unwrap().to_path_buf();
    let f = gantry_scenario::file::load_str_with(
        "encoder_noise.toml",
        &text,
        &gantry_scenario::file::DirIncludes(dir),
        overrides,
    )
    .unwrap();
    f.runs
        .iter()
        .map(|r| Resolved::new(&f.file, r).unwrap())
        .collect()
}

/// Runs `r` for at most `periods` (all of it: `u32::MAX`); the first fault's name and
/// period, and the periods run.
fn first_fault(r: &Resolved, periods: u32) -> (Option<(String, u32)>, u32) {
    let mut run = SimRun::<f32>::new(&r.run).unwrap();
    let mut k = 0u32;
    while !run.done() && k < periods {
        let cmds: &[Command] = match (k, r.run.hold) {
            (0, true) => &[Command::Arm],
            (0, false) => &[Command::Arm, Command::StartPath],
            _ => &[],
        };
        run.control_with(cmds);
        if let Some(f) = run.servo().faults().first() {
            return (Some((f.fault.kind.name().to_string(), k)), k);
        }
        run.finish_period();
        k += 1;
    }
    (None, k)
}

#[test]
fn two_counts_of_edge_noise_trip_nothing_in_ten_minutes() {
    let runs = runs("");
    assert_eq!(runs.len(), 4);
    let mut total_s = 0.0;
    std::thread::scope(|s| {
        let handles: Vec<_> = runs
            .iter()
            .map(|r| s.spawn(move || (r.name.clone(), first_fault(r, u32::MAX))))
            .collect();
        for h in handles {
            let (name, (fault, periods)) = h.join().unwrap();
            assert_eq!(fault, None, "{name}: a fault under 2 counts of edge noise");
            total_s += f64::from(periods) * 1e-4;
        }
    });
    assert!(total_s >= 600.0 - 1e-3, "{total_s} s simulated");
}

#[test]
fn without_the_allowance_the_noise_trips_the_checks() {
    // the same noise, the checks told of none: the count's second difference trips
    let runs = runs("[machine]\nsafety = { encoder_noise_counts = 0.0 }\n");
    let r = runs
        .iter()
        .find(|r| r.name.ends_with("square_fast"))
        .unwrap();
    let (fault, _) = first_fault(r, 100_000);
    let (kind, _) = fault.expect("2 counts of noise read as a jump without the allowance");
    assert!(kind.starts_with("encoder_"), "{kind}");
}

#[test]
fn told_of_the_noise_the_checks_still_find_a_stuck_encoder() {
    // X's encoder stops 0.3 s in, on the squares' first side (along X): the slow one at
    // its 5 mm/s, the fast one at its 200 mm/s
    let runs = runs("fault = { at_s = 0.3, fault = { encoder_stuck = { axis = \"x\" } } }\n");
    for (case, bound) in [("square_slow", 20u32), ("square_fast", 3)] {
        let r = runs.iter().find(|r| r.name.ends_with(case)).unwrap();
        let (fault, _) = first_fault(r, 10_000);
        let (kind, k) = fault.unwrap_or_else(|| panic!("{case}: stuck encoder not found"));
        assert_eq!(kind, "encoder_stuck", "{case}");
        assert!(
            k >= 3_000 && k - 3_000 <= bound,
            "{case}: {} periods",
            k - 3_000
        );
        eprintln!("{case}: stuck found after {} periods", k - 3_000);
    }
}
