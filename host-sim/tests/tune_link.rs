//! `gantry tune AXIS` over the link (host-sim/src/cli/tune/) on the simulated flexible
//! gantry (`gantry --sim --machine host-sim/machines/gantry_flexible.toml tune x`): the
//! model identified and accepted, the carriage's 90 Hz mode measured and shaped, the
//! friction feed-forward set from the model, the loop on the laws measured on the machine
//! and a notch at the mode kept on its margins, and the rapid stop's ringing at the
//! encoder measured before and after, at the machine's path tolerance and at the same
//! acceleration.

use controller_core::sim::world::PlantConfig;
use host_sim::cli::client::Client;
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::cli::tune::{self, ShaperChoice, TuneOptions};
use host_sim::cli::{get, Transport};
use host_sim::sim_gantry::machine_and_planner;
use host_sim::studies::freqresp::model_mode;
use std::path::PathBuf;

fn flexible() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("machines/gantry_flexible.toml")
}

fn number<T: Transport>(c: &mut Client<T>, key: &str) -> f64 {
    get(c, key).unwrap().parse().unwrap()
}

fn options(shaper: ShaperChoice) -> TuneOptions {
    TuneOptions {
        axis: 0,
        window_half_mm: None,
        bandwidth_rad_s: None,
        shaper,
        dry_run: false,
        telemetry_period_s: f64::from(DECIMATION) * 1e-4,
    }
}

/// Telemetry every this many periods (1 ms at the simulated machine's 10 kHz).
const DECIMATION: u32 = 10;

#[test]
fn bad_options_are_refused_by_name() {
    let e = ShaperChoice::parse("zvv").unwrap_err().to_string();
    assert!(
        e.contains("--shaper") && e.contains("zvv") && e.contains("mzv"),
        "{e}"
    );
    assert_eq!(ShaperChoice::parse("none").unwrap(), ShaperChoice::Off);
    assert_eq!(ShaperChoice::parse("auto").unwrap(), ShaperChoice::Auto);
    let sim = SimMachine::on_machine(SimModels::Designed, 0, Some(&flexible())).unwrap();
    let mut c = Client::connect(sim).unwrap();
    let p0 = c.status().unwrap().pos_mm;
    let mut o = options(ShaperChoice::Auto);
    o.bandwidth_rad_s = Some(-3.0);
    let e = tune::tune(&mut c, &o, &std::env::temp_dir())
        .unwrap_err()
        .to_string();
    assert!(e.contains("--bandwidth-rad-s"), "{e}");
    assert_eq!(
        c.status().unwrap().pos_mm,
        p0,
        "a refused tune moves nothing"
    );
}

#[test]
fn tune_x_shapes_and_notches_the_carriage_mode_and_the_stop_rings_less() {
    let machine = flexible();
    let sim = SimMachine::on_machine(SimModels::Designed, 0, Some(&machine)).unwrap();
    let mut c = Client::connect(sim).unwrap();
    assert_eq!(c.control_rate_hz(), 10_000);
    host_sim::cli::subscribe(&mut c, DECIMATION).unwrap();
    let tolerance_mm = number(&mut c, "planner.tolerance_mm");
    let out = std::env::temp_dir().join(format!("gantry-tune-{}", std::process::id()));
    let r = tune::tune(&mut c, &options(ShaperChoice::Auto), &out).unwrap();
    print!("{}", tune::table(&r));
    assert_eq!(r.outcome, "applied");
    // the model: identified, accepted, the axis' inertia
    let (run, _) = machine_and_planner(Some(&machine)).unwrap();
    let PlantConfig::Physical(axis) = &run.world.plants[0] else {
        panic!("a physical axis");
    };
    assert!(r.identify.accepted);
    let j = f64::from(r.identify.j.unwrap());
    assert!((j / f64::from(axis.inertia) - 1.0).abs() <= 0.05, "J {j}");
    assert_eq!(number(&mut c, "axis.x.model.inertia") as f32, j as f32);
    // the shaper: MZV (it fits the history at 35 Hz) on the file's mode within 3 %
    let truth = model_mode(axis).expect("X has a frame");
    let s = r.shaper.as_ref().expect("a shaper");
    assert_eq!(s.kind, "mzv");
    assert!(
        (f64::from(s.freq_hz) / truth.mode_hz - 1.0).abs() <= 0.03,
        "{s:?}"
    );
    assert_eq!(get(&mut c, "shaper.x.kind").unwrap(), "mzv");
    assert_eq!(number(&mut c, "shaper.x.freq_hz") as f32, s.freq_hz);
    // the feed-forward: the identified Coulomb terms
    let ff_pos = number(&mut c, "axis.x.feedforward.coulomb_pos_mnm") as f32;
    let ff_neg = number(&mut c, "axis.x.feedforward.coulomb_neg_mnm") as f32;
    assert_eq!(
        (ff_pos, ff_neg),
        (r.identify.f_pos.unwrap(), r.identify.f_neg.unwrap())
    );
    // the loop on the laws, measured on the machine: the crossover of `cargo sim filters`
    // (47 Hz), margins of 6 dB and 30° without the notch and with it (measured: 46.5 Hz,
    // 41.9°, 14.6 / 7.6 dB; with it 46.9 Hz, 38.6°, 15.7 / 7.6 dB)
    for l in [r.loop_without.as_ref(), r.loop_with.as_ref()] {
        let l = l.expect("the loop measured without and with the notch");
        let m = l.margins.as_ref().expect("margins");
        assert!(
            m.stable && l.failed.is_empty() && l.points.len() == 48,
            "{l:?}"
        );
        let f = m.gain_crossover_hz.unwrap();
        assert!((40.0..55.0).contains(&f), "{m:?}");
        assert!(m.phase_margin_deg >= 30.0, "{m:?}");
        assert!(
            m.gain_margin_db >= 6.0 && m.lower_gain_margin_db >= 6.0,
            "{m:?}"
        );
    }
    // the notch at the mode within 3 %, kept, in the settings
    assert_eq!(r.notch_verdict, "accepted");
    assert_eq!(r.notches_placed.len(), 1);
    let n = &r.notches_placed[0];
    assert!(
        (f64::from(n.freq_hz) / truth.mode_hz - 1.0).abs() <= 0.03,
        "{n:?}"
    );
    assert_eq!(get(&mut c, "axis.x.filter.stage1.kind").unwrap(), "notch");
    assert_eq!(
        number(&mut c, "axis.x.filter.stage1.freq_hz") as f32,
        n.freq_hz
    );
    assert_eq!(get(&mut c, "axis.x.filter.stage2.kind").unwrap(), "none");
    // the tolerance was raised for one stop only
    assert_eq!(number(&mut c, "planner.tolerance_mm"), tolerance_mm);
    // the stops: the machine's own acceleration before; at its tolerance the shaper's
    // deviation lowers it by tolerance / full_acc_tolerance; at full_acc_tolerance it
    // keeps it, and rings at most 1/1.5 as much (measured: 3.7×) and settles at once
    let (before, after, full) = (
        r.before.as_ref().unwrap(),
        r.after.as_ref().unwrap(),
        r.after_full_acc.as_ref().unwrap(),
    );
    let full_tol = f64::from(r.full_acc_tolerance_mm.unwrap());
    let acc = number(&mut c, "axis.x.planner.acc_max_mm_s2");
    assert!((before.acc_mm_s2 / acc - 1.0).abs() <= 0.05, "{before:?}");
    assert!((full.acc_mm_s2 / acc - 1.0).abs() <= 0.05, "{full:?}");
    let derated = acc * tolerance_mm / full_tol;
    assert!(
        (after.acc_mm_s2 / derated - 1.0).abs() <= 0.05,
        "{after:?}, {derated}"
    );
    assert!(before.peak_um >= 5.0, "the unshaped stop rings: {before:?}");
    assert!(
        full.peak_um <= before.peak_um / 1.5,
        "{full:?} against {before:?}"
    );
    assert!(before.settle_ms.unwrap_or(f64::MAX) >= 20.0, "{before:?}");
    assert_eq!(full.settle_ms, Some(0.0), "{full:?}");
    let _ = std::fs::remove_dir_all(out);
}
