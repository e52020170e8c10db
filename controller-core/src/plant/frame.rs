//! The mechanics between an axis' motor and its tool: a compliant mode, backlash and the
//! ball screw's lead error. A real gantry is not the rigid mass of [`super::physical`]:
//! its beam and column bend at a few tens of Hz, its nut has play, and its screw's lead
//! deviates from nominal along the travel. The encoder on the motor sees none of it; the
//! tool, where the contour is judged, sees all of it.
//!
//! A two-mass model per axis (units as [`super::physical`]: mm, s, mN·m, inertia in
//! mN·m/(mm/s²)): the axis' inertia `J` splits into a motor side `J_m = (1 - ρ) J` (rotor,
//! screw: the encoder's position `x_m`, the motor's torque, the screw's friction) and a
//! tool side `J_t = ρ J` (carriage, beam, tool: position `x_t`, the load). The screw
//! drives the nut to `p = x_m + e(x_m)`, `e` the lead error; the nut drives the tool
//! through a spring `k` and damper `c` across a backlash gap `g`:
//!
//! ```text
//! d   = p - x_t                                   (deflection)
//! F   = k · dz(d, g/2) + c · (x_m' - x_t') · [|d| > g/2]   (dz: the dead zone)
//! J_m x_m'' = sat(u) - (1 - φ) f(x_m') - F
//! J_t x_t'' = F - φ f(x_t') - T_load(t)
//! ```
//!
//! `f` is the axis' friction (`B v + F_c(v)`, [`super::physical`]); a share `φ` of it is
//! the linear guides' and acts on the tool side, the rest the screw's and the nut's on
//! the motor side. At constant speed both sides move together and the total is the
//! rigid axis' friction; at a reversal the guides' share is what the spring carries
//! while the nut crosses the backlash gap.
//!
//! The mode is given as it is measured: `mode_hz` is the resonance of the effort-to-encoder
//! response (the two masses swinging against each other, `ω_r² = k (1/J_m + 1/J_t)`), so
//! `k = ω_r² J_m J_t / J` and `c = 2 ζ ω_r J_m J_t / J`. The lead error is a ball screw's
//! (ISO 3408-3): a cumulative deviation growing linearly over the travel and a periodic
//! one (e.g. once per revolution or per 300 mm). Only the simulated world integrates the
//! frame (`crate::sim::world`); the laws and the identification see the rigid model.

use crate::config::{finite, non_negative, positive, ConfigError};
use crate::plant::state::AxisState;

/// The lead error of a ball screw: `e(x) = cumulative · x + periodic · sin(2π x / period)`.
/// The default is none.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PitchErrorConfig {
    /// Cumulative lead deviation, µm per m of travel (ISO 3408-3's `e_p` slope).
    #[cfg_attr(feature = "serde", serde(default))]
    pub cumulative_um_per_m: f32,
    /// Amplitude of the periodic deviation, µm.
    #[cfg_attr(feature = "serde", serde(default))]
    pub periodic_um: f32,
    /// Period of the periodic deviation, mm (e.g. the lead, or 300 mm).
    #[cfg_attr(feature = "serde", serde(default = "default_period"))]
    pub period_mm: f32,
}

impl Default for PitchErrorConfig {
    fn default() -> Self {
        Self {
            cumulative_um_per_m: 0.0,
            periodic_um: 0.0,
            period_mm: DEFAULT_PITCH_PERIOD_MM,
        }
    }
}

#[cfg(feature = "serde")]
fn default_period() -> f32 {
    DEFAULT_PITCH_PERIOD_MM
}

#[cfg(feature = "serde")]
fn default_tool_friction() -> f32 {
    DEFAULT_TOOL_FRICTION_RATIO
}

/// The guides' share of an axis' friction when a machine file gives none: 0.3. On a
/// preloaded ball-screw axis the nut and the screw's bearings make most of the
/// drag; a pair of preloaded profile-rail guides is a few N against the nut's tens
/// (manufacturers' catalogues: a preloaded nut's drag torque is 0.05-0.3 N·m, a carriage
/// block's seal and preload friction a few N).
pub const DEFAULT_TOOL_FRICTION_RATIO: f32 = 0.3;

/// Period of the periodic lead error when a machine file gives none: 300 mm, the window
/// ISO 3408-3 states the variation over.
pub const DEFAULT_PITCH_PERIOD_MM: f32 = 300.0;

/// The compliant frame of one axis (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct FrameConfig {
    /// Resonance of the effort-to-encoder response, Hz.
    pub mode_hz: f32,
    /// Damping ratio of the mode, 0..1.
    pub damping_ratio: f32,
    /// The tool side's share of the axis' inertia, `J_t / J`, in (0, 1).
    pub tool_inertia_ratio: f32,
    /// The share of the axis' friction on the tool side (the linear guides'), 0..1.
    #[cfg_attr(feature = "serde", serde(default = "default_tool_friction"))]
    pub tool_friction_ratio: f32,
    /// Backlash (the nut's play), mm.
    #[cfg_attr(feature = "serde", serde(default))]
    pub backlash_mm: f32,
    /// The screw's lead error.
    #[cfg_attr(feature = "serde", serde(default))]
    pub pitch_error: PitchErrorConfig,
}

/// Highest `ω_r h` (mode frequency times the plant's RK4 step) the world integrates: RK4
/// is accurate to well under 0.1 % of the mode's period per step there (its stability
/// limit is 2.8).
pub const MAX_MODE_OMEGA_STEP: f64 = 0.5;

/// A validated frame (f64: only the simulated world integrates it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The tool side's share of the friction.
    tool_friction: f64,
    inv_j_motor: f64,
    inv_j_tool: f64,
    /// Spring, mN·m/mm.
    k: f64,
    /// Damper, mN·m/(mm/s).
    c: f64,
    half_gap_mm: f64,
    cumulative_per_mm: f64,
    periodic_mm: f64,
    /// `2π / period`, 1/mm.
    wavenumber: f64,
    omega: f64,
}

impl Frame {
    /// The frame of an axis of inertia `inertia` (mN·m/(mm/s²)).
    pub fn new(c: &FrameConfig, inertia: f32) -> Result<Self, ConfigError> {
        let j = f64::from(positive(inertia, "inertia")?);
        let f_hz = f64::from(positive(c.mode_hz, "frame.mode_hz")?);
        let zeta = f64::from(non_negative(c.damping_ratio, "frame.damping_ratio")?);
        if zeta > 1.0 {
            return Err(ConfigError::OutOfRange("frame.damping_ratio (0..1)"));
        }
        let rho = f64::from(positive(c.tool_inertia_ratio, "frame.tool_inertia_ratio")?);
        if rho >= 1.0 {
            return Err(ConfigError::OutOfRange(
                "frame.tool_inertia_ratio (0 < ratio < 1)",
            ));
        }
        let phi = f64::from(non_negative(
            c.tool_friction_ratio,
            "frame.tool_friction_ratio",
        )?);
        if phi > 1.0 {
            return Err(ConfigError::OutOfRange("frame.tool_friction_ratio (0..1)"));
        }
        let gap = f64::from(non_negative(c.backlash_mm, "frame.backlash_mm")?);
        if gap > 1.0 {
            return Err(ConfigError::OutOfRange("frame.backlash_mm (0..1 mm)"));
        }
        let p = &c.pitch_error;
        let cumulative = f64::from(finite(
            p.cumulative_um_per_m,
            "frame.pitch_error.cumulative_um_per_m",
        )?);
        let periodic = f64::from(finite(p.periodic_um, "frame.pitch_error.periodic_um")?);
        let period = f64::from(positive(p.period_mm, "frame.pitch_error.period_mm")?);
        if cumulative.abs() > 1000.0 || periodic.abs() > 1000.0 {
            return Err(ConfigError::OutOfRange(
                "frame.pitch_error (at most 1000 µm/m and 1000 µm)",
            ));
        }
        let (jm, jt) = ((1.0 - rho) * j, rho * j);
        let omega = 2.0 * core::f64::consts::PI * f_hz;
        let mu = jm * jt / j;
        Ok(Self {
            tool_friction: phi,
            inv_j_motor: 1.0 / jm,
            inv_j_tool: 1.0 / jt,
            k: omega * omega * mu,
            c: 2.0 * zeta * omega * mu,
            half_gap_mm: 0.5 * gap,
            cumulative_per_mm: cumulative * 1e-6,
            periodic_mm: periodic * 1e-3,
            wavenumber: 2.0 * core::f64::consts::PI / period,
            omega,
        })
    }

    /// The tool side's share of the axis' friction.
    pub fn tool_friction(&self) -> f64 {
        self.tool_friction
    }

    /// The mode's angular frequency, rad/s.
    pub fn omega(&self) -> f64 {
        self.omega
    }

    /// `1 / J_m`.
    pub fn inv_j_motor(&self) -> f64 {
        self.inv_j_motor
    }

    /// `1 / J_t`.
    pub fn inv_j_tool(&self) -> f64 {
        self.inv_j_tool
    }

    /// The lead error at motor position `x_mm`, mm.
    pub fn lead_error_mm(&self, x_mm: f64) -> f64 {
        self.cumulative_per_mm * x_mm + self.periodic_mm * libm::sin(self.wavenumber * x_mm)
    }

    /// The force the nut puts on the tool side (mN·m): the spring across the backlash gap,
    /// the damper while in contact.
    pub fn coupling(&self, motor: AxisState<f64>, tool: AxisState<f64>) -> f64 {
        let d = motor.pos + self.lead_error_mm(motor.pos) - tool.pos;
        let excess = libm::fabs(d) - self.half_gap_mm;
        if excess <= 0.0 {
            return 0.0;
        }
        self.k * libm::copysign(excess, d) + self.c * (motor.vel - tool.vel)
    }

    /// How far a constant load `load_mnm` (gravity on a vertical axis) deflects the tool
    /// behind the nut at rest, mm: the spring carries it, and it presses the nut against
    /// one flank of the gap.
    pub fn load_deflection_mm(&self, load_mnm: f64) -> f64 {
        if load_mnm == 0.0 {
            0.0
        } else {
            load_mnm / self.k + libm::copysign(self.half_gap_mm, load_mnm)
        }
    }

    /// Where the tool rests with the motor at `motor_mm` under the constant load
    /// `load_mnm`.
    pub fn tool_at_rest(&self, motor_mm: f64, load_mnm: f64) -> f64 {
        motor_mm + self.lead_error_mm(motor_mm) - self.load_deflection_mm(load_mnm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> FrameConfig {
        FrameConfig {
            mode_hz: 35.0,
            damping_ratio: 0.03,
            tool_inertia_ratio: 0.6,
            tool_friction_ratio: 0.3,
            backlash_mm: 0.02,
            pitch_error: PitchErrorConfig {
                cumulative_um_per_m: 50.0,
                periodic_um: 15.0,
                period_mm: 100.0,
            },
        }
    }

    #[test]
    fn the_spring_gives_the_measured_resonance() {
        let f = Frame::new(&cfg(), 0.18).unwrap();
        // ω_r² = k (1/J_m + 1/J_t)
        let w = libm::sqrt(f.k * (f.inv_j_motor + f.inv_j_tool));
        assert!(
            (w / (2.0 * core::f64::consts::PI) - 35.0).abs() < 1e-9,
            "{w}"
        );
    }

    #[test]
    fn backlash_is_a_dead_zone_and_the_lead_error_shifts_the_nut() {
        let f = Frame::new(&cfg(), 0.18).unwrap();
        let at = |pos| AxisState { pos, vel: 0.0 };
        // within the gap: no force
        assert_eq!(f.coupling(at(0.0), at(0.009)), 0.0);
        assert_eq!(f.coupling(at(0.0), at(-0.009)), 0.0);
        // beyond it: the spring over the excess only
        let push = f.coupling(at(0.0), at(-0.015));
        assert!((push - f.k * 0.005).abs() < 1e-9 * f.k, "{push}");
        // 25 mm along: 50 µm/m · 25 mm + 15 µm · sin(π/2)
        let e = f.lead_error_mm(25.0);
        assert!((e - (1.25e-3 + 15e-3)).abs() < 1e-12, "{e}");
        // at rest under a load the tool sits a deflection and half the gap behind the nut
        let t = f.tool_at_rest(25.0, 23.0);
        assert!((25.0 + e - t - (23.0 / f.k + 0.01)).abs() < 1e-9);
        let force = f.coupling(at(25.0), at(t));
        assert!((force - 23.0).abs() < 1e-9, "{force}");
    }

    #[test]
    fn rejects_what_is_not_a_frame() {
        let bad = |c: FrameConfig| Frame::new(&c, 0.18).unwrap_err();
        let c = cfg();
        assert_eq!(
            bad(FrameConfig { mode_hz: 0.0, ..c }),
            ConfigError::NotPositive("frame.mode_hz")
        );
        assert!(matches!(
            bad(FrameConfig {
                tool_inertia_ratio: 1.0,
                ..c
            }),
            ConfigError::OutOfRange(_)
        ));
        assert!(matches!(
            bad(FrameConfig {
                damping_ratio: 1.5,
                ..c
            }),
            ConfigError::OutOfRange(_)
        ));
        assert!(matches!(
            bad(FrameConfig {
                backlash_mm: f32::NAN,
                ..c
            }),
            ConfigError::NotFinite(_) | ConfigError::Negative(_) | ConfigError::OutOfRange(_)
        ));
        let mut p = c;
        p.pitch_error.period_mm = 0.0;
        assert_eq!(
            bad(p),
            ConfigError::NotPositive("frame.pitch_error.period_mm")
        );
    }
}
