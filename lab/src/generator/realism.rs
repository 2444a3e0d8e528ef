//! How realistic a generator's draws are, measured: a classifier two-sample
//! test (Lopez-Paz & Oquab 2017, "Revisiting classifier two-sample tests",
//! arXiv:1610.06545). Two sets of clean whitened glitches are each scaled to
//! one SNR, centred on their energy and put in fresh unit-variance white
//! noise, as a detector would see them; a critic (`two_sample.gw`, trained
//! by gwml's `Trainer`) learns to tell them apart from band powers and an
//! energy envelope, and its accuracy on held-out folds is the statistic:
//! 0.5 when the sets are indistinguishable, 1 when every window gives its
//! set away.

use super::learned::centred;
use super::{quantiles, SAMPLES, SAMPLE_RATE};
use gwml_runtime::dataset::{Array, Dataset};
use gwml_runtime::optim::{Method, OptimConfig, Schedule};
use gwml_runtime::train::{TrainOptions, Trainer};
use gwml_runtime::{Error, Model};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use realfft::RealFftPlanner;
use std::collections::BTreeMap;

/// The critic: scene `classify` over [`FEATURES`] features.
pub const CRITIC_SOURCE: &str = include_str!("../../models/glitch/two_sample.gw");

/// Log band powers, log-spaced over [`BAND`].
const BANDS: usize = 16;

/// Bins of each log energy envelope: one over the whole second (64 ms
/// bins), one over its central 64 ms (4 ms bins), where a short glitch's
/// rise and decay are.
const ENVELOPE_BINS: usize = 16;

/// Features per window.
pub const FEATURES: usize = BANDS + 2 * ENVELOPE_BINS;

/// The band of the band powers (Hz).
const BAND: (f64, f64) = (20.0, 2000.0);

/// Folds of the cross-validation.
const FOLDS: usize = 5;

/// One window's features and its set (0 or 1).
type Window = (Vec<f64>, usize);

/// Settings of [`two_sample_accuracy`].
#[derive(Clone, Copy, Debug)]
pub struct TwoSampleOptions {
    /// The SNR every glitch is scaled to.
    pub snr: f64,
    /// Seed of the noise, the folds and the critic's training.
    pub seed: u64,
    /// Critic training epochs per fold.
    pub epochs: usize,
    /// Worker threads.
    pub threads: usize,
}

/// The features of whitened window `x` (centred on its glitch): [`BANDS`]
/// log band powers and two envelopes of [`ENVELOPE_BINS`] log mean powers
/// over time.
pub fn features(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut input = x.to_vec();
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum).expect("buffers sized by the plan");
    let df = SAMPLE_RATE / n as f64;
    let mut out = Vec::with_capacity(FEATURES);
    for b in 0..BANDS {
        let edge = |k: usize| BAND.0 * (BAND.1 / BAND.0).powf(k as f64 / BANDS as f64);
        let (lo, hi) = ((edge(b) / df).round() as usize, ((edge(b + 1) / df).round() as usize).max((edge(b) / df).round() as usize + 1));
        // White unit-variance noise has E|X_k|² = n: the ratio is 1 in noise.
        let mean = spectrum[lo..hi.min(spectrum.len())].iter().map(|c| c.norm_sqr()).sum::<f64>() / ((hi - lo) as f64 * n as f64);
        out.push(mean.ln());
    }
    let log_power = |c: &[f64]| (c.iter().map(|v| v * v).sum::<f64>() / c.len() as f64).ln();
    out.extend(x.chunks(n / ENVELOPE_BINS).take(ENVELOPE_BINS).map(log_power));
    let fine = n / 64;
    out.extend(x[n / 2 - fine / 2..n / 2 + fine / 2].chunks(fine / ENVELOPE_BINS).map(log_power));
    out
}

/// Clean glitch `s` as a detector would see it: scaled to `snr`, centred on
/// its energy, in fresh white noise from `rng`.
fn observed(s: &[f64], snr: f64, rng: &mut impl rand::Rng) -> Vec<f64> {
    let norm = s.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
    let (c, _) = centred(s);
    c.iter().map(|v| snr * v / norm + Distribution::<f64>::sample(&StandardNormal, rng)).collect()
}

/// Held-out accuracy of a critic telling set `a` from set `b` (clean
/// whitened glitches, rows of 4096), averaged over [`FOLDS`] folds of a
/// balanced draw (the larger set is cut to the smaller's size).
pub fn two_sample_accuracy(a: &[Vec<f64>], b: &[Vec<f64>], o: &TwoSampleOptions) -> Result<f64, Error> {
    let m = a.len().min(b.len());
    if m < 2 * FOLDS {
        return Err(Error::Bind(format!("a two-sample test needs at least {} glitches per set, got {m}", 2 * FOLDS)));
    }
    if a.iter().chain(b).any(|r| r.len() != SAMPLES) {
        return Err(Error::Bind(format!("two-sample sets hold rows of {SAMPLES} samples")));
    }
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(o.seed);
    let mut rows: Vec<Window> = Vec::with_capacity(2 * m);
    for (set, label) in [(a, 0), (b, 1)] {
        for s in &set[..m] {
            rows.push((features(&observed(s, o.snr, &mut rng)), label));
        }
    }
    rows.shuffle(&mut rng);
    let model = Model::from_source("lab/models/glitch/two_sample.gw", CRITIC_SOURCE)?;
    let scene = model.scene(None)?;
    let mut correct = 0;
    for fold in 0..FOLDS {
        let part =
            |held: bool| -> Vec<&Window> { rows.iter().enumerate().filter(|(i, _)| (i % FOLDS == fold) == held).map(|p| p.1).collect() };
        let (train, test) = (part(false), part(true));
        // Standardised by the training fold's mean and spread.
        let (mean, sd) = moments(&train);
        let dataset = |part: &[&Window]| -> Result<Dataset, Error> {
            let x: Vec<f64> = part.iter().flat_map(|(f, _)| f.iter().zip(&mean).zip(&sd).map(|((v, m), s)| (v - m) / s)).collect();
            let mut arrays = BTreeMap::new();
            arrays.insert("x".to_string(), Array::new(vec![part.len(), FEATURES], x)?);
            arrays.insert("label".to_string(), Array::new(vec![part.len()], part.iter().map(|(_, l)| *l as f64).collect())?);
            Ok(Dataset { arrays })
        };
        let (train_set, test_set) = (dataset(&train)?, dataset(&test)?);
        let options = TrainOptions {
            loss: "loss".into(),
            logits: "logits".into(),
            label: "label".into(),
            epochs: o.epochs,
            batch: 32,
            optim: OptimConfig { method: Method::adamw(1e-3), lr: 3e-3, schedule: Schedule::Constant, clip_norm: Some(10.0) },
            seed: o.seed.wrapping_add(fold as u64),
            threads: o.threads,
            patience: None,
            checkpoint_dir: None,
        };
        let mut critic = Trainer::new(&scene, options)?;
        critic.fit(&train_set, None, |_, _| {}, |_| {})?;
        let predicted = critic.predict_classes(&test_set)?;
        correct += predicted.iter().zip(&test).filter(|(p, (_, l))| *p == l).count();
    }
    Ok(correct as f64 / rows.len() as f64)
}

/// Per-feature mean and standard deviation (at least 1e-6).
fn moments(rows: &[&Window]) -> (Vec<f64>, Vec<f64>) {
    let n = rows.len() as f64;
    let mean: Vec<f64> = (0..FEATURES).map(|j| rows.iter().map(|(f, _)| f[j]).sum::<f64>() / n).collect();
    let sd = (0..FEATURES).map(|j| (rows.iter().map(|(f, _)| (f[j] - mean[j]).powi(2)).sum::<f64>() / n).sqrt().max(1e-6)).collect();
    (mean, sd)
}

/// One physical property of a glitch and how its distribution differs
/// between two sets.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureDistance {
    /// The property, with its unit.
    pub name: &'static str,
    /// 5 %, 50 % and 95 % quantiles in each set.
    pub quantiles: [[f64; 3]; 2],
    /// The two-sample Kolmogorov–Smirnov statistic: the largest gap
    /// between the two empirical distribution functions (0: the same).
    pub ks: f64,
}

/// Properties of a clean whitened glitch: peak frequency (Hz), bandwidth
/// (Hz, the power spectrum's standard deviation about its centroid),
/// duration (s, the shortest span holding 90 % of the energy), SNR (its
/// norm) and Q (2√2·π·peak frequency·duration / 3.29, so that a
/// sine-Gaussian's Q comes back in LALSimulation's convention, envelope
/// exp(−t²/2σ²) with σ = Q/(2π f0): its energy's 90 % span is 3.29·σ/√2).
pub fn glitch_properties(s: &[f64]) -> [f64; 5] {
    let n = s.len();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut input = s.to_vec();
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum).expect("buffers sized by the plan");
    let df = SAMPLE_RATE / n as f64;
    let power: Vec<f64> = spectrum.iter().map(|c| c.norm_sqr()).collect();
    let total: f64 = power.iter().sum::<f64>().max(1e-300);
    let peak = power.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).map_or(0.0, |(k, _)| k as f64 * df);
    let centroid = power.iter().enumerate().map(|(k, p)| k as f64 * df * p).sum::<f64>() / total;
    let bandwidth = (power.iter().enumerate().map(|(k, p)| (k as f64 * df - centroid).powi(2) * p).sum::<f64>() / total).sqrt();
    // The shortest window holding 90 % of the energy, by two pointers.
    let energy: Vec<f64> = s.iter().map(|v| v * v).collect();
    let e_total: f64 = energy.iter().sum::<f64>().max(1e-300);
    let (mut best, mut sum, mut lo) = (n, 0.0, 0);
    for hi in 0..n {
        sum += energy[hi];
        while sum - energy[lo] >= 0.9 * e_total {
            sum -= energy[lo];
            lo += 1;
        }
        if sum >= 0.9 * e_total {
            best = best.min(hi + 1 - lo);
        }
    }
    let duration = best as f64 / SAMPLE_RATE;
    let snr = e_total.sqrt();
    let q = 2.0 * std::f64::consts::SQRT_2 * std::f64::consts::PI * peak * duration / 3.29;
    [peak, bandwidth, duration, snr, q]
}

/// Names of [`glitch_properties`], with units.
pub const PROPERTY_NAMES: [&str; 5] = ["peak frequency (Hz)", "bandwidth (Hz)", "duration (s)", "SNR", "Q"];

/// How each of [`glitch_properties`] is distributed in set `a` and in set
/// `b` (clean glitches), and the Kolmogorov–Smirnov distance between them.
pub fn feature_distances(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<FeatureDistance> {
    let (pa, pb): (Vec<[f64; 5]>, Vec<[f64; 5]>) =
        (a.iter().map(|s| glitch_properties(s)).collect(), b.iter().map(|s| glitch_properties(s)).collect());
    (0..5)
        .map(|j| {
            let mut xa: Vec<f64> = pa.iter().map(|p| p[j]).collect();
            let mut xb: Vec<f64> = pb.iter().map(|p| p[j]).collect();
            xa.sort_by(f64::total_cmp);
            xb.sort_by(f64::total_cmp);
            let q = |v: &[f64]| <[f64; 3]>::try_from(quantiles(v, &[0.05, 0.5, 0.95])).expect("three fractions");
            FeatureDistance { name: PROPERTY_NAMES[j], quantiles: [q(&xa), q(&xb)], ks: kolmogorov_smirnov(&xa, &xb) }
        })
        .collect()
}

/// The largest gap between the empirical distribution functions of two
/// sorted samples.
fn kolmogorov_smirnov(a: &[f64], b: &[f64]) -> f64 {
    let (mut i, mut j, mut d) = (0, 0, 0.0f64);
    while i < a.len() && j < b.len() {
        let x = a[i].min(b[j]);
        while i < a.len() && a[i] <= x {
            i += 1;
        }
        while j < b.len() && b[j] <= x {
            j += 1;
        }
        d = d.max((i as f64 / a.len() as f64 - j as f64 / b.len() as f64).abs());
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine_gaussian(f0: f64, q: f64, amp: f64) -> Vec<f64> {
        let sigma = q / (std::f64::consts::TAU * f0);
        (0..SAMPLES)
            .map(|i| {
                let t = i as f64 / SAMPLE_RATE - 0.5;
                amp * (-(t / sigma).powi(2) / 2.0).exp() * (std::f64::consts::TAU * f0 * t).sin()
            })
            .collect()
    }

    #[test]
    fn a_sine_gaussian_has_its_frequency_q_and_norm() {
        let s = sine_gaussian(200.0, 6.0, 3.0);
        let [peak, bandwidth, duration, snr, q] = glitch_properties(&s);
        assert!((peak - 200.0).abs() <= 1.0, "peak {peak}");
        // The power spectrum is a Gaussian of standard deviation
        // 1/(2√2 π σ) = f0/(√2 Q) ≈ 23.6 Hz.
        assert!((bandwidth / 23.57 - 1.0).abs() < 0.05, "bandwidth {bandwidth}");
        assert!((q / 6.0 - 1.0).abs() < 0.05, "q {q}, duration {duration}");
        let norm = s.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((snr - norm).abs() < 1e-9);
    }

    #[test]
    fn distances_are_zero_for_one_set_and_large_for_shifted_frequencies() {
        let low: Vec<Vec<f64>> = (0..40).map(|i| sine_gaussian(100.0 + i as f64, 5.0, 1.0)).collect();
        let high: Vec<Vec<f64>> = (0..40).map(|i| sine_gaussian(300.0 + i as f64, 5.0, 1.0)).collect();
        assert!(feature_distances(&low, &low).iter().all(|d| d.ks == 0.0));
        let d = feature_distances(&low, &high);
        assert_eq!(d[0].ks, 1.0, "peak frequencies do not overlap");
        assert!(d[4].ks < d[0].ks, "the same Q: {d:?}");
        assert_eq!(kolmogorov_smirnov(&[1.0, 2.0], &[3.0, 4.0]), 1.0);
    }
}
