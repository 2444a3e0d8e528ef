//! Where a trigger's fits start. A long, coherent shape (a whistle's
//! sweep, a scratchy glitch's train of arches) matches a template only
//! when its params are nearly right — a whistle whose span is 100 Hz off
//! is tens of radians out of phase — so a coarse grid of starts misses
//! it. The seeds read those params from the data instead:
//! - the loudest Q tile within 0.25 s of the window's centre gives a time,
//!   a frequency and a Q;
//! - the ridge of the loudest Q plane (the brightest row in each column)
//!   fitted by a parabola `f(t) = f_turn + span ((t − t0) / half)²` gives a
//!   V-shaped track (inverted when it bends down): its vertex and curvature
//!   `span / half²`, and a guess
//!   of `half` from the fall of the ridge's energy, `∝ exp(−2 (t − t0)² /
//!   half²)` under a whistle's Gaussian envelope;
//! - the energy envelope of the data band-passed around the tile's
//!   frequency (the analytic signal's `|z|²`, by FFT) gives an arch rate
//!   (its strongest period in 6–40 Hz), the carrier (the spectrum's
//!   strongest line there), a centre and a duration (four
//!   times its standard deviation, as `exp(−u²)` with `u = 2 dt / duration`
//!   squared has σ = duration / 4).

use super::Window;
use gwml_strain::qimage::{ImageOptions, QTransform};
use gwml_strain::qtransform::QOptions;
use realfft::num_complex::Complex64;
use realfft::RealFftPlanner;

/// Where a trigger's fits start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seed {
    /// The loudest tile's time from the window's centre (s).
    pub dt: f64,
    /// Its frequency (Hz).
    pub frequency: f64,
    /// Its plane's Q.
    pub q: f64,
    /// A V-shaped ridge (or an inverted V), if the data show one.
    pub track: Option<Track>,
    /// A periodic energy envelope around the tile's frequency, if any.
    pub arches: Option<Arches>,
    /// The loudest pixel at or above [`HIGH_BAND`] Hz in the search span
    /// when the loudest tile is below it: `(dt, frequency)`. A Koi Fish's
    /// head, loud at 15-50 Hz, can outshine its blip; this finds the blip.
    pub high: Option<(f64, f64)>,
}

/// Where a Koi Fish's blip is looked for when the loudest tile is lower (Hz).
pub const HIGH_BAND: f64 = 60.0;

/// A V-shaped time-frequency ridge (a whistle's): `f(t) = f_turn +
/// curvature (t − t0)²`, so a whistle of half-width `half` has span
/// `curvature half²` (an inverted V when the curvature is negative).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Track {
    /// Its vertex's time `t0` from the window's centre (s).
    pub dt: f64,
    /// Frequency at the vertex (Hz).
    pub f_turn: f64,
    /// Hz per s².
    pub curvature: f64,
    /// The envelope's 1/e half-width (s), when the ridge's energy falls
    /// off as a Gaussian's.
    pub half: Option<f64>,
}

/// A train of arches (a scratchy glitch's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arches {
    /// The carrier: the strongest line of the spectrum near the loudest
    /// tile's frequency (Hz), to the spectrum's resolution (a Q tile's is
    /// too coarse for a template that stays coherent for a second).
    pub f0: f64,
    /// The envelope's centre from the window's centre (s).
    pub dt: f64,
    /// Arches per second (Hz).
    pub rate: f64,
    /// Four standard deviations of the envelope (s).
    pub duration: f64,
}

/// Normalised tile energy a ridge point needs (noise has mean 1).
const RIDGE_ENERGY: f64 = 8.0;

/// The seed of a window's fits over `band`.
pub fn seed_of(win: &Window, sample_rate: f64, band: (f64, f64)) -> Result<Seed, String> {
    let tiling = QOptions { f_range: band, ..QOptions::default() };
    let q = QTransform::new(&win.d, sample_rate, win.gps_start, &tiling).map_err(|e| e.to_string())?;
    let half_span = (0.75f64).min(0.5 * win.d.len() as f64 / sample_rate - 0.05);
    let image = q
        .image(&ImageOptions {
            outseg: (win.gps_centre - half_span, win.gps_centre + half_span),
            search: Some((win.gps_centre - 0.25, win.gps_centre + 0.25)),
            times: 300,
            frequencies: 120,
        })
        .map_err(|e| e.to_string())?;
    let nf = image.frequencies.len();
    let ridge: Vec<(f64, f64, f64)> = image
        .times
        .iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let column = &image.values[i * nf..(i + 1) * nf];
            let (k, e) = column.iter().enumerate().fold((0, f64::NEG_INFINITY), |b, (k, e)| if *e > b.1 { (k, *e) } else { b });
            (e >= RIDGE_ENERGY).then(|| (t - win.gps_centre, image.frequencies[k], e))
        })
        .collect();
    let (frequency, dt) = (image.peak.frequency, image.peak.time - win.gps_centre);
    // The ridge near the loudest tile: within 0.4 s of it, from a third of
    // its frequency to 3 times it (a whistle's arms leave its loudest part,
    // the vertex, where it sweeps slowest: upward for a V, down for an
    // inverted V).
    let near: Vec<(f64, f64, f64)> =
        ridge.into_iter().filter(|(t, f, _)| (t - dt).abs() <= 0.4 && *f >= frequency / 3.0 && *f <= 3.0 * frequency).collect();
    let high = (frequency < HIGH_BAND)
        .then(|| {
            let search = |t: f64| (t - win.gps_centre).abs() <= 0.25;
            let pixels = image.times.iter().enumerate().filter(|(_, t)| search(**t)).flat_map(|(i, t)| {
                let column = &image.values[i * nf..(i + 1) * nf];
                image.frequencies.iter().zip(column).filter(|(f, _)| **f >= HIGH_BAND).map(move |(f, e)| (*t, *f, *e))
            });
            pixels.fold(None, |best: Option<(f64, f64, f64)>, p| if best.is_none_or(|b| p.2 > b.2) { Some(p) } else { best })
        })
        .flatten()
        .map(|(t, f, _)| (t - win.gps_centre, f));
    Ok(Seed { dt, frequency, q: image.q, track: track(&near), arches: arches(&win.d, sample_rate, frequency), high })
}

/// Weighted least squares of `y = c0 + c1 t + c2 t²`.
fn parabola(points: &[(f64, f64, f64)]) -> Option<[f64; 3]> {
    let mut a = nalgebra::Matrix3::<f64>::zeros();
    let mut b = nalgebra::Vector3::<f64>::zeros();
    for &(t, y, w) in points {
        let v = nalgebra::Vector3::new(1.0, t, t * t);
        a += w * v * v.transpose();
        b += w * y * v;
    }
    let c = a.lu().solve(&b)?;
    c.iter().all(|v| v.is_finite()).then(|| [c[0], c[1], c[2]])
}

/// A V-shaped track through ridge points `(t, f, energy)`, if they bend
/// (upward, or downward for an inverted V); points more than 3 median
/// deviations off a first fit are dropped.
fn track(ridge: &[(f64, f64, f64)]) -> Option<Track> {
    if ridge.len() < 6 {
        return None;
    }
    let [a, b, c] = parabola(ridge)?;
    let off = |p: &(f64, f64, f64)| (p.1 - a - b * p.0 - c * p.0 * p.0).abs();
    let mut deviations: Vec<f64> = ridge.iter().map(off).collect();
    deviations.sort_by(f64::total_cmp);
    let limit = 3.0 * deviations[deviations.len() / 2];
    let ridge: Vec<(f64, f64, f64)> = ridge.iter().filter(|p| off(p) <= limit).copied().collect();
    if ridge.len() < 6 {
        return None;
    }
    let [a, b, c] = parabola(&ridge)?;
    if c == 0.0 {
        return None;
    }
    let log_energy: Vec<(f64, f64, f64)> = ridge.iter().map(|&(t, _, e)| (t, e.ln(), 1.0)).collect();
    let half = parabola(&log_energy).filter(|p| p[2] < 0.0).map(|p| (-2.0 / p[2]).sqrt());
    let dt = -b / (2.0 * c);
    Some(Track { dt, f_turn: a - b * b / (4.0 * c), curvature: c, half }).filter(|t| t.f_turn > 0.0 && t.dt.abs() < 0.5)
}

/// The energy envelope of `x` band-passed around `f0`, and its arches.
fn arches(x: &[f64], fs: f64, f0: f64) -> Option<Arches> {
    let n = x.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let (forward, inverse) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let mut input = x.to_vec();
    let mut spectrum = forward.make_output_vec();
    forward.process(&mut input, &mut spectrum).ok()?;
    let df = fs / n as f64;
    let width = (0.3 * f0).max(50.0);
    let power = |k: usize| spectrum[k.saturating_sub(1)..(k + 2).min(spectrum.len())].iter().map(|c| c.norm_sqr()).sum::<f64>();
    let (lo, hi) = (((f0 - width) / df).max(1.0) as usize, (((f0 + width) / df) as usize).min(spectrum.len() - 2));
    let carrier = (lo..=hi).map(|k| (k, power(k))).fold((0, f64::NEG_INFINITY), |b, (k, p)| if p > b.1 { (k, p) } else { b }).0 as f64 * df;
    spectrum.iter_mut().enumerate().for_each(|(k, c)| {
        if (k as f64 * df - f0).abs() > width || k == 0 || k == n / 2 {
            *c = Complex64::new(0.0, 0.0);
        }
    });
    // The band-passed signal and its Hilbert transform (−i X on positive frequencies).
    let mut quadrature: Vec<Complex64> = spectrum.iter().map(|c| Complex64::new(c.im, -c.re)).collect();
    let (mut real, mut imag) = (inverse.make_output_vec(), inverse.make_output_vec());
    inverse.process(&mut spectrum, &mut real).ok()?;
    inverse.process(&mut quadrature, &mut imag).ok()?;
    let energy: Vec<f64> = real.iter().zip(&imag).map(|(r, i)| (r * r + i * i) / (n * n) as f64).collect();
    // Above the noise floor (the median): the glitch's share.
    let mut sorted = energy.clone();
    sorted.sort_by(f64::total_cmp);
    let floor = sorted[n / 2];
    let excess: Vec<f64> = energy.iter().map(|e| (e - floor).max(0.0)).collect();
    let total: f64 = excess.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let t = |j: usize| j as f64 / fs - 0.5 * n as f64 / fs;
    let mean = excess.iter().enumerate().map(|(j, e)| t(j) * e).sum::<f64>() / total;
    let var = excess.iter().enumerate().map(|(j, e)| (t(j) - mean).powi(2) * e).sum::<f64>() / total;
    // The strongest period of the envelope in 6–40 Hz (a DFT at 0.25 Hz
    // steps, of every 8th sample: 512 Hz is ample for 40 Hz).
    let rate = (0..=136)
        .map(|k| 6.0 + 0.25 * k as f64)
        .map(|r| {
            let w = 2.0 * std::f64::consts::PI * r / fs;
            let (c, s) = excess
                .iter()
                .enumerate()
                .step_by(8)
                .fold((0.0, 0.0), |(c, s), (j, e)| (c + e * (w * j as f64).cos(), s + e * (w * j as f64).sin()));
            (r, c * c + s * s)
        })
        .fold((f64::NAN, f64::NEG_INFINITY), |b, (r, p)| if p > b.1 { (r, p) } else { b })
        .0;
    Some(Arches { f0: carrier, dt: mean, rate, duration: 4.0 * var.sqrt() }).filter(|a| a.rate.is_finite() && a.dt.abs() < 0.5)
}
