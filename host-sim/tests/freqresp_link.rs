//! `gantry freqresp` over the link (host-sim/src/cli/freqresp.rs): the machine's own
//! stepped sine (`Request::MeasureResponse`) on the simulated flexible gantry
//! (`gantry --sim --machine host-sim/machines/gantry_flexible.toml`), its points read back
//! in chunks (`Request::ResponseRead`) and the modes found on the host with the study's
//! code. The goals for the measured modes: frequency within 3 %, damping within
//! 30 % (of the linear model's pole: the damping the response has, docs/precision.md §2).

use controller_core::machine::messages::{Outcome, Request};
use controller_core::sim::world::PlantConfig;
use host_sim::cli::client::Client;
use host_sim::cli::freqresp;
use host_sim::cli::sim::{SimMachine, SimModels};
use host_sim::sim_gantry::machine_and_planner;
use host_sim::studies::freqresp::model_mode;
use std::path::PathBuf;

fn flexible() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("machines/gantry_flexible.toml")
}

#[test]
fn the_beam_mode_of_y_is_measured_over_the_link() {
    let machine = flexible();
    let sim = SimMachine::on_machine(SimModels::Designed, 0, Some(&machine)).unwrap();
    let mut c = Client::connect(sim).unwrap();
    // nothing measured yet: a read is refused, and so is a fourth axis
    match c.exec(Request::ResponseRead { first: 0 }).unwrap() {
        Outcome::Refused(why) => assert!(why.contains("no frequency response"), "{why}"),
        other => panic!("a read before any measurement: {other:?}"),
    }
    match c
        .exec(Request::MeasureResponse {
            axis: 3,
            window_mm: None,
        })
        .unwrap()
    {
        Outcome::Refused(why) => assert!(why.contains("axis must be 0, 1 or 2"), "{why}"),
        other => panic!("axis 3: {other:?}"),
    }
    let r = freqresp::measure(&mut c, 1, Some(50.0), "gantry_flexible.toml").unwrap();
    let y = &r.axes["y"];
    assert_eq!(y.status, "done");
    assert_eq!(y.points.len(), 64, "the stepped sine's 64 frequencies");
    assert!(y.bounds.is_none(), "the link does not see every period");
    let (run, _) = machine_and_planner(Some(&machine)).unwrap();
    let PlantConfig::Physical(axis) = &run.world.plants[1] else {
        panic!("a physical axis");
    };
    let truth = model_mode(axis).expect("Y has a frame");
    let res = y
        .resonances
        .iter()
        .min_by(|a, b| {
            let d = |f: f64| (f / truth.mode_hz).ln().abs();
            d(a.freq_hz).total_cmp(&d(b.freq_hz))
        })
        .expect("a resonance");
    let f_err = (res.freq_hz / truth.mode_hz - 1.0).abs();
    let z_err = (res.damping_ratio / truth.model_damping_ratio - 1.0).abs();
    println!(
        "Y over the link: {:.3} Hz (file {} Hz, {:.2} %), ζ {:.4} (model {:.4}, {:.1} %), {:.1} s",
        res.freq_hz,
        truth.mode_hz,
        100.0 * f_err,
        res.damping_ratio,
        truth.model_damping_ratio,
        100.0 * z_err,
        y.machine_time_s
    );
    assert!(f_err <= 0.03, "resonance {} Hz", res.freq_hz);
    assert!(z_err <= 0.30, "damping {}", res.damping_ratio);
    let anti = y.anti_resonances.first().expect("an anti-resonance");
    assert!(
        (anti.freq_hz / truth.anti_resonance_hz - 1.0).abs() <= 0.03,
        "anti-resonance {} Hz, model {} Hz",
        anti.freq_hz,
        truth.anti_resonance_hz
    );
    // the rigid line's inertia is the axis' (motor and tool sides together)
    assert!(
        (y.inertia / f64::from(axis.inertia) - 1.0).abs() <= 0.05,
        "inertia {} against {}",
        y.inertia,
        axis.inertia
    );
    // a refused measurement (a window that leaves the axis out) leaves the last one's
    // points readable
    match c
        .exec(Request::MeasureResponse {
            axis: 1,
            window_mm: Some([5.0, 60.0]),
        })
        .unwrap()
    {
        Outcome::Refused(why) => assert!(why.contains("window"), "{why}"),
        other => panic!("a window without the axis: {other:?}"),
    }
    match c.exec(Request::ResponseRead { first: 0 }).unwrap() {
        Outcome::Response(chunk) => {
            assert_eq!((chunk.axis, chunk.total), (1, 64), "{chunk:?}");
            assert_eq!(chunk.points.len(), 6);
            let f = f64::from(chunk.points[0].freq_hz);
            assert!(
                y.points.iter().any(|p| (p.freq_hz - f).abs() < 1e-3),
                "{f} Hz is not one of the measured frequencies"
            );
        }
        other => panic!("a read after a refused measurement: {other:?}"),
    }
    // a read past the measured points is refused
    match c.exec(Request::ResponseRead { first: 65 }).unwrap() {
        Outcome::Refused(why) => assert!(why.contains("past the measured"), "{why}"),
        other => panic!("a read past the end: {other:?}"),
    }
}
