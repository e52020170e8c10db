//! The seed methods' multi-axis controller: one law per axis (PID/SMC/DSMC from
//! [`crate::law`], DOB-SMC or adaptive SMC), plus the optional variable-gain
//! cross-coupling of the patent, whose correction is added to the axis inputs.
//!
//! Unlike [`crate::gantry::Gantry3`] (the paper's error-coupling, one integral per law),
//! these laws carry extra state (observer, parameter estimates) that must be advanced
//! with the torque actually applied after the coupling correction and the saturation;
//! this module does exactly that ordering: evaluate all laws, add the correction,
//! saturate, then update every state with the applied input.

use crate::adaptive_smc::{AdaptiveSmc, AdaptiveSmcConfig, AdaptiveState};
use crate::dob_smc::{DobSmc, DobSmcConfig, DobState};
use crate::gantry::Measured;
use crate::law::{integrate, AxisLaw, AxisSignals, LawState};
use crate::params::{limit, ConfigError, LawConfig};
use crate::trajectory::RefSample;
use crate::variable_gain_ccc::{CccConfig, CccState, VariableGainCcc};
use crate::{Real, Vec3};

/// Law of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum SeedLawConfig {
    /// PID / SMC / DSMC of [`crate::law`].
    Base(LawConfig),
    DobSmc(DobSmcConfig),
    Adaptive(AdaptiveSmcConfig),
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SeedLaw<R> {
    Base(AxisLaw<R>),
    DobSmc(DobSmc<R>),
    Adaptive(AdaptiveSmc<R>),
}

/// Every kind of law state; a law uses only its own part.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SeedLawState<R> {
    pub base: LawState<R>,
    pub dob: DobState<R>,
    pub adapt: AdaptiveState<R>,
}

/// Configuration of the controller for three axes (a 2-axis machine leaves Z at rest).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SeedControllerConfig {
    pub laws: [SeedLawConfig; 3],
    /// Variable-gain cross-coupling (None = independent axes).
    pub ccc: Option<CccConfig>,
    /// Limit on each axis' total input (law + correction), the amplifier's range.
    pub u_max: [f32; 3],
}

/// One period's result.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SeedOutput<R> {
    /// Applied (saturated) inputs.
    pub u: Vec3<R>,
    /// Sliding variables (0 for PID).
    pub s: Vec3<R>,
    /// Cross-coupling correction before saturation (0 without coupling).
    pub correction: Vec3<R>,
    /// Contour error estimate of the coupling (0 without coupling).
    pub contour_estimate: Vec3<R>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeedController<R> {
    laws: [SeedLaw<R>; 3],
    ccc: Option<VariableGainCcc<R>>,
    u_max: Vec3<R>,
    states: [SeedLawState<R>; 3],
    ccc_state: CccState<R>,
}

impl<R: Real> SeedController<R> {
    pub fn new(cfg: &SeedControllerConfig) -> Result<Self, ConfigError> {
        let law = |c: &SeedLawConfig| -> Result<SeedLaw<R>, ConfigError> {
            Ok(match c {
                SeedLawConfig::Base(b) => SeedLaw::Base(AxisLaw::new(b)?),
                SeedLawConfig::DobSmc(d) => SeedLaw::DobSmc(DobSmc::new(d)?),
                SeedLawConfig::Adaptive(a) => SeedLaw::Adaptive(AdaptiveSmc::new(a)?),
            })
        };
        let laws = [law(&cfg.laws[0])?, law(&cfg.laws[1])?, law(&cfg.laws[2])?];
        let ccc = match &cfg.ccc {
            Some(c) => Some(VariableGainCcc::new(c)?),
            None => None,
        };
        let mut u_max = Vec3::zero();
        for i in 0..3 {
            u_max[i] = R::from_f32(limit(cfg.u_max[i], "u_max")?);
        }
        let mut ctl = Self {
            laws,
            ccc,
            u_max,
            states: [SeedLawState::default(); 3],
            ccc_state: CccState::default(),
        };
        ctl.reset();
        Ok(ctl)
    }

    /// Initial states: zero integrals and observers, configured initial estimates.
    pub fn reset(&mut self) {
        for (st, law) in self.states.iter_mut().zip(&self.laws) {
            *st = SeedLawState::default();
            if let SeedLaw::Adaptive(a) = law {
                st.adapt = a.initial_state();
            }
        }
        self.ccc_state = CccState::default();
    }

    /// One sample period of length `dt`.
    pub fn step(&mut self, reference: &RefSample<R>, meas: &Measured<R>, dt: R) -> SeedOutput<R> {
        let tracking = reference.pos - meas.pos;
        let tracking_rate = reference.vel - meas.vel;
        let mut out = SeedOutput::default();
        let mut adapt_out = [None; 3];
        let mut integral_rate = [R::ZERO; 3];
        let mut u_law = Vec3::zero();
        for i in 0..3 {
            let sig = AxisSignals {
                e: tracking[i],
                e_dot: tracking_rate[i],
                qd_dot: reference.vel[i],
                qd_ddot: reference.acc[i],
                q: meas.pos[i],
                q_dot: meas.vel[i],
            };
            let st = &self.states[i];
            let o = match &self.laws[i] {
                SeedLaw::Base(l) => {
                    let o = l.evaluate(&st.base, &sig);
                    integral_rate[i] = o.integral_rate;
                    o
                }
                SeedLaw::DobSmc(l) => l.evaluate(&st.dob, &sig),
                SeedLaw::Adaptive(l) => {
                    let o = l.evaluate(&st.adapt, &sig);
                    adapt_out[i] = Some(o);
                    o.law
                }
            };
            u_law[i] = o.u;
            out.s[i] = o.s;
        }
        if let Some(ccc) = &self.ccc {
            let c = ccc.evaluate(&self.ccc_state, tracking, tracking_rate, reference.vel);
            ccc.integrate(&mut self.ccc_state, &c, dt);
            out.correction = c.correction;
            out.contour_estimate = c.contour;
        }
        for i in 0..3 {
            out.u[i] = (u_law[i] + out.correction[i])
                .finite_or_zero()
                .clamp_sym(self.u_max[i]);
            let st = &mut self.states[i];
            match &self.laws[i] {
                SeedLaw::Base(l) => {
                    integrate(&mut st.base, integral_rate[i], dt, R::from_f32(f32::MAX));
                    l.clamp_state(&mut st.base);
                }
                SeedLaw::DobSmc(l) => l.observe(&mut st.dob, out.u[i], meas.vel[i], dt),
                SeedLaw::Adaptive(l) => {
                    if let Some(o) = &adapt_out[i] {
                        l.adapt(&mut st.adapt, o, dt);
                    }
                }
            }
        }
        out
    }

    pub fn states(&self) -> &[SeedLawState<R>; 3] {
        &self.states
    }

    pub fn laws(&self) -> &[SeedLaw<R>; 3] {
        &self.laws
    }
}
