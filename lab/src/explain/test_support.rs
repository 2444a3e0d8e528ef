//! What the start searches' tests share.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use std::f64::consts::TAU;

/// std::glitch's scratchy shape at `t0` s: carrier, rate, duration, wobble.
pub fn scratchy(n: usize, fs: f64, t0: f64, (f0, rate, duration, wobble): (f64, f64, f64, f64)) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let tau = k as f64 / fs - t0;
            let u = 2.0 * tau / duration;
            let arches = 0.5 * (1.0 - (TAU * rate * tau).cos());
            (-u * u).exp() * arches * (TAU * f0 * tau + wobble * f0 / rate * (TAU * rate * tau).sin() + 0.4).cos()
        })
        .collect()
}

/// `h` scaled to SNR `snr` in unit white noise drawn from `seed`.
pub fn at_snr_in_white_noise(h: &[f64], snr: f64, seed: u64) -> Vec<f64> {
    let scale = snr / h.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    h.iter()
        .map(|v| {
            let noise: f64 = StandardNormal.sample(&mut rng);
            v * scale + noise
        })
        .collect()
}
