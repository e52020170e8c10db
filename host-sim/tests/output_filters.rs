//! The output filters placed and checked on the flexible gantry (issue 24, item 3;
//! `host-sim filters`): notches go to the resonances above the loop's bandwidth and stay
//! only when the loop, measured on the running machine with them, keeps its margins; a
//! notch inside the bandwidth (what the 35 Hz beam mode would need) is refused by that
//! measurement.

use controller_core::axes::Axis;
use controller_core::filter::{AxisFilterConfig, FilterConfig};
use host_sim::comp_file::read_filters;
use host_sim::studies::filters::{check, filters_toml, loop_base, run, LoopJson};

fn margins(l: &LoopJson) -> (f32, f32, f32) {
    let m = l.margins.as_ref().expect("margins");
    assert!(m.stable);
    (
        m.gain_crossover_hz.unwrap(),
        m.gain_margin_db.min(m.lower_gain_margin_db),
        m.phase_margin_deg,
    )
}

#[test]
fn notches_are_placed_above_the_bandwidth_and_kept_on_the_measured_margins() {
    let r = run(None, None).unwrap();
    print!("{}", host_sim::studies::filters::table(&r));
    for (name, a) in &r.axes {
        // the DSMC loop of the circle test: crossover 47-61 Hz, 7.5-7.8 dB, 38-44°
        let (fc, gm, pm) = margins(&a.without);
        assert!((40.0..70.0).contains(&fc), "{name}: crossover {fc}");
        assert!(gm >= 6.0 && pm >= 30.0, "{name}: {gm} dB {pm}°");
        assert!(
            a.without.failed.is_empty(),
            "{name}: {:?}",
            a.without.failed
        );
    }
    // X: its 90 Hz mode (+4.9 dB) is above 1.5 x 47 Hz: notched, and accepted
    let x = &r.axes["x"];
    match x.placed.as_slice() {
        [FilterConfig::Notch { freq_hz, .. }] => {
            assert!((freq_hz / 90.0 - 1.0).abs() < 0.03, "{freq_hz}")
        }
        other => panic!("x placed {other:?}"),
    }
    assert_eq!(x.verdict, "accepted");
    let (_, gm, pm) = margins(x.with.as_ref().unwrap());
    assert!(gm >= 6.0 && pm >= 30.0, "x with the notch: {gm} dB {pm}°");
    // Y: its 35 Hz beam mode sits inside the 59 Hz bandwidth: no notch
    let y = &r.axes["y"];
    assert!(y.placed.is_empty() && y.near_bandwidth == 1, "{y:?}");
    assert_eq!(y.verdict, "none placed");
    // Z: a +1.2 dB bump needs none
    assert!(r.axes["z"].placed.is_empty());

    // the file written holds what was accepted, bit for bit
    let dir = std::env::temp_dir().join(format!("gantry-filters-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("filters.toml"), filters_toml(&r)).unwrap();
    let read = read_filters(&dir, 10_000).unwrap().unwrap();
    assert_eq!(read[0], x.accepted().unwrap());
    assert_eq!(read[1], AxisFilterConfig::NONE);
}

#[test]
fn a_notch_inside_the_bandwidth_is_refused_by_the_measured_loop() {
    // a 35 Hz notch on Y (the beam mode) takes the phase out of the loop at its 59 Hz
    // crossover: on the circle it rings up to G 433 µm; the measured loop refuses it
    let base = loop_base(None).unwrap();
    let mut filters = [AxisFilterConfig::NONE; 3];
    filters[1] = AxisFilterConfig::new(&[FilterConfig::Notch {
        freq_hz: 35.0,
        width_hz: 7.0,
        depth_db: 20.0,
    }])
    .unwrap();
    let (l, verdict) = check(&base, Axis::Y, &filters, 0.18).unwrap();
    assert!(verdict.starts_with("refused"), "{verdict}: {:?}", l.margins);
    // and a low-pass far above the crossover passes
    filters[1] = AxisFilterConfig::new(&[FilterConfig::low_pass(2_000.0)]).unwrap();
    let (l, verdict) = check(&base, Axis::Y, &filters, 0.18).unwrap();
    assert_eq!(verdict, "accepted", "{:?}", l.margins);
}

#[test]
fn a_bad_filters_file_is_refused_naming_the_file_and_the_axis() {
    let dir = std::env::temp_dir().join(format!("gantry-badfilters-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("filters.toml");
    std::fs::write(&f, "z = [{ low_pass = { cutoff_hz = 6000.0 } }]\n").unwrap();
    let e = format!("{:#}", read_filters(&dir, 10_000).unwrap_err());
    assert!(
        e.contains("filters.toml") && e.contains("[z]") && e.contains("low_pass.cutoff_hz"),
        "{e}"
    );
    std::fs::write(&f, "y = [{ notch = { freq_hz = 35.0 } }]\n").unwrap();
    let e = format!("{:#}", read_filters(&dir, 10_000).unwrap_err());
    assert!(e.contains("filters.toml") && e.contains("width_hz"), "{e}");
}
