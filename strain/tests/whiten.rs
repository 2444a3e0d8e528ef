//! Whitening by a PSD estimated from the data (Welch, `psd.rs`) with the
//! scan's gwml scene `models/whiten.gw`: coloured Gaussian noise comes out
//! white, zero-mean and Gaussian, with the variance the band implies.

use gwml_compiler::Options;
use gwml_runtime::{Model, Value};
use gwml_strain::psd::{Average, Welch, WelchOptions};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// Coloured noise at strain scale: white noise through
/// `x_j = w_j + pole x_{j-1}`, seeded.
fn red_noise(n: usize, pole: f64, seed: u64) -> Vec<f64> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let mut prev = 0.0;
    (0..n)
        .map(|_| {
            let w: f64 = StandardNormal.sample(&mut rng);
            prev = w + pole * prev;
            1e-21 * prev
        })
        .collect()
}

#[test]
fn noise_whitened_by_its_estimated_psd_is_white_with_the_band_s_variance() {
    let (fs, duration, band) = (1024.0, 32.0, (20.0, 400.0));
    let n = (fs * duration) as usize;
    // A red spectrum spanning 30 dB.
    let x = red_noise(n, 0.95, 17);
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

/// The scan tiles the scene's `w_spectrum` as the spectrum of `w`
/// (`Whitener::spectrum_scene`): it must be the rfft of `w` in the
/// stdlib's normalisation, `X = dt Σ x_j e^{-2πi f t_j}`, bin by bin, with
/// the same `w_clf`.
#[test]
fn the_spectrum_scene_gives_the_rfft_of_the_whitened_series() {
    use gwml_strain::whitening::{whiten_spectrum_with, whiten_with, WhitenOptions, Whitener};
    use realfft::RealFftPlanner;
    let (fs, duration) = (1024.0, 16.0);
    let n = (fs * duration) as usize;
    let x = red_noise(n, 0.9, 5);
    let psd = Welch::new(fs, WelchOptions::seconds(2.0, fs)).unwrap().estimate(&x).unwrap();
    let whitener = Whitener::new().unwrap();
    let o = WhitenOptions { taper: 1.0, band: (20.0, 400.0), classifier_band: (30.0, 300.0) };
    let at = (fs, 1e9, "coloured noise");
    let (w, w_clf) = whiten_with(&mut whitener.scene(n, fs, &o).unwrap().bind(), &x, &psd, at).unwrap();
    let (spectrum, w_clf_too) = whiten_spectrum_with(&mut whitener.spectrum_scene(n, fs, &o).unwrap().bind(), &x, &psd, at).unwrap();
    assert_eq!(spectrum.len(), n / 2 + 1);
    let largest = w_clf.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in w_clf.iter().zip(&w_clf_too) {
        assert!((a - b).abs() <= 1e-12 * largest, "w_clf differs between the scenes: {a} against {b}");
    }
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let (mut input, mut want) = (w.clone(), fft.make_output_vec());
    fft.process(&mut input, &mut want).unwrap();
    let peak = spectrum.iter().fold(0.0f64, |m, c| m.max(c.norm()));
    assert!(peak > 0.0, "an empty spectrum");
    for (k, (got, rfft)) in spectrum.iter().zip(&want).enumerate() {
        let expected = rfft / fs;
        assert!((got - expected).norm() <= 1e-9 * peak, "bin {k} ({} Hz): {got} against {expected}", k as f64 / duration);
        if (k as f64) / duration < 20.0 || (k as f64) / duration > 400.0 {
            assert!(got.norm() <= 1e-12 * peak, "bin {k} outside the band holds {got}");
        }
    }
}
