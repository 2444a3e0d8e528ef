//! The input of the Gravity Spy-style baseline: Q-transform images of each
//! whitened example, as Gravity Spy classifies Omega scans (Zevin et al.
//! 2017; Bahaadini et al. 2018): Q 4–64 from 10 Hz, one image per view
//! duration, centred on the loudest tile. Gravity Spy's images reach
//! 2048 Hz from 16 kHz data; at 4096 Hz gwpy's tiling stops at 1.29 kHz,
//! where the lowest plane's (Q 5.7) bisquare window meets Nyquist.
//! Gravity Spy's views are 0.5, 1, 2 and 4 s; an example here holds 1 s,
//! so the views are the 0.5 s and 1 s ones ([`DURATIONS`]), stacked as two
//! channels of one image.
//!
//! Gravity Spy's Omega scans normalise each row by its median over a long
//! stretch, where a glitch is a small part; the median of one second is
//! not the noise's when a Scratchy or Scattered Light glitch fills it. The
//! examples are whitened to unit variance, so their rows are normalised by
//! white noise's level instead ([`NORM`]).

use gwml_runtime::dataset::{Array, Dataset};
use gwml_strain::qimage::{ImageOptions, QTransform, TileNorm};
use gwml_strain::qtransform::QOptions;

/// View durations (s), one image channel each.
pub const DURATIONS: [f64; 2] = [0.5, 1.0];
/// Log-spaced frequency rows (10–1,291 Hz at 4096 Hz) of each view.
pub const ROWS: usize = 32;
/// Time columns of each view.
pub const COLUMNS: usize = 32;

/// How tile energies are normalised (see the module's doc).
pub const NORM: TileNorm = TileNorm::WhiteNoise;
/// Elements of one example's images: `[views, rows, columns]`.
pub const IMAGE_LEN: usize = DURATIONS.len() * ROWS * COLUMNS;

/// The images of every example of `d` (array `x`: rows of whitened strain
/// at `sample_rate`) as array `x` of `[examples, IMAGE_LEN]`, with every
/// other array of `d` (the labels) kept; `threads` workers.
pub fn q_images(d: &Dataset, sample_rate: f64, threads: usize) -> Result<Dataset, String> {
    q_images_with(d, sample_rate, threads, NORM)
}

/// [`q_images`] with the tile energies normalised as `norm` says.
pub fn q_images_with(d: &Dataset, sample_rate: f64, threads: usize, norm: TileNorm) -> Result<Dataset, String> {
    let x = d.get("x").map_err(|e| e.to_string())?;
    let n = x.rows();
    let mut images = vec![0.0; n * IMAGE_LEN];
    let per = n.div_ceil(threads.max(1)).max(1);
    std::thread::scope(|s| {
        let jobs: Vec<_> = images
            .chunks_mut(per * IMAGE_LEN)
            .enumerate()
            .map(|(j, out)| {
                s.spawn(move || -> Result<(), String> {
                    for (k, image) in out.chunks_mut(IMAGE_LEN).enumerate() {
                        let i = j * per + k;
                        example_images(x.row(i), sample_rate, norm, image).map_err(|e| format!("error: Q-scan of example {i}: {e}"))?;
                    }
                    Ok(())
                })
            })
            .collect();
        jobs.into_iter().try_for_each(|h| h.join().map_err(|_| "error: a Q-scan worker panicked".to_string())?)
    })?;
    let mut out = d.clone();
    out.arrays.insert("x".into(), Array::new(vec![n, IMAGE_LEN], images).map_err(|e| e.to_string())?);
    Ok(out)
}

/// One example's views into `image` (`[views, rows, columns]`, frequency
/// rows from low to high): `ln(1 + E)` of the normalised tile energy E
/// (`norm`), which keeps the loud glitches' range (energies of thousands)
/// within a few units. The 1 s view's loudest tile centres the shorter
/// views, held inside the example.
fn example_images(x: &[f64], sample_rate: f64, norm: TileNorm, image: &mut [f64]) -> Result<(), String> {
    let duration = x.len() as f64 / sample_rate;
    let q = QTransform::with_norm(x, sample_rate, 0.0, &QOptions::default(), norm).map_err(|e| e.to_string())?;
    let view = |start: f64, length: f64| {
        let outseg = (start, start + length);
        q.image(&ImageOptions { outseg, search: Some(outseg), times: COLUMNS, frequencies: ROWS }).map_err(|e| e.to_string())
    };
    let whole = view(0.0, duration)?;
    let centre = whole.peak.time;
    for (v, &length) in DURATIONS.iter().enumerate() {
        let length = length.min(duration);
        let start = (centre - 0.5 * length).clamp(0.0, duration - length);
        let img = if length == duration { whole.clone() } else { view(start, length)? };
        let channel = &mut image[v * ROWS * COLUMNS..][..ROWS * COLUMNS];
        for (r, row) in channel.chunks_mut(COLUMNS).enumerate() {
            for (c, value) in row.iter_mut().enumerate() {
                *value = img.values[c * ROWS + r].max(0.0).ln_1p();
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1 s of unit-variance noise (a sum of 12 uniforms) plus `signal(t)`.
    fn example(signal: impl Fn(f64) -> f64) -> Vec<f64> {
        let rate = 4096.0;
        let mut s = 7u64;
        (0..4096)
            .map(|i| {
                let noise: f64 = (0..12)
                    .map(|_| {
                        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                        (s >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .sum::<f64>()
                    - 6.0;
                noise + signal(i as f64 / rate)
            })
            .collect()
    }

    /// Frequency of image row `r`: log-spaced over the band the tiling
    /// covers (10 Hz up to what its lowest Q allows below Nyquist, 1.29 kHz
    /// for 1 s at 4096 Hz).
    fn row_frequency(r: usize) -> f64 {
        let tiling = gwml_strain::qtransform::QTiling::new(1.0, 4096.0, &QOptions::default()).unwrap();
        let (lo, hi) = tiling.f_range;
        lo * (hi / lo).powf(r as f64 / (ROWS - 1) as f64)
    }

    /// A 200 Hz sine-Gaussian at 0.7 s in white noise: its views peak at
    /// its frequency and, in the 0.5 s view, at the view's centre.
    #[test]
    fn a_burst_lights_its_own_row_and_centres_the_short_view() {
        let rate = 4096.0;
        let x = example(|t| {
            let t = t - 0.7;
            3.0 * (-(t / 0.01).powi(2)).exp() * (2.0 * std::f64::consts::PI * 200.0 * t).sin()
        });
        let mut d = Dataset::default();
        d.arrays.insert("x".into(), Array::new(vec![1, 4096], x).unwrap());
        d.arrays.insert("label".into(), Array::new(vec![1], vec![1.0]).unwrap());
        let images = q_images(&d, rate, 2).unwrap();
        assert_eq!(images.get("label").unwrap().data, vec![1.0]);
        let img = images.get("x").unwrap().row(0).to_vec();
        let freq = row_frequency;
        for v in 0..DURATIONS.len() {
            let channel = &img[v * ROWS * COLUMNS..][..ROWS * COLUMNS];
            let (at, _) = channel.iter().enumerate().fold((0, f64::MIN), |b, (i, x)| if *x > b.1 { (i, *x) } else { b });
            let (r, c) = (at / COLUMNS, at % COLUMNS);
            assert!((freq(r) / 200.0).ln().abs() < 0.35, "view {v}: peak at {:.0} Hz", freq(r));
            let t = if v == 0 { 0.45 + (c as f64 + 0.5) / COLUMNS as f64 * 0.5 } else { (c as f64 + 0.5) / COLUMNS as f64 };
            assert!((t - 0.7).abs() < 0.05, "view {v}: peak at {t:.3} s");
        }
    }

    /// A tone filling the whole second (a long Scratchy's carrier) at an
    /// image row's frequency (269 Hz) stays bright over white noise's level;
    /// normalised by its row's own median, it would set that median and
    /// fade to noise's level.
    #[test]
    fn a_glitch_that_fills_the_example_stays_bright() {
        let tone = 19;
        let f = row_frequency(tone).round();
        let x = example(|t| (2.0 * std::f64::consts::PI * f * t).sin());
        let mut d = Dataset::default();
        d.arrays.insert("x".into(), Array::new(vec![1, 4096], x).unwrap());
        // The 1 s view's mean in the tone's row, over its mean in the rows
        // above 600 Hz.
        let contrast = |norm: TileNorm| {
            let img = q_images_with(&d, 4096.0, 1, norm).unwrap().get("x").unwrap().row(0).to_vec();
            let channel = &img[ROWS * COLUMNS..];
            let row_mean = |r: usize| channel[r * COLUMNS..][..COLUMNS].iter().sum::<f64>() / COLUMNS as f64;
            let high: Vec<usize> = (0..ROWS).filter(|&r| row_frequency(r) > 600.0).collect();
            row_mean(tone) / (high.iter().map(|&r| row_mean(r)).sum::<f64>() / high.len() as f64)
        };
        let (white, median) = (contrast(TileNorm::WhiteNoise), contrast(TileNorm::Median));
        assert!(white > 3.0, "tone row over noise rows, white-noise level: {white}");
        assert!(median < 2.0, "tone row over noise rows, own median: {median}");
    }
}
