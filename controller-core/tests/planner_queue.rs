//! Queue behaviour: rejected segments change nothing, zero-length moves are skipped,
//! the queue reports its free slots and refuses when full, rapids run at the axis limits,
//! dwells stop and wait, every sample carries its segment's tag.

use crate::planner_common;
use controller_core::motion::planner::{
    Blend, Feed, Motion, Plane, Planner, PlannerConfigError, Segment, SegmentError,
};
use planner_common::*;

#[test]
fn rejected_segments_change_nothing() {
    let cfg = config();
    let mut p: Planner<8, 64> = Planner::new(&cfg, [1.0, 2.0, 3.0]).unwrap();
    p.push(&Segment::line([5.0, 2.0, 3.0], 20.0, 1)).unwrap();
    p.push(&Segment::line([5.0, 6.0, 3.0], 20.0, 2)).unwrap();
    p.fill_spans();
    let bad = [
        (
            Segment::line([f32::NAN, 0.0, 0.0], 10.0, 3),
            SegmentError::NotFinite("end_mm"),
        ),
        (
            Segment::line([1.0, 0.0, 0.0], -1.0, 3),
            SegmentError::FeedNotPositive,
        ),
        (
            Segment::line([1.0, 0.0, 0.0], f32::INFINITY, 3),
            SegmentError::NotFinite("feed_mm_s"),
        ),
        (
            Segment::line([1.0, 0.0, 0.0], 10.0, 3).with_blend(Blend::Tolerance(-0.1)),
            SegmentError::NegativeTolerance,
        ),
        (
            // Center on the start point: zero radius.
            Segment::arc(
                [9.0, 6.0, 3.0],
                [5.0, 6.0, 3.0],
                Plane::XY,
                false,
                0,
                10.0,
                3,
            ),
            SegmentError::ArcZeroRadius,
        ),
        (
            Segment::arc(
                [5.0, 9.0, 3.0],
                [5.0, 8.0, 3.0],
                Plane::XY,
                true,
                0,
                10.0,
                3,
            ),
            SegmentError::ArcRadiusMismatch {
                start_mm: 2.0,
                end_mm: 1.0,
            },
        ),
        (
            Segment::arc(
                [5.0, 6.0, 3.0],
                [5.0, 8.0, 3.0],
                Plane::XY,
                true,
                40,
                10.0,
                3,
            ),
            SegmentError::ArcTooManyTurns,
        ),
        (Segment::dwell(-1.0, 3), SegmentError::NegativeDwell),
        (
            Segment {
                motion: Motion::Arc {
                    end_mm: [5.0, 6.0, 3.0],
                    center_mm: [5.0, f32::NAN, 3.0],
                    plane: Plane::XY,
                    clockwise: false,
                    turns: 0,
                    feed_mm_s: 10.0,
                },
                blend: Blend::Default,
                tag: 3,
            },
            SegmentError::NotFinite("center_mm"),
        ),
    ];
    for (seg, err) in bad {
        let before = p.clone();
        assert_eq!(p.push(&seg), Err(err));
        assert_eq!(p, before, "{seg:?} changed the planner");
    }
    // Out-of-range override: refused, unchanged.
    let before = p.clone();
    assert_eq!(
        p.set_feed_override(0.0),
        Err(PlannerConfigError::OutOfRange("feed_override"))
    );
    assert_eq!(
        p.set_feed_override(f32::NAN),
        Err(PlannerConfigError::NotFinite("feed_override"))
    );
    assert_eq!(p, before);
}

#[test]
fn zero_length_moves_are_skipped_and_the_queue_fills() {
    let cfg = config();
    let mut p: Planner<4, 64> = Planner::new(&cfg, [0.0; 3]).unwrap();
    assert_eq!(p.free_slots(), 4);
    let before = p.clone();
    assert_eq!(p.push(&Segment::line([0.0; 3], 10.0, 1)), Ok(()));
    assert_eq!(p.push(&Segment::line([0.0, 0.0, 1e-4], 10.0, 1)), Ok(()));
    assert_eq!(p, before, "a zero-length line queued something");
    for k in 0..4 {
        p.push(&Segment::line([k as f32 + 1.0, 0.0, 0.0], 10.0, k))
            .unwrap();
    }
    assert_eq!(p.free_slots(), 0);
    let before = p.clone();
    assert_eq!(
        p.push(&Segment::line([9.0, 0.0, 0.0], 10.0, 9)),
        Err(SegmentError::QueueFull)
    );
    assert_eq!(p, before);
    // A full circle with two extra turns needs three slots.
    let mut q: Planner<4, 64> = Planner::new(&cfg, [0.0; 3]).unwrap();
    q.push(&Segment::line([1.0, 0.0, 0.0], 10.0, 1)).unwrap();
    q.push(&Segment::line([2.0, 0.0, 0.0], 10.0, 2)).unwrap();
    let circle = Segment::arc([2.0, 0.0, 0.0], [0.0; 3], Plane::XY, false, 2, 10.0, 3);
    assert_eq!(q.push(&circle), Err(SegmentError::QueueFull));
    let mut r: Planner<4, 64> = Planner::new(&cfg, [2.0, 0.0, 0.0]).unwrap();
    assert_eq!(r.push(&circle), Ok(()));
    assert_eq!(r.free_slots(), 1);
}

#[test]
fn rapids_dwells_and_tags() {
    let cfg = config();
    let segs = [
        Segment {
            motion: Motion::Line {
                end_mm: [60.0, 80.0, 0.0],
                feed: Feed::Rapid,
            },
            blend: Blend::ExactStop,
            tag: 10,
        },
        Segment::dwell(0.05, 11),
        Segment::line([60.0, 80.0, 10.0], 20.0, 12),
    ];
    let mut mp = Mp::new(&cfg, [0.0; 3]).unwrap();
    let s = run(&mut mp, &segs, 100_000);
    let (rv, ra, rj) = limit_ratios(&s, &cfg);
    assert!(
        rv <= 1.0 + 1e-3 && ra <= 1.0 + 1e-3 && rj <= 1.0 + 1e-3,
        "{rv} {ra} {rj}"
    );
    // The rapid reaches the Y axis limit (Y moves 0.8 of the path).
    let vy = s.iter().map(|x| x.vel_mm_s.y).fold(0.0f32, f32::max);
    assert!((vy - 250.0).abs() < 0.1, "rapid vy {vy}");
    // Tags in program order; the dwell holds still for 500 periods at the corner.
    let tags: Vec<u32> = s.iter().map(|x| x.tag).collect();
    assert!(tags.windows(2).all(|w| w[0] <= w[1]));
    let dwell: Vec<_> = s.iter().filter(|x| x.tag == 11).collect();
    assert!(
        (499..=502).contains(&dwell.len()),
        "dwell {} periods",
        dwell.len()
    );
    assert!(dwell
        .iter()
        .all(|x| x.path_speed_mm_s == 0.0 && x.pos_mm.x == 60.0 && x.pos_mm.y == 80.0));
    let last = s.last().unwrap();
    assert_eq!(last.tag, 12);
    assert!((last.pos_mm.z - 10.0).abs() < 1e-4);
    // The feed move runs at its feed (feed ratio 1), the rapid reports 0.
    assert!(s
        .iter()
        .any(|x| x.tag == 12 && (x.feed_ratio - 1.0).abs() < 1e-4));
    assert!(s
        .iter()
        .filter(|x| x.tag == 10)
        .all(|x| x.feed_ratio == 0.0));
}
