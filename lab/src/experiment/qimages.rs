//! The input of the Gravity Spy-style baseline: Q-transform images of each
//! whitened example, as Gravity Spy classifies Omega scans (Zevin et al.
//! 2017; Bahaadini et al. 2018): Q 4–64, 10–2048 Hz, one image per view
//! duration, centred on the loudest tile. Gravity Spy's views are 0.5, 1,
//! 2 and 4 s; an example here holds 1 s, so the views are the 0.5 s and
//! 1 s ones ([`DURATIONS`]), stacked as two channels of one image.

use gwml_runtime::dataset::{Array, Dataset};
use gwml_strain::qimage::{ImageOptions, QTransform};
use gwml_strain::qtransform::QOptions;

/// View durations (s), one image channel each.
pub const DURATIONS: [f64; 2] = [0.5, 1.0];
/// Log-spaced frequency rows (10–2048 Hz) of each view.
pub const ROWS: usize = 32;
/// Time columns of each view.
pub const COLUMNS: usize = 32;

/// Elements of one example's images: `[views, rows, columns]`.
pub const IMAGE_LEN: usize = DURATIONS.len() * ROWS * COLUMNS;

/// The images of every example of `d` (array `x`: rows of whitened strain
/// at `sample_rate`) as array `x` of `[examples, IMAGE_LEN]`, with every
/// other array of `d` (the labels) kept; `threads` workers.
pub fn q_images(d: &Dataset, sample_rate: f64, threads: usize) -> Result<Dataset, String> {
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
                        example_images(x.row(i), sample_rate, image).map_err(|e| format!("error: Q-scan of example {i}: {e}"))?;
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
/// rows from low to high): `ln(1 + E)` of the median-normalised tile
/// energy E, which keeps the loud glitches' range (energies of thousands)
/// within a few units. The 1 s view's loudest tile centres the shorter
/// views, held inside the example.
fn example_images(x: &[f64], sample_rate: f64, image: &mut [f64]) -> Result<(), String> {
    let duration = x.len() as f64 / sample_rate;
    let q = QTransform::new(x, sample_rate, 0.0, &QOptions::default()).map_err(|e| e.to_string())?;
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

    /// A 200 Hz sine-Gaussian at 0.7 s in white noise: its views peak at
    /// its frequency and, in the 0.5 s view, at the view's centre.
    #[test]
    fn a_burst_lights_its_own_row_and_centres_the_short_view() {
        let rate = 4096.0;
        let mut s = 7u64;
        let x: Vec<f64> = (0..4096)
            .map(|i| {
                let t = i as f64 / rate - 0.7;
                let noise: f64 = (0..12)
                    .map(|_| {
                        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                        (s >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .sum::<f64>()
                    - 6.0;
                noise + 3.0 * (-(t / 0.01).powi(2)).exp() * (2.0 * std::f64::consts::PI * 200.0 * t).sin()
            })
            .collect();
        let mut d = Dataset::default();
        d.arrays.insert("x".into(), Array::new(vec![1, 4096], x).unwrap());
        d.arrays.insert("label".into(), Array::new(vec![1], vec![1.0]).unwrap());
        let images = q_images(&d, rate, 2).unwrap();
        assert_eq!(images.get("label").unwrap().data, vec![1.0]);
        let img = images.get("x").unwrap().row(0).to_vec();
        // Frequencies of the rows, log-spaced over 10–2048 Hz.
        let freq = |r: usize| 10.0 * (2048.0f64 / 10.0).powf(r as f64 / (ROWS - 1) as f64);
        for v in 0..DURATIONS.len() {
            let channel = &img[v * ROWS * COLUMNS..][..ROWS * COLUMNS];
            let (at, _) = channel.iter().enumerate().fold((0, f64::MIN), |b, (i, x)| if *x > b.1 { (i, *x) } else { b });
            let (r, c) = (at / COLUMNS, at % COLUMNS);
            assert!((freq(r) / 200.0).ln().abs() < 0.35, "view {v}: peak at {:.0} Hz", freq(r));
            let t = if v == 0 { 0.45 + (c as f64 + 0.5) / COLUMNS as f64 * 0.5 } else { (c as f64 + 0.5) / COLUMNS as f64 };
            assert!((t - 0.7).abs() < 0.05, "view {v}: peak at {t:.3} s");
        }
    }
}
