//! Feed hold, resume, abort, feed override and planner starvation: the reference stays
//! continuous, on the path and within the limits; hold stops within the jerk-limited
//! stopping distance; resume continues from exactly where it stopped.

use crate::planner_common;
use controller_core::motion::planner::profile::braking_distance;
use controller_core::motion::planner::{
    ExecMode, Executor, PathSample, Planner, PlannerState, Segment, Span, Step,
};
use heapless::spsc::Queue;
use planner_common::*;

fn square() -> (Vec<Segment>, Vec<Prog>) {
    let pts = [
        [0.0, 0.0, 0.0],
        [20.0, 0.0, 0.0],
        [20.0, 20.0, 0.0],
        [0.0, 20.0, 5.0],
        [0.0, 0.0, 0.0],
    ];
    polyline(&pts, 80.0)
}

/// Position continuity: each step equals the trapezoid of the reported velocities
/// within `tol` mm plus the f32 resolution of the span evaluation (4 ulp of the largest
/// coordinate of the program, `scale_mm`: 7.6e-6 mm at 25 mm), and the velocity changes by at most
/// amax·T per period.
fn assert_continuous(s: &[PathSample], from: usize, to: usize, tol: f64, scale_mm: f32) {
    let cfg = config();
    let t = cfg.period_s as f64;
    for k in from.max(1)..to.min(s.len()) {
        let (p0, p1) = (s[k - 1].pos_mm.to_array(), s[k].pos_mm.to_array());
        let (v0, v1) = (s[k - 1].vel_mm_s.to_array(), s[k].vel_mm_s.to_array());
        let (a0, a1) = (s[k - 1].acc_mm_s2.to_array(), s[k].acc_mm_s2.to_array());
        for i in 0..3 {
            // Trapezoid with the acceleration correction: exact for constant jerk.
            let pred = p0[i] as f64 + 0.5 * (v0[i] as f64 + v1[i] as f64) * t
                - (a1[i] as f64 - a0[i] as f64) * t * t / 12.0;
            let ulp = (scale_mm * f32::EPSILON) as f64;
            assert!(
                (p1[i] as f64 - pred).abs() < tol + 4.0 * ulp,
                "period {k} axis {i}: position {} vs {pred} (jump {})",
                p1[i],
                p1[i] as f64 - pred
            );
            let dv = (v1[i] - v0[i]).abs() as f64;
            assert!(
                dv <= cfg.acc_max_mm_s2[i] as f64 * t * 1.001 + 1e-4,
                "period {k}: velocity step"
            );
        }
    }
}

/// Steps buffered between planner and executor in [`Mp`]: the hold reaches the executor
/// after at most this many periods.
const BUFFERED_STEPS: usize = 32;

#[test]
fn hold_and_resume_are_continuous_and_stop_within_the_braking_distance() {
    let cfg = config();
    let (segs, prog) = square();
    // Hold while cruising (period 1500), while braking into the first corner (2660),
    // in the corner blend (2830), while accelerating out of it (3180), on the third side.
    for hold_at in [1500usize, 2660, 2830, 3180, 5200] {
        let mut mp = Mp::new(&cfg, [0.0; 3]).unwrap();
        let mut held_at = None;
        // Executor state (span, σ) around the resume: σ continues from the stop exactly.
        let mut around_resume = Vec::new();
        let s = run_with(&mut mp, &segs, 200_000, |n, mp| {
            if n == hold_at {
                mp.hold();
            }
            if n > hold_at
                && held_at.is_none()
                && mp.planner_status().state == PlannerState::Held
                && mp.is_idle()
            {
                held_at = Some(n);
            }
            if n == hold_at + 2000 {
                mp.resume();
            }
            if (hold_at + 1999..hold_at + 2010).contains(&n) {
                let st = mp.executor_status();
                around_resume.push((st.span_seq, st.sigma_mm));
            }
        });
        // From rest, period k after the resume adds J T³ (3k² − 3k + 1)/6 to σ: 1.7e-8 mm
        // in the first period, 5e-6 mm in the tenth; σ itself is f32 (ulp 1e-6 at 12 mm).
        for (k, w) in around_resume.windows(2).enumerate() {
            let ((q0, s0), (q1, s1)) = (w[0], w[1]);
            let kf = k as f32;
            let step = 1.0e5 * 1.0e-12 * (3.0 * kf * kf + 3.0 * kf + 1.0) / 6.0;
            let ulp = s1.abs() * f32::EPSILON;
            assert!(
                q0 == q1 && s1 >= s0 && s1 - s0 <= step + 2.0 * ulp,
                "resume {k}: {w:?}"
            );
        }
        let st = held_at.expect("hold never completed");
        assert!(st < hold_at + 2000, "stop took {} periods", st - hold_at);
        // Stopping distance: the buffered steps run as planned (at most BUFFERED_STEPS
        // periods, speed growing by at most amax per second), then the time-optimal
        // jerk-limited stop with at least the floor limits.
        let before = &s[hold_at - 1];
        let t = cfg.period_s;
        let lag = BUFFERED_STEPS as f32 * t;
        let v = before.path_speed_mm_s + 2000.0 * lag;
        let floor_a = cfg.tangential_share * 2000.0 / 2.0;
        let floor_j = cfg.tangential_share * 1.0e5 / 2.0;
        let bound = v * lag + braking_distance(v, 2000.0, 0.0, floor_a, floor_j) + v * t;
        let mut travelled = 0.0f32;
        for k in hold_at..=st {
            let (p0, p1) = (s[k - 1].pos_mm.to_array(), s[k].pos_mm.to_array());
            travelled +=
                ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2) + (p1[2] - p0[2]).powi(2))
                    .sqrt();
        }
        assert!(
            travelled <= bound,
            "hold at {hold_at}: stopped after {travelled} mm > {bound}"
        );
        // At rest while held, resumed afterwards, and the program completes.
        let held = s[st].pos_mm;
        for x in &s[st..hold_at + 2000] {
            assert_eq!(x.pos_mm, held);
            assert_eq!(x.path_speed_mm_s, 0.0);
        }
        let last = s.last().unwrap().pos_mm.to_array();
        assert!(last.iter().all(|c| c.abs() < 1e-4), "end {last:?}");
        // Continuous everywhere, on the path everywhere, within the limits.
        assert_continuous(&s, 1, s.len(), 1e-6, 25.0);
        let dev = max_deviation(&s, &prog);
        assert!(dev <= cfg.tolerance_mm as f64 + 3e-5, "deviation {dev}");
        let (rv, ra, rj) = limit_ratios(&s, &cfg);
        assert!(
            rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
            "{rv} {ra} {rj}"
        );
        assert_eq!(mp.planner_status().slips, 0);
    }
}

#[test]
fn abort_stops_on_the_path_and_clears_the_queue() {
    let cfg = config();
    let (segs, prog) = square();
    let mut mp = Mp::new(&cfg, [0.0; 3]).unwrap();
    let s = run_with(&mut mp, &segs, 20_000, |n, mp| {
        if n == 1800 {
            mp.abort();
        }
    });
    let stop = s.last().unwrap().pos_mm.to_array();
    assert!(mp.is_idle());
    assert_eq!(mp.planner_status().state, PlannerState::Idle);
    assert_eq!(mp.planner_status().queued_segments, 0);
    assert_eq!(mp.planner_status().queued_spans, 0);
    assert_eq!(mp.end_position_mm(), stop);
    // Stopped on the first side, short of the corner, on the path.
    assert!(
        stop[0] > 5.0 && stop[0] < 20.0 && stop[1].abs() < 1e-5,
        "{stop:?}"
    );
    assert!(max_deviation(&s, &prog) < 1e-4);
    assert_continuous(&s, 1, s.len(), 1e-6, 25.0);
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3);
    // A new program starts where the abort stopped.
    let segs2 = [Segment::line([stop[0], 10.0, 0.0], 50.0, 9)];
    let s2 = run(&mut mp, &segs2, 20_000);
    let end = s2.last().unwrap().pos_mm.to_array();
    assert!(
        (end[0] - stop[0]).abs() < 1e-4 && (end[1] - 10.0).abs() < 1e-4,
        "{end:?}"
    );
    assert_eq!(s2.last().unwrap().tag, 9);
}

#[test]
fn feed_override_changes_are_smooth_and_within_limits() {
    let cfg = config();
    let segs = [Segment::line([300.0, 0.0, 0.0], 60.0, 1)];
    for (ratio, expect) in [(0.5f32, 30.0f32), (1.5, 90.0), (2.0, 120.0), (0.01, 0.6)] {
        let mut mp = Mp::new(&cfg, [0.0; 3]).unwrap();
        let s = run_with(&mut mp, &segs, 400_000, |n, mp| {
            if n == 5000 {
                mp.set_feed_override(ratio).unwrap();
            }
            if n == 10000 {
                mp.set_feed_override(1.0).unwrap();
            }
        });
        let (rv, ra, rj) = limit_ratios(&s, &cfg);
        assert!(
            rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
            "{ratio}: {rv} {ra} {rj}"
        );
        // The new speed is reached and held before the override is reset.
        let v = s[9_000].path_speed_mm_s;
        assert!(
            (v - expect).abs() < 1e-3 * expect.max(1.0),
            "{ratio}: speed {v}"
        );
        assert_continuous(&s, 1, s.len(), 1e-6, 300.0);
        let last = s.last().unwrap().pos_mm.to_array();
        assert!((last[0] - 300.0).abs() < 1e-4);
    }
    assert!(Mp::new(&cfg, [0.0; 3])
        .unwrap()
        .set_feed_override(2.5)
        .is_err());
}

/// The two halves over `heapless::spsc` queues, as on the board; the planner task is
/// starved for 1500 periods: the executor stops on its own within the braking distance
/// and continues by itself when steps come again.
#[test]
fn starved_planner_stops_and_restarts_on_the_path() {
    let cfg = config();
    let (segs, prog) = square();
    let mut spans_q: Queue<Span, 129> = Queue::new();
    let mut steps_q: Queue<Step, 33> = Queue::new();
    let (mut span_tx, mut span_rx) = spans_q.split();
    let (mut step_tx, mut step_rx) = steps_q.split();
    let mut planner: Planner<64, 256> = Planner::new(&cfg, [0.0; 3]).unwrap();
    let mut exec = Executor::new(cfg.period_s, [0.0; 3]);
    let mut next = 0;
    let mut s = Vec::new();
    let mut stopped = false;
    for n in 0..60_000 {
        while next < segs.len() && planner.push(&segs[next]).is_ok() {
            next += 1;
        }
        if !(2000..3500).contains(&n) {
            planner.sync(&exec.status());
            planner.produce(&mut span_tx, &mut step_tx, 32);
        }
        let x = exec.sample(&mut span_rx, &mut step_rx);
        stopped |=
            x.mode == ExecMode::Idle && x.path_speed_mm_s == 0.0 && (2000..3500).contains(&n);
        s.push(x);
    }
    assert!(stopped, "the executor did not stop while starved");
    let last = s.last().unwrap().pos_mm.to_array();
    assert!(last.iter().all(|c| c.abs() < 1e-4), "end {last:?}");
    assert!(max_deviation(&s, &prog) <= cfg.tolerance_mm as f64 + 3e-5);
    assert_continuous(&s, 1, s.len(), 1e-6, 25.0);
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(
        rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
        "{rv} {ra} {rj}"
    );
}
