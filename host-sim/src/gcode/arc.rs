//! Arc geometry: centre from I/J/K or R, end-point-on-circle check, swept angle, and the
//! exact axis-aligned extent of an arc (for bounds and soft limits).
//!
//! Conventions (RS274NGC, grbl): in plane G17 the arc axes are (X, Y) with normal Z; in G18
//! (Z, X) with normal Y; in G19 (Y, Z) with normal X. With the axes in that order the
//! plane's normal is first × second, so "counter-clockwise" (G3) is the positive angle
//! seen from the positive normal axis, and G2 the negative one.

use std::f64::consts::{FRAC_PI_2, TAU};

use super::{Plane, FULL_CIRCLE_CHORD_MM, MIN_ARC_RADIUS_MM};

/// Upper bound of the end-point tolerance, whatever the relative part gives (grbl rejects
/// any arc whose end radius differs by more than 0.5 mm).
pub const ARC_TOLERANCE_CAP_MM: f64 = 0.5;

/// How the program defines the centre.
#[derive(Debug, Clone, Copy)]
pub(crate) enum CentreForm {
    /// Offsets of the centre from the start along the plane's first and second axes (mm).
    Offsets([f64; 2]),
    /// Signed radius (mm): positive for the arc of at most 180°, negative for the longer one.
    Radius(f64),
}

/// A resolved arc: centre (normal-axis component = the start's) and total swept angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Resolved {
    pub center: [f64; 3],
    pub sweep_rad: f64,
}

/// End-point tolerance for an arc of radius `radius_mm`: the larger of the absolute and
/// the relative part, capped at [`ARC_TOLERANCE_CAP_MM`] (grbl's rule with its defaults
/// 0.005 mm and 0.1 %).
pub fn arc_tolerance_mm(radius_mm: f64, abs_mm: f64, rel: f64) -> f64 {
    (abs_mm.max(rel * radius_mm.abs())).min(ARC_TOLERANCE_CAP_MM)
}

/// Resolves the centre and swept angle of an arc from `from` to `to`, or explains why the
/// arc is invalid (message without file/line).
#[allow(clippy::too_many_arguments)]
pub(crate) fn resolve(
    from: [f64; 3],
    to: [f64; 3],
    plane: Plane,
    clockwise: bool,
    form: CentreForm,
    turns: u32,
    tol_abs_mm: f64,
    tol_rel: f64,
) -> Result<Resolved, String> {
    let [a0, a1, n] = plane.axes();
    let (du, dv) = (to[a0] - from[a0], to[a1] - from[a1]);
    let chord = du.hypot(dv);
    let full_circle = chord <= FULL_CIRCLE_CHORD_MM;
    let (cu, cv) = match form {
        CentreForm::Offsets([o0, o1]) => {
            let r0 = o0.hypot(o1);
            if r0 < MIN_ARC_RADIUS_MM {
                return Err(
                    "arc radius is zero: the I/J/K offsets put the centre on the start point"
                        .into(),
                );
            }
            let (cu, cv) = (from[a0] + o0, from[a1] + o1);
            let r1 = (to[a0] - cu).hypot(to[a1] - cv);
            let tol = arc_tolerance_mm(r0, tol_abs_mm, tol_rel);
            let off = (r1 - r0).abs();
            if !(off <= tol) {
                return Err(format!(
                    "arc end point is {off:.4} mm off the circle (radius {r0:.4} mm at the start, \
                     {r1:.4} mm at the end; tolerance {tol:.4} mm)"
                ));
            }
            (cu, cv)
        }
        CentreForm::Radius(r) => {
            if !(r.abs() >= MIN_ARC_RADIUS_MM) {
                return Err("arc radius is zero (R0)".into());
            }
            if full_circle {
                return Err(
                    "R-form arc ends where it starts: a full circle needs I/J/K, not R".into(),
                );
            }
            let tol = arc_tolerance_mm(r, tol_abs_mm, tol_rel);
            if chord - 2.0 * r.abs() > tol {
                return Err(format!(
                    "R-form arc cannot reach its end point: the end is {chord:.4} mm from the \
                     start, more than 2 × |R| = {:.4} mm",
                    2.0 * r.abs()
                ));
            }
            // Distance of the centre from the chord's midpoint; 0 for a half circle (and
            // for a chord up to `tol` longer than the diameter, accepted as a half circle).
            let h = (r * r - 0.25 * chord * chord).max(0.0).sqrt();
            // Unit normal to the left of the chord direction (chord > 0 here).
            let (nu, nv) = (-dv / chord, du / chord);
            // Counter-clockwise with R > 0 (the short way round) has its centre on the
            // left of the chord; clockwise or a negative R each flip the side.
            let side = if clockwise == (r < 0.0) { 1.0 } else { -1.0 };
            let (mu, mv) = (from[a0] + 0.5 * du, from[a1] + 0.5 * dv);
            (mu + side * h * nu, mv + side * h * nv)
        }
    };
    let theta_s = (from[a1] - cv).atan2(from[a0] - cu);
    let theta_e = (to[a1] - cv).atan2(to[a0] - cu);
    let base = if full_circle {
        TAU
    } else {
        let d = if clockwise {
            theta_s - theta_e
        } else {
            theta_e - theta_s
        };
        let d = d.rem_euclid(TAU);
        if d > 0.0 {
            d
        } else {
            TAU
        }
    };
    let sweep_rad = base + TAU * f64::from(turns.saturating_sub(1));
    let mut center = [0.0; 3];
    center[a0] = cu;
    center[a1] = cv;
    center[n] = from[n];
    if !(center.iter().all(|c| c.is_finite()) && sweep_rad.is_finite()) {
        return Err("arc geometry cannot be computed (numbers out of range)".into());
    }
    Ok(Resolved { center, sweep_rad })
}

/// Length (mm) of the path of an arc from `from` to `to` about `center` sweeping
/// `sweep_rad` in `plane`, helix included: the mean of the start and end radii times the
/// swept angle, combined with the normal-axis travel (the planner interpolates the radius
/// and the normal coordinate linearly with the angle; the radii differ by at most the arc
/// tolerance).
pub fn arc_length_mm(
    from: [f64; 3],
    to: [f64; 3],
    center: [f64; 3],
    plane: Plane,
    sweep_rad: f64,
) -> f64 {
    let [a0, a1, n] = plane.axes();
    let r0 = (from[a0] - center[a0]).hypot(from[a1] - center[a1]);
    let r1 = (to[a0] - center[a0]).hypot(to[a1] - center[a1]);
    (0.5 * (r0 + r1) * sweep_rad).hypot(to[n] - from[n])
}

/// Exact axis-aligned extent `[[min, max]; 3]` of an arc (helical or not) from `from` to
/// `to` about `center`, sweeping `sweep_rad` (> 0) clockwise or not in `plane`.
///
/// In the plane the extremes are the end points plus, for each of the four axis
/// directions the sweep passes, the centre ± the radius. When the start and end radii
/// differ (end point within tolerance but not on the circle) the larger radius is used,
/// so the extent is a guaranteed bound for any path whose radius stays between the two
/// (a planner interpolating the radius with the angle); it is exact when they agree. Along
/// the normal axis the motion is linear, so its extremes are the end points.
pub fn arc_extent(
    from: [f64; 3],
    to: [f64; 3],
    center: [f64; 3],
    plane: Plane,
    clockwise: bool,
    sweep_rad: f64,
) -> [[f64; 2]; 3] {
    let mut ext = [[0.0; 2]; 3];
    for (a, e) in ext.iter_mut().enumerate() {
        *e = [from[a].min(to[a]), from[a].max(to[a])];
    }
    let [a0, a1, _] = plane.axes();
    let r_from = (from[a0] - center[a0]).hypot(from[a1] - center[a1]);
    let r_to = (to[a0] - center[a0]).hypot(to[a1] - center[a1]);
    let r = r_from.max(r_to);
    let theta_s = (from[a1] - center[a1]).atan2(from[a0] - center[a0]);
    // Quadrant index k: angle k·π/2 points along +first (0), +second (1), −first (2),
    // −second (3). Walk the axis directions strictly inside the sweep; four cover all.
    let q = theta_s / FRAC_PI_2;
    let (mut k, step) = if clockwise {
        (q.ceil() - 1.0, -1.0)
    } else {
        (q.floor() + 1.0, 1.0)
    };
    let limit = if clockwise {
        theta_s - sweep_rad
    } else {
        theta_s + sweep_rad
    };
    for _ in 0..4 {
        let phi = k * FRAC_PI_2;
        let inside = if clockwise { phi > limit } else { phi < limit };
        if !inside || !phi.is_finite() {
            break;
        }
        let (axis, value) = match (k.rem_euclid(4.0)) as u8 {
            0 => (a0, center[a0] + r),
            1 => (a1, center[a1] + r),
            2 => (a0, center[a0] - r),
            _ => (a1, center[a1] - r),
        };
        if let Some(e) = ext.get_mut(axis) {
            e[0] = e[0].min(value);
            e[1] = e[1].max(value);
        }
        k += step;
    }
    ext
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    const TOL: (f64, f64) = (0.005, 0.001);

    fn res(from: [f64; 3], to: [f64; 3], cw: bool, form: CentreForm) -> Resolved {
        resolve(from, to, Plane::XY, cw, form, 1, TOL.0, TOL.1).unwrap()
    }

    #[test]
    fn r_form_centres_and_sweeps() {
        let (a, b) = ([0.0; 3], [10.0, 0.0, 0.0]);
        let h = 75f64.sqrt();
        // CCW, R>0: centre left of the chord (+Y), 60° sweep.
        let r = res(a, b, false, CentreForm::Radius(10.0));
        assert!((r.center[0] - 5.0).abs() < 1e-12 && (r.center[1] - h).abs() < 1e-12);
        assert!((r.sweep_rad - PI / 3.0).abs() < 1e-12);
        // CW, R>0: centre right (−Y), 60°.
        let r = res(a, b, true, CentreForm::Radius(10.0));
        assert!((r.center[1] + h).abs() < 1e-12 && (r.sweep_rad - PI / 3.0).abs() < 1e-12);
        // CW, R<0: the long way, 300°, centre +Y.
        let r = res(a, b, true, CentreForm::Radius(-10.0));
        assert!((r.center[1] - h).abs() < 1e-12 && (r.sweep_rad - 5.0 * PI / 3.0).abs() < 1e-12);
        // Half circle.
        let r = res(a, b, true, CentreForm::Radius(5.0));
        assert!(r.center[1].abs() < 1e-12 && (r.sweep_rad - PI).abs() < 1e-12);
    }

    #[test]
    fn arc_length_with_helix_and_turns() {
        // quarter circle of radius 10: 5π; a full helical turn of radius 10 down 3 mm
        let q = arc_length_mm(
            [10.0, 0.0, 0.0],
            [0.0, 10.0, 0.0],
            [0.0; 3],
            Plane::XY,
            PI / 2.0,
        );
        assert!((q - 5.0 * PI).abs() < 1e-12);
        let h = arc_length_mm(
            [10.0, 0.0, 0.0],
            [10.0, 0.0, -3.0],
            [0.0; 3],
            Plane::XY,
            TAU,
        );
        assert!((h - (20.0 * PI).hypot(3.0)).abs() < 1e-12);
        // two turns in G19 (Y, Z), X the helix axis
        let t = arc_length_mm(
            [0.0, 5.0, 0.0],
            [4.0, 5.0, 0.0],
            [0.0; 3],
            Plane::YZ,
            2.0 * TAU,
        );
        assert!((t - (20.0 * PI).hypot(4.0)).abs() < 1e-12);
    }

    #[test]
    fn tolerance_rule() {
        assert_eq!(arc_tolerance_mm(1.0, 0.005, 0.001), 0.005);
        assert_eq!(arc_tolerance_mm(100.0, 0.005, 0.001), 0.1);
        assert_eq!(arc_tolerance_mm(1e6, 0.005, 0.001), ARC_TOLERANCE_CAP_MM);
    }

    #[test]
    fn extent_of_quarter_and_full_circles() {
        // CCW quarter from (10,0) to (0,10) about the origin: no axis direction strictly
        // inside, so the extent is the end points' box.
        let e = arc_extent(
            [10.0, 0.0, 0.0],
            [0.0, 10.0, 0.0],
            [0.0; 3],
            Plane::XY,
            false,
            PI / 2.0,
        );
        assert_eq!(e, [[0.0, 10.0], [0.0, 10.0], [0.0, 0.0]]);
        // CW the long way round: passes −Y, −X... 270°.
        let e = arc_extent(
            [10.0, 0.0, 0.0],
            [0.0, 10.0, 0.0],
            [0.0; 3],
            Plane::XY,
            true,
            1.5 * PI,
        );
        assert_eq!(e, [[-10.0, 10.0], [-10.0, 10.0], [0.0, 0.0]]);
        // Full helical circle in G18 (Z, X): all four, Y linear.
        let e = arc_extent(
            [5.0, 0.0, 0.0],
            [5.0, -2.0, 0.0],
            [0.0; 3],
            Plane::ZX,
            true,
            TAU,
        );
        assert_eq!(e, [[-5.0, 5.0], [-2.0, 0.0], [-5.0, 5.0]]);
    }
}
