//! Soft limits: the machine's travel as a box in machine coordinates, checked against a
//! whole program before it starts (every end point and every arc's exact extremes) or
//! against a single target point (jog / move commands).
//!
//! The travel is a box, hence convex: a straight move (rapid, feed or jog) between two
//! points inside it stays inside, and so does a path blended inside the convex hull of
//! the programmed points. Arcs bulge, so their extremes are computed exactly
//! ([`super::arc::arc_extent`]), not sampled.

use std::fmt;

use super::{Error, ErrorKind, Program, AXIS_NAMES};

/// Slack on the limit comparison (mm): only float noise, far below any encoder count, so
/// that an arc computed to touch the limit exactly is not rejected by rounding.
pub const TRAVEL_SLACK_MM: f64 = 1e-9;

/// The travel of the three axes in machine coordinates (mm), validated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Travel {
    min_mm: [f64; 3],
    max_mm: [f64; 3],
}

/// Why a travel is not usable.
#[derive(Debug, Clone, PartialEq)]
pub struct TravelError(pub String);

impl fmt::Display for TravelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for TravelError {}

/// A point beyond the travel: which axis, where, and the limit it passes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TravelViolation {
    /// Axis index: 0 = X, 1 = Y, 2 = Z.
    pub axis: usize,
    /// The offending coordinate (mm).
    pub value_mm: f64,
    /// The limit it passes (the maximum if `value_mm` is above it, else the minimum).
    pub limit_mm: f64,
}

impl fmt::Display for TravelViolation {
    /// `X would leave the travel: 212.000 mm > +150.000 mm`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let axis = AXIS_NAMES.get(self.axis).copied().unwrap_or('?');
        let rel = if self.value_mm > self.limit_mm {
            '>'
        } else {
            '<'
        };
        write!(
            f,
            "{axis} would leave the travel: {:.3} mm {rel} {:+.3} mm",
            self.value_mm, self.limit_mm
        )
    }
}

impl Travel {
    /// Travel from `[[min, max]; 3]` (mm, X Y Z): every bound finite and `min < max`.
    pub fn new(limits_mm: [[f64; 2]; 3]) -> Result<Self, TravelError> {
        for (a, [lo, hi]) in limits_mm.iter().enumerate() {
            let axis = AXIS_NAMES.get(a).copied().unwrap_or('?');
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(TravelError(format!(
                    "travel of {axis} must be finite with min < max, got [{lo}, {hi}] mm"
                )));
            }
        }
        Ok(Self {
            min_mm: limits_mm.map(|[lo, _]| lo),
            max_mm: limits_mm.map(|[_, hi]| hi),
        })
    }

    /// The limits as given to [`Travel::new`].
    pub fn limits_mm(&self) -> [[f64; 2]; 3] {
        [0, 1, 2].map(|a| [self.min_mm[a], self.max_mm[a]])
    }

    /// Checks one target point (a jog or a single move): the first axis (X, Y, Z order)
    /// outside the travel. A straight move from inside to an accepted target stays inside.
    pub fn check_point(&self, point_mm: [f64; 3]) -> Result<(), TravelViolation> {
        self.check_extent(point_mm.map(|p| [p, p]))
    }

    /// Checks an axis-aligned extent `[[min, max]; 3]`: the first axis (X, Y, Z order, the
    /// maximum side before the minimum) that leaves the travel. NaN counts as outside.
    pub fn check_extent(&self, extent_mm: [[f64; 2]; 3]) -> Result<(), TravelViolation> {
        for (axis, [lo, hi]) in extent_mm.into_iter().enumerate() {
            let (min, max) = (self.min_mm[axis], self.max_mm[axis]);
            if !(hi <= max + TRAVEL_SLACK_MM) {
                return Err(TravelViolation {
                    axis,
                    value_mm: hi,
                    limit_mm: max,
                });
            }
            if !(lo >= min - TRAVEL_SLACK_MM) {
                return Err(TravelViolation {
                    axis,
                    value_mm: lo,
                    limit_mm: min,
                });
            }
        }
        Ok(())
    }
}

/// Rejects a program that would leave the travel: the start point first (reported without
/// a line), then each move in order, naming the first move's file line and the axis.
///
/// A move's extent covers its whole path: the end point of straight moves (the start was
/// the previous end), the exact extremes of arcs.
pub fn check_travel(program: &Program, travel: &Travel) -> Result<(), Error> {
    if let Err(v) = travel.check_point(program.start_mm) {
        return Err(Error {
            file: program.name.clone(),
            line: None,
            kind: ErrorKind::Travel,
            message: format!("the start point is outside the travel: {v}"),
        });
    }
    for m in &program.moves {
        if let Err(v) = travel.check_extent(m.extent_mm()) {
            return Err(Error {
                file: program.name.clone(),
                line: Some(m.line),
                kind: ErrorKind::Travel,
                message: v.to_string(),
            });
        }
    }
    Ok(())
}
