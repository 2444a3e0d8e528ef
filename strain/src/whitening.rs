//! Whitening of strain by a PSD estimated from the data, with the gwml
//! scene `strain/models/whiten.gw`: the one owner of that scene, used by
//! the scan's chunks and by the views around one time (`gwml qscan`,
//! `gwml explain`).

use crate::psd::{Psd, Welch, WelchOptions};
use crate::series::Series;
use crate::Error;
use gwml_compiler::Options;
use gwml_runtime::{Model, Scene, Value};
use num_complex::Complex64;
use std::sync::{Arc, Mutex};

/// The whitening scene.
const WHITEN_SOURCE: &str = include_str!("../models/whiten.gw");

/// The whitening scene, parsed and checked once; compiled once per length,
/// sample rate and options, and kept.
pub struct Whitener {
    model: Model,
    compiled: Mutex<Vec<(SceneKey, Arc<Scene>)>>,
}

/// What a compiled whitening scene depends on (the last: whether it
/// outputs `w_spectrum` instead of `w`).
type SceneKey = (usize, u64, [u64; 5], bool);

/// How a stretch is whitened.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WhitenOptions {
    /// Seconds tapered to zero at each end (a Tukey window).
    pub taper: f64,
    /// Band of the output `w` (Hz).
    pub band: (f64, f64),
    /// Band of the second output `w_clf` (Hz), the classifier's.
    pub classifier_band: (f64, f64),
}

impl Whitener {
    /// Parses and checks `whiten.gw`.
    pub fn new() -> Result<Whitener, Error> {
        let model = Model::from_source("whiten.gw", WHITEN_SOURCE).map_err(|e| Error::Data(e.render(false)))?;
        Ok(Whitener { model, compiled: Mutex::new(Vec::new()) })
    }

    /// The scene compiled for `n` samples at `sample_rate`: inputs `x` (the
    /// strain) and `psd` (on the `n / 2 + 1` bins of the chunk's spectrum),
    /// outputs `w` and `w_clf` (read them with [`whiten_with`]). Compiled on
    /// the first call with these arguments, shared after.
    pub fn scene(&self, n: usize, sample_rate: f64, o: &WhitenOptions) -> Result<Arc<Scene>, Error> {
        self.scene_for(n, sample_rate, o, false)
    }

    /// [`Whitener::scene`] with outputs `w_spectrum` (the spectrum of `w`)
    /// and `w_clf`, read with [`whiten_spectrum_with`].
    pub fn spectrum_scene(&self, n: usize, sample_rate: f64, o: &WhitenOptions) -> Result<Arc<Scene>, Error> {
        self.scene_for(n, sample_rate, o, true)
    }

    fn scene_for(&self, n: usize, sample_rate: f64, o: &WhitenOptions, spectrum: bool) -> Result<Arc<Scene>, Error> {
        let bands = [o.taper, o.band.0, o.band.1, o.classifier_band.0, o.classifier_band.1].map(f64::to_bits);
        let key = (n, sample_rate.to_bits(), bands, spectrum);
        if let Some((_, scene)) = self.compiled.lock().expect("no thread panics holding it").iter().find(|(k, _)| *k == key) {
            return Ok(scene.clone());
        }
        let scene = Arc::new(self.compile(n, sample_rate, o, spectrum)?);
        self.compiled.lock().expect("no thread panics holding it").push((key, scene.clone()));
        Ok(scene)
    }

    fn compile(&self, n: usize, sample_rate: f64, o: &WhitenOptions, spectrum: bool) -> Result<Scene, Error> {
        let duration = n as f64 / sample_rate;
        let knobs = [
            ("rate", format!("{sample_rate:?} Hz")),
            ("duration", format!("{duration:?} s")),
            ("taper", format!("{:?} s", o.taper)),
            ("f_low", format!("{:?} Hz", o.band.0)),
            ("f_high", format!("{:?} Hz", o.band.1)),
            ("clf_low", format!("{:?} Hz", o.classifier_band.0)),
            ("clf_high", format!("{:?} Hz", o.classifier_band.1)),
        ];
        let outputs = [if spectrum { "w_spectrum" } else { "w" }, "w_clf"].map(str::to_string).to_vec();
        let knobs = knobs.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        let options = Options { knobs, outputs: Some(outputs), ..Options::default() };
        self.model.scene_with(None, options).map_err(|e| Error::Data(e.render(false)))
    }
}

/// Whitens `x` (sampled at `fs`, starting at GPS `gps_start`, from
/// `source`) by `psd` with a compiled [`Whitener::scene`] bound as `run`:
/// `(w, w_clf)`. A non-finite result is an error naming its GPS time.
pub fn whiten_with(
    run: &mut gwml_runtime::Run,
    x: &[f64],
    psd: &Psd,
    (fs, gps_start, source): (f64, f64, &str),
) -> Result<(Vec<f64>, Vec<f64>), Error> {
    let mut out = forward(run, x, psd, fs)?;
    let (w, w_clf) = (take_real(&mut out, "w")?, take_real(&mut out, "w_clf")?);
    let n = x.len();
    if let Some(i) = w.iter().chain(&w_clf).position(|v| !v.is_finite()) {
        return Err(Error::Data(format!("whitening made a non-finite value at GPS {:.4} ({source})", gps_start + (i % n) as f64 / fs)));
    }
    Ok((w, w_clf))
}

/// [`whiten_with`] for a [`Whitener::spectrum_scene`]: `(spectrum of w,
/// w_clf)`, the spectrum on the `n / 2 + 1` bins of the rfft.
pub fn whiten_spectrum_with(
    run: &mut gwml_runtime::Run,
    x: &[f64],
    psd: &Psd,
    (fs, gps_start, source): (f64, f64, &str),
) -> Result<(Vec<Complex64>, Vec<f64>), Error> {
    let mut out = forward(run, x, psd, fs)?;
    let w_clf = take_real(&mut out, "w_clf")?;
    let spectrum = match out.values.iter_mut().find(|(n, _)| n == "w_spectrum") {
        Some((_, Value::ComplexArray(v))) => std::mem::take(v),
        _ => return Err(Error::Data("the whitening scene has no complex array `w_spectrum`".into())),
    };
    if let Some(i) = w_clf.iter().position(|v| !v.is_finite()) {
        return Err(Error::Data(format!("whitening made a non-finite value at GPS {:.4} ({source})", gps_start + i as f64 / fs)));
    }
    if let Some(k) = spectrum.iter().position(|v| !(v.re.is_finite() && v.im.is_finite())) {
        return Err(Error::Data(format!(
            "whitening made a non-finite value at {:.2} Hz in the spectrum of GPS {gps_start:.1}+{:.0} s ({source})",
            k as f64 * fs / x.len() as f64,
            x.len() as f64 / fs
        )));
    }
    Ok((spectrum, w_clf))
}

/// Binds `x` and `psd` (resampled onto the chunk's bins) and runs the scene.
fn forward(run: &mut gwml_runtime::Run, x: &[f64], psd: &Psd, fs: f64) -> Result<gwml_runtime::Outputs, Error> {
    let n = x.len();
    let psd_grid = psd.resample(fs / n as f64, n / 2 + 1);
    let fail = |e: gwml_runtime::Error| Error::Data(format!("whitening failed: {}", e.render(false)));
    run.input_real("x", x).map_err(fail)?;
    run.input_real("psd", &psd_grid).map_err(fail)?;
    run.forward().map_err(fail)
}

/// Moves the real array output `name` out of `out`.
fn take_real(out: &mut gwml_runtime::Outputs, name: &str) -> Result<Vec<f64>, Error> {
    match out.values.iter_mut().find(|(n, _)| n == name) {
        Some((_, Value::RealArray(v))) => Ok(std::mem::take(v)),
        _ => Err(Error::Data(format!("the whitening scene has no real array `{name}`"))),
    }
}

/// A whitened stretch of strain.
#[derive(Clone, Debug, PartialEq)]
pub struct Whitened {
    /// GPS time of the first sample.
    pub gps_start: f64,
    /// Samples per second.
    pub sample_rate: f64,
    /// Whitened over [`WhitenOptions::band`] (unit variance per sample in noise).
    pub w: Vec<f64>,
    /// Whitened over [`WhitenOptions::classifier_band`].
    pub w_clf: Vec<f64>,
    /// The PSD it was whitened by (estimated from the same samples).
    pub psd: Psd,
}

/// Whitens the whole of `series` (which must hold no missing samples) by
/// its own Welch PSD (`fft_length` s segments).
pub fn whiten_series(whitener: &Whitener, series: &Series, fft_length: f64, o: &WhitenOptions) -> Result<Whitened, Error> {
    let fs = series.sample_rate;
    if let Some(i) = series.samples.iter().position(|v| !v.is_finite()) {
        return Err(Error::Data(format!(
            "{}: no data at GPS {:.3} (a missing stretch) within the {} s needed",
            series.source,
            series.gps_start + i as f64 / fs,
            series.duration()
        )));
    }
    let welch = Welch::new(fs, WelchOptions::seconds(fft_length, fs))?;
    let scene = whitener.scene(series.samples.len(), fs, o)?;
    let mut run = scene.bind();
    let psd = welch.estimate(&series.samples)?;
    let (w, w_clf) = whiten_with(&mut run, &series.samples, &psd, (fs, series.gps_start, &series.source))?;
    Ok(Whitened { gps_start: series.gps_start, sample_rate: fs, w, w_clf, psd })
}
