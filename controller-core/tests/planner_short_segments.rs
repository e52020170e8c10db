//! Thousands of very short segments on a smooth curve (CAM output): 5,027 chords of
//! 0.05 mm on a 20 mm radius circle at 50 mm/s with ε = 0.01 mm keep the programmed feed
//! (no stop-and-go), within the limits and the tolerance.

use crate::planner_common;
use controller_core::motion::planner::Segment;
use planner_common::*;

#[test]
fn five_thousand_chords_keep_the_feed() {
    let cfg = config();
    let r = 20.0f32;
    let n = 5027usize; // two turns
    let dphi = 0.05 / r;
    let start = [r, 0.0, 0.0];
    let mut segs = Vec::with_capacity(n);
    let mut prog = Vec::with_capacity(n);
    let mut prev = start;
    for k in 1..=n {
        let phi = dphi * k as f32;
        let p = [r * phi.cos(), r * phi.sin(), 0.0];
        segs.push(Segment::line(p, 50.0, k as u32));
        prog.push(Prog::Line { a: prev, b: p });
        prev = p;
    }
    let mut mp = Mp::new(&cfg, start).unwrap();
    let s = run(&mut mp, &segs, 400_000);
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(
        rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
        "{rv} {ra} {rj}"
    );
    assert_eq!(mp.planner_status().slips, 0);
    // Steady part: from the first time the feed is reached to 0.3 s before the end.
    let first = s
        .iter()
        .position(|x| x.feed_ratio >= 0.999)
        .expect("feed never reached");
    let steady = &s[first..s.len() - 3000];
    let mean = steady.iter().map(|x| x.feed_ratio as f64).sum::<f64>() / steady.len() as f64;
    let min = steady
        .iter()
        .map(|x| x.feed_ratio)
        .fold(f32::INFINITY, f32::min);
    assert!(mean >= 0.95, "mean feed ratio {mean}");
    assert!(min >= 0.9, "slowest {min}");
    // The whole program takes the time of the path at the feed plus one ramp up and down.
    let ideal = n as f32 * 0.05 / 50.0 / cfg.period_s;
    assert!(
        (s.len() as f32) < ideal + 2000.0,
        "{} periods vs {ideal}",
        s.len()
    );
    // Deviation from the chord polyline: a sampled subset (the full check is O(n²)).
    let dev = s
        .iter()
        .step_by(7)
        .map(|x| {
            let p = x.pos_mm.to_array();
            let k = (x.tag as usize).clamp(1, n) - 1;
            prog[k.saturating_sub(2)..(k + 3).min(n)]
                .iter()
                .map(|g| distance(p, g))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0f64, f64::max);
    assert!(dev <= cfg.tolerance_mm as f64, "deviation {dev}");
    let last = s.last().unwrap().pos_mm.to_array();
    assert!((last[0] - prev[0]).abs() < 1e-4 && (last[1] - prev[1]).abs() < 1e-4);
}
