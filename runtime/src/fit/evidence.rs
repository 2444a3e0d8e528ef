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

use super::{invert_fisher, FisherError};
use nalgebra::DMatrix;
use std::fmt;

/// The Laplace evidence of one fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Evidence {
    /// `ln Z` (up to the constant shared by models of the same data).
    pub ln_z: f64,
    /// `ln V`, the prior volume of the bounds in the params' declared units.
    pub ln_prior_volume: f64,
    /// `ln det F`.
    pub ln_det_fisher: f64,
    /// `ln M`, the Gaussian's log mass inside the bounds (≤ 0).
    pub ln_mass_inside: f64,
}

/// Why a fit has no Laplace evidence.
#[derive(Clone, Debug, PartialEq)]
pub enum EvidenceError {
    /// A param has no finite bounds, so its uniform prior is improper.
    Unbounded(usize),
    /// The Fisher matrix has no inverse.
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
pub fn laplace_evidence(loss: f64, x: &[f64], fisher: &[Vec<f64>], bounds: &[Option<(f64, f64)>]) -> Result<Evidence, EvidenceError> {
    let k = x.len();
    let mut ln_prior_volume = 0.0;
    for (i, b) in bounds.iter().enumerate() {
        match b {
            Some((lo, hi)) if lo.is_finite() && hi.is_finite() && hi > lo => ln_prior_volume += (hi - lo).ln(),
            _ => return Err(EvidenceError::Unbounded(i)),
        }
    }
    let cov = invert_fisher(fisher).map_err(EvidenceError::Fisher)?;
    // ln det F from the Cholesky factor of the correlation form D F D.
    let d: Vec<f64> = (0..k).map(|i| fisher[i][i].sqrt()).collect();
    let c = DMatrix::from_fn(k, k, |i, j| 0.5 * (fisher[i][j] + fisher[j][i]) / (d[i] * d[j]));
    let chol = c.cholesky().ok_or(EvidenceError::Fisher(FisherError::NotFinite))?;
    let ln_det_c: f64 = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
    let ln_det_fisher = ln_det_c + 2.0 * d.iter().map(|v| v.ln()).sum::<f64>();
    let ln_mass_inside: f64 = bounds
        .iter()
        .zip(x)
        .zip(&cov.sigma)
        .map(|((b, x), s)| {
            let (lo, hi) = b.expect("checked above");
            (normal_cdf((hi - x) / s) - normal_cdf((lo - x) / s)).max(f64::MIN_POSITIVE).ln()
        })
        .sum();
    let ln_z = -loss + 0.5 * k as f64 * (2.0 * std::f64::consts::PI).ln() - 0.5 * ln_det_fisher - ln_prior_volume + ln_mass_inside;
    Ok(Evidence { ln_z, ln_prior_volume, ln_det_fisher, ln_mass_inside })
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
    }
}
