//! The Q-transform as an image, as gwpy's `TimeSeries.q_transform` and the
//! Omega scan draw it: of the tiling's Q planes, the one holding the most
//! energetic tile (within a search window) is kept, and its rows of
//! median-normalised tile energies are interpolated onto a regular time
//! axis and a log-spaced frequency axis.
//!
//! gwpy interpolates each row in time with a cubic spline through its tiles
//! and then across rows with a bicubic spline; here both axes use cubic
//! Hermite interpolation with centred-difference slopes (Catmull–Rom on a
//! uniform grid), which passes through every tile as the splines do.
//! `strain/tests/qimage.rs` checks the image against gwpy's on the same
//! data.

use crate::qtransform::{QOptions, QTiling};
use crate::Error;
use realfft::RealFftPlanner;

/// The loudest tile of a Q-transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QPeak {
    /// GPS time of the tile.
    pub time: f64,
    /// Its row's frequency (Hz).
    pub frequency: f64,
    /// Its normalised energy.
    pub energy: f64,
}

/// A Q-transform image: normalised tile energy over time and frequency.
#[derive(Clone, Debug, PartialEq)]
pub struct QImage {
    /// Q of the plane drawn.
    pub q: f64,
    /// GPS times of the columns.
    pub times: Vec<f64>,
    /// Frequencies of the rows (Hz, log-spaced over the tiled band).
    pub frequencies: Vec<f64>,
    /// Normalised energies, `values[i * frequencies.len() + k]` at
    /// `times[i]`, `frequencies[k]`.
    pub values: Vec<f64>,
    /// The loudest tile of the plane within the search window.
    pub peak: QPeak,
}

impl QImage {
    /// The image's largest value with its time and frequency.
    pub fn max(&self) -> QPeak {
        let nf = self.frequencies.len();
        let (i, v) = self.values.iter().enumerate().fold((0, f64::MIN), |best, (i, v)| if *v > best.1 { (i, *v) } else { best });
        QPeak { time: self.times[i / nf], frequency: self.frequencies[i % nf], energy: v }
    }
}

/// What to draw: the GPS interval shown, the search window for the loudest
/// plane, and the image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageOptions {
    /// GPS `[start, end)` of the image.
    pub outseg: (f64, f64),
    /// GPS interval searched for the loudest tile (gwpy: 0.5 s around the
    /// time of interest); `None` searches the whole data.
    pub search: Option<(f64, f64)>,
    /// Columns (gwpy: 1000 over the output segment).
    pub times: usize,
    /// Log-spaced rows (gwpy with `logf=True`: 500).
    pub frequencies: usize,
}

/// How a [`QTransform`] normalises tile energies; either way a tile of
/// Gaussian noise has median 1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TileNorm {
    /// By each row's median over the data (gwpy's `norm='median'`, the Omega
    /// scan's): right for a stretch much longer than its glitches.
    #[default]
    Median,
    /// By the median the row has in unit-variance white noise: for whitened
    /// data too short for a median to be the noise's, where a glitch may fill
    /// a whole row (a 2 s Scratchy in 1 s of data).
    WhiteNoise,
}

/// The Q-transform of whitened data: every tile's normalised energy.
pub struct QTransform {
    tiling: QTiling,
    /// `energies[plane][row][tile]`.
    energies: Vec<Vec<Vec<f64>>>,
    gps_start: f64,
}

impl QTransform {
    /// Transforms whitened data `x` sampled at `sample_rate` from GPS
    /// `gps_start`, tiled as `options` says, energies median-normalised.
    pub fn new(x: &[f64], sample_rate: f64, gps_start: f64, options: &QOptions) -> Result<QTransform, Error> {
        QTransform::with_norm(x, sample_rate, gps_start, options, TileNorm::Median)
    }

    /// [`QTransform::new`] with the energies normalised as `norm` says.
    pub fn with_norm(x: &[f64], sample_rate: f64, gps_start: f64, options: &QOptions, norm: TileNorm) -> Result<QTransform, Error> {
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::Data(format!(
                "the Q-transform's input has a non-finite sample at GPS {:.4}",
                gps_start + i as f64 / sample_rate
            )));
        }
        let tiling = QTiling::new(x.len() as f64 / sample_rate, sample_rate, options)?;
        let mut input = x.to_vec();
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(x.len());
        let mut spectrum = fft.make_output_vec();
        fft.process(&mut input, &mut spectrum).map_err(|e| Error::Data(format!("FFT failed: {e}")))?;
        let row_energies = |r: &crate::qtransform::QRow| match norm {
            TileNorm::Median => r.energies(&spectrum),
            TileNorm::WhiteNoise => r.energies_over_white_noise(&spectrum, x.len()),
        };
        let energies = tiling.planes.iter().map(|p| p.rows.iter().map(row_energies).collect()).collect();
        Ok(QTransform { tiling, energies, gps_start })
    }

    /// The tiling.
    pub fn tiling(&self) -> &QTiling {
        &self.tiling
    }

    /// The loudest tile of plane `p` between GPS `search.0` and `search.1`.
    fn peak(&self, p: usize, search: Option<(f64, f64)>) -> QPeak {
        let mut peak = QPeak { time: 0.0, frequency: 0.0, energy: 0.0 };
        for (row, energies) in self.tiling.planes[p].rows.iter().zip(&self.energies[p]) {
            let dt = self.tiling.duration / row.tiles as f64;
            for (j, e) in energies.iter().enumerate() {
                let t = self.gps_start + j as f64 * dt;
                if search.is_none_or(|(a, b)| t >= a && t < b) && *e > peak.energy {
                    peak = QPeak { time: t, frequency: row.frequency, energy: *e };
                }
            }
        }
        peak
    }

    /// The image of the plane with the loudest tile in `o.search`.
    pub fn image(&self, o: &ImageOptions) -> Result<QImage, Error> {
        let (gps_start, duration) = (self.gps_start, self.tiling.duration);
        let end = gps_start + duration;
        let (t_lo, t_hi) = o.outseg;
        if !(t_lo >= gps_start && t_hi <= end && t_hi > t_lo) {
            return Err(Error::Data(format!("the image's interval {t_lo}..{t_hi} is not inside the data's {gps_start}..{end}")));
        }
        if o.times < 2 || o.frequencies < 2 {
            return Err(Error::Data("a Q image needs at least 2 columns and 2 rows".into()));
        }
        let search = o.search.map(|(a, b)| (a.max(gps_start), b.min(end)));
        let (p, peak) = (0..self.tiling.planes.len())
            .map(|p| (p, self.peak(p, search)))
            .fold(None, |best: Option<(usize, QPeak)>, (p, peak)| match best {
                Some(b) if b.1.energy >= peak.energy => Some(b),
                _ => Some((p, peak)),
            })
            .ok_or_else(|| Error::Data("the Q tiling has no planes".into()))?;
        let plane = &self.tiling.planes[p];
        let tres = (t_hi - t_lo) / o.times as f64;
        let times: Vec<f64> = (0..o.times).map(|i| t_lo + i as f64 * tres).collect();
        // Each row onto the common time axis.
        let columns: Vec<Vec<f64>> = plane
            .rows
            .iter()
            .zip(&self.energies[p])
            .map(|(row, energies)| {
                let dt = duration / row.tiles as f64;
                times.iter().map(|t| cubic_uniform(energies, (t - gps_start) / dt)).collect()
            })
            .collect();
        // Then across rows onto log-spaced frequencies.
        let (f_lo, f_hi) = self.tiling.f_range;
        let frequencies: Vec<f64> = (0..o.frequencies).map(|k| f_lo * (f_hi / f_lo).powf(k as f64 / (o.frequencies - 1) as f64)).collect();
        let row_freqs: Vec<f64> = plane.rows.iter().map(|r| r.frequency).collect();
        let mut values = Vec::with_capacity(o.times * o.frequencies);
        let mut across = vec![0.0; row_freqs.len()];
        for i in 0..o.times {
            for (a, c) in across.iter_mut().zip(&columns) {
                *a = c[i];
            }
            values.extend(frequencies.iter().map(|f| cubic_nonuniform(&row_freqs, &across, *f)));
        }
        Ok(QImage { q: plane.q, times, frequencies, values, peak })
    }
}

/// The Q-transform image of whitened data `x` sampled at `sample_rate`
/// from GPS `gps_start`, tiled as `tiling` says ([`QTransform::image`]).
pub fn q_image(x: &[f64], sample_rate: f64, gps_start: f64, tiling: &QOptions, o: &ImageOptions) -> Result<QImage, Error> {
    QTransform::new(x, sample_rate, gps_start, tiling)?.image(o)
}

/// Cubic Hermite interpolation of `y` (samples at 0, 1, 2, …) at `x`, with
/// centred-difference slopes (Catmull–Rom); held at the ends.
fn cubic_uniform(y: &[f64], x: f64) -> f64 {
    let n = y.len();
    if n == 1 || x <= 0.0 {
        return y[0];
    }
    if x >= (n - 1) as f64 {
        return y[n - 1];
    }
    let i = x.floor() as usize;
    let u = x - i as f64;
    let at = |k: isize| y[k.clamp(0, n as isize - 1) as usize];
    let (y0, y1) = (y[i], y[i + 1]);
    let m0 = 0.5 * (at(i as isize + 1) - at(i as isize - 1));
    let m1 = 0.5 * (at(i as isize + 2) - at(i as isize));
    hermite(y0, y1, m0, m1, u)
}

/// Cubic Hermite interpolation through `(xs, ys)` (`xs` increasing) at `x`,
/// with slopes from the neighbouring points; held outside `xs`.
fn cubic_nonuniform(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let n = xs.len();
    if n == 1 || x <= xs[0] {
        return ys[0];
    }
    if x >= xs[n - 1] {
        return ys[n - 1];
    }
    let i = xs.partition_point(|v| *v <= x) - 1;
    let slope = |k: usize| -> f64 {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        (ys[b] - ys[a]) / (xs[b] - xs[a])
    };
    let h = xs[i + 1] - xs[i];
    hermite(ys[i], ys[i + 1], slope(i) * h, slope(i + 1) * h, (x - xs[i]) / h)
}

/// The cubic through `y0`, `y1` with end slopes `m0`, `m1` (per unit `u`) at `u`.
fn hermite(y0: f64, y1: f64, m0: f64, m1: f64, u: f64) -> f64 {
    let (u2, u3) = (u * u, u * u * u);
    (2.0 * u3 - 3.0 * u2 + 1.0) * y0 + (u3 - 2.0 * u2 + u) * m0 + (-2.0 * u3 + 3.0 * u2) * y1 + (u3 - u2) * m1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_passes_through_the_samples_and_is_exact_for_lines() {
        let y = [1.0, 3.0, 2.0, 5.0, 4.0];
        for (i, v) in y.iter().enumerate() {
            assert_eq!(cubic_uniform(&y, i as f64), *v);
        }
        let line: Vec<f64> = (0..6).map(|i| 2.0 * i as f64 + 1.0).collect();
        assert!((cubic_uniform(&line, 2.3) - 5.6).abs() < 1e-12);
        let xs = [1.0, 2.0, 4.0, 7.0];
        let ys: Vec<f64> = xs.iter().map(|x| 3.0 * x - 2.0).collect();
        for x in [1.5, 3.0, 5.5] {
            assert!((cubic_nonuniform(&xs, &ys, x) - (3.0 * x - 2.0)).abs() < 1e-12, "{x}");
        }
        assert_eq!(cubic_nonuniform(&xs, &ys, 4.0), ys[2]);
    }
}
