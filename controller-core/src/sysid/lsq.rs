//! Weighted linear least squares for a fixed, small number of parameters, accumulated
//! row by row as normal equations (no storage of the rows) and solved once per phase.
//!
//! Rows arrive rarely (one per integration window, every few tens of milliseconds). Both
//! the accumulation and the solve run in `f32`, the Cortex-M4's hardware type. Measured
//! on the emulated M4 (`cargo insns` with a temporary kernel): adding a row costs ~160
//! instructions, the parameters of a 4×4 system ([`NormalEquations::solve_params`]) a
//! few hundred, the full solve with residual and standard errors about a thousand; in
//! `f64` (software floating point on the M4) the same solve would cost ~20k cycles, more
//! than a 100 µs control period. `f32` is accurate enough because the systems are small
//! and the pivot test below rejects the ill-conditioned ones: a relative pivot above
//! [`MIN_PIVOT`] keeps at least three significant digits, far below the percent-level
//! accuracy identification aims at.
//!
//! The solve factors the matrix as `L D Lᵀ` (unit lower `L`, diagonal `D`): no square
//! roots, which matters on the Cortex-M4, where `libm::sqrtf` is a software routine of
//! ~150 instructions (libm has no ARM32 hardware path and the crate forbids the `unsafe`
//! an inline `vsqrt` would need). Each pivot is judged relative to its diagonal entry,
//! `D_i / A_ii`: the fraction of the column's energy not explained by the previous
//! columns, independent of the columns' units (it equals the pivot of the Cholesky factor
//! of the matrix equilibrated to a unit diagonal). Below [`MIN_PIVOT`] the system is
//! rejected as ill-conditioned: a column is (nearly) a combination of others, e.g. no
//! acceleration in the data for the inertia, or one direction never travelled for a
//! Coulomb term.

// Index loops over the fixed dimension N read like the textbook algorithm; every index
// is bounded by N, so none can fail.
#![allow(clippy::needless_range_loop)]

/// Smallest accepted relative pivot `D_i / A_ii`: the fraction of a column's energy not
/// explained by the previous columns. Below 1e-4 the f32 solution loses four of its
/// seven digits to cancellation and the parameter is not determined by the data.
pub const MIN_PIVOT: f32 = 1e-4;

/// Normal equations `Σ w x xᵀ θ = Σ w x y` of `N` parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalEquations<const N: usize> {
    /// `Σ w x xᵀ` (full symmetric storage; N is 4 at most here).
    xtx: [[f32; N]; N],
    /// `Σ w x y`.
    xty: [f32; N],
    /// `Σ w y²`, for the residual without storing rows.
    yty: f32,
    /// `Σ w`.
    w_sum: f32,
    rows: u32,
}

impl<const N: usize> Default for NormalEquations<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// A solution and its quality figures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LsSolution<const N: usize> {
    pub theta: [f32; N],
    /// One-sigma standard error of each parameter, from the weighted residual variance
    /// and the diagonal of `(XᵀWX)⁻¹` (0 when there are no more rows than parameters).
    pub std_error: [f32; N],
    /// Weighted RMS of the row residuals (units of y).
    pub residual_rms: f32,
    /// Smallest relative pivot `D_i / A_ii`, in (0, 1]: 1 for orthogonal columns,
    /// [`MIN_PIVOT`] at the rejection limit.
    pub min_pivot: f32,
    pub rows: u32,
}

/// `A = L D Lᵀ` factorisation.
struct Factor<const N: usize> {
    /// Unit lower triangle (the diagonal is not stored).
    l: [[f32; N]; N],
    d: [f32; N],
    /// Smallest `D_i / A_ii`.
    min_pivot: f32,
}

impl<const N: usize> Factor<N> {
    /// `A u = rhs`: `L z = rhs`, `D w = z`, `Lᵀ u = w`.
    fn solve(&self, rhs: &[f32; N]) -> [f32; N] {
        let l = &self.l;
        let mut z = [0.0; N];
        for i in 0..N {
            let mut s = rhs[i];
            for k in 0..i {
                s -= l[i][k] * z[k];
            }
            z[i] = s;
        }
        for i in 0..N {
            z[i] /= self.d[i];
        }
        let mut u = [0.0; N];
        for i in (0..N).rev() {
            let mut s = z[i];
            for k in i + 1..N {
                s -= l[k][i] * u[k];
            }
            u[i] = s;
        }
        u
    }
}

/// Why a solve failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LsError {
    /// Fewer rows than parameters.
    TooFewRows,
    /// Parameter `index` has no excitation at all (zero column).
    Unexcited { index: usize },
    /// Parameter `index` is (nearly) a combination of the previous ones.
    IllConditioned { index: usize },
    /// Rows or solution were not finite.
    NotFinite,
}

impl<const N: usize> NormalEquations<N> {
    pub const fn new() -> Self {
        Self {
            xtx: [[0.0; N]; N],
            xty: [0.0; N],
            yty: 0.0,
            w_sum: 0.0,
            rows: 0,
        }
    }

    /// Add row `x θ ≈ y` with weight `w` (> 0). Non-finite rows and weights are ignored
    /// and reported with `false`, so that one bad window cannot poison the whole fit.
    pub fn add_row(&mut self, x: &[f32; N], y: f32, w: f32) -> bool {
        if !(w > 0.0) || !w.is_finite() || !y.is_finite() || x.iter().any(|v| !v.is_finite()) {
            return false;
        }
        for (i, xi) in x.iter().enumerate() {
            for (j, xj) in x.iter().enumerate() {
                self.xtx[i][j] += w * xi * xj;
            }
            self.xty[i] += w * xi * y;
        }
        self.yty += w * y * y;
        self.w_sum += w;
        self.rows = self.rows.saturating_add(1);
        true
    }

    pub fn rows(&self) -> u32 {
        self.rows
    }

    /// `L D Lᵀ` with the relative pivot test (module docs).
    fn factor(&self) -> Result<Factor<N>, LsError> {
        if (self.rows as usize) < N {
            return Err(LsError::TooFewRows);
        }
        let a = &self.xtx;
        for (i, row) in a.iter().enumerate() {
            if !row[i].is_finite() {
                return Err(LsError::NotFinite);
            }
            if !(row[i] > 0.0) {
                return Err(LsError::Unexcited { index: i });
            }
        }
        let mut l = [[0.0; N]; N];
        let mut d = [0.0; N];
        let mut min_pivot = 1.0_f32;
        for i in 0..N {
            for j in 0..i {
                let mut s = a[i][j];
                for k in 0..j {
                    s -= l[i][k] * d[k] * l[j][k];
                }
                l[i][j] = s / d[j];
            }
            let mut s = a[i][i];
            for k in 0..i {
                s -= l[i][k] * l[i][k] * d[k];
            }
            let pivot = s / a[i][i];
            if !(pivot > MIN_PIVOT) {
                return Err(LsError::IllConditioned { index: i });
            }
            min_pivot = min_pivot.min(pivot);
            d[i] = s;
        }
        Ok(Factor { l, d, min_pivot })
    }

    /// The parameters and the smallest relative pivot, without residual and standard
    /// errors (which need square roots): for fits whose quality figures are not
    /// reported.
    pub fn solve_params(&self) -> Result<([f32; N], f32), LsError> {
        let f = self.factor()?;
        let theta = f.solve(&self.xty);
        if theta.iter().any(|v| !v.is_finite()) {
            return Err(LsError::NotFinite);
        }
        Ok((theta, f.min_pivot))
    }

    /// Solve (module docs), with the quality figures.
    pub fn solve(&self) -> Result<LsSolution<N>, LsError> {
        let f = self.factor()?;
        let min_pivot = f.min_pivot;
        let theta = f.solve(&self.xty);
        // weighted residual sum: yᵀy - 2 θᵀ Xᵀy + θᵀ XᵀX θ (clamped: rounding can make it
        // slightly negative for a perfect fit)
        let mut quad = 0.0;
        let mut lin = 0.0;
        for i in 0..N {
            lin += theta[i] * self.xty[i];
            for j in 0..N {
                quad += theta[i] * self.xtx[i][j] * theta[j];
            }
        }
        let ssr = (self.yty - 2.0 * lin + quad).max(0.0);
        let residual_rms = if self.w_sum > 0.0 {
            libm::sqrtf(ssr / self.w_sum)
        } else {
            0.0
        };
        // residual variance per unit weight, with N degrees of freedom removed; the
        // weights are durations normalised so a typical row has weight ~1
        let dof = (self.rows as usize).saturating_sub(N);
        let sigma2 = if dof > 0 { ssr / dof as f32 } else { 0.0 };
        let mut std_error = [0.0; N];
        for i in 0..N {
            let mut e = [0.0; N];
            e[i] = 1.0;
            // (A⁻¹)_ii
            let col = f.solve(&e);
            std_error[i] = libm::sqrtf((col[i] * sigma2).max(0.0));
        }
        if theta.iter().chain(&std_error).any(|v| !v.is_finite()) || !residual_rms.is_finite() {
            return Err(LsError::NotFinite);
        }
        Ok(LsSolution {
            theta,
            std_error,
            residual_rms,
            min_pivot,
            rows: self.rows,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_fit_recovers_parameters() {
        let truth = [0.1, 0.5, 40.0, -30.0];
        let mut ne = NormalEquations::<4>::new();
        let rows = [
            [0.0, 20.0, 1.0, 0.0],
            [0.0, -20.0, 0.0, 1.0],
            [0.0, 100.0, 1.0, 0.0],
            [0.0, -100.0, 0.0, 1.0],
            [2000.0, 60.0, 1.0, 0.0],
            [-2000.0, 60.0, 1.0, 0.0],
        ];
        for x in &rows {
            let y: f32 = x.iter().zip(&truth).map(|(a, b)| a * b).sum();
            assert!(ne.add_row(x, y, 1.0));
        }
        let s = ne.solve().unwrap();
        for (t, e) in truth.iter().zip(&s.theta) {
            assert!((t - e).abs() < 1e-4 * t.abs().max(1.0), "{t} vs {e}");
        }
        assert!(s.residual_rms < 1e-2, "{}", s.residual_rms);
        assert!(s.min_pivot > 1e-3 && s.min_pivot <= 1.0);
    }

    #[test]
    fn unexcited_and_collinear_columns_are_rejected() {
        let mut ne = NormalEquations::<2>::new();
        ne.add_row(&[1.0, 0.0], 1.0, 1.0);
        ne.add_row(&[2.0, 0.0], 2.0, 1.0);
        assert_eq!(ne.solve(), Err(LsError::Unexcited { index: 1 }));
        let mut ne = NormalEquations::<2>::new();
        ne.add_row(&[1.0, 2.0], 1.0, 1.0);
        ne.add_row(&[2.0, 4.0], 2.0, 1.0);
        assert_eq!(ne.solve(), Err(LsError::IllConditioned { index: 1 }));
        let ne = NormalEquations::<2>::new();
        assert_eq!(ne.solve(), Err(LsError::TooFewRows));
    }

    #[test]
    fn non_finite_rows_are_ignored() {
        let mut ne = NormalEquations::<1>::new();
        assert!(!ne.add_row(&[f32::NAN], 1.0, 1.0));
        assert!(!ne.add_row(&[1.0], f32::INFINITY, 1.0));
        assert!(!ne.add_row(&[1.0], 1.0, 0.0));
        assert_eq!(ne.rows(), 0);
        assert!(ne.add_row(&[2.0], 4.0, 1.0));
        assert!(ne.add_row(&[1.0], 2.5, 1.0));
        let s = ne.solve().unwrap();
        // θ = (2·4 + 2.5)/(4 + 1) = 2.1, residuals -0.2 and 0.4
        assert!((s.theta[0] - 2.1).abs() < 1e-6);
        let rms = libm::sqrtf((0.04 + 0.16) / 2.0);
        assert!((s.residual_rms - rms).abs() < 1e-5);
    }
}
