//! The Q-transform: whitened data tiled in time, frequency and quality
//! factor Q, each tile's normalised energy the output of a matched filter
//! with a windowed sinusoid (Chatterji et al. 2004, Class. Quantum Grav.
//! 21, S1809; the tiling of Omega, Omicron and gwpy's `q_transform`).
//!
//! Tiling (Chatterji 2004 §4, as gwpy's `QTiling` lays it out): with the
//! mismatch `m` between neighbouring tiles, `Δ = 2 √(m/3)`; Q planes are
//! log-spaced over the Q range, `ln(q_max/q_min)/√2 / Δ` of them (rounded
//! up); in each plane, frequency rows are log-spaced with
//! `ln(f_max/f_min) √(2+Q²)/2 / Δ` rows (rounded up), each row's frequency
//! rounded down to a multiple of `1/T` (the segment's resolution). A row
//! at frequency `f` takes the data spectrum over `f ± f √11 / Q` times the
//! bisquare window `(1 − (ν Q' / f)²)²`, `Q' = Q/√11`, and an inverse FFT
//! of `2^⌈log2(2π f T/(Q Δ))⌉` points gives its tiles in time (below
//! Q = √11 the window would reach past 0 Hz: it is cut there, which gwpy
//! does not allow, and `gwml scan` uses for one plane). Energies are
//! normalised by the row's median: in Gaussian noise a tile's energy is
//! exponential, so its median-normalised energy `Z` has mean `1/ln 2`
//! (or, for whitened data too short for the median to be the noise's, by
//! the median unit-variance white noise would give the row).

use crate::psd::median;
use num_complex::{Complex32, Complex64};
use rustfft::{Fft, FftPlanner};
use std::f64::consts::{LN_2, PI, TAU};
use std::sync::Arc;

/// Tiling settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QOptions {
    /// Range of Q (Gravity Spy: 4 to 64). Planes below √11 ≈ 3.32, whose
    /// window would reach past 0 Hz, have it cut there.
    pub q_range: (f64, f64),
    /// Frequency range in Hz; the top is lowered to what the smallest Q
    /// allows below the Nyquist frequency.
    pub f_range: (f64, f64),
    /// Fractional energy lost between neighbouring tiles (gwpy: 0.2).
    pub mismatch: f64,
    /// Inverse FFT lengths of the form 2^a or 3·2^a (at most 1.5× the
    /// needed tiles, against 2× for gwpy's powers of two): fewer tiles in
    /// time for the same resolution.
    pub smooth_sizes: bool,
    /// Let each plane tile up to its own limit below Nyquist,
    /// `fs/2 / (1 + √11/Q)`, instead of the smallest Q's for every plane
    /// (gwpy's tiling): higher-Q planes then reach higher frequencies.
    pub plane_nyquist: bool,
}

impl Default for QOptions {
    fn default() -> Self {
        QOptions { q_range: (4.0, 64.0), f_range: (10.0, 2048.0), mismatch: 0.2, smooth_sizes: false, plane_nyquist: false }
    }
}

/// One frequency row of a Q plane.
pub struct QRow {
    /// Centre frequency in Hz.
    pub frequency: f64,
    /// The plane's Q.
    pub q: f64,
    /// Index of the first spectrum bin under the window.
    first_bin: usize,
    /// Window weights over the bins from `first_bin`.
    window: Vec<f64>,
    /// Tiles in time over the segment (the inverse FFT length).
    pub tiles: usize,
    /// [`QRow::correlation_time`], computed once.
    correlation_time: f64,
    fft: Arc<dyn Fft<f64>>,
    /// The same inverse FFT in single precision, for scans.
    fft32: Arc<dyn Fft<f32>>,
}

impl QRow {
    /// Correlation time of the tile energies in Gaussian noise, `∫ |ρ(τ)|² dτ`
    /// for the normalised autocorrelation ρ of the filter output:
    /// `∫ W⁴ df / (∫ W² df)²` for the window `W`. Sums of energies over a
    /// time `D` hold `D / τ_c` independent tiles' worth of noise.
    pub fn correlation_time(&self) -> f64 {
        self.correlation_time
    }

    /// Duration of a tile's Gaussian envelope, `Q / (2 √π f)` (the inverse
    /// of its bandwidth `2 √π f / Q`).
    pub fn tile_duration(&self) -> f64 {
        self.q / (2.0 * PI.sqrt() * self.frequency)
    }

    /// Median-normalised tile energies over the segment (`tiles` values,
    /// tile `j` at time `j T / tiles` from the segment's start), from the
    /// segment's one-sided spectrum (any normalisation: it cancels).
    pub fn energies(&self, spectrum: &[Complex64]) -> Vec<f64> {
        let mut buffers = RowBuffers::default();
        self.transform(spectrum, &mut buffers);
        let raw: Vec<f64> = buffers.values.iter().map(|c| c.norm_sqr()).collect();
        let med = median(&mut raw.clone());
        let inv = if med > 0.0 { 1.0 / med } else { 1.0 };
        raw.into_iter().map(|e| e * inv).collect()
    }

    /// [`QRow::energies`] for scans, read through the returned view: the
    /// inverse FFT runs in f32 (relative error ~1e-7 on energies, twice
    /// the speed) and the median is taken over every `median_stride`-th
    /// tile (neighbouring tiles overlap heavily, so a stride of a few
    /// changes it by a fraction of a percent and saves most of the
    /// selection). No energy array is written: a scan reads each tile's
    /// energy once, from the transform's output.
    pub fn single_energies<'b>(&self, spectrum: &[Complex64], buffers: &'b mut RowBuffers, median_stride: usize) -> RowEnergies<'b> {
        let buf = &mut buffers.values32;
        self.band_into(spectrum, buf, |v| Complex32::new(v.re as f32, v.im as f32));
        buffers.scratch32.resize(self.fft32.get_inplace_scratch_len(), Complex32::new(0.0, 0.0));
        self.fft32.process_with_scratch(buf, &mut buffers.scratch32);
        let RowBuffers { values32, sample, .. } = buffers;
        sample.clear();
        sample.extend(values32.iter().step_by(median_stride.max(1)).map(|c| f64::from(c.norm_sqr())));
        let med = median(sample);
        RowEnergies { values: values32, scale: if med > 0.0 { 1.0 / med } else { 1.0 } }
    }

    /// Tile energies of whitened data normalised by the median they would
    /// have in unit-variance white noise, from the unnormalised spectrum of
    /// `samples` samples: noise has median 1 as with [`QRow::energies`], but
    /// a glitch that fills the whole row (a long Scratchy's carrier in a
    /// short segment) keeps its energy instead of setting the median.
    pub fn energies_over_white_noise(&self, spectrum: &[Complex64], samples: usize) -> Vec<f64> {
        let mut buffers = RowBuffers::default();
        self.transform(spectrum, &mut buffers);
        let median = self.white_noise_mean(spectrum.len(), samples) * LN_2;
        let inv = if median > 0.0 { 1.0 / median } else { 1.0 };
        buffers.values.iter().map(|c| c.norm_sqr() * inv).collect()
    }

    /// The mean raw tile energy of unit-variance white noise of `samples`
    /// samples: each unnormalised spectrum bin has `E|X_k|² = samples`, and
    /// the unnormalised inverse FFT sums the windowed bins, so the mean is
    /// `samples Σ W²` over the window's bins that the spectrum (of
    /// `bins` bins) holds.
    fn white_noise_mean(&self, bins: usize, samples: usize) -> f64 {
        let held = bins.saturating_sub(self.first_bin).min(self.window.len());
        samples as f64 * self.window[..held].iter().map(|w| w * w).sum::<f64>()
    }

    /// The row's complex filter output in double precision, left in
    /// `buffers.values`.
    fn transform(&self, spectrum: &[Complex64], buffers: &mut RowBuffers) {
        let buf = &mut buffers.values;
        self.band_into(spectrum, buf, |v| v);
        buffers.scratch.resize(self.fft.get_inplace_scratch_len(), Complex64::new(0.0, 0.0));
        self.fft.process_with_scratch(buf, &mut buffers.scratch);
    }

    /// The windowed band padded symmetrically to `tiles` points with its
    /// centre rotated to index 0 (numpy's ifftshift), so the inverse FFT
    /// gives the baseband envelope: the band is written in (at most) two
    /// runs and only the rest is zeroed.
    fn band_into<T: Copy + Default>(&self, spectrum: &[Complex64], buf: &mut Vec<T>, convert: impl Fn(Complex64) -> T) {
        let (n, w) = (self.tiles, self.window.len());
        buf.resize(n, T::default());
        let start = ((n - w) / 2 + n - n / 2) % n;
        let value = |i: usize| convert(spectrum.get(self.first_bin + i).copied().unwrap_or_default() * self.window[i]);
        let first = w.min(n - start);
        for (i, slot) in buf[start..start + first].iter_mut().enumerate() {
            *slot = value(i);
        }
        for (i, slot) in buf[..w - first].iter_mut().enumerate() {
            *slot = value(first + i);
        }
        // The n − w points outside the band, from just after it, cyclically.
        let gap = (start + w) % n;
        let tail = (n - w).min(n - gap);
        buf[gap..gap + tail].fill(T::default());
        buf[..n - w - tail].fill(T::default());
    }
}

/// A row's median-normalised tile energies as [`QRow::single_energies`]
/// leaves them: the filter output and the normalisation.
pub struct RowEnergies<'b> {
    values: &'b [Complex32],
    scale: f64,
}

impl RowEnergies<'_> {
    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether the row has no tiles.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Energy of tile `k`.
    pub fn get(&self, k: usize) -> f64 {
        let c = self.values[k];
        f64::from(c.re * c.re + c.im * c.im) * self.scale
    }

    /// The energies of `N` tiles from `k` on (written as two loops over
    /// fixed-size arrays, which the compiler turns into vector code).
    #[inline(always)]
    pub fn block<const N: usize>(&self, k: usize) -> [f64; N] {
        let c: &[Complex32; N] = self.values[k..k + N].try_into().expect("N values");
        let mut norms = [0f32; N];
        for (n, c) in norms.iter_mut().zip(c) {
            *n = c.re * c.re + c.im * c.im;
        }
        let mut z = [0f64; N];
        for (z, n) in z.iter_mut().zip(norms) {
            *z = f64::from(n) * self.scale;
        }
        z
    }
}

/// Work buffers of [`QRow::single_energies`], reused from row to row.
#[derive(Default)]
pub struct RowBuffers {
    values: Vec<Complex64>,
    scratch: Vec<Complex64>,
    values32: Vec<Complex32>,
    scratch32: Vec<Complex32>,
    sample: Vec<f64>,
}

/// One plane of constant Q.
pub struct QPlane {
    /// The plane's Q.
    pub q: f64,
    /// Its frequency rows, in increasing frequency.
    pub rows: Vec<QRow>,
}

/// The tiling of a segment of `duration` seconds at `sample_rate` Hz.
pub struct QTiling {
    /// Segment duration in seconds.
    pub duration: f64,
    /// Sample rate in Hz.
    pub sample_rate: f64,
    /// The frequency range actually tiled (with `plane_nyquist`, up to the
    /// highest row's centre).
    pub f_range: (f64, f64),
    /// The planes, in increasing Q.
    pub planes: Vec<QPlane>,
}

impl QTiling {
    /// Lays out the tiles.
    pub fn new(duration: f64, sample_rate: f64, o: &QOptions) -> Result<QTiling, crate::Error> {
        let bad = |what: String| Err(crate::Error::Data(what));
        if !(duration > 0.0 && sample_rate > 0.0 && duration.is_finite() && sample_rate.is_finite()) {
            return bad(format!("a Q tiling needs a positive duration and sample rate (got {duration} s, {sample_rate} Hz)"));
        }
        let (qmin, qmax) = o.q_range;
        if !(qmin > 0.0 && qmax >= qmin && qmax.is_finite()) {
            return bad(format!("the Q range {qmin}..{qmax} must be positive and increasing"));
        }
        if !(o.mismatch > 0.0 && o.mismatch < 1.0) {
            return bad(format!("the tile mismatch {} must be between 0 and 1", o.mismatch));
        }
        let delta = 2.0 * (o.mismatch / 3.0).sqrt();
        let qs = log_steps(qmin, qmax, std::f64::consts::SQRT_2, delta);
        let q_low = qs[0];
        let f_top = sample_rate / 2.0 / (1.0 + 11f64.sqrt() / q_low);
        // As gwpy: a zero lower frequency becomes the lowest whose tiles in
        // the largest Q still fit the segment, 50 Q_max / (2π T).
        let f_low = if o.f_range.0 > 0.0 { o.f_range.0 } else { 50.0 * qs[qs.len() - 1] / (TAU * duration) };
        let f_high = o.f_range.1.min(f_top);
        if !(f_low > 0.0 && f_high > f_low) {
            return bad(format!(
                "no frequencies to tile: {}..{} Hz at {sample_rate} Hz over {duration} s tiles {f_low:.1}..{f_high:.1} Hz",
                o.f_range.0, o.f_range.1
            ));
        }
        let mut planner = FftPlanner::new();
        let mut planner32 = FftPlanner::new();
        let planes: Vec<QPlane> = qs
            .iter()
            .map(|&q| {
                let step = 1.0 / duration;
                let top = if o.plane_nyquist { o.f_range.1.min(sample_rate / 2.0 / (1.0 + 11f64.sqrt() / q)) } else { f_high };
                let mut frequencies: Vec<f64> = log_steps(f_low, top, 2.0 / (2.0 + q * q).sqrt(), delta)
                    .into_iter()
                    .map(|f| ((f / step).floor() * step).max(step))
                    .collect();
                // Rounding to the resolution can repeat a frequency: one row each.
                frequencies.dedup();
                let rows = frequencies
                    .into_iter()
                    .map(|frequency| {
                        let q_prime = q / 11f64.sqrt();
                        let half = (frequency / q_prime * duration).floor() as i64;
                        let tiles = (TAU * frequency * duration / q / delta).ceil().max(1.0) as usize;
                        let tiles = if o.smooth_sizes { smooth_size(tiles) } else { tiles.next_power_of_two() };
                        let tiles = tiles.max((2 * half + 1) as usize);
                        let centre = frequency * duration;
                        let lowest = (-half as f64 + 1.0 + centre).round() as i64;
                        // Below Q = √11 the window reaches past 0 Hz: it is
                        // cut there (bins from 1 on), a one-sided filter still.
                        let cut = (1 - lowest).max(0);
                        let first = (lowest + cut) as usize;
                        let norm = tiles as f64 / (duration * sample_rate) * (315.0 * q_prime / (128.0 * frequency)).sqrt();
                        let window = (-half + cut..=half)
                            .map(|k| {
                                let x = k as f64 / duration * q_prime / frequency;
                                (1.0 - x * x).powi(2) * norm
                            })
                            .collect::<Vec<f64>>();
                        // ∫ W⁴ df / (∫ W² df)² with df = 1/T.
                        let (w2, w4) = window.iter().fold((0.0, 0.0), |(a, b), w| (a + w * w, b + w.powi(4)));
                        QRow {
                            frequency,
                            q,
                            first_bin: first,
                            window,
                            tiles,
                            correlation_time: duration * w4 / (w2 * w2),
                            fft: planner.plan_fft_inverse(tiles),
                            fft32: planner32.plan_fft_inverse(tiles),
                        }
                    })
                    .collect();
                QPlane { q, rows }
            })
            .collect();
        let f_top = planes.iter().flat_map(|p: &QPlane| p.rows.last()).map(|r| r.frequency).fold(f_high, f64::max);
        let f_high = if o.plane_nyquist { f_top } else { f_high };
        Ok(QTiling { duration, sample_rate, f_range: (f_low, f_high), planes })
    }

    /// Tiles in the whole tiling (what one segment costs).
    pub fn tile_count(&self) -> usize {
        self.planes.iter().flat_map(|p| &p.rows).map(|r| r.tiles).sum()
    }
}

/// The smallest 2^a or 3·2^a at least `n`.
fn smooth_size(n: usize) -> usize {
    let pow2 = n.next_power_of_two();
    if pow2 / 4 * 3 >= n && pow2 >= 4 {
        pow2 / 4 * 3
    } else {
        pow2
    }
}

/// `count` log-spaced points over `lo..hi` at the centres of equal steps of
/// `ln(hi/lo) / scale` no wider than `delta`: `lo · exp(scale (i + ½) s)`.
fn log_steps(lo: f64, hi: f64, scale: f64, delta: f64) -> Vec<f64> {
    let cumulative = (hi / lo).ln() / scale;
    let count = (cumulative / delta).ceil().max(1.0) as usize;
    let step = cumulative / count as f64;
    (0..count).map(|i| lo * (scale * (i as f64 + 0.5) * step).exp()).collect()
}

/// The SNR of a tile from its median-normalised energy `z`: a tile's
/// complex filter output in unit noise has mean energy 1 after
/// normalising by the mean (`z ln 2`), and a matched signal of SNR ρ adds
/// ρ²/2, so ρ = √(2 (z ln 2 − 1)) (0 below the noise mean).
pub fn tile_snr(z: f64) -> f64 {
    (2.0 * (z * LN_2 - 1.0)).max(0.0).sqrt()
}

/// Excess power along a row: the energies of `D` seconds of tiles summed,
/// for glitches longer than any one tile (Scratchy's arches, a Whistle's
/// sweep; Anderson et al. 2001, PRD 63, 042003). With mean-normalised
/// energies `e_j = z_j ln 2` sampled every `dt`, the excess
/// `X = Σ (e_j − 1) dt / τ_c` is ρ²/2 for a signal of SNR ρ inside the
/// window and the row's band, while noise makes `X + ν` a Gamma(ν, 1)
/// variable, `ν = D / τ_c`. Equal (and hashed alike) when its numbers are
/// bit for bit equal.
#[derive(Clone, Debug)]
pub struct ExcessPower {
    /// `dt / τ_c`.
    scale: f64,
    /// `ν`.
    nu: f64,
    /// `½ ln(2πν)`, clipped at 0.
    half_ln_2pi_nu: f64,
    /// `−ln P` a window needs: `1 + floor²/2`.
    need: f64,
}

impl ExcessPower {
    fn bits(&self) -> [u64; 3] {
        [self.scale.to_bits(), self.nu.to_bits(), self.need.to_bits()]
    }
}

impl PartialEq for ExcessPower {
    fn eq(&self, other: &Self) -> bool {
        self.bits() == other.bits()
    }
}

impl Eq for ExcessPower {}

impl std::hash::Hash for ExcessPower {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.bits().hash(state);
    }
}

impl ExcessPower {
    /// Windows of `window` seconds of tiles every `dt` s with correlation time
    /// `correlation_time` ([`QRow::correlation_time`]), kept when their
    /// significance reaches `floor`.
    pub fn new(dt: f64, correlation_time: f64, window: f64, floor: f64) -> ExcessPower {
        let nu = window / correlation_time;
        ExcessPower {
            scale: dt / correlation_time,
            nu,
            half_ln_2pi_nu: 0.5 * (2.0 * PI * nu).ln().max(0.0),
            need: 1.0 + 0.5 * floor * floor,
        }
    }

    /// A window sum (of `e_j − 1`) that fails [`ExcessPower::test`], as does
    /// every smaller one (the tail probability falls as the sum grows), so a
    /// scan can skip most windows with one comparison; `∞` if none passes.
    /// Found by bisection to 1e-4 relative (~15 tests).
    pub fn failing_sum(&self) -> f64 {
        let passes = |x: f64| self.test(x / self.scale).is_some();
        let mut hi = self.nu.sqrt().max(1.0);
        let mut doublings = 0;
        while !passes(hi) {
            hi *= 2.0;
            doublings += 1;
            if doublings > 64 {
                return f64::INFINITY;
            }
        }
        let mut lo = 0.0;
        while hi - lo > 1e-4 * hi {
            let mid = 0.5 * (lo + hi);
            if passes(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        lo / self.scale
    }

    /// For a window whose `e_j − 1` sum to `sum_excess`: `(energy SNR √(2X),
    /// significance)`, the significance being the single-tile SNR as
    /// unlikely in noise, `√(2 (−ln P − 1))` with `P = Q(ν, ν + X)` (the
    /// regularised upper incomplete gamma function); `None` below `floor`.
    pub fn test(&self, sum_excess: f64) -> Option<(f64, f64)> {
        let (x, nu) = (sum_excess * self.scale, self.nu);
        if x <= 0.0 {
            return None;
        }
        // −ln P exceeds the Chernoff exponent ν (r − 1 − ln r), r = 1 + X/ν,
        // by about ½ ln(2πν) + ln(r/(r−1)); the exponent is at most X²/(2ν)
        // and ln(r/(r−1)) at most ν/X. When even these generous bounds stay
        // below what `floor` needs, no logarithm is taken.
        if x * x / (2.0 * nu) + self.half_ln_2pi_nu + nu / x + 2.0 < self.need {
            return None;
        }
        let r = 1.0 + x / nu;
        let chernoff = nu * (r - 1.0 - r.ln());
        if chernoff + self.half_ln_2pi_nu + (r / (r - 1.0)).ln() + 2.0 < self.need {
            return None;
        }
        let p = statrs::function::gamma::gamma_ur(nu, nu + x);
        let minus_ln_p = if p > 0.0 { -p.ln() } else { chernoff };
        let significance = (2.0 * (minus_ln_p - 1.0)).max(0.0).sqrt();
        (significance >= (2.0 * (self.need - 1.0)).sqrt()).then(|| ((2.0 * x).sqrt(), significance))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use realfft::RealFftPlanner;

    fn spectrum(x: &[f64]) -> Vec<Complex64> {
        let mut input = x.to_vec();
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(x.len());
        let mut out = fft.make_output_vec();
        fft.process(&mut input, &mut out).unwrap();
        out
    }

    /// Adds to `x` (sampled at `fs`) a sine-Gaussian `e^{−(t−t0)²/τ²} cos 2πf0(t−t0)`,
    /// `τ = Q/(√2 π f0)`, scaled to `snr` in unit-variance white noise.
    fn add_sine_gaussian(x: &mut [f64], fs: f64, (f0, q, t0): (f64, f64, f64), snr: f64) {
        let tau = q / (std::f64::consts::SQRT_2 * PI * f0);
        let h: Vec<f64> = (0..x.len())
            .map(|j| {
                let dt = j as f64 / fs - t0;
                (-(dt / tau).powi(2)).exp() * (TAU * f0 * dt).cos()
            })
            .collect();
        let norm = h.iter().map(|v| v * v).sum::<f64>().sqrt();
        x.iter_mut().zip(&h).for_each(|(v, s)| *v += snr * s / norm);
    }

    #[test]
    fn the_tiling_has_gwpy_s_planes() {
        // Q 4..64 at mismatch 0.2: ln(16)/√2 / (2√(0.2/3)) = 3.8 → 4 planes,
        // Q = 4 e^{√2 (i+½) dq}: 5.66, 11.3, 22.6, 45.3.
        let t = QTiling::new(64.0, 4096.0, &QOptions::default()).unwrap();
        let qs: Vec<f64> = t.planes.iter().map(|p| p.q).collect();
        assert_eq!(qs.len(), 4);
        for (q, want) in qs.iter().zip([5.657, 11.314, 22.627, 45.255]) {
            assert!((q - want).abs() < 1e-3, "{qs:?}");
        }
        // The top frequency: fs/2 / (1 + √11/Q_min).
        assert!((t.f_range.1 - 2048.0 / (1.0 + 11f64.sqrt() / qs[0])).abs() < 1e-9);
        for p in &t.planes {
            assert!(p.rows.windows(2).all(|w| w[0].frequency <= w[1].frequency));
            for r in &p.rows {
                assert!(r.first_bin + r.window.len() <= 64 * 2048 + 1, "window past Nyquist at {} Hz", r.frequency);
            }
        }
    }

    #[test]
    fn noise_energies_are_exponential_and_a_sine_gaussian_lights_its_tile() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let (fs, duration) = (1024.0, 16.0);
        let n = (fs * duration) as usize;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
        let mut x: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
        let tiling = QTiling::new(duration, fs, &QOptions { f_range: (20.0, 400.0), ..Default::default() }).unwrap();
        // Noise: the mean of z ln 2 is 1.
        let spec = spectrum(&x);
        let (mut sum, mut count) = (0.0, 0usize);
        for row in tiling.planes.iter().flat_map(|p| &p.rows) {
            let e = row.energies(&spec);
            sum += e.iter().map(|z| z * LN_2).sum::<f64>();
            count += e.len();
        }
        assert!((sum / count as f64 - 1.0).abs() < 0.03, "mean normalised energy {}", sum / count as f64);
        // A sine-Gaussian of SNR 20 at 120 Hz, Q 8, t0 = 9 s.
        let (f0, q, t0, snr) = (120.0, 8.0, 9.0, 20.0);
        add_sine_gaussian(&mut x, fs, (f0, q, t0), snr);
        let spec = spectrum(&x);
        let mut best = (0.0, 0.0, 0.0, 0.0);
        for row in tiling.planes.iter().flat_map(|p| &p.rows) {
            for (j, z) in row.energies(&spec).iter().enumerate() {
                let rho = tile_snr(*z);
                if rho > best.0 {
                    best = (rho, row.frequency, row.q, j as f64 * duration / row.tiles as f64);
                }
            }
        }
        let (rho, f, bq, t) = best;
        assert!((t - t0).abs() < 0.01, "peak time {t}");
        assert!((f / f0 - 1.0).abs() < 0.15, "peak frequency {f}");
        assert!((0.8 * snr..=1.1 * snr).contains(&rho), "tile SNR {rho} for an injected {snr}");
        assert!((4.0..=23.0).contains(&bq), "Q {bq}");
    }

    /// Below Q = √11 a row's window is cut at 0 Hz. Its tiles are still a
    /// one-sided matched filter: noise energies keep mean `1/ln 2`, and a
    /// broadband burst of Q 1.2 (a Blip's) keeps 0.88 of its SNR in the Q 2.8
    /// plane, where gwpy's planes from Q 5.7 keep 0.73 (measured here).
    #[test]
    fn planes_below_q_root_11_cut_their_window_at_dc_and_hold_low_q_bursts() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let (fs, duration) = (4096.0, 16.0);
        let n = (fs * duration) as usize;
        let low = QOptions { q_range: (2.0, 64.0), f_range: (10.0, 1000.0), plane_nyquist: true, ..Default::default() };
        let tiling = QTiling::new(duration, fs, &low).unwrap();
        let qs: Vec<f64> = tiling.planes.iter().map(|p| p.q).collect();
        // The same grid as gwpy's, one plane lower.
        assert_eq!(qs.len(), 5);
        for (q, want) in qs.iter().zip([2.828, 5.657, 11.314, 22.627, 45.255]) {
            assert!((q - want).abs() < 1e-3, "{qs:?}");
        }
        let lowest = &tiling.planes[0];
        let cut = lowest.rows.iter().filter(|r| r.first_bin == 1).count();
        assert!(cut > 0 && lowest.rows.iter().all(|r| r.first_bin >= 1), "no row reaches 0 Hz at Q {}", lowest.q);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let mut x: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
        let spec = spectrum(&x);
        for row in &lowest.rows {
            let e = row.energies(&spec);
            let mean = e.iter().map(|z| z * LN_2).sum::<f64>() / e.len() as f64;
            assert!((mean - 1.0).abs() < 0.05, "row at {} Hz: mean normalised energy {mean}", row.frequency);
        }
        // A sine-Gaussian of Q 1.2 at 150 Hz, SNR 20, t0 = 7 s.
        let (t0, snr) = (7.0, 20.0);
        add_sine_gaussian(&mut x, fs, (150.0, 1.2, t0), snr);
        let spec = spectrum(&x);
        let best = |planes: &[QPlane]| {
            let mut best = (0.0f64, 0.0f64);
            for row in planes.iter().flat_map(|p| &p.rows) {
                for (j, z) in row.energies(&spec).iter().enumerate() {
                    if tile_snr(*z) > best.0 {
                        best = (tile_snr(*z), j as f64 * duration / row.tiles as f64);
                    }
                }
            }
            best
        };
        let (rho_low, t_low) = best(&tiling.planes[..1]);
        let (rho_gwpy, _) = best(&tiling.planes[1..]);
        assert!((t_low - t0).abs() < 0.005, "peak time {t_low}");
        assert!(rho_low >= 0.83 * snr && rho_low <= 1.1 * snr, "Q 2.8 plane: SNR {rho_low} of {snr}");
        assert!(rho_gwpy < 0.78 * snr, "Q 5.7+ planes: SNR {rho_gwpy} of {snr}");
    }

    /// Normalised by white noise's level, unit-variance noise has mean
    /// `1/ln 2` (median 1) in every row, as by its own median; a tone
    /// filling the whole segment sets its row's own median, but not white
    /// noise's.
    #[test]
    fn white_noise_normalisation_matches_the_median_in_noise_and_keeps_a_row_filling_tone() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let (fs, duration) = (1024.0, 16.0);
        let n = (fs * duration) as usize;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let mut x: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
        let tiling = QTiling::new(duration, fs, &QOptions { f_range: (20.0, 500.0), ..Default::default() }).unwrap();
        let spec = spectrum(&x);
        let rows: Vec<&QRow> = tiling.planes.iter().flat_map(|p| &p.rows).collect();
        // Each row's mean of z ln 2 (a row of few independent tiles, at low
        // frequency and high Q, scatters by tens of percent).
        let means: Vec<f64> = rows
            .iter()
            .map(|row| {
                let e = row.energies_over_white_noise(&spec, n);
                e.iter().map(|z| z * LN_2).sum::<f64>() / e.len() as f64
            })
            .collect();
        let mean = means.iter().sum::<f64>() / means.len() as f64;
        assert!((mean - 1.0).abs() < 0.03, "mean over rows {mean}");
        assert!(means.iter().all(|r| (0.5..2.0).contains(r)), "{means:?}");
        // A 200 Hz tone of amplitude 1 (energy per sample ½ against noise's 1).
        x.iter_mut().enumerate().for_each(|(j, v)| *v += (TAU * 200.0 * j as f64 / fs).sin());
        let spec = spectrum(&x);
        let row = rows.iter().min_by(|a, b| (a.frequency - 200.0).abs().total_cmp(&(b.frequency - 200.0).abs())).unwrap();
        let (mut by_median, mut by_noise) = (row.energies(&spec), row.energies_over_white_noise(&spec, n));
        let (m, w) = (median(&mut by_median), median(&mut by_noise));
        assert!((m - 1.0).abs() < 1e-12, "a row's median-normalised median is 1: {m}");
        // Over white noise, the tone's tiles stand at its bin's |X|² = (n/2)²
        // through the window, over noise's median n Σ W² ln 2 (plus the
        // noise's own ~1, and the tone's beat with it).
        let k = (200.0 * duration) as usize - row.first_bin;
        let expected = (n as f64 / 2.0 * row.window[k]).powi(2) / (n as f64 * row.window.iter().map(|w| w * w).sum::<f64>() * LN_2);
        assert!(
            expected > 10.0 && (w / (expected + 1.0) - 1.0).abs() < 0.15,
            "the tone's median over white noise's {w}, expected {expected}"
        );
    }

    #[test]
    fn excess_power_fails_every_sum_up_to_its_failing_sum_and_passes_just_above() {
        // Windows of 1/8-1 s of tiles 2 ms apart, correlation times 5-40 ms,
        // at the scan's floor of 5: the pass/fail boundary is one sum, which
        // failing_sum brackets from below within 1e-4.
        for (tau, window) in [(0.005, 0.125), (0.02, 0.5), (0.04, 1.0), (0.01, 1.0)] {
            let ep = ExcessPower::new(0.002, tau, window, 5.0);
            let bound = ep.failing_sum();
            assert!(bound.is_finite() && bound > 0.0, "{bound}");
            assert!(ep.test(bound).is_none());
            assert!(ep.test(bound * (1.0 + 3e-4)).is_some(), "tau {tau} window {window}: bound {bound}");
            for i in 0..200 {
                assert!(ep.test(bound * i as f64 / 200.0).is_none(), "tau {tau} window {window}: passes at {i}/200 of {bound}");
            }
            for i in 1..200 {
                assert!(ep.test(bound * (1.0 + 3e-4) * (1.0 + i as f64 / 20.0)).is_some());
            }
        }
    }
}
