//! The glitch benchmark's data (`gwml data glitch`): whitened 1 s segments
//! at 4096 Hz of eight classes ([`GLITCH_CLASSES`]), the signals from the
//! data's own shapes (`lab/models/glitch/synth.gw`, drawn as
//! [`super::population`] says), whitened by the aLIGO zero-detuned
//! high-power PSD with `std::detector::whiten` (band 20 Hz to 2 kHz).
//! Whitening is linear, so whitened coloured noise plus a whitened signal
//! is drawn as unit-variance noise plus the whitened signal scaled to the
//! drawn optimal SNR; unless the noise is ideal, that noise is coloured by
//! a misestimated PSD and carries residual lines and weak background
//! transients ([`NoiseExtras`]).

use super::population::{draw_shape, draw_snr, NoiseExtras, CHIRP, KOI_FISH};
use gwml_runtime::dataset::{Array, Dataset};
use gwml_runtime::{Error, Value};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::collections::BTreeMap;

/// The classes of `gwml data glitch`, in label order.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum GlitchClass {
    /// Noise alone, perhaps with a weak transient (label 0).
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
    /// Tomte (label 6).
    Tomte,
    /// Scattered Light (label 7).
    ScatteredLight,
}

impl GlitchClass {
    /// The label, an index into [`GLITCH_CLASSES`].
    pub fn label(self) -> usize {
        self as usize
    }
}

/// Class labels of [`glitches`], in label order.
pub const GLITCH_CLASSES: &[&str] = &["None", "Blip", "Koi Fish", "Whistle", "Scratchy", "Chirp", "Tomte", "Scattered Light"];

/// The index in [`GLITCH_CLASSES`] of a class named as there, in any case,
/// with `_` for spaces (`koi_fish`), or why there is none.
pub fn glitch_class(name: &str) -> Result<usize, String> {
    let key = |s: &str| s.to_ascii_lowercase().replace('_', " ");
    GLITCH_CLASSES
        .iter()
        .position(|c| key(c) == key(name.trim()))
        .ok_or_else(|| format!("error: no glitch class `{name}`; the classes are {}", GLITCH_CLASSES.join(", ")))
}

/// The scene that draws one whitened signal of any class (`class` selects).
pub(crate) const GLITCH_SCENE: &str = include_str!("../../models/glitch/synth.gw");

/// Samples per row, and per second.
pub(super) const SAMPLES: usize = 4096;
pub(super) const RATE: f64 = 4096.0;

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

    /// A run of the signal scene, for [`unit_signal`]. Its params are those
    /// [`super::draw_shape`] draws; unset ones keep their defaults, with
    /// which Blip, Koi Fish, Whistle and Scratchy are the `std::glitch`
    /// formulas.
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

/// What makes a drawn Koi Fish one: a body that carries most of the
/// whitened energy (20 Hz–2 kHz) and a head that can be seen. Gravity
/// Spy's Koi Fish are blip-like bodies with a low-frequency head, peaking
/// at 110–160 Hz (median peak frequencies of O3's classes, Glanz et al.
/// 2024): the loudest tiles are the body's. Drawn freely, the population's
/// heads (0.5–4 times the body before whitening, longer, at 15–45 Hz) held
/// most of the whitened energy in ~70 % of Koi Fish (42 of 60 draws),
/// Tomtes with a faint blip; and a head at 15–20 Hz, below most of the
/// band, often held under 1 %, a Blip. Neither a classifier nor a fit can
/// name those Koi Fish.
pub const KOI_FISH_BODY_SHARE: f64 = 0.5;
/// The head's least whitened SNR: a Q tile of normalised energy ~12, half
/// the top of Gravity Spy's colour scale (25.5). Below SNR ~8 the head's
/// share is held at [`KOI_FISH_MAX_HEAD_SHARE`] instead.
pub const KOI_FISH_HEAD_SNR: f64 = 5.0;
/// The most a head is asked to carry at a low SNR (what the body's least
/// share leaves room for).
pub const KOI_FISH_MAX_HEAD_SHARE: f64 = 0.4;

/// [`draw_shape`] for a signal of optimal SNR `snr`, with a Koi Fish
/// redrawn until its body carries at least [`KOI_FISH_BODY_SHARE`] of its
/// whitened energy and its head [`KOI_FISH_HEAD_SNR`] (`run`: a run of the
/// [`GlitchSignals`] scene).
pub fn draw_signal_shape<R: Rng>(
    run: &mut gwml_runtime::Run,
    rng: &mut R,
    class: usize,
    snr: f64,
) -> Result<Vec<(&'static str, f64)>, Error> {
    if class != KOI_FISH {
        return Ok(draw_shape(rng, class));
    }
    let head_share = (KOI_FISH_HEAD_SNR / snr).powi(2).min(KOI_FISH_MAX_HEAD_SHARE);
    // The body rule alone passes ~30 % of draws: a thousand failures mean
    // a broken scene.
    for _ in 0..1000 {
        let settings = draw_shape(rng, class);
        let (body, head) = koi_fish_shares(run, &settings)?;
        if body >= KOI_FISH_BODY_SHARE && head >= head_share {
            return Ok(settings);
        }
    }
    Err(Error::Bind(format!("no Koi Fish in 1000 draws had the body and the head of one at SNR {snr}")))
}

/// The shares of a Koi Fish's whitened energy in its body (the glitch
/// without its head) and in its head (the whole minus the body; whitening
/// is linear).
pub fn koi_fish_shares(run: &mut gwml_runtime::Run, settings: &[(&'static str, f64)]) -> Result<(f64, f64), Error> {
    let (whole, norm) = signal_and_norm(run, KOI_FISH, settings)?;
    let mut body = settings.to_vec();
    body.iter_mut().filter(|p| p.0 == "head").for_each(|p| p.1 = 0.0);
    let (body, _) = signal_and_norm(run, KOI_FISH, &body)?;
    let head: Vec<f64> = whole.iter().zip(&body).map(|(a, b)| a - b).collect();
    let share = |w: &[f64]| w.iter().map(|v| v * v).sum::<f64>() / (norm * norm);
    Ok((share(&body), share(&head)))
}

/// The energy-weighted mean time of a clean signal, in seconds from the
/// start of its row.
pub fn signal_centre(w: &[f64]) -> f64 {
    let (sum, weighted) = w.iter().enumerate().fold((0.0, 0.0), |(s, m), (i, v)| (s + v * v, m + v * v * i as f64));
    if sum > 0.0 {
        weighted / sum / RATE
    } else {
        0.5
    }
}

/// The whitened signal of `class` with shape params `settings` moved so its
/// [`signal_centre`] is at `at` seconds (by its time param, `t0`, or `tc`
/// for the chirp, so nothing wraps around the row), and its norm. A signal
/// longer than the row moves its centre less than its time param: up to
/// three corrections, stopping within 1 ms; the longest Scratchy and
/// Scattered Light fill the row and stay nearer its middle.
fn placed_signal(run: &mut gwml_runtime::Run, class: usize, settings: &mut [(&str, f64)], at: f64) -> Result<(Vec<f64>, f64), Error> {
    let time = if class == CHIRP { "tc" } else { "t0" };
    let mut placed = signal_and_norm(run, class, settings)?;
    for _ in 0..3 {
        let shift = at - signal_centre(&placed.0);
        if shift.abs() < 1e-3 {
            break;
        }
        settings.iter_mut().filter(|p| p.0 == time).for_each(|p| p.1 += shift);
        placed = signal_and_norm(run, class, settings)?;
    }
    Ok(placed)
}

/// Ranges of the glitch benchmark's data.
#[derive(Clone, Debug)]
pub struct GlitchOptions {
    /// Examples to draw (classes uniformly at random).
    pub n: usize,
    /// Seed: the same seed gives the same dataset; use different seeds for
    /// training, validation and test sets.
    pub seed: u64,
    /// One optimal-SNR range (uniform) for every class, for tests at a
    /// stated loudness; `None`: each class's own range
    /// ([`super::snr_range`]).
    pub snr: Option<(f64, f64)>,
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
    /// Where signals are centred (their energy centre, in seconds), drawn
    /// uniformly, the same for every class: 0.3–0.7 by default; 0.4–0.6 as
    /// a scan's trigger window sees them.
    pub position: (f64, f64),
    /// Unit-variance Gaussian noise only: no PSD misestimate, residual lines
    /// or weak transients ([`NoiseExtras`]).
    pub ideal_noise: bool,
}

impl Default for GlitchOptions {
    fn default() -> Self {
        GlitchOptions { n: 1000, seed: 1, snr: None, psd_knee: 0.0, class: None, position: (0.3, 0.7), ideal_noise: false }
    }
}

/// Signal centres of a scan's 1 s trigger windows (see [`GlitchOptions::position`]).
pub const CENTRED: (f64, f64) = (0.4, 0.6);

/// Classes a weak background transient is drawn from (every glitch class).
const BACKGROUND: [usize; 6] = [1, 2, 3, 4, 6, 7];
/// Chance of a weak transient in a None row, and in any other row.
const BACKGROUND_IN_NONE: f64 = 0.75;
const BACKGROUND_ELSEWHERE: f64 = 0.1;
/// Optimal SNR range of the weak transients (below a scan's trigger
/// threshold of 7.5), and where they sit in rows of the other classes; in
/// a None row the transient is what a scan's window would be centred on,
/// so it sits where signals do ([`GlitchOptions::position`]): noise rows
/// whose loudest moment could be anywhere while every glitch's is near the
/// middle would give None away by position alone.
const BACKGROUND_SNR: (f64, f64) = (2.0, 5.0);
const BACKGROUND_AT: (f64, f64) = (0.1, 0.9);

/// Draws whitened segments `x` (`n × 4096`) with labels `label` (`n`,
/// indices into [`GLITCH_CLASSES`]) of the benchmark population
/// ([`super::population`]). A None row is noise, three in four of them
/// with a weak (SNR 2–5) transient of a glitch class where signals are
/// centred; one row in ten of the other classes carries such a transient
/// anywhere in 0.1–0.9 s. Half the Blips, Koi Fish and Tomtes take the
/// shape of a real glitch's fit instead of their formula
/// ([`super::real_fits`]; a Koi Fish's with its fitted SNR).
pub fn glitches(o: &GlitchOptions) -> Result<Dataset, Error> {
    glitches_with(o, &mut |_| Ok(None))
}

/// A glitch shape from outside the library's formulas.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    /// The clean whitened glitch: 4096 samples at 4096 Hz, at any scale.
    pub samples: Vec<f64>,
    /// The optimal SNR it comes with (a real glitch's fitted loudness), or
    /// `None` to draw the class's; a fixed SNR range given by the caller
    /// overrides it.
    pub snr: Option<f64>,
}

impl From<Vec<f64>> for Shape {
    /// A shape without an SNR of its own.
    fn from(samples: Vec<f64>) -> Shape {
        Shape { samples, snr: None }
    }
}

impl Shape {
    /// The SNR to inject it at: its own unless `fixed` was asked for,
    /// else `drawn`.
    pub fn snr_or(&self, fixed: Option<(f64, f64)>, drawn: f64) -> f64 {
        match (fixed, self.snr) {
            (None, Some(own)) => own,
            _ => drawn,
        }
    }
}

/// A source of glitch shapes other than the library's formulas (a fitted
/// generator, real glitches' fits): `shape(class)` gives a shape for that
/// class, or `None` to draw the class's formula.
pub type ShapeSource<'a> = dyn FnMut(usize) -> Result<Option<Shape>, Error> + 'a;

/// [`glitches`], with the shapes of some classes from `shape`: each such
/// row is its noise plus the given shape, its energy centre moved to the
/// drawn centre, scaled to the drawn SNR.
pub fn glitches_with(o: &GlitchOptions, shape: &mut ShapeSource<'_>) -> Result<Dataset, Error> {
    if let Some(snr) = o.snr.filter(|r| !(r.0 > 0.0 && r.1 >= r.0 && r.1.is_finite())) {
        return Err(Error::Bind(format!("SNR range {}..{} must be positive and increasing", snr.0, snr.1)));
    }
    if o.psd_knee.is_nan() || o.psd_knee < 0.0 || o.psd_knee.is_infinite() {
        return Err(Error::Bind(format!("the PSD knee {} Hz must be zero or positive", o.psd_knee)));
    }
    if !(o.position.0 >= 0.05 && o.position.1 >= o.position.0 && o.position.1 <= 0.95) {
        return Err(Error::Bind(format!("signal centres {}..{} s must be increasing within 0.05..0.95 s", o.position.0, o.position.1)));
    }
    if let Some(c) = o.class.filter(|c| *c >= GLITCH_CLASSES.len()) {
        return Err(Error::Bind(format!("class {c} is not one of the {} glitch classes", GLITCH_CLASSES.len())));
    }
    let signals = GlitchSignals::new()?;
    let mut run = signals.bind();
    let noise_scene = signals.model.scene(Some("coloured_noise"))?;
    let mut noise_run = noise_scene.bind();
    noise_run.param("knee", o.psd_knee)?;
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(o.seed);
    let (mut x, mut labels) = (Vec::with_capacity(o.n * SAMPLES), Vec::with_capacity(o.n));
    for _ in 0..o.n {
        let class = o.class.unwrap_or_else(|| rng.random_range(0..GLITCH_CLASSES.len()));
        let mut row: Vec<f64> = (0..SAMPLES).map(|_| StandardNormal.sample(&mut rng)).collect();
        let extras = (!o.ideal_noise).then(|| NoiseExtras::draw(&mut rng));
        if o.psd_knee > 0.0 || extras.is_some() {
            let e = extras.clone().unwrap_or_default();
            noise_run.param("tilt", e.tilt)?;
            noise_run.param("curve", e.curve)?;
            noise_run.input_real("n", &row)?;
            match noise_run.forward()?.value("noise")? {
                Value::RealArray(coloured) => row.clone_from(coloured),
                _ => return Err(Error::Bind("the coloured-noise scene's output is not a real array".into())),
            }
        }
        if let Some(e) = &extras {
            e.add_lines(&mut row, RATE);
            let chance = if class == 0 { BACKGROUND_IN_NONE } else { BACKGROUND_ELSEWHERE };
            if rng.random_bool(chance) {
                let weak = BACKGROUND[rng.random_range(0..BACKGROUND.len())];
                let snr = rng.random_range(BACKGROUND_SNR.0..=BACKGROUND_SNR.1);
                let mut settings = draw_signal_shape(&mut run, &mut rng, weak, snr)?;
                let (lo, hi) = if class == 0 { o.position } else { BACKGROUND_AT };
                let at = rng.random_range(lo..=hi);
                let (w, norm) = placed_signal(&mut run, weak, &mut settings, at)?;
                row.iter_mut().zip(&w).for_each(|(r, v)| *r += snr * v / norm);
            }
        }
        if class == 0 && !o.ideal_noise {
            // A scan's window is centred on what triggered it: the row's
            // loudest moment goes where signals are centred (a circular
            // shift leaves the noise's statistics unchanged).
            let at = rng.random_range(o.position.0..=o.position.1);
            row = crate::generator::learned::roll(&row, ((at - loudest_moment(&row)) * RATE).round() as i64);
        }
        if class > 0 {
            let at = rng.random_range(o.position.0..=o.position.1);
            let mut snr = draw_snr(&mut rng, class, o.snr);
            let given = match shape(class)? {
                Some(s) => Some(s),
                None => super::real_fits::draw(&mut rng, class),
            };
            let (w, norm) = match given {
                Some(s) => {
                    let norm = s.samples.iter().map(|v| v * v).sum::<f64>().sqrt();
                    if s.samples.len() != SAMPLES || !(norm > 0.0 && norm.is_finite()) {
                        return Err(Error::Bind(format!(
                            "a generated {} is not {SAMPLES} finite samples with energy",
                            GLITCH_CLASSES[class]
                        )));
                    }
                    snr = s.snr_or(o.snr, snr);
                    (centred_at(&s.samples, at), norm)
                }
                None => {
                    let mut settings = draw_signal_shape(&mut run, &mut rng, class, snr)?;
                    placed_signal(&mut run, class, &mut settings, at)?
                }
            };
            row.iter_mut().zip(&w).for_each(|(r, v)| *r += snr * v / norm);
        }
        x.extend(row);
        labels.push(class as f64);
    }
    let mut arrays = BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![o.n, SAMPLES], x)?);
    arrays.insert("label".to_string(), Array::new(vec![o.n], labels)?);
    Ok(Dataset { arrays })
}

/// Where x² smoothed over 8 ms (circularly, as the row is rolled) peaks,
/// in seconds from the row's start.
pub fn loudest_moment(x: &[f64]) -> f64 {
    let n = x.len();
    let mut prefix = vec![0.0; 3 * n + 1];
    for i in 0..3 * n {
        prefix[i + 1] = prefix[i] + x[i % n] * x[i % n];
    }
    let power = |i: usize| prefix[n + i + 17] - prefix[n + i - 16];
    (0..n).max_by(|a, b| power(*a).total_cmp(&power(*b))).unwrap_or(0) as f64 / RATE
}

/// `s` shifted circularly so that its [`signal_centre`] is at `at` seconds.
fn centred_at(s: &[f64], at: f64) -> Vec<f64> {
    crate::generator::learned::roll(s, ((at - signal_centre(s)) * RATE).round() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::population::{snr_range, BLIP as BLIP_CLASS, KOI_FISH};

    #[test]
    fn glitch_classes_are_named_in_any_case_with_underscores_for_spaces() {
        assert_eq!(glitch_class("Koi Fish"), Ok(2));
        assert_eq!(glitch_class("koi_fish"), Ok(2));
        assert_eq!(glitch_class(" SCATTERED_light "), Ok(7));
        let e = glitch_class("Koi").unwrap_err();
        assert!(e.contains("no glitch class `Koi`") && e.contains("Scattered Light"), "{e}");
    }

    #[test]
    fn generated_shapes_replace_the_formula_at_the_drawn_snr_and_centre() {
        // One Blip row in ideal noise: its noise, then its centre and SNR.
        let mut spike = vec![0.0; SAMPLES];
        (spike[1000], spike[1001]) = (3.0, -4.0);
        let o = GlitchOptions { n: 1, seed: 9, snr: Some((10.0, 20.0)), class: Some(1), ideal_noise: true, ..Default::default() };
        // Its own SNR (as a real Koi Fish fit brings) yields to the fixed range.
        let shape = Shape { samples: spike.clone(), snr: Some(300.0) };
        let ds = glitches_with(&o, &mut |c| Ok((c == 1).then(|| shape.clone()))).unwrap();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
        let noise: Vec<f64> = (0..SAMPLES).map(|_| StandardNormal.sample(&mut rng)).collect();
        let at: f64 = rng.random_range(0.3..=0.7);
        let snr = rng.random_range(10.0..=20.0);
        // The spike's energy centre (sample 1000 + 16/25) lands on `at`.
        let shift = (at * RATE - (1000.0 + 16.0 / 25.0)).round() as usize;
        let row = ds.arrays["x"].row(0);
        for i in 0..SAMPLES {
            let s = if i == 1000 + shift {
                3.0
            } else if i == 1001 + shift {
                -4.0
            } else {
                0.0
            };
            assert!((row[i] - (noise[i] + snr * s / 5.0)).abs() < 1e-12, "sample {i}");
        }
        assert_eq!(ds.arrays["label"].data, [1.0]);
        // Without a fixed range the shape's own SNR is the injected one.
        let own = GlitchOptions { snr: None, ..o.clone() };
        let ds = glitches_with(&own, &mut |c| Ok((c == 1).then(|| shape.clone()))).unwrap();
        let row = ds.arrays["x"].row(0);
        let spike_at = |i: usize| row[i] - noise[i];
        assert!((spike_at(1000 + shift) - 300.0 * 3.0 / 5.0).abs() < 1e-9, "{}", spike_at(1000 + shift));
        // A shape of the wrong length is an error, not a silent cut.
        assert!(glitches_with(&o, &mut |_| Ok(Some(vec![1.0; 10].into()))).is_err());
    }

    #[test]
    fn glitch_data_is_reproducible_covers_every_class_and_has_the_drawn_snr() {
        let o = GlitchOptions { n: 160, seed: 3, snr: Some((60.0, 60.0)), ideal_noise: true, ..Default::default() };
        let a = glitches(&o).unwrap();
        assert_eq!(a, glitches(&o).unwrap());
        let labels = &a.arrays["label"].data;
        for (c, name) in GLITCH_CLASSES.iter().enumerate() {
            let k = labels.iter().filter(|l| **l == c as f64).count();
            assert!(k >= 8, "class {name} drawn {k} times of 160");
        }
        // Unit-variance noise plus a signal of optimal SNR 60: the row's
        // power exceeds the noise's 4096 by 3600 (the noise's own spread is
        // ±90 per row, the cross term ±120).
        let x = &a.arrays["x"];
        for (i, label) in labels.iter().enumerate() {
            let excess = x.row(i).iter().map(|v| v * v).sum::<f64>() - 4096.0;
            let expected = if *label == 0.0 { 0.0 } else { 3600.0 };
            assert!((excess - expected).abs() < 600.0, "class {label} row {i}: excess power {excess}");
        }
    }

    /// Every class's signal is placed with its energy centre at the drawn
    /// time, so position says nothing about the class.
    #[test]
    fn every_class_is_centred_where_drawn() {
        let signals = GlitchSignals::new().unwrap();
        let mut run = signals.bind();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        for (class, name) in GLITCH_CLASSES.iter().enumerate().skip(1) {
            let mut misses = Vec::new();
            for _ in 0..20 {
                let at = rng.random_range(0.3..=0.7);
                let (w, _) = placed_signal(&mut run, class, &mut draw_shape(&mut rng, class), at).unwrap();
                misses.push((signal_centre(&w) - at).abs());
            }
            misses.sort_by(f64::total_cmp);
            // Within 2 ms (median) and 10 ms; Scratchy and Scattered Light,
            // most longer than the row, cannot move far from its middle.
            let (median, worst) = (misses[10], misses[19]);
            let long = [4, 7].contains(&class);
            let (median_max, worst_max) = if long { (0.05, 0.15) } else { (0.002, 0.01) };
            assert!(median < median_max && worst < worst_max, "{name}: median miss {median} s, worst {worst} s");
        }
    }

    /// Every Koi Fish drawn has a body carrying at least
    /// [`KOI_FISH_BODY_SHARE`] of the whitened energy and a head seen at
    /// [`KOI_FISH_HEAD_SNR`] (or its share capped at low SNR), where the
    /// free draws of the params often have neither (the check is not idle).
    #[test]
    fn koi_fish_have_a_loud_body_and_a_visible_head() {
        let signals = GlitchSignals::new().unwrap();
        let mut run = signals.bind();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(8);
        let free: Vec<(f64, f64)> = (0..200).map(|_| koi_fish_shares(&mut run, &draw_shape(&mut rng, KOI_FISH)).unwrap()).collect();
        let head_led = free.iter().filter(|s| s.0 < KOI_FISH_BODY_SHARE).count();
        let faint = free.iter().filter(|s| s.1 < (KOI_FISH_HEAD_SNR / 20.0).powi(2)).count();
        assert!((60..=170).contains(&head_led) && faint >= 4, "{head_led} head-led, {faint} faint at SNR 20 of 200: {free:?}");
        for snr in [6.0, 12.0, 40.0, 300.0] {
            for _ in 0..10 {
                let settings = draw_signal_shape(&mut run, &mut rng, KOI_FISH, snr).unwrap();
                let (body, head) = koi_fish_shares(&mut run, &settings).unwrap();
                assert!(body >= KOI_FISH_BODY_SHARE, "SNR {snr}: body share {body}");
                let seen = snr * head.sqrt();
                assert!(seen >= KOI_FISH_HEAD_SNR - 1e-9 || head >= KOI_FISH_MAX_HEAD_SHARE, "SNR {snr}: head at SNR {seen}");
                let head = settings.iter().find(|p| p.0 == "head").unwrap().1;
                assert!((0.5..=4.0).contains(&head), "head {head}");
            }
        }
        // Other classes are drawn as draw_shape draws them.
        let (mut a, mut b) = (rand_pcg::Pcg64Mcg::seed_from_u64(9), rand_pcg::Pcg64Mcg::seed_from_u64(9));
        assert_eq!(draw_signal_shape(&mut run, &mut a, BLIP_CLASS, 20.0).unwrap(), draw_shape(&mut b, BLIP_CLASS));
    }

    /// Every class takes the drawn phase: a phase of π negates the signal (a
    /// class told apart by a fixed phase would teach a classifier something
    /// no real glitch has).
    #[test]
    fn every_signal_takes_the_drawn_phase() {
        let signals = GlitchSignals::new().unwrap();
        let mut run = signals.bind();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(6);
        for (class, name) in GLITCH_CLASSES.iter().enumerate().skip(1) {
            let mut settings = draw_shape(&mut rng, class);
            settings.iter_mut().filter(|p| p.0 == "phi").for_each(|p| p.1 = 0.0);
            let w0 = unit_signal(&mut run, class, &settings).unwrap();
            settings.iter_mut().filter(|p| p.0 == "phi").for_each(|p| p.1 = std::f64::consts::PI);
            let w1 = unit_signal(&mut run, class, &settings).unwrap();
            let worst = w0.iter().zip(&w1).map(|(a, b)| (a + b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-9, "{name}: phase π differs from the negated signal by {worst}");
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
        let o = GlitchOptions { n: 100, seed: 9, class: Some(0), ideal_noise: true, ..Default::default() };
        let plain = glitches(&o).unwrap();
        let shifted = glitches(&GlitchOptions { psd_knee: knee, ..o.clone() }).unwrap();
        let power = |d: &Dataset| -> f64 { d.arrays["x"].data.iter().map(|v| v * v).sum() };
        let ratio = power(&shifted) / power(&plain);
        let expected = 1.0 + knee * knee * (1.0 / 20.0 - 1.0 / 2000.0) / 2048.0;
        assert!((ratio / expected - 1.0).abs() < 0.03, "power ratio {ratio}, expected {expected}");
        assert!(glitches(&GlitchOptions { psd_knee: -1.0, ..Default::default() }).is_err());
    }

    /// Realistic noise: the mains line stands out of the noise at 60 Hz on
    /// average, and a None row's loudest moment and weak transient sit where
    /// signals are centred (more energy in 0.4–0.6 s than in 0.05–0.25 s).
    #[test]
    fn realistic_noise_has_lines_and_centred_weak_transients() {
        let n = 800;
        let o = GlitchOptions { n, seed: 11, class: Some(0), ..Default::default() };
        let d = glitches(&o).unwrap();
        let x = &d.arrays["x"];
        let bin = |row: &[f64], f: f64| {
            let (c, s) = row.iter().enumerate().fold((0.0, 0.0), |(c, s), (i, v)| {
                let a = std::f64::consts::TAU * f * i as f64 / RATE;
                (c + v * a.cos(), s + v * a.sin())
            });
            (c * c + s * s) / SAMPLES as f64
        };
        let mains = (0..200).map(|i| bin(x.row(i), 60.0)).sum::<f64>() / 200.0;
        let neighbour = (0..200).map(|i| bin(x.row(i), 75.0)).sum::<f64>() / 200.0;
        // E|bin|² / N is 1 for the noise and 1 + N a² / 4 with a line of
        // amplitude a, uniform on 0..0.05: 1 + 4096 · 0.05² / 12 ≈ 1.85.
        assert!(mains > 1.5 && neighbour < 1.3, "60 Hz bin {mains}, 75 Hz bin {neighbour}");
        // Three rows in four carry SNR 2-5 (E[SNR²] = 13), most of it within
        // 0.1 s of its centre: ~7,000 of energy over 800 rows against a
        // noise spread of ~1,600 in the difference of two 0.2 s windows.
        let energy = |from: f64| -> f64 {
            let (a, b) = ((from * RATE) as usize, ((from + 0.2) * RATE) as usize);
            (0..n).map(|i| x.row(i)[a..b].iter().map(|v| v * v).sum::<f64>()).sum()
        };
        let excess = energy(0.4) - energy(0.05);
        assert!(excess > 2000.0, "None rows: centre minus edge energy {excess}");
        let off_centre = (0..n).filter(|i| !(0.29..=0.71).contains(&loudest_moment(x.row(*i)))).count();
        assert_eq!(off_centre, 0, "None rows whose loudest moment is outside 0.3-0.7 s");
    }

    /// A loud Blip and a quiet Koi Fish exist: the SNR ranges overlap, and
    /// the drawn SNRs fill the overlap.
    #[test]
    fn blip_and_koi_fish_loudness_overlap() {
        let (blip, koi) = (snr_range(1), snr_range(KOI_FISH));
        assert!(blip.1 > 2.0 * koi.0, "Blip up to {}, Koi Fish from {}", blip.1, koi.0);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(1);
        let louder = (0..1000).filter(|_| draw_snr(&mut rng, 1, None) > draw_snr(&mut rng, KOI_FISH, None)).count();
        assert!(louder > 50, "a Blip is louder than a Koi Fish in {louder} of 1000 pairs");
    }
}
