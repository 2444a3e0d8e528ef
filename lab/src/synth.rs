//! Synthetic labelled datasets for training and tests, reproducible by seed.
//!
//! [`glitches`]: whitened 1 s segments at 4096 Hz of the six classes of the
//! glitch experiment (see [`GLITCH_CLASSES`]), the glitch shapes from
//! `std::glitch` and the chirp from `std::taylorf2`, whitened by the aLIGO
//! zero-detuned high-power PSD with `std::detector::whiten` (band 20 Hz to
//! 2 kHz). Whitening is linear, so whitened coloured noise plus a whitened
//! signal is drawn as unit-variance white noise plus the whitened signal
//! scaled to the drawn optimal SNR.
//!
//! [`bursts`]: sine-Gaussian bursts in white Gaussian noise (label 1) against
//! noise alone (label 0), the smallest detection problem a 1-D CNN should
//! solve. The burst is the form of `std::burst::sine_gaussian`,
//! `h(t) = exp(-((t - t0)/τ)²) cos(2π f0 (t - t0) + φ)` with
//! `τ = Q / (√2 π f0)`, scaled so its optimal signal-to-noise ratio in
//! unit-variance white noise, `√(Σ h²)`, is the drawn SNR.

use gwml_runtime::dataset::{Array, Dataset};
use gwml_runtime::{Error, Value};
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

/// The classes of `gwml data glitch`, in label order.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum GlitchClass {
    /// Noise alone (label 0).
    None,
    /// Blip (label 1).
    Blip,
    /// Koi Fish (label 2).
    KoiFish,
    /// Whistle (label 3).
    Whistle,
    /// Scratchy (label 4).
    Scratchy,
    /// A binary chirp (label 5).
    Chirp,
}

impl GlitchClass {
    /// The label, an index into [`GLITCH_CLASSES`].
    pub fn label(self) -> usize {
        self as usize
    }
}

/// Class labels of [`glitches`], in label order.
pub const GLITCH_CLASSES: &[&str] = &["None", "Blip", "Koi Fish", "Whistle", "Scratchy", "Chirp"];

/// The scene that draws one whitened signal of any class (`class` selects).
pub(crate) const GLITCH_SCENE: &str = include_str!("../models/glitch/synth.gw");

/// The whitened signal shapes of [`glitches`], to draw one signal at a time
/// with params of the caller's choosing (the learned glitch generator
/// samples through it).
pub struct GlitchSignals {
    model: gwml_runtime::Model,
    scene: gwml_runtime::Scene,
}

impl GlitchSignals {
    /// Compiles the signal scene.
    pub fn new() -> Result<GlitchSignals, Error> {
        let model = gwml_runtime::Model::from_source("glitch-data.gw", GLITCH_SCENE)?;
        let scene = model.scene(Some("glitch"))?;
        Ok(GlitchSignals { model, scene })
    }

    /// A run of the signal scene, for [`unit_signal`]. Its params are the
    /// glitch shapes' (`t0`, `f0`, `q`, `f_head`, `head`, `lead`, `f_min`,
    /// `f_max`, `half`, `rate`, `duration`, `phi`) and the chirp's (`mc`,
    /// `mass_ratio`, `tc`); unset ones keep their defaults.
    pub fn bind(&self) -> gwml_runtime::Run<'_> {
        self.scene.bind()
    }
}

/// The whitened signal of `class` (an index into [`GLITCH_CLASSES`], not
/// 0) with the given params, scaled to unit norm (optimal SNR 1 in
/// unit-variance white noise): 4096 samples over 1 s.
pub fn unit_signal(run: &mut gwml_runtime::Run, class: usize, settings: &[(&str, f64)]) -> Result<Vec<f64>, Error> {
    let (mut w, norm) = signal_and_norm(run, class, settings)?;
    w.iter_mut().for_each(|v| *v /= norm);
    Ok(w)
}

/// The whitened signal and its (positive) norm.
fn signal_and_norm(run: &mut gwml_runtime::Run, class: usize, settings: &[(&str, f64)]) -> Result<(Vec<f64>, f64), Error> {
    if class == 0 || class >= GLITCH_CLASSES.len() {
        return Err(Error::Bind(format!("class {class} has no signal shape")));
    }
    run.param("class", class as f64)?;
    for (name, value) in settings {
        run.param(name, *value)?;
    }
    let Value::RealArray(w) = run.forward()?.value("w")?.clone() else {
        return Err(Error::Bind("the glitch scene's output is not a real array".into()));
    };
    let norm = w.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm.is_nan() || norm <= 0.0 {
        return Err(Error::Bind(format!("a {} signal whitened to zero", GLITCH_CLASSES[class])));
    }
    Ok((w, norm))
}

/// Ranges of the glitch experiment's data.
#[derive(Clone, Debug)]
pub struct GlitchOptions {
    /// Examples to draw (classes uniformly at random).
    pub n: usize,
    /// Seed: the same seed gives the same dataset; use different seeds for
    /// training, validation and test sets.
    pub seed: u64,
    /// Optimal SNR range of every signal (with respect to the modelled PSD)
    /// but Koi Fish, which are drawn `koi_fish_loudness` times louder.
    pub snr: (f64, f64),
    /// How much louder Koi Fish are drawn than the other classes: their SNR
    /// is `snr` times this ([`KOI_FISH_LOUDNESS`] by default; 1 draws every
    /// class from the same range).
    pub koi_fish_loudness: f64,
    /// A shifted PSD for generalisation tests: when positive, the noise's
    /// true PSD is the modelled aLIGO PSD times `1 + (knee / f)²` over the
    /// whitening band (20 Hz to 2 kHz), excess low-frequency noise the
    /// whitening does not know about: at `knee` the noise power is doubled,
    /// at 20 Hz it is `1 + (knee / 20 Hz)²` times the model's. Zero: the
    /// modelled PSD.
    pub psd_knee: f64,
    /// Draw only this class (an index into [`GLITCH_CLASSES`]); `None`:
    /// every class, uniformly at random.
    pub class: Option<usize>,
    /// Centre every signal as a scan's trigger window does: glitch centres
    /// and the chirp's merger at 0.4–0.6 s (instead of glitches at 0.3–0.7 s
    /// and mergers at 0.8–0.95 s, where position tells a chirp apart).
    pub centred: bool,
}

impl Default for GlitchOptions {
    fn default() -> Self {
        GlitchOptions {
            n: 1000,
            seed: 1,
            snr: (8.0, 30.0),
            koi_fish_loudness: KOI_FISH_LOUDNESS,
            psd_knee: 0.0,
            class: None,
            centred: false,
        }
    }
}

/// The factor by which Koi Fish are drawn louder than the other classes.
/// Gravity Spy describes Koi Fish as loud Blips: the O3a medians of their
/// SNR are 140–195 against ~23 for Blips (Zevin et al. 2017, Class. Quantum
/// Grav. 34 064003; medians from the public O3a metadata), 6–8 times louder.
/// A factor of 3 (SNR 24–90 for the default 8–30) keeps part of the Koi
/// Fish as quiet as the loudest Blips, so loudness is a cue and not a label.
pub const KOI_FISH_LOUDNESS: f64 = 3.0;

/// Draws the shape params of a signal of `class` from the ranges of
/// [`glitches`] (every param of the signal scene; the class's own are used).
pub fn draw_shape<R: Rng>(rng: &mut R, class: usize) -> [(&'static str, f64); 15] {
    let mut u = |lo: f64, hi: f64| rng.random_range(lo..=hi);
    let f_min = u(300.0, 900.0);
    [
        ("t0", u(0.3, 0.7)),
        (
            "f0",
            if class == 2 {
                u(110.0, 160.0)
            } else if class == 4 {
                u(30.0, 400.0)
            } else {
                u(30.0, 250.0)
            },
        ),
        ("q", u(2.0, 6.0)),
        ("f_head", u(20.0, 50.0)),
        ("head", u(0.1, 0.3)),
        ("lead", u(0.01, 0.03)),
        ("f_min", f_min),
        ("f_max", f_min + u(200.0, 600.0)),
        ("half", u(0.1, 0.3)),
        ("rate", u(12.0, 25.0)),
        ("duration", u(0.4, 0.8)),
        ("mc", u(18.0, 40.0)),
        ("mass_ratio", u(0.3, 1.0)),
        ("tc", u(0.8, 0.95)),
        ("phi", u(0.0, std::f64::consts::TAU)),
    ]
}

/// Draws whitened segments `x` (`n × 4096`) with labels `label` (`n`,
/// indices into [`GLITCH_CLASSES`]). Parameter ranges, per class:
/// Blip f0 30–250 Hz, Q 2–6; Koi Fish f0 110–160 Hz, Q 2–6, head at
/// 20–50 Hz with 10–30 % of the amplitude, 10–30 ms before; Whistle
/// f_min 300–900 Hz, f_max f_min + 200–600 Hz, half-width 0.1–0.3 s;
/// Scratchy f0 30–400 Hz, 12–25 arches/s over 0.4–0.8 s; glitch centres
/// 0.3–0.7 s; Chirp: TaylorF2 from 30 Hz, chirp mass 18–40 Msun, mass
/// ratio 0.3–1, merger at 0.8–0.95 s (a detector projection up to
/// amplitude, which the SNR normalisation removes). Every signal has a
/// random phase (0–2π), so no class can be told by its phase. The SNR is
/// drawn uniformly from `o.snr`, times `o.koi_fish_loudness` for Koi Fish.
pub fn glitches(o: &GlitchOptions) -> Result<Dataset, Error> {
    glitches_with(o, &mut |_| Ok(None))
}

/// A source of glitch shapes other than the library's formulas (a fitted
/// generator): `shape(class)` gives a clean whitened row of 4096 samples
/// for that class, or `None` to draw the class's formula.
pub type ShapeSource<'a> = dyn FnMut(usize) -> Result<Option<Vec<f64>>, Error> + 'a;

/// [`glitches`], with the shapes of some classes from `shape`: each such
/// row is its noise plus the given shape scaled to the drawn SNR (with
/// `centred`, its energy centre moved to the drawn centre).
pub fn glitches_with(o: &GlitchOptions, shape: &mut ShapeSource<'_>) -> Result<Dataset, Error> {
    if !(o.snr.0 > 0.0 && o.snr.1 >= o.snr.0 && o.snr.1.is_finite()) {
        return Err(Error::Bind(format!("SNR range {}..{} must be positive and increasing", o.snr.0, o.snr.1)));
    }
    if !(o.koi_fish_loudness > 0.0 && o.koi_fish_loudness.is_finite()) {
        return Err(Error::Bind(format!("the Koi Fish loudness {} must be positive and finite", o.koi_fish_loudness)));
    }
    if o.psd_knee.is_nan() || o.psd_knee < 0.0 || o.psd_knee.is_infinite() {
        return Err(Error::Bind(format!("the PSD knee {} Hz must be zero or positive", o.psd_knee)));
    }
    if let Some(c) = o.class.filter(|c| *c >= GLITCH_CLASSES.len()) {
        return Err(Error::Bind(format!("class {c} is not one of the {} glitch classes", GLITCH_CLASSES.len())));
    }
    let signals = GlitchSignals::new()?;
    let mut run = signals.bind();
    let model = &signals.model;
    let noise_scene = model.scene(Some("coloured_noise"))?;
    let mut noise_run = noise_scene.bind();
    noise_run.param("knee", o.psd_knee)?;
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(o.seed);
    let samples = 4096;
    let (mut x, mut labels) = (Vec::with_capacity(o.n * samples), Vec::with_capacity(o.n));
    for _ in 0..o.n {
        let class = o.class.unwrap_or_else(|| rng.random_range(0..GLITCH_CLASSES.len()));
        let mut row: Vec<f64> = (0..samples).map(|_| StandardNormal.sample(&mut rng)).collect();
        if o.psd_knee > 0.0 {
            noise_run.input_real("n", &row)?;
            match noise_run.forward()?.value("noise")? {
                Value::RealArray(coloured) => row.clone_from(coloured),
                _ => return Err(Error::Bind("the coloured-noise scene's output is not a real array".into())),
            }
        }
        if class > 0 {
            if let Some(s) = shape(class)? {
                let s = if o.centred { centred_at(&s, rng.random_range(0.4..=0.6)) } else { s };
                let snr = rng.random_range(o.snr.0..=o.snr.1) * if class == 2 { o.koi_fish_loudness } else { 1.0 };
                let norm = s.iter().map(|v| v * v).sum::<f64>().sqrt();
                if s.len() != samples || !(norm > 0.0 && norm.is_finite()) {
                    return Err(Error::Bind(format!("a generated {} is not {samples} finite samples with energy", GLITCH_CLASSES[class])));
                }
                for (r, v) in row.iter_mut().zip(&s) {
                    *r += snr * v / norm;
                }
                x.extend(row);
                labels.push(class as f64);
                continue;
            }
            let mut settings = draw_shape(&mut rng, class);
            if o.centred {
                let centre = rng.random_range(0.4..=0.6);
                settings.iter_mut().filter(|p| p.0 == "t0" || p.0 == "tc").for_each(|p| p.1 = centre);
            }
            let snr = rng.random_range(o.snr.0..=o.snr.1) * if class == 2 { o.koi_fish_loudness } else { 1.0 };
            // `snr * v / norm` rather than a unit signal: the same rounding
            // as the datasets `results/glitch` was computed from.
            let (w, norm) = signal_and_norm(&mut run, class, &settings)?;
            for (r, v) in row.iter_mut().zip(&w) {
                *r += snr * v / norm;
            }
        }
        x.extend(row);
        labels.push(class as f64);
    }
    let mut arrays = BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![o.n, samples], x)?);
    arrays.insert("label".to_string(), Array::new(vec![o.n], labels)?);
    Ok(Dataset { arrays })
}

/// `s` shifted circularly so that its energy centre is at `at` seconds.
fn centred_at(s: &[f64], at: f64) -> Vec<f64> {
    use crate::generator::learned::{centred, roll};
    roll(&centred(s).0, ((at - 0.5) * 4096.0).round() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_shapes_replace_the_formula_at_the_drawn_snr() {
        // One Blip row: its noise, then its SNR, from the seeded generator.
        let spike: Vec<f64> = (0..4096)
            .map(|i| {
                if i == 1000 {
                    3.0
                } else if i == 1001 {
                    -4.0
                } else {
                    0.0
                }
            })
            .collect();
        let o = GlitchOptions { n: 1, seed: 9, snr: (10.0, 20.0), class: Some(1), ..Default::default() };
        let ds = glitches_with(&o, &mut |c| Ok((c == 1).then(|| spike.clone()))).unwrap();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
        let noise: Vec<f64> = (0..4096).map(|_| StandardNormal.sample(&mut rng)).collect();
        let snr = rng.random_range(10.0..=20.0);
        let row = ds.arrays["x"].row(0);
        for i in 0..4096 {
            assert!((row[i] - (noise[i] + snr * spike[i] / 5.0)).abs() < 1e-12, "sample {i}");
        }
        assert_eq!(ds.arrays["label"].data, [1.0]);
        // A shape of the wrong length is an error, not a silent cut.
        assert!(glitches_with(&o, &mut |_| Ok(Some(vec![1.0; 10]))).is_err());
    }

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

#[cfg(test)]
mod glitch_tests {
    use super::*;

    #[test]
    fn glitch_data_is_reproducible_covers_every_class_and_has_the_drawn_snr() {
        let o = GlitchOptions { n: 120, seed: 3, snr: (60.0, 60.0), ..Default::default() };
        let a = glitches(&o).unwrap();
        assert_eq!(a, glitches(&o).unwrap());
        let labels = &a.arrays["label"].data;
        for (c, name) in GLITCH_CLASSES.iter().enumerate() {
            let k = labels.iter().filter(|l| **l == c as f64).count();
            assert!(k >= 8, "class {name} drawn {k} times of 120");
        }
        // Unit-variance noise plus a signal of optimal SNR 60 (180 for a
        // Koi Fish, drawn three times louder): the row's power exceeds the
        // noise's 4096 by 3600 (32,400) (the noise's own spread is ±90 per
        // row, the cross term ±120 (±360)).
        let x = &a.arrays["x"];
        for (i, label) in labels.iter().enumerate() {
            let p: f64 = x.row(i).iter().map(|v| v * v).sum();
            let excess = p - 4096.0;
            if *label == 0.0 {
                assert!(excess.abs() < 450.0, "noise row {i}: excess power {excess}");
            } else {
                let snr = if *label == 2.0 { 180.0 } else { 60.0 };
                assert!((excess - snr * snr).abs() < 600.0, "class {label} row {i}: excess {excess}");
            }
        }
    }

    #[test]
    fn a_shifted_psd_adds_the_stated_low_frequency_noise() {
        // Noise only: the same white draws, coloured by 1 + (knee/f)² over
        // 20 Hz - 2 kHz. White noise of unit variance spreads its power
        // evenly over the 2048 Hz of bins, so the expected power ratio is
        // 1 + (1/2048 Hz) ∫_{20}^{2000} (knee/f)² df
        //   = 1 + knee² (1/20 - 1/2000) / 2048.
        let knee = 60.0;
        let plain = glitches(&GlitchOptions { n: 200, seed: 9, ..Default::default() }).unwrap();
        let shifted = glitches(&GlitchOptions { n: 200, seed: 9, psd_knee: knee, ..Default::default() }).unwrap();
        let labels = &plain.arrays["label"].data;
        assert_eq!(labels, &shifted.arrays["label"].data);
        let power = |d: &Dataset| -> f64 {
            (0..200).filter(|i| labels[*i] == 0.0).map(|i| d.arrays["x"].row(i).iter().map(|v| v * v).sum::<f64>()).sum()
        };
        let ratio = power(&shifted) / power(&plain);
        let expected = 1.0 + knee * knee * (1.0 / 20.0 - 1.0 / 2000.0) / 2048.0;
        assert!((ratio / expected - 1.0).abs() < 0.03, "power ratio {ratio}, expected {expected}");
        assert!(glitches(&GlitchOptions { psd_knee: -1.0, ..Default::default() }).is_err());
    }

    /// With a loudness of 1 every class, Koi Fish included, is drawn from
    /// the same SNR range, and the other classes' rows do not change.
    #[test]
    fn koi_fish_loudness_scales_only_koi_fish() {
        let loud = glitches(&GlitchOptions { n: 60, seed: 4, snr: (60.0, 60.0), ..Default::default() }).unwrap();
        let even = glitches(&GlitchOptions { n: 60, seed: 4, snr: (60.0, 60.0), koi_fish_loudness: 1.0, ..Default::default() }).unwrap();
        let labels = &loud.arrays["label"].data;
        assert_eq!(labels, &even.arrays["label"].data);
        assert!(labels.iter().filter(|l| **l == 2.0).count() >= 3);
        for (i, label) in labels.iter().enumerate() {
            let (a, b) = (loud.arrays["x"].row(i), even.arrays["x"].row(i));
            let excess = b.iter().map(|v| v * v).sum::<f64>() - 4096.0;
            let expected = if *label == 0.0 { 0.0 } else { 3600.0 };
            assert!((excess - expected).abs() < 600.0, "class {label} row {i}: excess {excess} at loudness 1");
            assert_eq!(a == b, *label != 2.0, "row {i} of class {label}");
        }
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(glitches(&GlitchOptions { koi_fish_loudness: bad, ..Default::default() }).is_err(), "loudness {bad}");
        }
    }

    /// Every glitch class and the chirp take the drawn phase: a phase of π
    /// negates the signal (a class told apart by a fixed phase would teach
    /// a classifier something no real glitch has).
    #[test]
    fn every_signal_takes_the_drawn_phase() {
        let signals = GlitchSignals::new().unwrap();
        let mut run = signals.bind();
        for (class, name) in GLITCH_CLASSES.iter().enumerate().skip(1) {
            let w0 = unit_signal(&mut run, class, &[("phi", 0.0)]).unwrap();
            let w1 = unit_signal(&mut run, class, &[("phi", std::f64::consts::PI)]).unwrap();
            let worst = w0.iter().zip(&w1).map(|(a, b)| (a + b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-9, "{name}: phase π differs from the negated signal by {worst}");
        }
    }
}
