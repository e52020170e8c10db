//! Program input: the segment types a G-code interpreter (or any caller) queues, and their
//! validation into geometric pieces. Validation either produces the pieces or an error;
//! it never touches planner state, so a rejected segment changes nothing.

use super::config::ValidPlannerConfig;
use super::fmath::{self, F32Ext};
use super::geometry::{norm, Helix, Piece, Shape, V3};
use core::f32::consts::TAU;

/// Arc plane: G17 (XY, normal +Z), G18 (ZX, normal +Y), G19 (YZ, normal +X).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
// serde + Schema always: segments travel on the host link (machine::messages)
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub enum Plane {
    /// G17: arc in X, Y; helix along Z.
    XY,
    /// G18: arc in Z, X (first axis Z); helix along Y.
    ZX,
    /// G19: arc in Y, Z; helix along X.
    YZ,
}

impl Plane {
    /// Axis indices `[first, second, normal]`; first × second = normal, so positive angles
    /// (G3, counter-clockwise) are seen from the positive normal axis.
    pub const fn axes(self) -> [usize; 3] {
        match self {
            Plane::XY => [0, 1, 2],
            Plane::ZX => [2, 0, 1],
            Plane::YZ => [1, 2, 0],
        }
    }

    /// "G17 (XY)" etc., for messages.
    pub const fn name(self) -> &'static str {
        match self {
            Plane::XY => "G17 (XY)",
            Plane::ZX => "G18 (ZX)",
            Plane::YZ => "G19 (YZ)",
        }
    }
}

/// Axes (in-plane first, in-plane second, normal) of a plane. The order makes a positive
/// rotation (i1 toward i2) counter-clockwise seen from the positive normal, as G2/G3
/// define it: XY about +Z, ZX about +Y, YZ about +X.
pub(crate) fn plane_axes(p: Plane) -> (usize, usize, usize) {
    let [first, second, normal] = p.axes();
    (first, second, normal)
}

/// Feed of a line.
#[derive(Clone, Copy, Debug, PartialEq)]
// serde + Schema always: segments travel on the host link (machine::messages)
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub enum Feed {
    /// Programmed path speed (mm/s), scaled by the feed override.
    MmPerS(f32),
    /// G0: as fast as the per-axis velocity limits allow (override capped at 100 %).
    Rapid,
}

/// What happens at the junction after a segment.
#[derive(Clone, Copy, Debug, PartialEq)]
// serde + Schema always: segments travel on the host link (machine::messages)
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub enum Blend {
    /// G64 without P: blend within the configured `tolerance_mm`.
    Default,
    /// G64 P<ε>: blend within ε mm of the programmed path (0 = stop at corners, pass
    /// smooth junctions: G61, exact path).
    Tolerance(f32),
    /// G61.1 (exact stop): stop exactly at the end of the segment.
    ExactStop,
}

/// The motion of one segment. Positions are absolute machine coordinates (mm); the start
/// is where the previous segment ended.
#[derive(Clone, Copy, Debug, PartialEq)]
// serde + Schema always: segments travel on the host link (machine::messages)
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub enum Motion {
    /// G0/G1.
    Line { end_mm: [f32; 3], feed: Feed },
    /// G2/G3 (helix when the end differs from the start along the plane normal). `turns`
    /// extra full turns (LinuxCNC's P−1); end == start is a full circle.
    Arc {
        end_mm: [f32; 3],
        center_mm: [f32; 3],
        plane: Plane,
        clockwise: bool,
        turns: u32,
        feed_mm_s: f32,
    },
    /// G4: stop and wait.
    Dwell { duration_s: f32 },
    /// A circular arc in any plane, from the start through `via_mm` to `end_mm` (less than
    /// a full turn): what the host's path compressor fits to runs of short chords. The
    /// three points give the plane, the centre and the sense; no far-away centre travels
    /// (f32 keeps the arc as exact as its points, whatever its radius).
    ArcThrough {
        via_mm: [f32; 3],
        end_mm: [f32; 3],
        feed_mm_s: f32,
    },
}

/// One queued segment.
#[derive(Clone, Copy, Debug, PartialEq)]
// serde + Schema always: segments travel on the host link (machine::messages)
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub struct Segment {
    pub motion: Motion,
    /// Junction after this segment.
    pub blend: Blend,
    /// Caller's tag (e.g. the G-code line number), reported by every sample on it.
    pub tag: u32,
}

impl Segment {
    pub fn line(end_mm: [f32; 3], feed_mm_s: f32, tag: u32) -> Self {
        Self {
            motion: Motion::Line {
                end_mm,
                feed: Feed::MmPerS(feed_mm_s),
            },
            blend: Blend::Default,
            tag,
        }
    }
    pub fn rapid(end_mm: [f32; 3], tag: u32) -> Self {
        Self {
            motion: Motion::Line {
                end_mm,
                feed: Feed::Rapid,
            },
            blend: Blend::Default,
            tag,
        }
    }
    #[allow(clippy::too_many_arguments)]
    pub fn arc(
        end_mm: [f32; 3],
        center_mm: [f32; 3],
        plane: Plane,
        clockwise: bool,
        turns: u32,
        feed_mm_s: f32,
        tag: u32,
    ) -> Self {
        Self {
            motion: Motion::Arc {
                end_mm,
                center_mm,
                plane,
                clockwise,
                turns,
                feed_mm_s,
            },
            blend: Blend::Default,
            tag,
        }
    }
    /// A circular arc from the start through `via_mm` to `end_mm` (see
    /// [`Motion::ArcThrough`]).
    pub fn arc_through(via_mm: [f32; 3], end_mm: [f32; 3], feed_mm_s: f32, tag: u32) -> Self {
        Self {
            motion: Motion::ArcThrough {
                via_mm,
                end_mm,
                feed_mm_s,
            },
            blend: Blend::Default,
            tag,
        }
    }
    pub fn dwell(duration_s: f32, tag: u32) -> Self {
        Self {
            motion: Motion::Dwell { duration_s },
            blend: Blend::ExactStop,
            tag,
        }
    }
    /// The same segment with another junction mode.
    pub fn with_blend(mut self, blend: Blend) -> Self {
        self.blend = blend;
        self
    }
}

/// Why a segment was rejected. The planner is unchanged after any of these.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SegmentError {
    /// The named field holds NaN or ±∞.
    NotFinite(&'static str),
    /// Feed must be > 0.
    FeedNotPositive,
    /// Blend tolerance must be ≥ 0.
    NegativeTolerance,
    /// Dwell time must be ≥ 0.
    NegativeDwell,
    /// Start or end radius below `min_segment_mm` (grbl error 33-35 family).
    ArcZeroRadius,
    /// Start and end radius differ by more than `arc_radius_tolerance_mm`.
    ArcRadiusMismatch { start_mm: f32, end_mm: f32 },
    /// More turns than one push can queue (at most [`MAX_ARC_PIECES`] full turns).
    ArcTooManyTurns,
    /// The three points of an arc through a point lie on a line (or two coincide): no
    /// arc; send a line.
    ArcCollinear,
    /// An arc through a point with a radius above [`MAX_ARC_THROUGH_RADIUS_MM`]: send a
    /// line (within any tolerance the arc would be one).
    ArcRadiusTooLarge,
    /// Not enough free queue slots (an arc of n turns needs n+1); retry later.
    QueueFull,
    /// An abort is stopping the machine; pushes resume once it has stopped.
    Aborting,
}

/// Largest radius of an arc through a point (mm): 10 m. Over a 100 mm chord such an arc
/// departs 0.125 mm from its chord; the compressor sends lines for flatter runs.
pub const MAX_ARC_THROUGH_RADIUS_MM: f32 = 1.0e4;

/// An arc is queued as pieces of at most one full turn each (f32 angles stay below 2π
/// and the look-ahead sees every turn); this bounds one push.
pub const MAX_ARC_PIECES: usize = 16;

/// Attributes a piece carries besides its geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PieceAttr {
    /// Programmed feed (mm/s); +∞ for rapids.
    pub feed: f32,
    pub rapid: bool,
    pub tag: u32,
    /// Blend tolerance at the junction after the piece (mm); `None` = exact stop.
    pub tol_after: Option<f32>,
    /// Dwell length in control periods (dwell pieces only).
    pub dwell_periods: u32,
}

/// A validated segment: 0 pieces (skipped zero-length line), 1, or several (arc turns),
/// generated on demand by [`Prepared::piece`] (no array of pieces to copy around).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Prepared {
    pub n: usize,
    pub attr: PieceAttr,
    kind: PrepKind,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum PrepKind {
    Single(Piece),
    Arc(ArcSplit),
}

/// An arc cut into `count` equal pieces of at most one turn.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ArcSplit {
    start: V3,
    end: V3,
    center: V3,
    axes: (usize, usize, usize),
    psi0: f32,
    r0: f32,
    count: usize,
    /// Length, sweep, rise and radius change of one piece.
    plen: f32,
    psweep: f32,
    prise: f32,
    pdr: f32,
}

impl ArcSplit {
    /// The point between piece `k − 1` and piece `k` (the programmed ends exactly).
    fn point(&self, k: usize) -> V3 {
        if k == 0 {
            return self.start;
        }
        if k >= self.count {
            return self.end;
        }
        let (i1, i2, n) = self.axes;
        let (sn, cs) = fmath::sin_cos(self.psi0 + self.psweep * k as f32);
        let r = self.r0 + self.pdr * k as f32;
        // (the plane's axes are 0-2 by construction; `get` keeps a panic path out of the
        // control interrupt all the same)
        let rise = self.start.to_array().get(n).copied().unwrap_or(0.0) + self.prise * k as f32;
        let mut e = self.center.to_array();
        for (i, add, x) in [(i1, true, r * cs), (i2, true, r * sn), (n, false, rise)] {
            if let Some(slot) = e.get_mut(i) {
                *slot = if add { *slot + x } else { x };
            }
        }
        V3::from_array(e)
    }

    fn piece(&self, k: usize) -> Piece {
        let (i1, i2, n) = self.axes;
        Piece {
            start: self.point(k),
            end: self.point(k + 1),
            len: self.plen,
            shape: Shape::Helix(Helix {
                e1: V3::unit_axis(i1),
                e2: V3::unit_axis(i2),
                n: V3::unit_axis(n),
                psi0: libm::fmodf(self.psi0 + self.psweep * k as f32, TAU),
                omega: self.psweep / self.plen,
                r0: self.r0 + self.pdr * k as f32,
                rho: self.pdr / self.plen,
                eta: self.prise / self.plen,
            }),
        }
    }
}

impl Prepared {
    /// Piece `k` (`k < n`).
    pub fn piece(&self, k: usize) -> Piece {
        match &self.kind {
            PrepKind::Single(p) => *p,
            PrepKind::Arc(a) => a.piece(k),
        }
    }
}

fn finite3(v: [f32; 3], name: &'static str) -> Result<V3, SegmentError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(V3::from_array(v))
    } else {
        Err(SegmentError::NotFinite(name))
    }
}

fn feed_ok(f: f32) -> Result<f32, SegmentError> {
    if !f.is_finite() {
        Err(SegmentError::NotFinite("feed_mm_s"))
    } else if !(f > 0.0) {
        Err(SegmentError::FeedNotPositive)
    } else {
        Ok(f)
    }
}

const EMPTY: Piece = Piece {
    start: V3::new(0.0, 0.0, 0.0),
    end: V3::new(0.0, 0.0, 0.0),
    len: 0.0,
    shape: Shape::Dwell,
};

/// Validates `seg` starting at `start` into pieces.
pub(crate) fn prepare(
    seg: &Segment,
    start: V3,
    s: &ValidPlannerConfig,
) -> Result<Prepared, SegmentError> {
    let tol_after = match seg.blend {
        Blend::Default => Some(s.tolerance_mm),
        Blend::Tolerance(e) => {
            if !e.is_finite() {
                return Err(SegmentError::NotFinite("blend tolerance"));
            }
            if !(e >= 0.0) {
                return Err(SegmentError::NegativeTolerance);
            }
            Some(e)
        }
        Blend::ExactStop => None,
    };
    let mut out = Prepared {
        kind: PrepKind::Single(EMPTY),
        n: 0,
        attr: PieceAttr {
            feed: f32::INFINITY,
            rapid: false,
            tag: seg.tag,
            tol_after,
            dwell_periods: 0,
        },
    };
    match seg.motion {
        Motion::Line { end_mm, feed } => {
            let end = finite3(end_mm, "end_mm")?;
            match feed {
                Feed::MmPerS(f) => out.attr.feed = feed_ok(f)?,
                Feed::Rapid => out.attr.rapid = true,
            }
            let d = end - start;
            let len = norm(d);
            if len >= s.min_segment_mm {
                let k = 1.0 / len;
                out.kind = PrepKind::Single(Piece {
                    start,
                    end,
                    len,
                    shape: Shape::Line {
                        u: V3::new(d[0] * k, d[1] * k, d[2] * k),
                    },
                });
                out.n = 1;
            }
        }
        Motion::Arc {
            end_mm,
            center_mm,
            plane,
            clockwise,
            turns,
            feed_mm_s,
        } => {
            let end = finite3(end_mm, "end_mm")?;
            let center = finite3(center_mm, "center_mm")?;
            out.attr.feed = feed_ok(feed_mm_s)?;
            let split = arc_split(start, end, center, plane, clockwise, turns, s)?;
            out.n = split.count;
            out.kind = PrepKind::Arc(split);
        }
        Motion::ArcThrough {
            via_mm,
            end_mm,
            feed_mm_s,
        } => {
            let via = finite3(via_mm, "via_mm")?;
            let end = finite3(end_mm, "end_mm")?;
            out.attr.feed = feed_ok(feed_mm_s)?;
            out.kind = PrepKind::Single(arc_through(start, via, end, s)?);
            out.n = 1;
        }
        Motion::Dwell { duration_s } => {
            if !duration_s.is_finite() {
                return Err(SegmentError::NotFinite("duration_s"));
            }
            if !(duration_s >= 0.0) {
                return Err(SegmentError::NegativeDwell);
            }
            // Saturating conversion; 1e9 periods is over a day at 10 kHz.
            let periods = (duration_s / s.period_s + 0.5).mn(1.0e9);
            out.attr.dwell_periods = periods as u32;
            out.attr.tol_after = None;
            out.kind = PrepKind::Single(Piece {
                start,
                end: start,
                len: 0.0,
                shape: Shape::Dwell,
            });
            out.n = 1;
        }
    }
    Ok(out)
}

/// The circle through `start`, `via`, `end` as a helix piece (no rise), in the order the
/// three points give. All in offsets from `start`, so f32 keeps the local precision.
fn arc_through(start: V3, via: V3, end: V3, s: &ValidPlannerConfig) -> Result<Piece, SegmentError> {
    let a = via - start;
    let b = end - start;
    let (la, lb, lc) = (norm(a), norm(b), norm(end - via));
    if !(la >= s.min_segment_mm && lb >= s.min_segment_mm && lc >= s.min_segment_mm) {
        return Err(SegmentError::ArcCollinear);
    }
    let axb = a.cross(b);
    let n2 = axb.dot(axb);
    // |a × b| = |a||b| sin(angle at the start): below 1e-6 relative, no usable plane.
    if !(n2 > (1.0e-6 * la * lb) * (1.0e-6 * la * lb)) {
        return Err(SegmentError::ArcCollinear);
    }
    // Circumcentre relative to the start: (|a|² b − |b|² a) × (a × b) / (2 |a × b|²).
    let m = b.scale(a.dot(a)) - a.scale(b.dot(b));
    let c = m.cross(axb).scale(0.5 / n2);
    let r = norm(c);
    if !(r >= s.min_segment_mm) {
        return Err(SegmentError::ArcZeroRadius);
    }
    if !(r <= MAX_ARC_THROUGH_RADIUS_MM) {
        return Err(SegmentError::ArcRadiusTooLarge);
    }
    let n = axb.scale(1.0 / fmath::sqrt(n2));
    let e1 = c.scale(-1.0 / r);
    let e2 = n.cross(e1);
    // End angle from e1 toward e2 in (0, 2π): the points run counter-clockwise about n.
    let pe = b - c;
    let mut sweep = libm::atan2f(pe.dot(e2), pe.dot(e1));
    if sweep <= 0.0 {
        sweep += TAU;
    }
    let len = r * sweep;
    if !(len >= s.min_segment_mm) || !len.is_finite() {
        return Err(SegmentError::ArcCollinear);
    }
    Ok(Piece {
        start,
        end,
        len,
        shape: Shape::Helix(Helix {
            e1,
            e2,
            n,
            psi0: 0.0,
            omega: 1.0 / r,
            r0: r,
            rho: 0.0,
            eta: 0.0,
        }),
    })
}

fn arc_split(
    start: V3,
    end: V3,
    center: V3,
    plane: Plane,
    clockwise: bool,
    turns: u32,
    s: &ValidPlannerConfig,
) -> Result<ArcSplit, SegmentError> {
    let (i1, i2, n) = plane_axes(plane);
    let (a0, b0) = (start[i1] - center[i1], start[i2] - center[i2]);
    let (a1, b1) = (end[i1] - center[i1], end[i2] - center[i2]);
    let r0 = fmath::hypot(a0, b0);
    let r1 = fmath::hypot(a1, b1);
    if !(r0 >= s.min_segment_mm) || !(r1 >= s.min_segment_mm) {
        return Err(SegmentError::ArcZeroRadius);
    }
    if !((r1 - r0).abs() <= s.arc_tol_mm) {
        return Err(SegmentError::ArcRadiusMismatch {
            start_mm: r0,
            end_mm: r1,
        });
    }
    if turns as usize >= MAX_ARC_PIECES {
        return Err(SegmentError::ArcTooManyTurns);
    }
    let psi0 = libm::atan2f(b0, a0);
    let psi1 = libm::atan2f(b1, a1);
    // Angle from start to end in (-π, π].
    let mut d = psi1 - psi0;
    if d > core::f32::consts::PI {
        d -= TAU;
    } else if d <= -core::f32::consts::PI {
        d += TAU;
    }
    let full = fmath::hypot(a1 - a0, b1 - b0) < s.min_segment_mm;
    let sweep = if clockwise {
        let base = if full || d >= 0.0 { d - TAU } else { d };
        base - TAU * turns as f32
    } else {
        let base = if full || d <= 0.0 { d + TAU } else { d };
        base + TAU * turns as f32
    };
    let rise = end[n] - start[n];
    let r_mean = 0.5 * (r0 + r1);
    let len = fmath::hypot(r_mean * sweep, rise);
    if !(len >= s.min_segment_mm) {
        return Err(SegmentError::ArcZeroRadius);
    }
    // Pieces of at most one turn (plus the rounding of `sweep`).
    let count = ((sweep.abs() / TAU - 1.0e-4).mx(0.0) as usize + 1).min(MAX_ARC_PIECES);
    let kf = 1.0 / count as f32;
    Ok(ArcSplit {
        start,
        end,
        center,
        axes: (i1, i2, n),
        psi0,
        r0,
        count,
        plen: len * kf,
        psweep: sweep * kf,
        prise: rise * kf,
        pdr: (r1 - r0) * kf,
    })
}

#[cfg(test)]
mod tests {
    use super::super::config::{ValidPlannerConfig, GANTRY_PLANNER};
    use super::*;

    fn settings() -> ValidPlannerConfig {
        ValidPlannerConfig::new(&GANTRY_PLANNER).unwrap()
    }

    #[test]
    fn arcs_in_every_plane_end_on_the_programmed_point() {
        let s = settings();
        for plane in [Plane::XY, Plane::ZX, Plane::YZ] {
            for cw in [false, true] {
                let (i1, i2, n) = plane_axes(plane);
                let mut start = [1.0, 2.0, 3.0];
                let mut center = start;
                center[i1] -= 5.0; // start at angle 0, radius 5
                let mut end = center;
                end[i2] += 5.0; // angle +90°
                end[n] += 2.0;
                start[n] += 0.0;
                let seg = Segment::arc(end, center, plane, cw, 0, 10.0, 1);
                let p = prepare(&seg, V3::from_array(start), &s).unwrap();
                assert_eq!(p.n, 1);
                let pc = &p.piece(0);
                // CCW: quarter turn; CW: three quarters.
                let quarter = if cw { 3.0 } else { 1.0 } * core::f32::consts::FRAC_PI_2 * 5.0;
                let len = fmath::hypot(quarter, 2.0);
                assert!((pc.len - len).abs() < 1e-4, "{plane:?} cw {cw}: {}", pc.len);
                let e = pc.start + pc.delta(0.0, pc.len);
                assert!(norm(e - V3::from_array(end)) < 2e-5);
                // The tangent at the start turns the right way about the normal.
                let t = pc.derivs(0.0).d1;
                let sign = if cw { -1.0 } else { 1.0 };
                assert!(t[i2] * sign > 0.9, "{plane:?} cw {cw}: {t:?}");
            }
        }
    }

    #[test]
    fn full_circle_and_turns_split_into_turn_pieces() {
        let s = settings();
        let start = [10.0, 0.0, 0.0];
        let seg = Segment::arc(start, [0.0; 3], Plane::XY, false, 2, 10.0, 1);
        let p = prepare(&seg, V3::from_array(start), &s).unwrap();
        assert_eq!(p.n, 3);
        for k in 0..3 {
            let pc = &p.piece(k);
            assert!((pc.len - TAU * 10.0).abs() < 1e-3);
            assert!(norm(pc.end - V3::from_array(start)) < 1e-4);
        }
    }

    #[test]
    fn arcs_through_a_point_in_tilted_planes_pass_through_it() {
        let s = settings();
        // circles of several radii in planes of several orientations, sweeps to 300°
        let mut k = 0u32;
        for r in [0.5f32, 3.0, 40.0, 900.0] {
            for (tilt, yaw) in [(0.0f32, 0.0f32), (0.4, 1.1), (1.2, -2.0), (-0.9, 2.9)] {
                for sweep in [0.05f32, 1.0, 3.0, 5.2] {
                    k += 1;
                    let n = V3::new(tilt.sin() * yaw.cos(), tilt.sin() * yaw.sin(), tilt.cos());
                    // an orthonormal frame about n
                    let helper = if n[0].abs() < 0.9 {
                        V3::new(1.0, 0.0, 0.0)
                    } else {
                        V3::new(0.0, 1.0, 0.0)
                    };
                    let u = helper.cross(n);
                    let u = u.scale(1.0 / norm(u));
                    let w = n.cross(u);
                    let center = [10.0f32, -20.0, 5.0];
                    let at = |ang: f32| {
                        let (sn, cs) = (libm::sinf(ang), libm::cosf(ang));
                        [
                            center[0] + r * (cs * u[0] + sn * w[0]),
                            center[1] + r * (cs * u[1] + sn * w[1]),
                            center[2] + r * (cs * u[2] + sn * w[2]),
                        ]
                    };
                    let (start, via, end) = (at(0.3), at(0.3 + 0.37 * sweep), at(0.3 + sweep));
                    let seg = Segment::arc_through(via, end, 10.0, k);
                    let p = prepare(&seg, V3::from_array(start), &s).unwrap();
                    assert_eq!(p.n, 1);
                    let pc = p.piece(0);
                    let tol = 2e-5 * (1.0 + r);
                    assert!(
                        (pc.len - r * sweep).abs() < 1e-4 * r * sweep.max(1.0),
                        "{r} {sweep}: {}",
                        pc.len
                    );
                    let e = pc.start + pc.delta(0.0, pc.len);
                    assert!(
                        norm(e - V3::from_array(end)) < tol,
                        "{r} {sweep}: end {e:?} vs {end:?}"
                    );
                    let mid = pc.start + pc.delta(0.0, 0.37 * pc.len);
                    assert!(
                        norm(mid - V3::from_array(via)) < tol,
                        "{r} {sweep}: via {mid:?} vs {via:?}"
                    );
                    // curvature 1/r, in the plane
                    let d = pc.derivs(0.5 * pc.len);
                    // (a flat arc's curvature is only as good as its points over its
                    // sagitta: f32 positions near 20 mm are good to 1e-6 mm)
                    let sagitta = r * (1.0 - libm::cosf(0.5 * sweep));
                    let kt = 1e-3 + 4e-6 / sagitta;
                    assert!(
                        (norm(d.d2) * r - 1.0).abs() < kt,
                        "{r} {sweep}: {}",
                        norm(d.d2)
                    );
                    assert!(d.d2.dot(n).abs() < kt * norm(d.d2), "{r} {sweep}: plane");
                }
            }
        }
    }

    #[test]
    fn arcs_through_degenerate_points_are_refused() {
        let s = settings();
        let o = [1.0f32, 2.0, 3.0];
        let e = |via: [f32; 3], end: [f32; 3]| {
            prepare(
                &Segment::arc_through(via, end, 5.0, 0),
                V3::from_array(o),
                &s,
            )
            .err()
        };
        assert_eq!(
            e([2.0, 2.0, 3.0], [3.0, 2.0, 3.0]),
            Some(SegmentError::ArcCollinear)
        );
        assert_eq!(e(o, [3.0, 2.0, 3.0]), Some(SegmentError::ArcCollinear));
        assert_eq!(
            e([2.0, 3.0, 3.0], [2.0, 3.0, 3.0]),
            Some(SegmentError::ArcCollinear)
        );
        // a 20 km circle through three points 10 mm apart
        assert_eq!(
            e([6.0, 2.000_625, 3.0], [11.0, 2.0, 3.0]),
            Some(SegmentError::ArcRadiusTooLarge)
        );
        assert_eq!(
            e([f32::NAN, 0.0, 0.0], [3.0, 2.0, 3.0]),
            Some(SegmentError::NotFinite("via_mm"))
        );
        assert_eq!(
            prepare(
                &Segment::arc_through([2.0, 3.0, 3.0], [3.0, 2.0, 3.0], -1.0, 0),
                V3::from_array(o),
                &s
            )
            .err(),
            Some(SegmentError::FeedNotPositive)
        );
    }

    #[test]
    fn bad_segments_are_rejected_with_the_reason() {
        let s = settings();
        let o = [0.0; 3];
        let e = |seg: Segment| prepare(&seg, V3::from_array(o), &s).err();
        assert_eq!(
            e(Segment::line([f32::NAN, 0.0, 0.0], 10.0, 0)),
            Some(SegmentError::NotFinite("end_mm"))
        );
        assert_eq!(
            e(Segment::line([1.0, 0.0, 0.0], 0.0, 0)),
            Some(SegmentError::FeedNotPositive)
        );
        assert_eq!(
            e(Segment::arc(
                [1.0, 0.0, 0.0],
                o,
                Plane::XY,
                false,
                0,
                5.0,
                0
            )),
            Some(SegmentError::ArcZeroRadius)
        );
        assert!(matches!(
            e(Segment::arc(
                [0.0, 2.0, 0.0],
                [1.0, 0.0, 0.0],
                Plane::XY,
                false,
                0,
                5.0,
                0
            )),
            Some(SegmentError::ArcRadiusMismatch { .. })
        ));
        assert_eq!(
            e(Segment::line([1.0, 0.0, 0.0], 5.0, 0).with_blend(Blend::Tolerance(-1.0))),
            Some(SegmentError::NegativeTolerance)
        );
        assert_eq!(
            e(Segment::dwell(-1.0, 0)),
            Some(SegmentError::NegativeDwell)
        );
        // A zero-length line is accepted and yields no piece.
        assert_eq!(
            prepare(&Segment::line(o, 5.0, 0), V3::from_array(o), &s)
                .unwrap()
                .n,
            0
        );
    }
}
