//! Noise power spectral density estimated from the data: Welch's method as
//! gwpy and PyCBC use it (Hann window, 50 % overlap, median average with the
//! median bias correction), matching `scipy.signal.welch(x, fs,
//! window='hann', nperseg, noverlap, average='median'|'mean',
//! scaling='density')` (checked against scipy fixtures in `tests/psd.rs`).
//!
//! Welch (1967), IEEE Trans. Audio Electroacoust. 15, 70: average the
//! periodograms of overlapping windowed segments. The median of K
//! exponentially distributed periodogram values is biased low; dividing by
//! `b(K) = Σ_{i=1}^{K} (-1)^{i+1} / i` (Allen et al. 2012, PRD 85, 122006,
//! Appendix B; scipy's `_median_bias`, for odd K; for even K the median of
//! the middle two) makes it unbiased for Gaussian noise while a loud glitch
//! in one segment leaves it nearly untouched.

use crate::Error;
use num_complex::Complex64;
use realfft::{RealFftPlanner, RealToComplex};
use std::sync::Arc;

/// How the per-segment periodograms are combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Average {
    /// The median, divided by its bias for exponential statistics (robust
    /// to glitches; gwpy's and PyCBC's default for strain).
    Median,
    /// The arithmetic mean (Welch's original estimator).
    Mean,
}

/// Welch settings in samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WelchOptions {
    /// Samples per segment (the FFT length; the PSD's resolution is
    /// `sample_rate / segment`).
    pub segment: usize,
    /// Samples shared by consecutive segments (half a segment is standard).
    pub overlap: usize,
    /// How segments are combined.
    pub average: Average,
    /// Subtract each segment's mean before windowing (scipy's
    /// `detrend='constant'`, its default and gwpy's).
    pub detrend: bool,
}

impl WelchOptions {
    /// Segments of `fft_length` seconds overlapping by half, median average,
    /// constant detrend: gwpy's `TimeSeries.psd(fftlength, overlap=fftlength/2,
    /// method='median')`.
    pub fn seconds(fft_length: f64, sample_rate: f64) -> WelchOptions {
        let segment = (fft_length * sample_rate).round().max(0.0) as usize;
        WelchOptions { segment, overlap: segment / 2, average: Average::Median, detrend: true }
    }
}

/// A one-sided PSD (strain²/Hz for strain) on bins `k · df`, `k = 0..=segment/2`.
#[derive(Clone, Debug, PartialEq)]
pub struct Psd {
    /// Bin spacing in Hz.
    pub df: f64,
    /// One value per bin from 0 Hz.
    pub values: Vec<f64>,
}

impl Psd {
    /// The PSD at frequency `f` by linear interpolation between bins (the
    /// last bin's value beyond it).
    pub fn at(&self, f: f64) -> f64 {
        let x = (f / self.df).max(0.0);
        let k = x.floor() as usize;
        match (self.values.get(k), self.values.get(k + 1)) {
            (Some(a), Some(b)) => a + (b - a) * (x - k as f64),
            (Some(a), None) => *a,
            _ => *self.values.last().unwrap_or(&f64::NAN),
        }
    }

    /// The PSD on the bins `k · df` of another grid (`bins` of them), by
    /// linear interpolation.
    pub fn resample(&self, df: f64, bins: usize) -> Vec<f64> {
        (0..bins).map(|k| self.at(k as f64 * df)).collect()
    }
}

/// A Welch estimator for one segment length (plans and window kept for reuse).
pub struct Welch {
    options: WelchOptions,
    sample_rate: f64,
    window: Vec<f64>,
    /// `1 / (fs Σ w²)`: periodogram scaling to a density.
    scale: f64,
    fft: Arc<dyn RealToComplex<f64>>,
}

impl Welch {
    /// An estimator for data sampled at `sample_rate` Hz.
    pub fn new(sample_rate: f64, options: WelchOptions) -> Result<Welch, Error> {
        let n = options.segment;
        if !(sample_rate > 0.0 && sample_rate.is_finite()) {
            return Err(Error::Data(format!("the sample rate {sample_rate} Hz must be positive and finite")));
        }
        if n < 2 || options.overlap >= n {
            return Err(Error::Data(format!(
                "a Welch segment of {n} samples with {} overlapping: the segment needs at least 2 samples and more than the overlap",
                options.overlap
            )));
        }
        // scipy's 'hann' is the periodic (DFT-even) Hann window.
        let window: Vec<f64> = (0..n).map(|j| 0.5 - 0.5 * (std::f64::consts::TAU * j as f64 / n as f64).cos()).collect();
        let scale = 1.0 / (sample_rate * window.iter().map(|w| w * w).sum::<f64>());
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        Ok(Welch { options, sample_rate, window, scale, fft })
    }

    /// Segments that fit in `samples` samples (scipy drops a trailing partial one).
    pub fn segments(&self, samples: usize) -> usize {
        let (n, step) = (self.options.segment, self.options.segment - self.options.overlap);
        if samples < n {
            0
        } else {
            (samples - n) / step + 1
        }
    }

    /// The PSD of `x` (finite samples, at least one segment long).
    pub fn estimate(&self, x: &[f64]) -> Result<Psd, Error> {
        let n = self.options.segment;
        let step = n - self.options.overlap;
        let count = self.segments(x.len());
        if count == 0 {
            return Err(Error::Data(format!(
                "{} samples are too few for a Welch segment of {n} ({} s)",
                x.len(),
                n as f64 / self.sample_rate
            )));
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::Data(format!("sample {i} is not finite ({}); the PSD needs finite data", x[i])));
        }
        let bins = n / 2 + 1;
        let mut periodograms = vec![0.0; count * bins];
        let mut input = vec![0.0; n];
        let mut spectrum = vec![Complex64::new(0.0, 0.0); bins];
        let mut scratch = self.fft.make_scratch_vec();
        for (s, row) in periodograms.chunks_mut(bins).enumerate() {
            let seg = &x[s * step..s * step + n];
            let mean = if self.options.detrend { seg.iter().sum::<f64>() / n as f64 } else { 0.0 };
            for ((dst, v), w) in input.iter_mut().zip(seg).zip(&self.window) {
                *dst = (v - mean) * w;
            }
            self.fft.process_with_scratch(&mut input, &mut spectrum, &mut scratch).map_err(|e| Error::Data(format!("FFT failed: {e}")))?;
            for (k, (p, c)) in row.iter_mut().zip(&spectrum).enumerate() {
                // One-sided: fold negative frequencies in, but not at DC or
                // (for even n) the Nyquist bin, which have no mirror.
                let fold = if k == 0 || (n.is_multiple_of(2) && k == n / 2) { 1.0 } else { 2.0 };
                *p = c.norm_sqr() * self.scale * fold;
            }
        }
        let mut column = vec![0.0; count];
        let values = (0..bins)
            .map(|k| {
                column.iter_mut().enumerate().for_each(|(s, c)| *c = periodograms[s * bins + k]);
                match self.options.average {
                    Average::Mean => column.iter().sum::<f64>() / count as f64,
                    Average::Median => median(&mut column) / median_bias(count),
                }
            })
            .collect();
        Ok(Psd { df: self.sample_rate / n as f64, values })
    }
}

/// The median (the mean of the middle two for an even count), as NumPy's.
pub fn median(values: &mut [f64]) -> f64 {
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    let (_, upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    if !n.is_multiple_of(2) {
        upper
    } else {
        let lower = values[..n / 2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + upper)
    }
}

/// The bias of the median of `k` exponential periodogram values relative to
/// their mean, as scipy computes it for any `k`: `1 + Σ_{i=1}^{⌊(k−1)/2⌋}
/// (1/(2i+1) − 1/(2i))`, the alternating harmonic sum to the odd count
/// `2⌊(k−1)/2⌋ + 1`.
pub fn median_bias(k: usize) -> f64 {
    let m = k.saturating_sub(1) / 2;
    1.0 + (1..=m).map(|i| 1.0 / (2 * i + 1) as f64 - 1.0 / (2 * i) as f64).sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_matches_numpy_for_odd_and_even_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&mut []).is_nan());
    }

    #[test]
    fn median_bias_is_the_alternating_harmonic_sum() {
        assert_eq!(median_bias(1), 1.0);
        assert_eq!(median_bias(2), 1.0);
        assert!((median_bias(3) - (1.0 - 0.5 + 1.0 / 3.0)).abs() < 1e-15);
        // It tends to ln 2, the median of Exp(1).
        assert!((median_bias(10_001) - std::f64::consts::LN_2).abs() < 1e-4);
    }

    #[test]
    fn white_noise_has_the_density_two_sigma_squared_dt() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let fs = 256.0;
        // Uniform noise on ±√3 has unit variance.
        let x: Vec<f64> = (0..256 * 512).map(|_| rng.random_range(-3f64.sqrt()..3f64.sqrt())).collect();
        for average in [Average::Median, Average::Mean] {
            let welch = Welch::new(fs, WelchOptions { segment: 256, overlap: 128, average, detrend: true }).unwrap();
            let psd = welch.estimate(&x).unwrap();
            let mid = &psd.values[10..118];
            let mean = mid.iter().sum::<f64>() / mid.len() as f64;
            assert!((mean / (2.0 / fs) - 1.0).abs() < 0.03, "{average:?}: {mean} vs {}", 2.0 / fs);
        }
    }

    #[test]
    fn bad_settings_and_data_are_errors() {
        assert!(Welch::new(0.0, WelchOptions::seconds(4.0, 256.0)).is_err());
        assert!(Welch::new(256.0, WelchOptions { segment: 8, overlap: 8, average: Average::Mean, detrend: false }).is_err());
        let welch = Welch::new(256.0, WelchOptions::seconds(1.0, 256.0)).unwrap();
        assert!(welch.estimate(&[0.0; 100]).is_err());
        let mut x = vec![0.0; 1024];
        x[500] = f64::NAN;
        assert!(welch.estimate(&x).unwrap_err().to_string().contains("sample 500"));
    }
}
