//! Fits at a lower sample rate. A family whose whitened templates carry no
//! energy above some frequency `top` within its bounds (a Tomte's, below
//! ~400 Hz) gains nothing from the data's full rate, and its scene costs
//! the factor less at a rate whose Nyquist frequency is above `top`.
//!
//! The whitened window `d` (unit-variance white noise) is cut to the bins
//! below the lower rate's Nyquist frequency and brought back to the time
//! domain at that rate, scaled by `√factor` so its noise keeps unit
//! variance per sample. For a template `m` with no energy in the cut bins,
//! `½ Σ (d − m)²` over the full window is `½ Σ (d″ − m″)²` at the lower
//! rate plus `½ (Σ d² − Σ d″²)`, the energy of the cut bins, which no
//! template of the family touches ([`Decimated::cut_loss`]): losses,
//! Fisher matrices and evidences are those of the full-rate fit.

use realfft::num_complex::Complex64;
use realfft::RealFftPlanner;

/// Rates are lowered by powers of two down to this factor at most.
pub const MAX_FACTOR: usize = 8;

/// The largest power-of-two factor (up to [`MAX_FACTOR`]) that divides
/// `samples` and leaves a Nyquist frequency of at least `top` Hz.
pub fn factor_for(sample_rate: f64, samples: usize, top: f64) -> usize {
    let mut factor = 1;
    while factor < MAX_FACTOR && samples.is_multiple_of(2 * factor) && 0.5 * sample_rate / (2 * factor) as f64 >= top {
        factor *= 2;
    }
    factor
}

/// A whitened window at `1 / factor` of its rate.
#[derive(Clone, Debug, PartialEq)]
pub struct Decimated {
    /// The rate's divisor.
    pub factor: usize,
    /// The window's bins below the lower rate's Nyquist frequency, at that
    /// rate, with unit noise variance per sample.
    pub d: Vec<f64>,
    /// The PSD on the lower rate's bins (the same frequencies).
    pub psd: Vec<f64>,
    /// `½ (Σ d² − Σ d″²)`: what the cut bins add to every loss.
    pub cut_loss: f64,
}

/// Cuts the whitened window `d` (PSD `psd` on its `len / 2 + 1` bins) to
/// `1 / factor` of its rate; `factor` must divide `d.len()`.
pub fn decimate(d: &[f64], psd: &[f64], factor: usize) -> Decimated {
    let low = downsample(d, factor);
    let m = low.len();
    let energy = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>();
    Decimated { factor, cut_loss: 0.5 * (energy(d) - energy(&low)), d: low, psd: psd[..m / 2 + 1].to_vec() }
}

/// The whitened series `d`'s bins below `1 / factor` of its rate's Nyquist
/// frequency, at that rate, scaled so white noise keeps unit variance per
/// sample; `factor` must divide `d.len()`.
pub fn downsample(d: &[f64], factor: usize) -> Vec<f64> {
    let n = d.len();
    let m = n / factor;
    if factor == 1 {
        return d.to_vec();
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let mut input = d.to_vec();
    let forward = planner.plan_fft_forward(n);
    let mut spectrum = forward.make_output_vec();
    forward.process(&mut input, &mut spectrum).expect("buffers sized by the plan");
    // Bins 0..m/2 (the lower rate's Nyquist bin stays empty).
    let mut kept: Vec<Complex64> = spectrum[..m / 2 + 1].to_vec();
    kept[m / 2] = Complex64::new(0.0, 0.0);
    kept[0].im = 0.0;
    let inverse = planner.plan_fft_inverse(m);
    let mut low = inverse.make_output_vec();
    inverse.process(&mut kept, &mut low).expect("buffers sized by the plan");
    let scale = (factor as f64).sqrt() / n as f64;
    low.iter().map(|v| v * scale).collect()
}

/// A series at `1 / factor` of the rate, with unit noise variance per
/// sample, brought back to the full rate (band-limited interpolation):
/// the inverse of [`decimate`] on what it keeps.
pub fn interpolate(x: &[f64], factor: usize) -> Vec<f64> {
    if factor == 1 {
        return x.to_vec();
    }
    let (m, n) = (x.len(), x.len() * factor);
    let mut planner = RealFftPlanner::<f64>::new();
    let mut input = x.to_vec();
    let forward = planner.plan_fft_forward(m);
    let mut spectrum = forward.make_output_vec();
    forward.process(&mut input, &mut spectrum).expect("buffers sized by the plan");
    let inverse = planner.plan_fft_inverse(n);
    let mut full = inverse.make_input_vec();
    full[..m / 2].copy_from_slice(&spectrum[..m / 2]);
    full[0].im = 0.0;
    let mut out = inverse.make_output_vec();
    inverse.process(&mut full, &mut out).expect("buffers sized by the plan");
    let scale = 1.0 / ((factor as f64).sqrt() * m as f64);
    out.iter().map(|v| v * scale).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A band-limited tone series and white-ish noise, at 4096 Hz.
    fn series(n: usize) -> (Vec<f64>, Vec<f64>) {
        let fs = 4096.0;
        let tone: Vec<f64> =
            (0..n).map(|j| (TAU * 37.0 * j as f64 / fs).sin() * (-(((j as f64 / n as f64) - 0.5) * 8.0).powi(2)).exp()).collect();
        let mut state = 12345u64;
        let noise = (0..n)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        (tone, noise)
    }

    #[test]
    fn factor_is_the_largest_power_of_two_with_room_for_the_top() {
        assert_eq!(factor_for(4096.0, 8192, 400.0), 4);
        assert_eq!(factor_for(4096.0, 8192, 600.0), 2);
        assert_eq!(factor_for(4096.0, 8192, f64::INFINITY), 1);
        assert_eq!(factor_for(16384.0, 32768, 100.0), MAX_FACTOR);
        assert_eq!(factor_for(4096.0, 8194, 100.0), 2, "8194 samples are not divisible by 4");
    }

    #[test]
    fn the_loss_of_a_band_limited_model_is_the_full_rate_loss() {
        let n = 8192;
        let (tone, noise) = series(n);
        let d: Vec<f64> = tone.iter().zip(&noise).map(|(s, e)| 3.0 * s + e).collect();
        let psd = vec![1.0; n / 2 + 1];
        let full = 0.5 * d.iter().zip(&tone).map(|(d, m)| (d - 2.5 * m).powi(2)).sum::<f64>();
        for factor in [2, 4, 8] {
            let low = decimate(&d, &psd, factor);
            assert_eq!(low.d.len(), n / factor);
            assert_eq!(low.psd.len(), n / factor / 2 + 1);
            let model = decimate(&tone, &psd, factor);
            assert!(model.cut_loss.abs() < 1e-9 * n as f64, "the tone has no energy above 256 Hz: {}", model.cut_loss);
            let reduced = 0.5 * low.d.iter().zip(&model.d).map(|(d, m)| (d - 2.5 * m).powi(2)).sum::<f64>() + low.cut_loss;
            assert!((reduced - full).abs() < 1e-8 * full, "factor {factor}: {reduced} vs {full}");
        }
    }

    #[test]
    fn interpolation_brings_a_band_limited_series_back() {
        let n = 8192;
        let (tone, _) = series(n);
        let psd = vec![1.0; n / 2 + 1];
        for factor in [2, 4] {
            let back = interpolate(&decimate(&tone, &psd, factor).d, factor);
            let worst = back.iter().zip(&tone).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-10, "factor {factor}: {worst}");
        }
    }
}
