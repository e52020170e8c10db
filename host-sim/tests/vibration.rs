//! `host-sim vibration` (issue 24, items 4 and 7): the residual vibration at the tool after
//! a 200 mm/s rapid stop on the flexible gantry's Y (its 35 Hz beam mode), with the stiff
//! planner (jerk 1e6 mm/s³, whose acceleration steps excite the mode), unshaped and with
//! the input shapers that fit the board's history at the mode.
//!
//! The mode is passed as the study measures it (`host-sim vibration`, docs/precision.md
//! "Input shaping: residual vibration": 35.00 Hz, ζ 0.0423), so the test does not spend
//! the frequency response's seconds; the study itself measures it.
//!
//! Measured: unshaped 14.1 µm peak, settled to 5 µm in 51.1 ms; ZV 2.1 µm, never outside
//! the 5 µm band. With the shapers switched off (every run unshaped) both ratios are 1
//! and the assertions fail.
//!
//! Release-mode: `cargo test -p host-sim --release --test sim_tests vibration::` (about 2 s).

use controller_core::axes::Axis;
use host_sim::studies::freqresp::ModeJson;
use host_sim::studies::vibration::{default_machine, run_axes, PlannerKind};

#[test]
fn shaping_y_cuts_the_stiff_stops_residual_vibration() {
    let y = ModeJson {
        freq_hz: 35.0,
        damping_ratio: 0.0423,
        peak_db: 0.0,
    };
    let r = run_axes(&default_machine(), &[None, Some(y), None], &[Axis::Y]).unwrap();
    let a = &r.axes[0];
    assert_eq!(a.axis, 'Y');
    // the board's 256-period history holds ZV and MZV at 35 Hz, nothing longer
    let kinds: Vec<&str> = a.stops[0].shaped.iter().map(|f| f.kind.as_str()).collect();
    assert_eq!(kinds, ["zv", "mzv"]);
    assert_eq!(a.refused, ["zvd", "ei", "2hump_ei", "3hump_ei"]);
    let stiff = a
        .stops
        .iter()
        .find(|s| s.planner == PlannerKind::Stiff)
        .unwrap();
    let (u, b) = (&stiff.unshaped, stiff.best.as_ref().unwrap());
    let (u_settle, b_settle) = (u.settle_ms.unwrap(), b.settle_ms.unwrap());
    // the mode is excited: the unshaped tool swings well outside the band
    assert!(u.peak_um > 10.0 && u_settle > 30.0, "unshaped: {u:?}");
    // measured 6.7× (14.1 -> 2.1 µm): the goal's 5× with margin
    assert!(
        u.peak_um >= 5.5 * b.peak_um,
        "peak {:.2} -> {:.2} µm ({})",
        u.peak_um,
        b.peak_um,
        b.kind
    );
    // measured 51.1 ms -> 0 (never outside the band)
    assert!(
        u_settle >= 5.0 * b_settle.max(0.1),
        "settle {u_settle:.1} -> {b_settle:.1} ms ({})",
        b.kind
    );
    assert!(stiff.goal_met);
    // equal acceleration: the shaped run stopped as hard as the unshaped one
    assert_eq!(u.acc_mm_s2, b.acc_mm_s2);
    assert!(b.shaper_delay_ms > 10.0 && u.shaper_delay_ms == 0.0);
}
