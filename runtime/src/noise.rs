//! Seeded, reproducible coloured Gaussian noise in the frequency domain.
//!
//! Convention (one-sided PSD). For stationary Gaussian noise with one-sided
//! power spectral density `S(f)`, the continuous Fourier transform obeys
//! `⟨ñ(f) ñ*(f')⟩ = ½ S(|f|) δ(f − f')` (Allen, Anderson, Brady, Brown &
//! Creighton, "FINDCHIRP", PRD 85, 122006 (2012), Sec. II; the same
//! convention as Cutler & Flanagan 1994 and LALSuite). On a grid of
//! frequency bins of width `df`, `δ(0) → 1/df`, so each bin is an
//! independent complex Gaussian with `⟨|ñ_k|²⟩ = S_k / (2 df)`, shared
//! equally by its real and imaginary parts: each is `N(0, S_k / (4 df))`.
//!
//! With the noise-weighted inner product `(a|b) = 4 df Re Σ a_k b_k* / S_k`
//! (`std::detector::inner`), each bin then contributes a χ² with two
//! degrees of freedom to `(n|n)`, so `⟨(n|n)⟩ = 2 N` for `N` bins and the
//! likelihood of data `d = h + n` is `∝ exp(−½ (d − h | d − h))`.
//!
//! Randomness: `rand_pcg::Pcg64Mcg` seeded from a `u64` (via
//! `SeedableRng::seed_from_u64`) and `rand_distr::StandardNormal`. PCG's
//! output is fixed by its published algorithm, so a seed gives the same
//! noise on every platform and rand version that keeps
//! `StandardNormal`'s value stability (rand's `StdRng` makes no such
//! promise across versions).

use crate::Error;
use num_complex::Complex64 as C64;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_pcg::Pcg64Mcg;

/// The generator [`colored_noise`] uses, seeded from `seed`.
pub fn rng(seed: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed)
}

/// Frequency-domain noise for one-sided PSD values `psd` (one per bin, in
/// s = 1/Hz for strain) and bin width `df` (Hz): independent real and
/// imaginary parts with variance `psd[k] / (4 df)`. The same seed gives the
/// same noise. A zero PSD gives zero noise; negative or non-finite values,
/// or a `df` that is not positive and finite, are errors.
pub fn colored_noise(psd: &[f64], df: f64, seed: u64) -> Result<Vec<C64>, Error> {
    colored_noise_with(&mut rng(seed), psd, df)
}

/// [`colored_noise`] drawing from a caller's generator.
pub fn colored_noise_with<R: Rng + ?Sized>(rng: &mut R, psd: &[f64], df: f64) -> Result<Vec<C64>, Error> {
    if !(df.is_finite() && df > 0.0) {
        return Err(Error::Bind(format!("noise: the bin width df = {df} must be positive and finite")));
    }
    if let Some(k) = psd.iter().position(|s| !(s.is_finite() && *s >= 0.0)) {
        return Err(Error::Bind(format!("noise: PSD value {} at bin {k} is not a finite non-negative number", psd[k])));
    }
    Ok(psd
        .iter()
        .map(|s| {
            let sd = (s / (4.0 * df)).sqrt();
            let re: f64 = rng.sample(StandardNormal);
            let im: f64 = rng.sample(StandardNormal);
            C64::new(sd * re, sd * im)
        })
        .collect())
}

/// The noise-weighted inner product `(a|b) = 4 df Re Σ a_k conj(b_k) / S_k`
/// (as `std::detector::inner`), for checks in Rust. Bins with `S_k = 0`
/// are skipped.
pub fn inner(a: &[C64], b: &[C64], psd: &[f64], df: f64) -> f64 {
    4.0 * df * a.iter().zip(b).zip(psd).filter(|(_, s)| **s > 0.0).map(|((a, b), s)| (a * b.conj()).re / s).sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn psd(n: usize) -> Vec<f64> {
        (0..n).map(|k| 1e-46 * (1.0 + (k as f64 / 100.0).powi(2))).collect()
    }

    #[test]
    fn same_seed_same_noise_other_seed_other_noise() {
        let s = psd(64);
        let a = colored_noise(&s, 0.25, 7).unwrap();
        assert_eq!(a, colored_noise(&s, 0.25, 7).unwrap());
        assert_ne!(a, colored_noise(&s, 0.25, 8).unwrap());
    }

    #[test]
    fn variance_per_part_is_psd_over_4df() {
        // Whitened parts re/sqrt(S/(4df)) should be standard normal: check
        // the sample mean and variance over 200k draws (tolerances ~5σ).
        let n = 100_000;
        let s = psd(n);
        let df = 0.125;
        let x = colored_noise(&s, df, 1).unwrap();
        let w: Vec<f64> = x.iter().zip(&s).flat_map(|(z, s)| [z.re, z.im].map(|v| v / (s / (4.0 * df)).sqrt())).collect();
        let m = w.len() as f64;
        let mean = w.iter().sum::<f64>() / m;
        let var = w.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (m - 1.0);
        assert!(mean.abs() < 5.0 / m.sqrt(), "mean {mean}");
        assert!((var - 1.0).abs() < 5.0 * (2.0 / m).sqrt(), "variance {var}");
        // Real and imaginary parts are uncorrelated.
        let cov = x.iter().zip(&s).map(|(z, s)| z.re * z.im / (s / (4.0 * df))).sum::<f64>() / n as f64;
        assert!(cov.abs() < 5.0 / (n as f64).sqrt(), "re/im covariance {cov}");
        // (n|n) is χ² with 2N degrees of freedom: mean 2N, sd 2 sqrt(N).
        let nn = inner(&x, &x, &s, df);
        assert!((nn - 2.0 * n as f64).abs() < 5.0 * 2.0 * (n as f64).sqrt(), "(n|n) = {nn}");
    }

    #[test]
    fn zero_psd_gives_zero_and_bad_input_is_an_error() {
        let x = colored_noise(&[0.0, 0.0], 1.0, 3).unwrap();
        assert!(x.iter().all(|z| *z == C64::new(0.0, 0.0)));
        assert!(colored_noise(&[-1.0], 1.0, 3).is_err());
        assert!(colored_noise(&[f64::NAN], 1.0, 3).is_err());
        assert!(colored_noise(&[1.0], 0.0, 3).is_err());
    }
}
