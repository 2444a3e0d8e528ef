//! Where a trigger's fits start. A long, coherent shape (a whistle's
//! sweep, a scratchy glitch's train of arches) matches a template only
//! when its params are nearly right — a whistle whose span is 100 Hz off
//! is tens of radians out of phase — so a coarse grid of starts misses
//! it. The seeds read those params from the data instead:
//! - the loudest Q tile within 0.25 s of the window's centre gives a time,
//!   a frequency and a Q;
//! - the phase symmetry of the band around the tile's frequency gives a
//!   whistle's vertex time to a sample or two ([`Seed::vertex`]), which
//!   the tile (10–200 ms off) cannot: a V whose vertex is
//!   5 ms off is radians out of phase along its arms;
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
#[derive(Clone, Debug, PartialEq)]
pub struct Seed {
    /// The loudest tile's time from the window's centre (s).
    pub dt: f64,
    /// Its frequency (Hz).
    pub frequency: f64,
    /// Its plane's Q.
    pub q: f64,
    /// A periodic energy envelope around the tile's frequency, if any.
    pub arches: Option<Arches>,
    /// The loudest pixel at or above [`HIGH_BAND`] Hz in the search span
    /// when the loudest tile is below it: `(dt, frequency)`. A Koi Fish's
    /// head, loud at 15-50 Hz, can outshine its blip; this finds the blip.
    pub high: Option<(f64, f64)>,
    /// Where a whistle is looked for: the loudest tile, then the loudest
    /// pixel of each band of [`WHISTLE_OCTAVES`] the tile is not in (a
    /// quiet whistle's sweep spreads over time, so a noise excursion
    /// elsewhere can outshine it).
    pub whistle: Vec<WhistleOrigin>,
}

/// The lowest frequency (Hz) a whistle's vertex is looked for at: the
/// whistle scene's lower bound on `f_turn`.
pub const WHISTLE_BAND: f64 = 150.0;

/// The bands (Hz) a whistle is looked for in beside the loudest tile's:
/// octaves from [`WHISTLE_BAND`], the last up to the window's band.
pub const WHISTLE_OCTAVES: [(f64, f64); 4] = [(WHISTLE_BAND, 300.0), (300.0, 600.0), (600.0, 1200.0), (1200.0, f64::INFINITY)];

/// How many vertex times each [`WhistleOrigin`] offers: at SNR 10-15 the
/// whistle's vertex is the best of the phase symmetry's peaks about half
/// the time, and among its best three nearly always (100 whistles of the
/// explain campaign, seed 1).
pub const VERTEX_CANDIDATES: usize = 3;

/// A place a whistle is looked for from.
#[derive(Clone, Debug, PartialEq)]
pub struct WhistleOrigin {
    /// The tile's or pixel's time from the window's centre (s).
    pub dt: f64,
    /// Its frequency (Hz).
    pub frequency: f64,
    /// The times (s from the window's centre) about which the data around
    /// `frequency` are most nearly symmetric in phase, best first: a
    /// whistle's vertex, to a sample or two, is among them ([`vertices`]).
    pub vertices: Vec<f64>,
}

/// Where a Koi Fish's blip is looked for when the loudest tile is lower (Hz).
pub const HIGH_BAND: f64 = 60.0;

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
    let (frequency, dt) = (image.peak.frequency, image.peak.time - win.gps_centre);
    // The loudest pixel in `lo..hi` Hz within 0.25 s of the centre: `(dt, f)`.
    let loudest_in = |lo: f64, hi: f64| {
        let search = |t: f64| (t - win.gps_centre).abs() <= 0.25;
        let pixels = image.times.iter().enumerate().filter(|(_, t)| search(**t)).flat_map(|(i, t)| {
            let column = &image.values[i * nf..(i + 1) * nf];
            image.frequencies.iter().zip(column).filter(move |(f, _)| (lo..hi).contains(*f)).map(move |(f, e)| (*t, *f, *e))
        });
        let best = pixels.fold(None, |best: Option<(f64, f64, f64)>, p| if best.is_none_or(|b| p.2 > b.2) { Some(p) } else { best });
        best.map(|(t, f, _)| (t - win.gps_centre, f))
    };
    let high = (frequency < HIGH_BAND).then(|| loudest_in(HIGH_BAND, f64::INFINITY)).flatten();
    let origin =
        |dt: f64, frequency: f64| WhistleOrigin { dt, frequency, vertices: vertices(&win.d, sample_rate, frequency, VERTEX_CANDIDATES) };
    let whistle = std::iter::once(origin(dt, frequency))
        .chain(
            WHISTLE_OCTAVES
                .iter()
                .filter(|(lo, hi)| !(*lo..*hi).contains(&frequency) && *lo < band.1)
                .filter_map(|(lo, hi)| loudest_in(*lo, *hi))
                .map(|(dt, f)| origin(dt, f)),
        )
        .collect();
    Ok(Seed { dt, frequency, q: image.q, arches: arches(&win.d, sample_rate, frequency), high, whistle })
}

/// The analytic signal of `x` band-passed to `lo..hi` Hz, and the
/// strongest line of its spectrum in that band (Hz, to the spectrum's
/// resolution; each bin's power summed with its neighbours').
fn analytic(x: &[f64], fs: f64, lo: f64, hi: f64) -> Option<(Vec<Complex64>, f64)> {
    let n = x.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let (forward, inverse) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let mut input = x.to_vec();
    let mut spectrum = forward.make_output_vec();
    forward.process(&mut input, &mut spectrum).ok()?;
    let df = fs / n as f64;
    let power = |k: usize| spectrum[k.saturating_sub(1)..(k + 2).min(spectrum.len())].iter().map(|c| c.norm_sqr()).sum::<f64>();
    let (first, last) = ((lo / df).max(1.0) as usize, ((hi / df) as usize).min(spectrum.len() - 2));
    let line =
        (first..=last).map(|k| (k, power(k))).fold((0, f64::NEG_INFINITY), |b, (k, p)| if p > b.1 { (k, p) } else { b }).0 as f64 * df;
    spectrum.iter_mut().enumerate().for_each(|(k, c)| {
        let f = k as f64 * df;
        if f < lo || f > hi || k == 0 || k == n / 2 {
            *c = Complex64::new(0.0, 0.0);
        }
    });
    // The band-passed signal and its Hilbert transform (−i X on positive frequencies).
    let mut quadrature: Vec<Complex64> = spectrum.iter().map(|c| Complex64::new(c.im, -c.re)).collect();
    let (mut real, mut imag) = (inverse.make_output_vec(), inverse.make_output_vec());
    inverse.process(&mut spectrum, &mut real).ok()?;
    inverse.process(&mut quadrature, &mut imag).ok()?;
    let z = real.iter().zip(&imag).map(|(r, i)| Complex64::new(*r, *i) / n as f64).collect();
    Some((z, line))
}

/// The `count` times (s from the window's centre, best first, at least
/// 10 ms apart), within 0.25 s of it (the span the loudest tile is looked
/// for in), about which the band 0.6–1.8 `f0` is most nearly symmetric in
/// phase: the best local maxima of the symmetry score. A
/// whistle's frequency is even about its vertex `t0` (every term of
/// `f(t)` is a power of `(t − t0)²`), so its phase is odd about it and
/// `z(t0 + τ) z(t0 − τ)` of its analytic signal `z` keeps one phase for
/// every τ: the sum of those products over τ (weighted by a Gaussian of
/// 0.15 s) is largest at the vertex, whatever the sweep's span, width or
/// wiggle. The tile's time is 10–200 ms off; a template needs ~1 ms.
pub fn vertices(x: &[f64], fs: f64, f0: f64, count: usize) -> Vec<f64> {
    let Some((z, _)) = analytic(x, fs, 0.6 * f0, (1.8 * f0).min(0.49 * fs)) else { return Vec::new() };
    let n = z.len();
    let (reach, search) = ((0.3 * fs) as usize, (0.25 * fs) as i64);
    let centre = (n / 2) as i64;
    let weights: Vec<f64> = (0..=reach).map(|k| (-(k as f64 / fs / 0.15).powi(2)).exp()).collect();
    let score = |j: i64| {
        let reach = reach.min(j as usize).min(n - 1 - j as usize);
        (1..=reach).map(|k| weights[k] * z[j as usize + k] * z[j as usize - k]).sum::<Complex64>().norm()
    };
    let candidates: Vec<(i64, f64)> = ((centre - search).max(1)..=(centre + search).min(n as i64 - 2)).map(|j| (j, score(j))).collect();
    let mut peaks: Vec<(i64, f64)> =
        candidates.windows(3).filter(|w| w[1].1 >= w[0].1 && w[1].1 >= w[2].1 && w[1].1.is_finite()).map(|w| w[1]).collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut kept: Vec<(i64, f64)> = Vec::new();
    let apart = (0.01 * fs) as i64;
    for p in peaks {
        if kept.len() < count && kept.iter().all(|k| (k.0 - p.0).abs() >= apart) {
            kept.push(p);
        }
    }
    kept.into_iter().map(|(j, _)| (j - centre) as f64 / fs).collect()
}

/// The energy envelope of `x` band-passed around `f0`, and its arches.
fn arches(x: &[f64], fs: f64, f0: f64) -> Option<Arches> {
    let n = x.len();
    let width = (0.3 * f0).max(50.0);
    let (z, carrier) = analytic(x, fs, f0 - width, f0 + width)?;
    let energy: Vec<f64> = z.iter().map(|c| c.norm_sqr()).collect();
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// Unit-variance Gaussian noise from a fixed LCG (Box–Muller).
    fn noise(n: usize, mut state: u64) -> Vec<f64> {
        let mut uniform = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n).map(|_| (-2.0 * uniform().ln()).sqrt() * (TAU * uniform()).cos()).collect()
    }

    /// A whistle (`f = f_turn + span u² + wiggle u⁴`) at SNR `snr` in white noise.
    fn whistle_in_noise(t0: f64, f_turn: f64, span: f64, wiggle: f64, half: f64, snr: f64, seed: u64) -> Vec<f64> {
        let (fs, n) = (4096.0, 8192);
        let shape: Vec<f64> = (0..n)
            .map(|j| {
                let dt = j as f64 / fs - 1.0 - t0;
                let u = dt / half;
                (-u * u).exp() * (TAU * dt * (f_turn + span * u * u / 3.0 + wiggle * u.powi(4) / 5.0) + 0.7).cos()
            })
            .collect();
        let norm = shape.iter().map(|v| v * v).sum::<f64>().sqrt();
        shape.iter().zip(noise(n, seed)).map(|(s, e)| snr * s / norm + e).collect()
    }

    #[test]
    fn the_vertex_of_a_whistle_is_found_to_a_sample_or_two() {
        for (t0, f_turn, span, wiggle, half, seed) in [
            (0.083, 800.0, 300.0, 0.0, 0.15, 1),
            (-0.12, 1100.0, -350.0, 0.0, 0.22, 2),
            (0.031, 600.0, 400.0, -250.0, 0.2, 3),
            (0.2, 500.0, 150.0, 0.0, 0.1, 4),
        ] {
            let x = whistle_in_noise(t0, f_turn, span, wiggle, half, 15.0, seed);
            // The loudest tile's frequency is within a few percent of the vertex's.
            let found = *vertices(&x, 4096.0, 1.03 * f_turn, 1).first().expect("a vertex");
            assert!((found - t0).abs() < 1e-3, "vertex at {t0} s found at {found} s");
        }
    }

    #[test]
    fn noise_alone_has_a_vertex_anywhere_but_no_panic() {
        let found = *vertices(&noise(8192, 9), 4096.0, 700.0, 1).first().expect("a time");
        assert!(found.abs() <= 0.25 + 1e-9, "{found}");
    }
}
