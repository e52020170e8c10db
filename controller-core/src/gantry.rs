//! The complete 3-axis control step: tracking error, contour error and cross-coupling,
//! then one law per axis. This is exactly what the firmware's control interrupt runs every
//! period and what host-sim runs against the plant models.

use crate::contour::{cross_couple, Coupled, DirectionSource};
use crate::law::{AxisLaw, AxisSignals, LawState};
use crate::params::{non_negative, ConfigError, LawConfig};
use crate::trajectory::RefSample;
use crate::{Real, Vec3};

/// Configuration of the 3-axis controller.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct GantryConfig {
    /// Law per axis (x, y, z).
    pub laws: [LawConfig; 3],
    /// Cross-coupling gain λ (0 disables cross-coupling).
    pub lambda: f32,
    #[cfg_attr(feature = "serde", serde(default))]
    pub direction: DirectionSource,
    /// Directions with `|d|²` at or below this are treated as undefined.
    #[cfg_attr(feature = "serde", serde(default = "default_min_dir"))]
    pub min_direction_norm_sq: f32,
}

/// `|d|²` threshold below which a path direction counts as zero.
pub const DEFAULT_MIN_DIRECTION_NORM_SQ: f32 = 1e-12;

#[cfg(feature = "serde")]
fn default_min_dir() -> f32 {
    DEFAULT_MIN_DIRECTION_NORM_SQ
}

impl GantryConfig {
    /// The same law on all three axes, paper cross-coupling defaults otherwise.
    pub const fn uniform(law: LawConfig, lambda: f32) -> Self {
        Self {
            laws: [law, law, law],
            lambda,
            direction: DirectionSource::Tangent,
            min_direction_norm_sq: DEFAULT_MIN_DIRECTION_NORM_SQ,
        }
    }
}

/// Measured axis positions and velocities (velocities from an estimator on hardware).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measured<R> {
    pub pos: Vec3<R>,
    pub vel: Vec3<R>,
}

/// Result of one evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GantryOutput<R> {
    /// Saturated per-axis control outputs.
    pub u: Vec3<R>,
    /// Sliding variables (0 for PID axes).
    pub s: Vec3<R>,
    /// Rates of the laws' integral states.
    pub integral_rate: Vec3<R>,
    /// Tracking, contour and coupled errors.
    pub errors: Coupled<R>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gantry3<R> {
    laws: [AxisLaw<R>; 3],
    lambda: R,
    direction: DirectionSource,
    min_dir_sq: R,
    state: [LawState<R>; 3],
    prev_ref: Option<Vec3<R>>,
}

impl<R: Real> Gantry3<R> {
    pub fn new(cfg: &GantryConfig) -> Result<Self, ConfigError> {
        Ok(Self {
            laws: [
                AxisLaw::new(&cfg.laws[0])?,
                AxisLaw::new(&cfg.laws[1])?,
                AxisLaw::new(&cfg.laws[2])?,
            ],
            lambda: R::from_f32(non_negative(cfg.lambda, "lambda")?),
            direction: cfg.direction,
            min_dir_sq: R::from_f32(non_negative(
                cfg.min_direction_norm_sq,
                "min_direction_norm_sq",
            )?),
            state: [LawState::default(); 3],
            prev_ref: None,
        })
    }

    /// Pure evaluation for given law states and path direction `dir` (the continuous
    /// mode passes the analytic tangent; [`Self::step`] chooses per configuration).
    pub fn evaluate(
        &self,
        states: &[LawState<R>; 3],
        reference: &RefSample<R>,
        meas: &Measured<R>,
        dir: Vec3<R>,
    ) -> GantryOutput<R> {
        let tracking = reference.pos - meas.pos;
        let tracking_rate = reference.vel - meas.vel;
        let errors = cross_couple(
            tracking,
            tracking_rate,
            dir,
            reference.vel,
            self.lambda,
            self.min_dir_sq,
        );
        let mut out = GantryOutput {
            errors,
            ..Default::default()
        };
        for (i, (law, st)) in self.laws.iter().zip(states).enumerate() {
            let sig = AxisSignals {
                e: errors.c[i],
                e_dot: errors.c_dot[i],
                qd_dot: reference.vel[i],
                qd_ddot: reference.acc[i],
                q: meas.pos[i],
                q_dot: meas.vel[i],
            };
            let o = law.evaluate(st, &sig);
            out.u[i] = o.u;
            out.s[i] = o.s;
            out.integral_rate[i] = o.integral_rate;
        }
        out
    }

    /// One sample period: evaluate, then integrate the law states over `dt`.
    pub fn step(&mut self, reference: &RefSample<R>, meas: &Measured<R>, dt: R) -> GantryOutput<R> {
        let dir = match (self.direction, self.prev_ref) {
            (DirectionSource::Chord, Some(prev)) => reference.pos - prev,
            _ => reference.vel,
        };
        self.prev_ref = Some(reference.pos);
        let out = self.evaluate(&self.state, reference, meas, dir);
        for i in 0..3 {
            let st = &mut self.state[i];
            st.integral += out.integral_rate[i] * dt;
            self.laws[i].clamp_state(st);
        }
        out
    }

    pub fn states(&self) -> &[LawState<R>; 3] {
        &self.state
    }

    /// Set the law states (continuous mode integrates them alongside the plant); each
    /// is clamped to its law's integral limit.
    pub fn set_states(&mut self, states: [LawState<R>; 3]) {
        self.state = states;
        for i in 0..3 {
            self.laws[i].clamp_state(&mut self.state[i]);
        }
    }

    /// Forget integral states and the previous reference point (e.g. after a fault).
    pub fn reset(&mut self) {
        self.state = [LawState::default(); 3];
        self.prev_ref = None;
    }

    pub fn laws(&self) -> &[AxisLaw<R>; 3] {
        &self.laws
    }
}
