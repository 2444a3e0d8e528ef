//! Synthetic labelled datasets for training and tests, reproducible by seed.
//!
//! [`glitches`] (`glitch.rs`): the glitch benchmark, whitened 1 s segments
//! at 4096 Hz of eight classes ([`GLITCH_CLASSES`]) drawn from the
//! population of `population.rs` (shapes, loudness and positions after
//! Gravity Spy's numbers; noise with the flaws of whitened real strain);
//! half the Blips, Koi Fish and Tomtes take the shapes of real glitches'
//! fits (`real_fits.rs`).
//!
//! [`bursts`]: sine-Gaussian bursts in white Gaussian noise (label 1) against
//! noise alone (label 0), the smallest detection problem a 1-D CNN should
//! solve. The burst is the form of `std::burst::sine_gaussian`,
//! `h(t) = exp(-((t - t0)/τ)²) cos(2π f0 (t - t0) + φ)` with
//! `τ = Q / (√2 π f0)`, scaled so its optimal signal-to-noise ratio in
//! unit-variance white noise, `√(Σ h²)`, is the drawn SNR.

mod glitch;
mod population;
pub mod real_fits;

pub(crate) use glitch::GLITCH_SCENE;
pub use glitch::{
    draw_signal_shape, glitch_class, glitches, glitches_with, koi_fish_shares, signal_centre, unit_signal, GlitchClass, GlitchOptions,
    GlitchSignals, Shape, ShapeSource, CENTRED, GLITCH_CLASSES, KOI_FISH_BODY_SHARE, KOI_FISH_HEAD_SNR, KOI_FISH_MAX_HEAD_SHARE,
};
pub use population::{draw_shape, draw_snr, snr_range, NoiseExtras};

use gwml_runtime::dataset::{Array, Dataset};
use gwml_runtime::Error;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::collections::BTreeMap;

/// Ranges of the burst population.
#[derive(Clone, Debug)]
pub struct BurstOptions {
    /// Examples to draw (half with a burst, in random order).
    pub n: usize,
    /// Seed: the same seed gives the same dataset.
    pub seed: u64,
    /// Samples per second.
    pub rate: f64,
    /// Samples per example.
    pub samples: usize,
    /// Central frequency range in Hz (below the Nyquist frequency).
    pub f0: (f64, f64),
    /// Quality factor range.
    pub q: (f64, f64),
    /// Optimal SNR range.
    pub snr: (f64, f64),
}

impl Default for BurstOptions {
    fn default() -> Self {
        BurstOptions { n: 1000, seed: 1, rate: 256.0, samples: 256, f0: (20.0, 100.0), q: (3.0, 12.0), snr: (6.0, 15.0) }
    }
}

/// Draws the dataset: arrays `x` (`n × samples`) and `label` (`n`, 0 or 1).
pub fn bursts(o: &BurstOptions) -> Result<Dataset, Error> {
    let ranges = [("f0", o.f0), ("q", o.q), ("snr", o.snr)];
    if let Some((name, r)) = ranges.iter().find(|(_, r)| !(r.0 > 0.0 && r.1 >= r.0 && r.1.is_finite())) {
        return Err(Error::Bind(format!("burst {name} range {}..{} must be positive and increasing", r.0, r.1)));
    }
    if o.rate.is_nan() || o.rate <= 0.0 || o.samples < 8 || o.f0.1 >= o.rate / 2.0 {
        return Err(Error::Bind(format!("bursts need at least 8 samples and f0 below the Nyquist frequency {} Hz", o.rate / 2.0)));
    }
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(o.seed);
    let (mut x, mut labels) = (Vec::with_capacity(o.n * o.samples), Vec::with_capacity(o.n));
    let duration = o.samples as f64 / o.rate;
    for _ in 0..o.n {
        let label = rng.random_bool(0.5);
        let mut row: Vec<f64> = (0..o.samples).map(|_| StandardNormal.sample(&mut rng)).collect();
        if label {
            let f0 = rng.random_range(o.f0.0..=o.f0.1);
            let q = rng.random_range(o.q.0..=o.q.1);
            let snr = rng.random_range(o.snr.0..=o.snr.1);
            let t0 = rng.random_range(0.25 * duration..=0.75 * duration);
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let tau = q / (std::f64::consts::SQRT_2 * std::f64::consts::PI * f0);
            let h: Vec<f64> = (0..o.samples)
                .map(|j| {
                    let dt = j as f64 / o.rate - t0;
                    (-(dt / tau).powi(2)).exp() * (std::f64::consts::TAU * f0 * dt + phi).cos()
                })
                .collect();
            let norm = h.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm > 0.0 {
                for (r, v) in row.iter_mut().zip(&h) {
                    *r += snr * v / norm;
                }
            }
        }
        x.extend(row);
        labels.push(if label { 1.0 } else { 0.0 });
    }
    let mut arrays = BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![o.n, o.samples], x)?);
    arrays.insert("label".to_string(), Array::new(vec![o.n], labels)?);
    Ok(Dataset { arrays })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bursts_are_reproducible_balanced_and_at_the_drawn_snr() {
        let o = BurstOptions { n: 400, ..Default::default() };
        let a = bursts(&o).unwrap();
        assert_eq!(a, bursts(&o).unwrap());
        assert_ne!(a, bursts(&BurstOptions { seed: 2, ..o.clone() }).unwrap());
        let labels = &a.arrays["label"].data;
        let ones = labels.iter().filter(|l| **l == 1.0).count();
        assert!((150..250).contains(&ones), "{ones} of 400 have a burst");
        // Noise-only rows have unit variance; burst rows carry extra power
        // of about SNR² over the row.
        let x = &a.arrays["x"];
        let power = |i: usize| x.row(i).iter().map(|v| v * v).sum::<f64>();
        let mean_power = |l: f64| {
            let rows: Vec<usize> = (0..400).filter(|i| labels[*i] == l).collect();
            rows.iter().map(|i| power(*i)).sum::<f64>() / rows.len() as f64
        };
        let (noise, signal) = (mean_power(0.0), mean_power(1.0));
        assert!((noise / 256.0 - 1.0).abs() < 0.05, "noise power per sample {}", noise / 256.0);
        // E[SNR²] for SNR uniform on 6..15 is (15³ - 6³) / (3 · 9) = 117.
        assert!((signal - noise - 117.0).abs() < 25.0, "burst power {}", signal - noise);
    }

    #[test]
    fn bad_ranges_are_errors() {
        assert!(bursts(&BurstOptions { f0: (20.0, 200.0), ..Default::default() }).is_err());
        assert!(bursts(&BurstOptions { snr: (5.0, 1.0), ..Default::default() }).is_err());
    }
}
