//! Whitening by a PSD estimated from the data (Welch, `psd.rs`) with the
//! scan's gwml scene `models/whiten.gw`: coloured Gaussian noise comes out
//! white, zero-mean and Gaussian, with the variance the band implies.

use gwml_compiler::Options;
use gwml_runtime::{Model, Value};
use gwml_strain::psd::{Average, Welch, WelchOptions};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

#[test]
fn noise_whitened_by_its_estimated_psd_is_white_with_the_band_s_variance() {
    let (fs, duration, band) = (1024.0, 32.0, (20.0, 400.0));
    let n = (fs * duration) as usize;
    // Coloured noise: white noise through x_j = w_j + 0.95 x_{j-1} (a
    // red spectrum spanning 30 dB), at strain scale.
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(17);
    let mut x = vec![0.0; n];
    let mut prev = 0.0;
    for v in x.iter_mut() {
        let w: f64 = StandardNormal.sample(&mut rng);
        prev = w + 0.95 * prev;
        *v = 1e-21 * prev;
    }
    let psd = Welch::new(fs, WelchOptions::seconds(4.0, fs)).unwrap().estimate(&x).unwrap();
    let source = include_str!("../models/whiten.gw");
    let knobs = [
        ("rate", "1024.0 Hz"),
        ("duration", "32.0 s"),
        ("taper", "2.0 s"),
        ("f_low", "20.0 Hz"),
        ("f_high", "400.0 Hz"),
        ("clf_low", "20.0 Hz"),
        ("clf_high", "400.0 Hz"),
    ];
    let options = Options { knobs: knobs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect(), ..Options::default() };
    let scene = Model::from_source("whiten.gw", source).unwrap().scene_with(None, options).unwrap();
    let mut run = scene.bind();
    run.input_real("x", &x).unwrap();
    run.input_real("psd", &psd.resample(1.0 / duration, n / 2 + 1)).unwrap();
    let out = run.forward().unwrap();
    let Value::RealArray(w) = out.value("w").unwrap().clone() else { panic!("w is a real array") };
    // The middle, away from the tapered ends.
    let mid = &w[(4.0 * fs) as usize..n - (4.0 * fs) as usize];
    let m = mid.len() as f64;
    let mean = mid.iter().sum::<f64>() / m;
    let var = mid.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / m;
    let kurtosis = mid.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / m / (var * var);
    // Unit variance per sample over the whole band; this band is
    // (400 - 20) / 512 of it.
    let want = (band.1 - band.0) / (fs / 2.0);
    assert!(mean.abs() < 0.02, "mean {mean}");
    assert!((var / want - 1.0).abs() < 0.05, "variance {var}, expected {want}");
    assert!((kurtosis - 3.0).abs() < 0.15, "kurtosis {kurtosis}");
    // White: the whitened series' own PSD is flat over the band, 2/fs.
    let white =
        Welch::new(fs, WelchOptions { segment: 1024, overlap: 512, average: Average::Mean, detrend: true }).unwrap().estimate(mid).unwrap();
    // Averaged over 20 Hz: a PSD estimated from 32 s scatters by ~30 % per
    // 0.25 Hz bin, and so does the whitened spectrum bin by bin.
    for f in [40.0, 80.0, 120.0, 250.0, 370.0] {
        let level = (-10..=10).map(|k| white.at(f + k as f64)).sum::<f64>() / 21.0 * fs / 2.0;
        assert!((level - 1.0).abs() < 0.1, "whitened PSD around {f} Hz is {level} of white");
    }
}
