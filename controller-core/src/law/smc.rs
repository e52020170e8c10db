//! Sliding-mode position laws for the normalised axis (spec 2.2, 2.3).
//!
//! One implementation covers the paper's "SMC" (terminal surface + exponential reaching
//! law) and "DSMC" (terminal surface + double-power reaching law + integral compensation
//! `k4 ∫e dt`); the nonsingular terminal surface is a configuration option of the same law.
//! With plant `θ'' = -a θ' - b θ + k u` and `e = q_d - q`, forcing `s' = -reach(s)` gives
//!
//! ```text
//! terminal:     u = (1/k) [q_d'' + a q' + b q + α e' + β (q/p) |e|^(q/p-1) e' + reach + k4 ∫e]
//! nonsingular:  u = (1/k) [q_d'' + a q' + b q + (β/γ) sig(e')^(2-γ)           + reach + k4 ∫e]
//! ```

use super::signals::{finish, AxisSignals, LawOutput};
use super::state::LawState;
use crate::config::{limit, non_negative, positive, ConfigError};
use crate::num::shared_root::{root_powers, PowerSet};
use crate::plant::PlantParams;
use crate::{Exponent, Real};

/// Sliding surface (spec 2.2/2.3).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(rename_all = "snake_case", deny_unknown_fields)
)]
pub enum SurfaceConfig {
    /// `s = e' + α e + β sig(e)^(q/p)`, p, q odd, 0 < q < p. The `|e|^(q/p-1)` factor of the
    /// equivalent control is evaluated with `|e|` floored at `singular_floor`, which bounds
    /// it by `β (q/p) singular_floor^(q/p-1) |e'|`.
    Terminal {
        alpha: f32,
        beta: f32,
        p: i16,
        q: i16,
        singular_floor: f32,
    },
    /// Nonsingular terminal surface (Feng, Yu, Man 2002): `s = e + (1/β) sig(e')^(p/q)`,
    /// p, q odd, 1 < p/q < 2. Its equivalent control has only the positive power
    /// `sig(e')^(2-p/q)`, so nothing needs a floor.
    Nonsingular { beta: f32, p: i16, q: i16 },
}

/// Reaching law (spec 2.2/2.3).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(rename_all = "snake_case", deny_unknown_fields)
)]
pub enum ReachingConfig {
    /// `s' = -k s - ε sign(s)`; with `boundary_layer > 0`, `sign(s)` is replaced by
    /// `sat(s / boundary_layer)` (0 = the paper's pure sign).
    Exponential {
        k: f32,
        epsilon: f32,
        #[cfg_attr(feature = "serde", serde(default))]
        boundary_layer: f32,
    },
    /// `s' = -k1 sig(s)^(2-β2) - k2 sig(s)^β2 - k3 |e|^β3 s`, 0 < β2 < 1, β3 > 0.
    DoublePower {
        k1: f32,
        k2: f32,
        k3: f32,
        beta2: Exponent,
        beta3: Exponent,
    },
}

/// A sliding-mode law: surface, reaching law, optional integral compensation `k4 ∫e dt`
/// (spec 2.3). SMC is `k4 = 0` with the exponential law; DSMC the double-power law with
/// `k4 > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct SmcConfig {
    /// The model the equivalent control cancels.
    pub plant: PlantParams,
    pub surface: SurfaceConfig,
    pub reaching: ReachingConfig,
    #[cfg_attr(feature = "serde", serde(default))]
    pub k4: f32,
    #[cfg_attr(feature = "serde", serde(default = "crate::config::inf"))]
    pub integral_limit: f32,
    #[cfg_attr(feature = "serde", serde(default = "crate::config::inf"))]
    pub u_max: f32,
}

/// Floor on `|e|` in the singular factor `|e|^(q/p-1)`: 1e-4 plant units (0.1 µm when
/// the unit is mm). The factor `(5/9) |e|^(-4/9)` is then at most 33.
pub const DEFAULT_SINGULAR_FLOOR: f32 = 1e-4;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Surface<R> {
    /// `e_powers` = [q/p, β3] (β3 of the double-power law, else q/p again).
    Terminal {
        alpha: R,
        beta: R,
        e_powers: PowerSet<2>,
        qp_minus_one: Exponent,
        beta_qp: R,
        floor: R,
    },
    /// `e_dot_powers` = [γ, 2 - γ].
    Nonsingular {
        inv_beta: R,
        e_dot_powers: PowerSet<2>,
        beta_over_gamma: R,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Reaching<R> {
    /// `inv_phi == 0` selects the pure `sign(s)`.
    Exponential { k: R, epsilon: R, inv_phi: R },
    /// `s_powers` = [β1, β2]; `|e|^β3` comes from the surface's shared root when the
    /// surface is terminal.
    DoublePower {
        k1: R,
        k2: R,
        k3: R,
        s_powers: PowerSet<2>,
        beta3: Exponent,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Smc<R> {
    a: R,
    b: R,
    inv_k: R,
    surface: Surface<R>,
    reaching: Reaching<R>,
    k4: R,
    pub(crate) integral_limit: R,
    u_max: R,
}

fn odd_pair(p: i16, q: i16, name: &'static str) -> Result<Exponent, ConfigError> {
    if p <= 0 || q <= 0 || p % 2 == 0 || q % 2 == 0 {
        return Err(ConfigError::BadExponent(name));
    }
    Exponent::new(q, p).ok_or(ConfigError::BadExponent(name))
}

fn unit_interval(e: Exponent, name: &'static str) -> Result<Exponent, ConfigError> {
    if e.num > 0 && e.num < e.den {
        Ok(e)
    } else {
        Err(ConfigError::BadExponent(name))
    }
}

impl<R: Real> Smc<R> {
    pub fn new(c: &SmcConfig) -> Result<Self, ConfigError> {
        let f = R::from_f32;
        let beta3_cfg = match c.reaching {
            ReachingConfig::DoublePower { beta3, .. } => Some(beta3),
            ReachingConfig::Exponential { .. } => None,
        };
        let surface = match c.surface {
            SurfaceConfig::Terminal {
                alpha,
                beta,
                p,
                q,
                singular_floor,
            } => {
                let qp = unit_interval(odd_pair(p, q, "q/p")?, "q/p")?;
                Surface::Terminal {
                    alpha: f(positive(alpha, "alpha")?),
                    beta: f(positive(beta, "beta")?),
                    e_powers: PowerSet::new([qp, beta3_cfg.unwrap_or(qp)]),
                    qp_minus_one: qp.minus_one(),
                    beta_qp: f(beta) * R::from_f64(qp.as_f64()),
                    floor: f(positive(singular_floor, "singular_floor")?),
                }
            }
            SurfaceConfig::Nonsingular { beta, p, q } => {
                // γ = p/q must lie in (1, 2)
                let gamma = odd_pair(q, p, "p/q")?;
                if !(gamma.num > gamma.den && gamma.num < 2 * gamma.den) {
                    return Err(ConfigError::BadExponent("p/q"));
                }
                let beta = positive(beta, "beta")?;
                Surface::Nonsingular {
                    inv_beta: R::from_f64(1.0 / beta as f64),
                    e_dot_powers: PowerSet::new([gamma, gamma.two_minus()]),
                    beta_over_gamma: R::from_f64(beta as f64 / gamma.as_f64()),
                }
            }
        };
        let reaching = match c.reaching {
            ReachingConfig::Exponential {
                k,
                epsilon,
                boundary_layer,
            } => Reaching::Exponential {
                k: f(positive(k, "k")?),
                epsilon: f(non_negative(epsilon, "epsilon")?),
                inv_phi: if non_negative(boundary_layer, "boundary_layer")? > 0.0 {
                    f(1.0 / boundary_layer)
                } else {
                    R::ZERO
                },
            },
            ReachingConfig::DoublePower {
                k1,
                k2,
                k3,
                beta2,
                beta3,
            } => {
                let beta2 = unit_interval(beta2, "beta2")?;
                if beta3.num <= 0 || Exponent::new(beta3.num, beta3.den).is_none() {
                    return Err(ConfigError::BadExponent("beta3"));
                }
                Reaching::DoublePower {
                    k1: f(positive(k1, "k1")?),
                    k2: f(positive(k2, "k2")?),
                    k3: f(positive(k3, "k3")?),
                    s_powers: PowerSet::new([beta2.two_minus(), beta2]),
                    beta3,
                }
            }
        };
        Ok(Self {
            a: f(non_negative(c.plant.a, "plant.a")?),
            b: f(non_negative(c.plant.b, "plant.b")?),
            inv_k: R::from_f64(1.0 / positive(c.plant.k, "plant.k")? as f64),
            surface,
            reaching,
            k4: f(non_negative(c.k4, "k4")?),
            integral_limit: f(limit(c.integral_limit, "integral_limit")?),
            u_max: f(limit(c.u_max, "u_max")?),
        })
    }

    pub fn evaluate(&self, st: &LawState<R>, sig: &AxisSignals<R>) -> LawOutput<R> {
        self.evaluate_with(st.integral, sig, &OwnPowers)
    }

    /// True when the law's powers are those of the paper's DSMC ([`PaperDsmcPowers`]): a
    /// terminal surface with q/p = 5/9 and the double-power reaching law with
    /// β2 = β3 = 1/3.
    pub(crate) fn has_paper_dsmc_powers(&self) -> bool {
        let e_ok = matches!(self.surface, Surface::Terminal { e_powers, .. }
            if e_powers == PowerSet::new(PAPER_DSMC_E_POWERS));
        let s_ok = matches!(self.reaching, Reaching::DoublePower { s_powers, .. }
            if s_powers == PowerSet::new(PAPER_DSMC_S_POWERS));
        e_ok && s_ok
    }

    /// The law with its integral state `integral`, the powers formed by `powers` (the
    /// law's own plans, or a plan fixed at compile time that the caller has checked is
    /// the law's): the one definition of the law, whichever way its powers are formed.
    #[inline(always)]
    pub(crate) fn evaluate_with<P: SmcPowers>(
        &self,
        integral: R,
        sig: &AxisSignals<R>,
        powers: &P,
    ) -> LawOutput<R> {
        let (e, e_dot) = (sig.e, sig.e_dot);
        let (s, u_surface, e_beta3) = match self.surface {
            Surface::Terminal {
                alpha,
                beta,
                e_powers,
                qp_minus_one,
                beta_qp,
                floor,
            } => {
                let [e_qp, e_b3] = powers.e_powers(&e_powers, e);
                let abs_e = e.abs();
                // |e|^(q/p-1) = |e|^(q/p) / |e| above the floor (no second root); the
                // floored value below it keeps the factor bounded.
                let singular = if abs_e >= floor {
                    e_qp.div_or(abs_e, R::ZERO)
                } else {
                    e.pow_abs(qp_minus_one, floor)
                };
                (
                    // sig(e)^(q/p): e_qp is 0 where e is, so the sign flip is sign(e)·e_qp
                    e_dot + alpha * e + beta * e_qp.with_sign_of(e),
                    alpha * e_dot + beta_qp * singular * e_dot,
                    Some(e_b3),
                )
            }
            Surface::Nonsingular {
                inv_beta,
                e_dot_powers,
                beta_over_gamma,
            } => {
                let [g, two_minus_g] = e_dot_powers.eval(e_dot);
                (
                    e + inv_beta * g.with_sign_of(e_dot),
                    beta_over_gamma * two_minus_g.with_sign_of(e_dot),
                    None,
                )
            }
        };
        let reach = match self.reaching {
            Reaching::Exponential {
                k,
                epsilon,
                inv_phi,
            } => {
                let switch = if inv_phi == R::ZERO {
                    s.sign()
                } else {
                    (s * inv_phi).clamp_sym(R::ONE)
                };
                k * s + epsilon * switch
            }
            Reaching::DoublePower {
                k1,
                k2,
                k3,
                s_powers,
                beta3,
            } => {
                let [s_b1, s_b2] = powers.s_powers(&s_powers, s);
                let e_b3 = e_beta3.unwrap_or_else(|| e.pow_abs(beta3, R::ZERO));
                (k1 * s_b1 + k2 * s_b2).with_sign_of(s) + k3 * e_b3 * s
            }
        };
        let u = self.inv_k
            * (sig.qd_ddot
                + self.a * sig.q_dot
                + self.b * sig.q
                + u_surface
                + reach
                + self.k4 * integral);
        finish(u, e, self.u_max, s)
    }

    /// The integral limit (the state [`Self::evaluate_with`] integrates).
    #[inline(always)]
    pub(crate) fn integral_limit(&self) -> R {
        self.integral_limit
    }
}

/// Exponents of the terminal surface's shared root in the paper's DSMC: `|e|^(q/p)` with
/// q/p = 5/9 and `|e|^β3` with β3 = 1/3 (both integer powers of `|e|^(1/9)`).
const PAPER_DSMC_E_POWERS: [Exponent; 2] =
    [Exponent { num: 5, den: 9 }, Exponent { num: 1, den: 3 }];
/// Exponents of the reaching law's shared root in the paper's DSMC: `|s|^(2-β2)` and
/// `|s|^β2` with β2 = 1/3 (integer powers of `|s|^(1/3)`).
const PAPER_DSMC_S_POWERS: [Exponent; 2] =
    [Exponent { num: 5, den: 3 }, Exponent { num: 1, den: 3 }];

/// How [`Smc::evaluate_with`] forms the law's fractional powers from their shared roots.
pub(crate) trait SmcPowers {
    /// `[|e|^(q/p), |e|^β3]` of a terminal surface; `set` is the law's own plan of them.
    fn e_powers<R: Real>(&self, set: &PowerSet<2>, e: R) -> [R; 2];
    /// `[|s|^(2-β2), |s|^β2]` of the double-power reaching law; `set` is the law's plan.
    fn s_powers<R: Real>(&self, set: &PowerSet<2>, s: R) -> [R; 2];
}

/// The law's own power plans, whatever its exponents (resolved at run time).
pub(crate) struct OwnPowers;

impl SmcPowers for OwnPowers {
    #[inline(always)]
    fn e_powers<R: Real>(&self, set: &PowerSet<2>, e: R) -> [R; 2] {
        set.eval(e)
    }
    #[inline(always)]
    fn s_powers<R: Real>(&self, set: &PowerSet<2>, s: R) -> [R; 2] {
        set.eval(s)
    }
}

/// The paper's DSMC exponents with their plan fixed at compile time: one ninth root `r`
/// of `|e|` gives `|e|^(5/9) = r⁵` and `|e|^(1/3) = r³`, one cube root `c` of `|s|` gives
/// `|s|^(5/3) = c⁵` and `|s|^(1/3) = c`, the same operations as the law's own plan for
/// these exponents ([`PowerSet`]), so the results are identical, without the plan's
/// run-time dispatch. Only for laws whose [`Smc::has_paper_dsmc_powers`] holds.
pub(crate) struct PaperDsmcPowers;

impl SmcPowers for PaperDsmcPowers {
    #[inline(always)]
    fn e_powers<R: Real>(&self, _: &PowerSet<2>, e: R) -> [R; 2] {
        root_powers::<R, 9, 5, 3>(e)
    }
    #[inline(always)]
    fn s_powers<R: Real>(&self, _: &PowerSet<2>, s: R) -> [R; 2] {
        root_powers::<R, 3, 5, 1>(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::presets::paper::{PAPER_DSMC, PAPER_SMC};

    fn sig(e: f64, e_dot: f64) -> AxisSignals<f64> {
        AxisSignals {
            e,
            e_dot,
            ..Default::default()
        }
    }

    #[test]
    fn dsmc_matches_hand_computation() {
        let l = Smc::<f64>::new(&PAPER_DSMC).unwrap();
        let (e, ed) = (0.1f64, 0.2f64);
        let s = ed + 10.0 * e + libm::pow(e, 5.0 / 9.0);
        let ueq = 10.0 * ed + (5.0 / 9.0) * libm::pow(e, -4.0 / 9.0) * ed;
        let reach = 20.0 * libm::pow(s, 5.0 / 3.0)
            + 20.0 * libm::pow(s, 1.0 / 3.0)
            + 200.0 * libm::pow(e, 1.0 / 3.0) * s;
        let st = LawState {
            integral: 0.5,
            ..Default::default()
        };
        let out = l.evaluate(&st, &sig(e, ed));
        assert!((out.s - s).abs() < 1e-12);
        assert!(
            (out.u - (ueq + reach + 20.0 * 0.5)).abs() < 1e-9,
            "{}",
            out.u
        );
    }

    #[test]
    fn singular_term_is_bounded_at_zero_error() {
        let l = Smc::<f32>::new(&PAPER_SMC).unwrap();
        let out = l.evaluate(&LawState::default(), &sig(0.0, 1.0).into_f32());
        // α e' + (5/9) (1e-4)^(-4/9) e' + k s + ε = 10 + 33.3 + 200 + 33
        assert!((out.u - 276.3).abs() < 0.5, "{}", out.u);
    }

    #[test]
    fn nonsingular_option_validates_exponent() {
        let mut c = PAPER_DSMC;
        c.surface = SurfaceConfig::Nonsingular {
            beta: 10.0,
            p: 5,
            q: 3,
        };
        assert!(Smc::<f32>::new(&c).is_ok());
        c.surface = SurfaceConfig::Nonsingular {
            beta: 10.0,
            p: 7,
            q: 3,
        };
        assert_eq!(Smc::<f32>::new(&c), Err(ConfigError::BadExponent("p/q")));
        c.surface = SurfaceConfig::Terminal {
            alpha: 1.0,
            beta: 1.0,
            p: 4,
            q: 3,
            singular_floor: 1e-4,
        };
        assert_eq!(Smc::<f32>::new(&c), Err(ConfigError::BadExponent("q/p")));
    }

    #[test]
    fn paper_dsmc_plan_is_recognised() {
        use crate::presets::gantry::{dsmc_for, GANTRY_X};
        assert!(Smc::<f32>::new(&PAPER_DSMC)
            .unwrap()
            .has_paper_dsmc_powers());
        assert!(Smc::<f32>::new(&dsmc_for(&GANTRY_X))
            .unwrap()
            .has_paper_dsmc_powers());
        // the exponential reaching law has no reaching powers; other exponents differ
        assert!(!Smc::<f32>::new(&PAPER_SMC).unwrap().has_paper_dsmc_powers());
        let mut c = PAPER_DSMC;
        if let ReachingConfig::DoublePower { beta2, .. } = &mut c.reaching {
            *beta2 = Exponent { num: 1, den: 9 };
        }
        assert!(!Smc::<f32>::new(&c).unwrap().has_paper_dsmc_powers());
    }

    proptest::proptest! {
        /// The compile-time plan of the paper's powers gives the law's own plan's result,
        /// bit for bit, in f32 and in fixed point.
        #[test]
        fn paper_plan_is_bit_identical_to_the_own_plan(
            e in -2.0f32..2.0, e_dot in -50.0f32..50.0, integral in -1.0f32..1.0,
            q in -100.0f32..100.0, q_dot in -50.0f32..50.0, acc in -10.0f32..10.0,
            tiny in 0usize..4,
        ) {
            use crate::num::fixed::FxQ32;
            use crate::presets::gantry::{dsmc_for, GANTRY_Y};
            // errors at and around zero and the singular floor as well
            let e = [e, 0.0, 1.0e-5 * e, -1.0e-4][tiny];
            let sig = AxisSignals { e, e_dot, qd_dot: q_dot, qd_ddot: acc, q, q_dot };
            for cfg in [PAPER_DSMC, dsmc_for(&GANTRY_Y)] {
                let l = Smc::<f32>::new(&cfg).unwrap();
                let a = l.evaluate_with(integral, &sig, &PaperDsmcPowers);
                let b = l.evaluate_with(integral, &sig, &OwnPowers);
                proptest::prop_assert_eq!(a.u.to_bits(), b.u.to_bits());
                proptest::prop_assert_eq!(a.s.to_bits(), b.s.to_bits());
                proptest::prop_assert_eq!(a, l.evaluate(&LawState { integral, ..Default::default() }, &sig));
                let f = |x: f32| FxQ32::from_f32(x);
                let lx = Smc::<FxQ32>::new(&cfg).unwrap();
                let sx = AxisSignals {
                    e: f(e), e_dot: f(e_dot), qd_dot: f(q_dot), qd_ddot: f(acc), q: f(q), q_dot: f(q_dot),
                };
                proptest::prop_assert_eq!(
                    lx.evaluate_with(f(integral), &sx, &PaperDsmcPowers),
                    lx.evaluate_with(f(integral), &sx, &OwnPowers)
                );
            }
        }
    }

    trait IntoF32 {
        fn into_f32(self) -> AxisSignals<f32>;
    }
    impl IntoF32 for AxisSignals<f64> {
        fn into_f32(self) -> AxisSignals<f32> {
            AxisSignals {
                e: self.e as f32,
                e_dot: self.e_dot as f32,
                ..Default::default()
            }
        }
    }
}
