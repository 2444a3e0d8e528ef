//! `gwml data strain`: realistic long strain for users and tests, coloured
//! Gaussian noise from a PSD with glitches of the library's families
//! injected at known times, optional stretches of missing data, in the
//! layout of a GWOSC file.
//!
//! Noise: each frequency bin of the whole duration is an independent
//! complex Gaussian of variance `S(f)/(2 df)` (runtime's `noise`
//! convention), inverse-FFT'd, so the noise is exactly stationary with
//! one-sided PSD `S`. Glitches: the signals of `lab/models/glitch/synth.gw`
//! (scene `glitch_strain`) with shape params drawn as for `gwml data glitch`
//! ([`crate::synth::draw_signal_shape`]), centred on their injection time (the
//! chirp's merger at it, [`CHIRP_TAIL`] s before the window's end), drawn
//! over an [`INJECTION_WINDOW`] of 4 s — Scratchy glitches last up to 2.5 s
//! and Scattered Light up to 4 s, as real ones do — and cut to it by a
//! Tukey taper of [`TAPER`] s at each end (so that a glitch longer than the
//! window does not end in a step, a broadband transient of its own),
//! scaled to an optimal SNR drawn uniformly from the
//! range: `ρ² = 4 df Σ |h̃(f)|² / S(f)` over 20 Hz–2 kHz, the band of the
//! glitch datasets. Injection times: a Poisson process of the given rate,
//! at least 2 s apart and 10 s from the ends, never in a gap.

use crate::synth::ShapeSource;
use crate::synth::{draw_signal_shape, draw_snr, GlitchSignals, GLITCH_CLASSES};
use gwml_runtime::noise::colored_noise;
use gwml_runtime::spectrum::Spectrum;
use gwml_runtime::{Error, Model, Value};
use gwml_strain::series::Series;
use rand::{Rng, SeedableRng};
use realfft::RealFftPlanner;

/// Sample rate of simulated strain (that of the glitch signal scene).
pub const SAMPLE_RATE: f64 = 4096.0;
/// The band (Hz) an injection's SNR, energy span and colouring are
/// computed over: that of the glitch datasets.
const SIGNAL_BAND: (f64, f64) = (20.0, 2000.0);

/// Whether `f` (Hz) lies in [`SIGNAL_BAND`].
fn in_signal_band(f: f64) -> bool {
    (SIGNAL_BAND.0..=SIGNAL_BAND.1).contains(&f)
}

/// Seconds of strain each injected signal is drawn over, centred on it.
/// (Until 2026-11-26 it was 1 s, which cut long glitches short: a 2.5 s
/// Scratchy was injected as a 1 s one.)
pub const INJECTION_WINDOW: f64 = 4.0;

/// Seconds from a chirp's merger to the end of its window, as the glitch
/// benchmark's 1 s rows place it (`tc` 0.8-0.95 s).
pub const CHIRP_TAIL: f64 = 0.1;

/// Length (s) of the cosine taper at each end of an injection's window.
pub const TAPER: f64 = 0.1;

/// The Tukey window that cuts an injected signal to `n` samples at `fs`:
/// a half cosine rising over the first [`TAPER`] s, one in the middle.
fn injection_taper(n: usize, fs: f64) -> Vec<f64> {
    let edge = (TAPER * fs) as usize;
    (0..n)
        .map(|i| {
            let d = i.min(n - 1 - i);
            if d >= edge {
                1.0
            } else {
                0.5 * (1.0 - (std::f64::consts::PI * d as f64 / edge as f64).cos())
            }
        })
        .collect()
}

/// The noise PSD of simulated strain.
#[derive(Clone, Debug)]
pub enum NoiseCurve {
    /// aLIGO zero-detuned high power (`std::psd`), held below 9 Hz.
    Aligo,
    /// A two-column ASD or PSD file (runtime's `spectrum` reader).
    File(Spectrum),
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct StrainOptions {
    /// Seconds of data (whole seconds).
    pub duration: f64,
    /// GPS time of the first sample.
    pub gps_start: f64,
    /// Detector name written to the file.
    pub ifo: String,
    /// Noise PSD.
    pub psd: NoiseCurve,
    /// Mean glitches per minute (0: noise only).
    pub glitch_rate: f64,
    /// Classes to inject (indices into [`GLITCH_CLASSES`], not 0), drawn uniformly.
    pub classes: Vec<usize>,
    /// Optimal SNR range (uniform) for every class; `None`: each class's
    /// own range, log-uniform ([`crate::synth::snr_range`]: Koi Fish loud,
    /// the others from 6.5).
    pub snr: Option<(f64, f64)>,
    /// Missing data: (start seconds from the first sample, length seconds).
    pub gaps: Vec<(f64, f64)>,
    /// Seed.
    pub seed: u64,
}

/// One injected signal.
#[derive(Clone, Debug, PartialEq)]
pub struct Injection {
    /// GPS time of the glitch's centre (the chirp's merger).
    pub gps_time: f64,
    /// GPS span holding the central [`SPAN_ENERGY`] of the signal's
    /// whitened energy (20 Hz–2 kHz): where a search may place the loudest
    /// moment of a long glitch (a Scratchy's arches, a Whistle's sweep).
    pub span: (f64, f64),
    /// Index into [`GLITCH_CLASSES`].
    pub class: usize,
    /// Optimal SNR.
    pub snr: f64,
    /// The shape params the signal scene was given.
    pub params: Vec<(&'static str, f64)>,
}

/// Fraction of an injection's whitened energy inside [`Injection::span`].
pub const SPAN_ENERGY: f64 = 0.9;

impl Injection {
    /// Whether a trigger at `time` marks this injection: within `tolerance`
    /// seconds of its [`span`](Injection::span) (for a short glitch, of its
    /// centre).
    pub fn is_marked_by(&self, time: f64, tolerance: f64) -> bool {
        time >= self.span.0 - tolerance && time <= self.span.1 + tolerance
    }
}

/// The span (sample indices, end exclusive) of `w` holding the central
/// `fraction` of its energy Σ w².
fn energy_span(w: &[f64], fraction: f64) -> (usize, usize) {
    let total: f64 = w.iter().map(|v| v * v).sum();
    let tail = 0.5 * (1.0 - fraction) * total;
    let mut acc = 0.0;
    let start = w.iter().position(|v| {
        acc += v * v;
        acc > tail
    });
    acc = 0.0;
    let end = w.iter().rposition(|v| {
        acc += v * v;
        acc > tail
    });
    match (start, end) {
        (Some(a), Some(b)) if a <= b => (a, b + 1),
        _ => (w.len() / 2, w.len() / 2 + 1),
    }
}

/// Simulates the strain and lists what was injected.
pub fn simulate(o: &StrainOptions) -> Result<(Series, Vec<Injection>), Error> {
    simulate_with(o, &mut |_| Ok(None))
}

/// [`simulate`], with the shapes of some classes from `shape` (clean
/// whitened rows of 4096 samples at 4096 Hz, from a fitted generator):
/// each is coloured by the PSD, so that whitening gives it back, centred in
/// its window and scaled to the drawn SNR.
pub fn simulate_with(o: &StrainOptions, shape: &mut ShapeSource<'_>) -> Result<(Series, Vec<Injection>), Error> {
    if !(o.duration >= 32.0 && o.duration.fract() == 0.0 && o.duration <= 1e6) {
        return Err(Error::Bind(format!("--duration {} must be a whole number of seconds from 32 to 1e6", o.duration)));
    }
    if !(o.glitch_rate >= 0.0 && o.glitch_rate.is_finite() && o.glitch_rate <= 30.0) {
        return Err(Error::Bind(format!("--glitch-rate {} per minute must be between 0 and 30", o.glitch_rate)));
    }
    if let Some(snr) = o.snr.filter(|r| !(r.0 > 0.0 && r.1 >= r.0 && r.1.is_finite())) {
        return Err(Error::Bind(format!("SNR range {}..{} must be positive and increasing", snr.0, snr.1)));
    }
    if o.classes.is_empty() || o.classes.iter().any(|c| *c == 0 || *c >= GLITCH_CLASSES.len()) {
        return Err(Error::Bind("--classes must name at least one signal class (not None)".into()));
    }
    for &(start, len) in &o.gaps {
        if !(start >= 0.0 && len > 0.0 && start + len <= o.duration) {
            return Err(Error::Bind(format!("--gap {start}:{len} must lie inside the {} s of data", o.duration)));
        }
    }
    let fs = SAMPLE_RATE;
    let n = (o.duration * fs) as usize;
    let curve = psd_curve(&o.psd)?;
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(o.seed);
    let samples = noise(n, fs, &curve, rng.random())?;
    let mut series =
        Series { detector: o.ifo.clone(), gps_start: o.gps_start, sample_rate: fs, samples, dq: None, source: "simulated".into() };
    let injections = inject(&mut series, o, &curve, &mut rng, shape)?;
    let seconds = o.duration as usize;
    let mut dq = vec![127u32; seconds];
    for &(start, len) in &o.gaps {
        let (a, b) = ((start * fs) as usize, (((start + len) * fs) as usize).min(n));
        series.samples[a..b].iter_mut().for_each(|v| *v = f64::NAN);
        for word in &mut dq[start.floor() as usize..((start + len).ceil() as usize).min(seconds)] {
            *word = 0;
        }
    }
    series.dq = Some(dq);
    Ok((series, injections))
}

/// The PSD as a function of frequency, positive everywhere.
pub(crate) fn psd_curve(psd: &NoiseCurve) -> Result<Spectrum, Error> {
    match psd {
        NoiseCurve::File(s) => Ok(s.clone()),
        NoiseCurve::Aligo => {
            let model = Model::from_source(
                "aligo.gw",
                "use std::psd::{psd_aligo_zerodet_highpower}\n\
                 scene aligo {\n    grid f = frequencies(from: 9 Hz, to: 4096 Hz, step: 0.25 Hz)\n    \
                 output psd = psd_aligo_zerodet_highpower(f)\n}\n",
            )?;
            let scene = model.scene(None)?;
            let out = scene.bind().forward()?;
            let Value::RealArray(psd) = out.value("psd")?.clone() else {
                return Err(Error::Bind("the aLIGO PSD scene's output is not a real array".into()));
            };
            let freqs = (0..psd.len()).map(|k| 9.0 + 0.25 * k as f64).collect();
            Spectrum::new(freqs, psd, "std::psd aLIGO zero-detuned high power")
        }
    }
}

/// Stationary Gaussian noise of `n` samples with one-sided PSD `curve`.
fn noise(n: usize, fs: f64, curve: &Spectrum, seed: u64) -> Result<Vec<f64>, Error> {
    let df = fs / n as f64;
    let bins = n / 2 + 1;
    let psd: Vec<f64> = (0..bins).map(|k| if k == 0 || k == bins - 1 { 0.0 } else { curve.psd_at(k as f64 * df) }).collect();
    let mut spectrum = colored_noise(&psd, df, seed)?;
    let fft = RealFftPlanner::<f64>::new().plan_fft_inverse(n);
    let mut out = fft.make_output_vec();
    fft.process(&mut spectrum, &mut out).map_err(|e| Error::Bind(format!("inverse FFT failed: {e}")))?;
    // x_j = df Σ_k X_k e^{2πi jk/n} over the two-sided spectrum.
    out.iter_mut().for_each(|v| *v *= df);
    Ok(out)
}

/// Draws injection times and signals and adds them to the samples.
fn inject<R: Rng>(
    series: &mut Series,
    o: &StrainOptions,
    curve: &Spectrum,
    rng: &mut R,
    shape: &mut ShapeSource<'_>,
) -> Result<Vec<Injection>, Error> {
    if o.glitch_rate == 0.0 {
        return Ok(Vec::new());
    }
    let model = Model::from_source("synth.gw", crate::synth::GLITCH_SCENE)?;
    let knobs = vec![("window".to_string(), format!("{INJECTION_WINDOW:?} s"))];
    let scene = model.scene_with(Some("glitch_strain"), gwml_compiler::Options { knobs, ..gwml_compiler::Options::default() })?;
    let mut run = scene.bind();
    // The whitened scene, for the shape draws' checks (`draw_signal_shape`).
    let signals = GlitchSignals::new()?;
    let mut shape_run = signals.bind();
    let fs = series.sample_rate;
    let window = (INJECTION_WINDOW * fs) as usize;
    let df = fs / window as f64;
    let psd: Vec<f64> = (0..=window / 2).map(|k| curve.psd_at(k as f64 * df)).collect();
    let band = |k: usize| in_signal_band(k as f64 * df);
    let mut planner = RealFftPlanner::<f64>::new();
    let (fft, ifft) = (planner.plan_fft_forward(window), planner.plan_fft_inverse(window));
    let taper = injection_taper(window, fs);
    // A generator's rows are 1 s long: coloured and tapered over their own second.
    let row = fs as usize;
    let psd_row: Vec<f64> = (0..=row / 2).map(|k| curve.psd_at(k as f64)).collect();
    let row_plans = (planner.plan_fft_forward(row), planner.plan_fft_inverse(row));
    let row_taper = injection_taper(row, fs);
    let mean_gap = 60.0 / o.glitch_rate;
    let mut injections = Vec::new();
    let mut t = 10.0;
    loop {
        // Exponential waiting times, at least 2 s.
        let u: f64 = rng.random_range(f64::EPSILON..1.0);
        t += (-mean_gap * u.ln()).max(2.0);
        if t > o.duration - 10.0 {
            break;
        }
        let class = o.classes[rng.random_range(0..o.classes.len())];
        let generated = shape(class)?;
        let drawn = draw_snr(rng, class, o.snr);
        let mut params = if generated.is_some() { Vec::new() } else { draw_signal_shape(&mut shape_run, rng, class, drawn)? };
        let snr = generated.as_ref().map_or(drawn, |g| g.snr_or(o.snr, drawn));
        // Glitches centred in their window; a chirp merges CHIRP_TAIL before its end.
        let centre = if class == 5 && generated.is_none() {
            let tc = INJECTION_WINDOW - CHIRP_TAIL;
            params.iter_mut().filter(|p| p.0 == "tc").for_each(|p| p.1 = tc);
            tc
        } else {
            params.iter_mut().filter(|p| p.0 == "t0").for_each(|p| p.1 = 0.5 * INJECTION_WINDOW);
            0.5 * INJECTION_WINDOW
        };
        let window_start = ((t - centre) * fs).round() as usize;
        // The window, t - centre to t - centre + INJECTION_WINDOW, must miss every gap.
        if o.gaps.iter().any(|&(s, l)| t - centre < s + l && t - centre + INJECTION_WINDOW > s) {
            continue;
        }
        let h = match &generated {
            Some(w) => {
                let h = coloured(&w.samples, &psd_row, fs, (&row_plans.0, &row_plans.1))?;
                let mut padded = vec![0.0; window];
                let at = (window - row) / 2;
                padded[at..at + row].iter_mut().zip(h.iter().zip(&row_taper)).for_each(|(x, (v, w))| *x = v * w);
                padded
            }
            None => {
                run.param("class", class as f64)?;
                for (name, value) in &params {
                    run.param(name, *value)?;
                }
                let Value::RealArray(h) = run.forward()?.value("h")?.clone() else {
                    return Err(Error::Bind("the glitch strain scene's output is not a real array".into()));
                };
                h
            }
        };
        let h: Vec<f64> = h.iter().zip(&taper).map(|(v, w)| v * w).collect();
        let mut input: Vec<f64> = h.iter().map(|v| v * 1e-21).collect();
        let mut spectrum = fft.make_output_vec();
        fft.process(&mut input, &mut spectrum).map_err(|e| Error::Bind(format!("FFT failed: {e}")))?;
        let dt = 1.0 / fs;
        let rho2: f64 = (0..spectrum.len()).filter(|k| band(*k)).map(|k| 4.0 * df * (spectrum[k] * dt).norm_sqr() / psd[k]).sum();
        if !(rho2 > 0.0 && rho2.is_finite()) {
            return Err(Error::Bind(format!("a {} signal has no power in 20-2000 Hz", GLITCH_CLASSES[class])));
        }
        let scale = snr / rho2.sqrt() * 1e-21;
        for (x, v) in series.samples[window_start..window_start + window].iter_mut().zip(&h) {
            *x += scale * v;
        }
        // The whitened signal (20 Hz-2 kHz), for the span of its energy.
        for (k, x) in spectrum.iter_mut().enumerate() {
            *x = if band(k) { *x / psd[k].sqrt() } else { 0.0.into() };
        }
        let mut whitened = ifft.make_output_vec();
        ifft.process(&mut spectrum, &mut whitened).map_err(|e| Error::Bind(format!("inverse FFT failed: {e}")))?;
        let (a, b) = energy_span(&whitened, SPAN_ENERGY);
        let at = |i: usize| series.gps_start + (window_start + i) as f64 / fs;
        injections.push(Injection {
            gps_time: series.gps_start + window_start as f64 / fs + centre,
            span: (at(a), at(b - 1)),
            class,
            snr,
            params,
        });
    }
    Ok(injections)
}

/// A generated whitened glitch `w` (one 1 s window at `fs`, which must be
/// its 4096 Hz) as strain in units of 1e-21: centred on its energy, then
/// each bin from 20 Hz to 2 kHz times √(S(f)·fs/2), the inverse of the
/// whitening (`std::detector::whiten`); zero outside that band.
fn coloured(
    w: &[f64],
    psd_1hz: &[f64],
    fs: f64,
    (fft, ifft): (&std::sync::Arc<dyn realfft::RealToComplex<f64>>, &std::sync::Arc<dyn realfft::ComplexToReal<f64>>),
) -> Result<Vec<f64>, Error> {
    if w.len() != fs as usize {
        return Err(Error::Bind(format!("a generator's glitches are {} samples per second, the strain {fs}", w.len())));
    }
    let (mut input, _) = crate::generator::learned::centred(w);
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum).map_err(|e| Error::Bind(format!("FFT failed: {e}")))?;
    for (k, x) in spectrum.iter_mut().enumerate() {
        *x *= if in_signal_band(k as f64) { (psd_1hz[k] * fs / 2.0).sqrt() / 1e-21 / w.len() as f64 } else { 0.0 };
    }
    let mut h = ifft.make_output_vec();
    ifft.process(&mut spectrum, &mut h).map_err(|e| Error::Bind(format!("inverse FFT failed: {e}")))?;
    Ok(h)
}

/// Writes the injections as CSV: `gps_time,label,snr,start,end` (the
/// GPS span of [`Injection::span`]), then one column per
/// shape param of any injected class (in order of first appearance), empty
/// where an injection's class has no such param.
pub fn write_truth(path: &std::path::Path, injections: &[Injection]) -> Result<(), Error> {
    std::fs::write(path, truth_csv(injections)).map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))
}

/// The text of [`write_truth`].
fn truth_csv(injections: &[Injection]) -> String {
    use std::fmt::Write;
    let mut names: Vec<&str> = Vec::new();
    for p in injections.iter().flat_map(|i| &i.params) {
        if !names.contains(&p.0) {
            names.push(p.0);
        }
    }
    let mut text = String::from("gps_time,label,snr,start,end");
    names.iter().for_each(|n| text.push_str(&format!(",{n}")));
    text.push('\n');
    for i in injections {
        let _ = write!(text, "{:.6},{},{:.4},{:.6},{:.6}", i.gps_time, GLITCH_CLASSES[i.class], i.snr, i.span.0, i.span.1);
        for n in &names {
            text.push(',');
            if let Some(p) = i.params.iter().find(|p| p.0 == *n) {
                text.push_str(&p.1.to_string());
            }
        }
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_injection_taper_cuts_smoothly_to_zero_at_the_window_ends() {
        let w = injection_taper(4096, 4096.0);
        assert_eq!((w[0], w[4095]), (0.0, 0.0));
        assert!(w[410..3686].iter().all(|v| *v == 1.0));
        assert!(w.windows(2).take(410).all(|p| p[1] >= p[0]), "rises monotonically");
        assert!((0..4096).all(|i| (w[i] - w[4095 - i]).abs() < 1e-15), "symmetric");
        // The half-way point of the taper is at TAPER / 2.
        assert!((w[205] - 0.5).abs() < 0.01, "{}", w[205]);
    }

    #[test]
    fn truth_columns_line_up_across_classes() {
        let blip = Injection { gps_time: 10.0, span: (9.99, 10.01), class: 1, snr: 12.0, params: vec![("f0", 100.0), ("q", 4.0)] };
        let whistle = Injection { gps_time: 20.0, span: (19.8, 20.2), class: 3, snr: 15.0, params: vec![("f_min", 500.0), ("q", 9.0)] };
        let generated = Injection { gps_time: 30.0, span: (29.9, 30.1), class: 1, snr: 20.0, params: vec![] };
        let text = truth_csv(&[blip, whistle, generated]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "gps_time,label,snr,start,end,f0,q,f_min");
        assert_eq!(lines[1], "10.000000,Blip,12.0000,9.990000,10.010000,100,4,");
        assert_eq!(lines[2], "20.000000,Whistle,15.0000,19.800000,20.200000,,9,500");
        assert_eq!(lines[3], "30.000000,Blip,20.0000,29.900000,30.100000,,,");
    }

    #[test]
    fn the_energy_span_holds_the_central_energy() {
        // A box of ones from 100 to 199 in 1000 zeros: 2.5 % of its energy
        // lies in its first 2.5 samples and 2.5 % in its last 2.5.
        let mut w = vec![0.0; 1000];
        w[100..200].iter_mut().for_each(|v| *v = 1.0);
        assert_eq!(energy_span(&w, 0.95), (102, 198));
        // A single spike is its own span.
        let mut spike = vec![0.0; 64];
        spike[10] = 3.0;
        assert_eq!(energy_span(&spike, 0.9), (10, 11));
    }

    #[test]
    fn long_glitches_are_injected_at_their_full_length() {
        // Scratchy glitches of 0.8-2.5 s: under a Gaussian envelope of 1/e
        // half-width duration / 2 the energy has σ = duration / 4, so its
        // central 90 % spans ±1.645 σ, 0.82 duration: up to 2 s, more than
        // the 1 s window they were once drawn over could hold.
        let o = StrainOptions {
            duration: 200.0,
            gps_start: 0.0,
            ifo: "H1".into(),
            psd: NoiseCurve::Aligo,
            glitch_rate: 12.0,
            classes: vec![4],
            snr: Some((20.0, 20.0)),
            gaps: Vec::new(),
            seed: 9,
        };
        let (_, injections) = simulate(&o).unwrap();
        assert!(injections.len() >= 20, "{} injections", injections.len());
        for i in &injections {
            let duration = i.params.iter().find(|p| p.0 == "duration").unwrap().1;
            let span = i.span.1 - i.span.0;
            assert!((span - 0.82 * duration).abs() < 0.12 * duration, "a {duration:.2} s scratchy's energy spans {span:.2} s");
            assert!((i.snr - 20.0).abs() < 1e-9);
        }
        assert!(injections.iter().any(|i| i.span.1 - i.span.0 > 1.5), "no energy span over 1.5 s");
    }
}
