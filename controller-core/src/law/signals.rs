//! What every law shares: the signals of one axis it sees ([`AxisSignals`]), the output of
//! a PID or sliding-mode evaluation ([`LawOutput`]), and the saturation, anti-windup and
//! integration steps they all finish with.

use crate::Real;

/// Signals one axis law sees in one evaluation. `e = q_d - q` (paper convention); with
/// cross-coupling, `e` and `e_dot` are the coupled errors `C_i`, `C_i'`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisSignals<R> {
    pub e: R,
    pub e_dot: R,
    pub qd_dot: R,
    pub qd_ddot: R,
    pub q: R,
    pub q_dot: R,
}

/// One evaluation of a PID or sliding-mode law.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawOutput<R> {
    /// Saturated control output.
    pub u: R,
    /// `d/dt` of [`LawState::integral`](super::state::LawState::integral) (0 while anti-windup holds the integrator).
    pub integral_rate: R,
    /// Sliding variable (0 for PID), for telemetry and plots.
    pub s: R,
    /// False when the law's raw output was not finite (then replaced by 0): a fault the
    /// servo step reports instead of letting the replacement hide it.
    pub finite: bool,
}

/// Saturation and conditional integration shared by PID and the sliding-mode laws: the
/// output is clamped to `±u_max`, and the error is not integrated while the output is
/// saturated in the direction the error would push it further.
#[inline(always)]
pub(crate) fn finish<R: Real>(u_raw: R, e: R, u_max: R, s: R) -> LawOutput<R> {
    // The common case: `u_raw` finite and not saturated, `e` and `s` finite (one range
    // test covers all three, see `zero_if_finite`); the result is what the general path
    // below gives.
    if (u_raw + (zero_if_finite(e) + zero_if_finite(s))).in_range(u_max) {
        return LawOutput {
            u: u_raw,
            integral_rate: e,
            s,
            finite: true,
        };
    }
    let finite = u_raw.is_finite();
    let u_raw = u_raw.finite_or_zero();
    let u = u_raw.clamp_sym(u_max);
    let saturated = u != u_raw;
    let winds_up = saturated && (e * u_raw > R::ZERO);
    LawOutput {
        u,
        integral_rate: if winds_up {
            R::ZERO
        } else {
            e.finite_or_zero()
        },
        s: s.finite_or_zero(),
        finite,
    }
}

/// `x - x`: zero for a finite `x`, NaN for ±inf and NaN (in fixed point always zero), so
/// adding it to a value makes that value fail a finiteness or range test exactly when `x`
/// is not finite: several tests in one.
#[allow(clippy::eq_op)]
#[inline(always)]
fn zero_if_finite<R: Real>(x: R) -> R {
    x - x
}

/// Advance an integral by one period, clamped to `±limit`.
#[inline(always)]
pub(crate) fn integrate<R: Real>(integral: R, rate: R, dt: R, limit: R) -> R {
    (integral + rate * dt).clamp_sym(limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `finish` as it was written before its fast path (the general path alone).
    fn finish_general(u_raw: f32, e: f32, u_max: f32, s: f32) -> LawOutput<f32> {
        let finite = u_raw.is_finite();
        let u_raw = u_raw.finite_or_zero();
        let u = u_raw.max_of(-u_max).min_of(u_max);
        let saturated = u != u_raw;
        let winds_up = saturated && (e * u_raw > 0.0);
        LawOutput {
            u,
            integral_rate: if winds_up { 0.0 } else { e.finite_or_zero() },
            s: s.finite_or_zero(),
            finite,
        }
    }

    #[test]
    fn finish_fast_path_equals_the_general_path() {
        let values = [
            0.0,
            -0.0,
            1.0e-3,
            -2.5,
            99.0,
            100.0,
            100.000_01,
            -250.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut fast = 0;
        for u in values {
            for e in values {
                for s in values {
                    for u_max in [100.0, f32::INFINITY] {
                        let a = finish(u, e, u_max, s);
                        let b = finish_general(u, e, u_max, s);
                        let same = |x: f32, y: f32| x.to_bits() == y.to_bits();
                        assert!(
                            same(a.u, b.u)
                                && same(a.integral_rate, b.integral_rate)
                                && same(a.s, b.s)
                                && a.finite == b.finite,
                            "finish({u}, {e}, {u_max}, {s}): {a:?} vs {b:?}"
                        );
                        fast += usize::from(u.in_range(u_max) && e.is_finite() && s.is_finite());
                    }
                }
            }
        }
        // both paths were exercised
        assert!(fast > 100 && fast < values.len().pow(3) * 2, "{fast}");
    }
}
