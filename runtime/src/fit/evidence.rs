//! Model comparison: the evidence of a fit by the Laplace approximation,
//! and the Bayesian information criterion.
//!
//! With a loss `L(θ) = −ln p(d | θ) + c` (the `c` shared by every model
//! of the same data) and a uniform prior over the box of the params'
//! bounds, of volume `V`, the evidence `Z = ∫ p(d | θ) / V dθ` is, around
//! the best fit `θ̂` with Fisher matrix `F` (the Hessian of `L` there),
//!
//! `ln Z ≈ −L(θ̂) + (k/2) ln 2π − ½ ln det F − ln V + ln M`,
//!
//! `k` params (MacKay 2003, *Information Theory, Inference, and Learning
//! Algorithms*, §28.1). `M` is the Gaussian's mass inside the bounds,
//! taken per param from its marginal σ, `Π_i [Φ((hi − θ̂_i)/σ_i) −
//! Φ((lo − θ̂_i)/σ_i)]`, so a fit against a bound is not credited with
//! probability outside the prior. Differences of `ln Z` between models of
//! the same data are log Bayes factors; the `ln V` term is the Occam
//! penalty of wide bounds, so the bounds are part of the model and are
//! reported with it.

use super::FisherError;
use nalgebra::{DMatrix, SymmetricEigen};
use std::fmt;

/// The Laplace evidence of one fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Evidence {
    /// `ln Z` (up to the constant shared by models of the same data).
    pub ln_z: f64,
    /// `ln V`, the prior volume of the bounds in the params' declared units.
    pub ln_prior_volume: f64,
    /// `ln det F` (after clipping).
    pub ln_det_fisher: f64,
    /// `ln M`, the Gaussian's log mass inside the bounds (≤ 0).
    pub ln_mass_inside: f64,
    /// Directions of the Fisher matrix whose curvature was raised to the
    /// floor (see [`laplace_evidence`]): 0 for a well-determined fit.
    pub clipped: usize,
}

/// Why a fit has no Laplace evidence.
#[derive(Clone, Debug, PartialEq)]
pub enum EvidenceError {
    /// A param has no finite bounds, so its uniform prior is improper.
    Unbounded(usize),
    /// The Fisher matrix has non-finite entries.
    Fisher(FisherError),
}

impl fmt::Display for EvidenceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EvidenceError::Unbounded(i) => {
                write!(f, "free param {} has no finite bounds: the evidence needs a proper (bounded) prior; give it `in LO..HI`", i + 1)
            }
            EvidenceError::Fisher(e) => write!(f, "{e}"),
        }
    }
}

/// The Laplace evidence of a fit at `x` (loss `loss`, Fisher matrix
/// `fisher`, both in the params' declared units) under uniform priors on
/// `bounds`.
///
/// The Fisher matrix is taken in units of each param's prior width, where
/// a curvature of 2π makes the Gaussian's integral the whole width: a
/// direction the data do not constrain (a smaller curvature), or one
/// along which the loss still falls at a bound (a negative curvature: the
/// fit ended there), gets that floor, so it neither earns nor costs more
/// than its prior. [`Evidence::clipped`] counts such directions; the
/// approximation is rough along them, and exact for a Gaussian well
/// inside its bounds.
pub fn laplace_evidence(loss: f64, x: &[f64], fisher: &[Vec<f64>], bounds: &[Option<(f64, f64)>]) -> Result<Evidence, EvidenceError> {
    let k = x.len();
    let mut widths = Vec::with_capacity(k);
    for (i, b) in bounds.iter().enumerate() {
        match b {
            Some((lo, hi)) if lo.is_finite() && hi.is_finite() && hi > lo => widths.push(hi - lo),
            _ => return Err(EvidenceError::Unbounded(i)),
        }
    }
    let ln_prior_volume: f64 = widths.iter().map(|w| w.ln()).sum();
    if fisher.iter().flatten().any(|v| !v.is_finite()) {
        return Err(EvidenceError::Fisher(FisherError::NotFinite));
    }
    // F in prior-width units, symmetrised; eigenvalues floored at 2π.
    let scaled = DMatrix::from_fn(k, k, |i, j| 0.5 * (fisher[i][j] + fisher[j][i]) * widths[i] * widths[j]);
    let eigen = SymmetricEigen::new(scaled);
    let floor = 2.0 * std::f64::consts::PI;
    let clipped = eigen.eigenvalues.iter().filter(|l| **l < floor).count();
    let values = eigen.eigenvalues.map(|l| l.max(floor));
    let ln_det_scaled: f64 = values.iter().map(|l| l.ln()).sum();
    let ln_det_fisher = ln_det_scaled - 2.0 * widths.iter().map(|w| w.ln()).sum::<f64>();
    // Marginal σ of the clipped Gaussian, in declared units.
    let inverse = &eigen.eigenvectors * DMatrix::from_diagonal(&values.map(|l| 1.0 / l)) * eigen.eigenvectors.transpose();
    let ln_mass_inside: f64 = bounds
        .iter()
        .zip(x)
        .enumerate()
        .map(|(i, (b, x))| {
            let (lo, hi) = b.expect("checked above");
            let s = inverse[(i, i)].sqrt() * widths[i];
            (normal_cdf((hi - x) / s) - normal_cdf((lo - x) / s)).max(f64::MIN_POSITIVE).ln()
        })
        .sum();
    let ln_z = -loss + 0.5 * k as f64 * (2.0 * std::f64::consts::PI).ln() - 0.5 * ln_det_fisher - ln_prior_volume + ln_mass_inside;
    Ok(Evidence { ln_z, ln_prior_volume, ln_det_fisher, ln_mass_inside, clipped })
}

/// The Bayesian information criterion `2 L + k ln n` of a fit with loss
/// `loss` (a negative log-likelihood), `k` params and `n` data points
/// (Schwarz 1978): lower is better.
pub fn bic(loss: f64, k: usize, n: usize) -> f64 {
    2.0 * loss + k as f64 * (n as f64).ln()
}

/// How well one fitted model explains the data: what `gwml compare` and
/// `gwml explain` rank by.
#[derive(Clone, Debug, PartialEq)]
pub struct Score {
    /// The loss at the best fit.
    pub loss: f64,
    /// Free params.
    pub params: usize,
    /// The Laplace evidence (or why there is none).
    pub evidence: Result<Evidence, EvidenceError>,
    /// [`bic`] with `n` data points.
    pub bic: f64,
}

/// Scores a [`super::SceneFit`] of data with `n` points.
pub fn score_fit(fit: &super::SceneFit, n: usize) -> Score {
    let bounds: Vec<Option<(f64, f64)>> = fit.free.iter().map(|p| p.bounds).collect();
    let k = fit.free.len();
    Score {
        loss: fit.minimum.loss,
        params: k,
        evidence: laplace_evidence(fit.minimum.loss, &fit.minimum.x, &fit.fisher, &bounds),
        bic: bic(fit.minimum.loss, k, n),
    }
}

/// The standard normal CDF, `½ erfc(−z/√2)`.
fn normal_cdf(z: f64) -> f64 {
    0.5 * statrs::function::erf::erfc(-z / std::f64::consts::SQRT_2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gaussian_inside_its_bounds_has_the_closed_form_evidence() {
        // L = ½ xᵀ F x − 3 over a 10 × 20 box centred on 0: Z = e³ 2π / √det F / 200.
        let f = vec![vec![4.0, 1.0], vec![1.0, 2.0]];
        let bounds = [Some((-5.0, 5.0)), Some((-10.0, 10.0))];
        let e = laplace_evidence(-3.0, &[0.0, 0.0], &f, &bounds).unwrap();
        let want = 3.0 + (2.0 * std::f64::consts::PI).ln() - 0.5 * 7f64.ln() - 200f64.ln();
        assert!((e.ln_z - want).abs() < 1e-9, "{} vs {want}", e.ln_z);
        assert!(e.ln_mass_inside.abs() < 1e-9);
        // At a bound, half the Gaussian lies outside: ln 2 less.
        let f1 = vec![vec![100.0]];
        let inside = laplace_evidence(0.0, &[0.5], &f1, &[Some((0.0, 1.0))]).unwrap();
        let edge = laplace_evidence(0.0, &[0.0], &f1, &[Some((0.0, 1.0))]).unwrap();
        assert!((inside.ln_z - edge.ln_z - 2f64.ln()).abs() < 1e-6);
        assert_eq!(laplace_evidence(0.0, &[0.0], &f1, &[None]), Err(EvidenceError::Unbounded(0)));
        assert_eq!(inside.clipped, 0);
    }

    #[test]
    fn an_unconstrained_direction_costs_nothing_beyond_its_prior() {
        // A param the loss does not depend on: Z is the constrained part's
        // evidence times (width / width) = 1, whatever its width.
        let constrained = laplace_evidence(1.0, &[0.0], &[vec![50.0]], &[Some((-1.0, 1.0))]).unwrap();
        for width in [0.1, 10.0] {
            let f = vec![vec![50.0, 0.0], vec![0.0, 0.0]];
            let e = laplace_evidence(1.0, &[0.0, 0.0], &f, &[Some((-1.0, 1.0)), Some((-width / 2.0, width / 2.0))]).unwrap();
            assert_eq!(e.clipped, 1);
            // Less only the floored Gaussian's mass outside the prior: its
            // σ is width / √(2π), so ±1.25σ lie inside (ln 0.79 = −0.24).
            assert!((e.ln_z - constrained.ln_z + 0.237).abs() < 0.01, "{} vs {}", e.ln_z, constrained.ln_z);
        }
        // A negative curvature (a fit against a bound) is floored too, not an error.
        let f = vec![vec![50.0, 0.0], vec![0.0, -3.0]];
        let e = laplace_evidence(1.0, &[0.0, 1.0], &f, &[Some((-1.0, 1.0)), Some((0.0, 1.0))]).unwrap();
        assert_eq!(e.clipped, 1);
        assert!(e.ln_z.is_finite() && e.ln_z < constrained.ln_z);
    }
}
