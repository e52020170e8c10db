//! Planner configuration: machine limits per axis, path tolerance, control period. Validated
//! once into [`ValidPlannerConfig`], the runtime value both halves (planner and executor) use.

/// Machine limits and planning parameters. Units in the names; every value is checked by
/// [`ValidPlannerConfig::new`].
use super::fmath::F32Ext;

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PlannerConfig {
    /// Control period: one reference sample per period (s).
    pub period_s: f32,
    /// Per-axis velocity limit (mm/s); also the speed of rapid moves.
    pub vel_max_mm_s: [f32; 3],
    /// Per-axis acceleration limit (mm/s²).
    pub acc_max_mm_s2: [f32; 3],
    /// Per-axis jerk limit (mm/s³).
    pub jerk_max_mm_s3: [f32; 3],
    /// Path tolerance ε used by `Blend::Default` (G64 without P): the commanded path stays
    /// within this distance of the programmed one (mm).
    pub tolerance_mm: f32,
    /// Share of each axis' acceleration and jerk kept for speeding up and slowing down
    /// along curved spans; the rest bounds the centripetal terms and so the corner speed
    /// (0 < share < 1). LinuxCNC keeps half on arcs.
    pub tangential_share: f32,
    /// Share of each axis' jerk limit the planner leaves to the servo along the path: the
    /// path's own jerk on a span (σ⃛) is at most `1 − servo_reserve` of the axis limits
    /// projected on it, never below the floor every span keeps (0 ≤ reserve < 1; 0 = the
    /// full limits). The servo's tracking error grows with the reference's acceleration
    /// steps: docs/planner.md gives the measured trade-off.
    pub servo_reserve: f32,
    /// Largest allowed difference of an arc's start and end radius (mm); grbl rejects
    /// beyond 0.005 mm (error 33).
    pub arc_radius_tolerance_mm: f32,
    /// Lines shorter than this are skipped and arcs with a smaller radius rejected (mm).
    pub min_segment_mm: f32,
}

/// Limits for the gantry: 10 kHz loop; 250 mm/s (3000 rpm on a 5 mm lead); 2000 mm/s²
/// (a fifth of what the 1 N·m peak torque gives the X inertia, presets::gantry); 1e5 mm/s³
/// (acceleration reached in 20 ms, a usual ball-screw value); ε = 0.01 mm (grbl's junction
/// deviation default); half the limits for the path on curves (LinuxCNC's arc rule); three
/// quarters of the jerk kept for the servo along the path (the simulated gantry's contour
/// error at exact stops and blends then stays where it was with a quarter of the jerk
/// everywhere: docs/planner.md).
pub const GANTRY_PLANNER: PlannerConfig = PlannerConfig {
    period_s: 1.0e-4,
    vel_max_mm_s: [250.0, 250.0, 250.0],
    acc_max_mm_s2: [2000.0, 2000.0, 2000.0],
    jerk_max_mm_s3: [1.0e5, 1.0e5, 1.0e5],
    tolerance_mm: 0.01,
    tangential_share: 0.5,
    servo_reserve: 0.75,
    arc_radius_tolerance_mm: 0.005,
    min_segment_mm: 1.0e-3,
};

/// Invalid configuration value; the name says which field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlannerConfigError {
    /// Must be finite.
    NotFinite(&'static str),
    /// Must be > 0.
    NotPositive(&'static str),
    /// Outside the documented range.
    OutOfRange(&'static str),
}

/// Validated configuration plus derived values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidPlannerConfig {
    pub period_s: f32,
    pub vel_max: [f32; 3],
    pub acc_max: [f32; 3],
    pub jerk_max: [f32; 3],
    pub tolerance_mm: f32,
    pub share: f32,
    /// `1 − servo_reserve`: the share of the projected jerk the path may use.
    pub path_jerk_share: f32,
    pub arc_tol_mm: f32,
    pub min_segment_mm: f32,
    /// Lower bound of every span's path acceleration limit (mm/s²): spans reserve
    /// `share · amax / |p'|` and |p'| ≤ [`MAX_TANGENT_GAIN`].
    pub acc_floor: f32,
    /// Same for jerk (mm/s³).
    pub jerk_floor: f32,
}

/// Largest |dp/dσ| component the span limits allow for; the blends keep |p'| ≤ 1 plus the
/// spiral/helix rounding, so 2 is a wide margin.
pub const MAX_TANGENT_GAIN: f32 = 2.0;

fn positive(x: f32, name: &'static str) -> Result<f32, PlannerConfigError> {
    if !x.is_finite() {
        Err(PlannerConfigError::NotFinite(name))
    } else if !(x > 0.0) {
        Err(PlannerConfigError::NotPositive(name))
    } else {
        Ok(x)
    }
}

fn positive3(v: [f32; 3], name: &'static str) -> Result<[f32; 3], PlannerConfigError> {
    for x in v {
        positive(x, name)?;
    }
    Ok(v)
}

impl ValidPlannerConfig {
    /// No configuration (zero limits): what [`super::planner::Planner::BLANK`] holds
    /// until it is restarted with a validated one.
    pub const BLANK: Self = Self {
        period_s: 0.0,
        vel_max: [0.0; 3],
        acc_max: [0.0; 3],
        jerk_max: [0.0; 3],
        tolerance_mm: 0.0,
        share: 0.0,
        path_jerk_share: 0.0,
        arc_tol_mm: 0.0,
        min_segment_mm: 0.0,
        acc_floor: 0.0,
        jerk_floor: 0.0,
    };

    /// Shortest span the planner cuts (mm): half the shortest segment.
    pub fn min_span_mm(&self) -> f32 {
        0.5 * self.min_segment_mm
    }

    pub fn new(c: &PlannerConfig) -> Result<Self, PlannerConfigError> {
        let period_s = positive(c.period_s, "period_s")?;
        if period_s > 0.1 {
            return Err(PlannerConfigError::OutOfRange("period_s"));
        }
        let vel_max = positive3(c.vel_max_mm_s, "vel_max_mm_s")?;
        let acc_max = positive3(c.acc_max_mm_s2, "acc_max_mm_s2")?;
        let jerk_max = positive3(c.jerk_max_mm_s3, "jerk_max_mm_s3")?;
        if !c.tolerance_mm.is_finite() {
            return Err(PlannerConfigError::NotFinite("tolerance_mm"));
        }
        if !(c.tolerance_mm >= 0.0) {
            return Err(PlannerConfigError::OutOfRange("tolerance_mm"));
        }
        let share = positive(c.tangential_share, "tangential_share")?;
        if !(share < 1.0) {
            return Err(PlannerConfigError::OutOfRange("tangential_share"));
        }
        if !c.servo_reserve.is_finite() {
            return Err(PlannerConfigError::NotFinite("servo_reserve"));
        }
        if !(c.servo_reserve >= 0.0 && c.servo_reserve < 1.0) {
            return Err(PlannerConfigError::OutOfRange("servo_reserve"));
        }
        let arc_tol_mm = positive(c.arc_radius_tolerance_mm, "arc_radius_tolerance_mm")?;
        let min_segment_mm = positive(c.min_segment_mm, "min_segment_mm")?;
        if min_segment_mm > 1.0 {
            return Err(PlannerConfigError::OutOfRange("min_segment_mm"));
        }
        let amin = acc_max[0].mn(acc_max[1]).mn(acc_max[2]);
        let jmin = jerk_max[0].mn(jerk_max[1]).mn(jerk_max[2]);
        Ok(Self {
            period_s,
            vel_max,
            acc_max,
            jerk_max,
            tolerance_mm: c.tolerance_mm,
            share,
            path_jerk_share: 1.0 - c.servo_reserve,
            arc_tol_mm,
            min_segment_mm,
            acc_floor: share * amin / MAX_TANGENT_GAIN,
            jerk_floor: share * jmin / MAX_TANGENT_GAIN,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gantry_config_is_valid_and_errors_name_the_field() {
        assert!(ValidPlannerConfig::new(&GANTRY_PLANNER).is_ok());
        let mut c = GANTRY_PLANNER;
        c.acc_max_mm_s2[1] = 0.0;
        assert_eq!(
            ValidPlannerConfig::new(&c),
            Err(PlannerConfigError::NotPositive("acc_max_mm_s2"))
        );
        let mut c = GANTRY_PLANNER;
        c.jerk_max_mm_s3[2] = f32::NAN;
        assert_eq!(
            ValidPlannerConfig::new(&c),
            Err(PlannerConfigError::NotFinite("jerk_max_mm_s3"))
        );
        let mut c = GANTRY_PLANNER;
        c.tangential_share = 1.0;
        assert_eq!(
            ValidPlannerConfig::new(&c),
            Err(PlannerConfigError::OutOfRange("tangential_share"))
        );
        let mut c = GANTRY_PLANNER;
        c.servo_reserve = 1.0;
        assert_eq!(
            ValidPlannerConfig::new(&c),
            Err(PlannerConfigError::OutOfRange("servo_reserve"))
        );
        let mut c = GANTRY_PLANNER;
        c.tolerance_mm = -0.1;
        assert_eq!(
            ValidPlannerConfig::new(&c),
            Err(PlannerConfigError::OutOfRange("tolerance_mm"))
        );
    }
}
