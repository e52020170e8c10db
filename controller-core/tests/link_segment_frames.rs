//! What the host link carries of a program: the frame of a planner segment (a line, an arc
//! in a plane, an arc through a point) at its largest, and so the segments per second at
//! the board's 921,600 baud (8N1: 10 bits a byte). The host streams commands in one
//! direction while acks come back in the other, so the segment frames alone set the rate.

use controller_core::link::{encode, Seq, ToDevice, MAX_FRAME_LEN};
use controller_core::machine::messages::Request;
use controller_core::motion::planner::{Blend, Plane, Segment};

/// The board's host UART (firmware USART2).
const BAUD: f64 = 921_600.0;
const BITS_PER_BYTE: f64 = 10.0;

fn frame_len(seg: Segment) -> usize {
    let msg: ToDevice<Request> = ToDevice::Command {
        // the largest sequence numbers and tags: the longest varints
        seq: Seq(u16::MAX),
        cmd: Request::Segment(seg),
    };
    let mut frame = [0u8; MAX_FRAME_LEN];
    encode(&msg, &mut frame).unwrap()
}

#[test]
fn segment_frames_and_the_rate_the_link_carries() {
    let p = [-123.456_79f32, 98.765_43, -12.345_67];
    let line = Segment::line(p, 123.4, u32::MAX).with_blend(Blend::Tolerance(0.0123));
    let arc = Segment::arc(p, [1.5, -2.5, 3.5], Plane::ZX, true, 3, 45.6, u32::MAX)
        .with_blend(Blend::Tolerance(0.0123));
    let through = Segment::arc_through([1.5, -2.5, 3.5], p, 45.6, u32::MAX)
        .with_blend(Blend::Tolerance(0.0123));
    let bytes_s = BAUD / BITS_PER_BYTE;
    for (name, seg, max) in [
        ("line", line, 40),
        ("arc", arc, 56),
        ("arc through", through, 52),
    ] {
        let n = frame_len(seg);
        println!(
            "{name}: {n} bytes a frame, {:.0} segments/s at 921,600 baud",
            bytes_s / n as f64
        );
        assert!(n <= max, "{name}: {n} bytes");
    }
    // at least 1,800 arcs through a point a second (the compressed benchmark programs
    // need at most a few hundred: docs/planner.md)
    assert!(bytes_s / frame_len(through) as f64 > 1800.0);
}
