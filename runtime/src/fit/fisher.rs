//! The Fisher matrix at an optimum (central differences of the analytic
//! gradient) and its inverse, the covariance.

use nalgebra::{DMatrix, SymmetricEigen};
use std::fmt;

/// Finite-difference steps for [`fisher_matrix`] at `x`: a tenth of the
/// conditional standard deviation `1/sqrt(F_ii)` estimated from a first,
/// small central difference of the gradient (relative step 1e-6 of
/// `max(|x_i|, 1e-3 · width_i)`, or 1e-6 if both vanish).
pub fn fisher_steps<G, E>(mut grad: G, x: &[f64], bounds: &[Option<(f64, f64)>]) -> Result<Vec<f64>, E>
where
    G: FnMut(&[f64]) -> Result<Vec<f64>, E>,
{
    let mut steps = Vec::with_capacity(x.len());
    for i in 0..x.len() {
        let width = bounds[i].map(|(lo, hi)| hi - lo).filter(|w| w.is_finite()).unwrap_or(0.0);
        let mut h0 = 1e-6 * x[i].abs().max(1e-3 * width);
        if h0 == 0.0 {
            h0 = 1e-6;
        }
        let col = column(&mut grad, x, bounds, i, h0)?;
        let c = col.0[i];
        let h = if c.is_finite() && c > 0.0 { 0.1 / c.sqrt() } else { h0 };
        steps.push(h);
    }
    Ok(steps)
}

/// Column `i` of the Hessian by differences of the gradient, with the step
/// actually used: central when `x ± h` fits within the bounds, one-sided
/// when only one side does, and central with the step shrunk to half the
/// distance to the nearer bound otherwise.
fn column<G, E>(grad: &mut G, x: &[f64], bounds: &[Option<(f64, f64)>], i: usize, h: f64) -> Result<(Vec<f64>, f64), E>
where
    G: FnMut(&[f64]) -> Result<Vec<f64>, E>,
{
    let (lo, hi) = bounds[i].unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    // At most half the width, so that one side always fits.
    let h = h.min(0.5 * (hi - lo));
    let fits = |v: f64| v >= lo && v <= hi;
    let at = |grad: &mut G, v: f64| {
        let mut p = x.to_vec();
        p[i] = v;
        grad(&p)
    };
    let (a, b, h_used) = if fits(x[i] + h) && fits(x[i] - h) {
        (x[i] + h, x[i] - h, h)
    } else if fits(x[i] - h) {
        (x[i], x[i] - h, h / 2.0)
    } else if fits(x[i] + h) {
        (x[i] + h, x[i], h / 2.0)
    } else {
        let h = 0.5 * (hi - x[i]).min(x[i] - lo).max(0.0);
        (x[i] + h, x[i] - h, h)
    };
    let ga = at(grad, a)?;
    let gb = at(grad, b)?;
    let col = ga.iter().zip(&gb).map(|(p, m)| (p - m) / (a - b)).collect();
    Ok((col, h_used))
}

/// The Hessian of a loss at `x` by central differences of its gradient
/// `grad` with per-param `steps` (see [`fisher_steps`]), symmetrised.
/// Everything is in the units `x` and `grad` use.
pub fn fisher_matrix<G, E>(mut grad: G, x: &[f64], bounds: &[Option<(f64, f64)>], steps: &[f64]) -> Result<Vec<Vec<f64>>, E>
where
    G: FnMut(&[f64]) -> Result<Vec<f64>, E>,
{
    let n = x.len();
    let mut cols = Vec::with_capacity(n);
    for (i, h) in steps.iter().enumerate() {
        cols.push(column(&mut grad, x, bounds, i, *h)?.0);
    }
    Ok((0..n).map(|i| (0..n).map(|j| 0.5 * (cols[j][i] + cols[i][j])).collect()).collect())
}

/// Uncertainties from an invertible Fisher matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Covariance {
    /// `F⁻¹`.
    pub covariance: Vec<Vec<f64>>,
    /// `σ_i = sqrt((F⁻¹)_ii)`.
    pub sigma: Vec<f64>,
    /// `C_ij = (F⁻¹)_ij / (σ_i σ_j)`.
    pub correlation: Vec<Vec<f64>>,
    /// Condition number of the correlation-scaled Fisher matrix.
    pub condition: f64,
}

/// Why a Fisher matrix gives no uncertainties.
#[derive(Clone, Debug, PartialEq)]
pub enum FisherError {
    /// An entry is NaN or infinite.
    NotFinite,
    /// Not positive definite (or singular to working precision): the point
    /// is not a strict local minimum, or some params are not constrained.
    NotPositiveDefinite {
        /// Eigenvalues of the (symmetrised) matrix, ascending.
        eigenvalues: Vec<f64>,
    },
}

impl fmt::Display for FisherError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FisherError::NotFinite => write!(f, "the Fisher matrix has non-finite entries"),
            FisherError::NotPositiveDefinite { eigenvalues } => write!(
                f,
                "the Fisher matrix is not positive definite (eigenvalues {eigenvalues:?}): the fit is not at a strict minimum, \
                 or some params are not constrained by the data; no uncertainties"
            ),
        }
    }
}

/// Inverts a symmetric Fisher matrix. To be robust to params of very
/// different scales it factors the correlation form `D F D`, `D =
/// diag(F_ii^(-1/2))`, by Cholesky (which exists exactly when `F` is
/// positive definite), and rejects condition numbers beyond 1e14.
pub fn invert_fisher(f: &[Vec<f64>]) -> Result<Covariance, FisherError> {
    let n = f.len();
    if f.iter().flatten().any(|v| !v.is_finite()) {
        return Err(FisherError::NotFinite);
    }
    let m = DMatrix::from_fn(n, n, |i, j| 0.5 * (f[i][j] + f[j][i]));
    let not_pd = || {
        let mut eigenvalues: Vec<f64> = SymmetricEigen::new(m.clone()).eigenvalues.iter().copied().collect();
        eigenvalues.sort_by(f64::total_cmp);
        FisherError::NotPositiveDefinite { eigenvalues }
    };
    if (0..n).any(|i| m[(i, i)] <= 0.0) {
        return Err(not_pd());
    }
    let d: Vec<f64> = (0..n).map(|i| 1.0 / m[(i, i)].sqrt()).collect();
    let c = DMatrix::from_fn(n, n, |i, j| m[(i, j)] * d[i] * d[j]);
    let eig = SymmetricEigen::new(c.clone()).eigenvalues;
    let (emin, emax) = eig.iter().fold((f64::INFINITY, 0.0f64), |(a, b), e| (a.min(*e), b.max(*e)));
    let condition = emax / emin;
    if emin <= 0.0 || condition.is_nan() || condition >= 1e14 {
        return Err(not_pd());
    }
    let chol = c.cholesky().ok_or_else(not_pd)?;
    let ci = chol.inverse();
    let covariance: Vec<Vec<f64>> = (0..n).map(|i| (0..n).map(|j| ci[(i, j)] * d[i] * d[j]).collect()).collect();
    let sigma: Vec<f64> = (0..n).map(|i| covariance[i][i].sqrt()).collect();
    let correlation = (0..n).map(|i| (0..n).map(|j| covariance[i][j] / (sigma[i] * sigma[j])).collect()).collect();
    Ok(Covariance { covariance, sigma, correlation, condition })
}
