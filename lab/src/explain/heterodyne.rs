//! Whistle starts found by heterodyning. A whistle's match with the data
//! lives in a lobe a few Hz wide in its vertex frequency (a 0.3 s sweep
//! 5 Hz off has slipped a full cycle), far narrower than any grid of
//! starts the fits can afford to evaluate. Shifting the vertex frequency by
//! `δ` multiplies the analytic template by `e^{2πiδτ}`, so the data's
//! match over every shift at once is one FFT of the data times the
//! template's conjugate: `z(δ) = Σ_k d_k a*_k e^{−2πiδ τ_k}`, whose largest
//! `|z|` gives the vertex frequency to a fraction of `fs / n` (0.5 Hz for
//! 2 s). The templates are not whitened here (a whistle spans well under
//! an octave, over which the whitened PSD's slope matters little for
//! finding the lobe); the fit proper, whitened, takes over from there.

use super::seeds::Seed;
use super::Start;
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::f64::consts::TAU;
use std::sync::Arc;

/// Spans (Hz, from the vertex to the ends at ±`half`; negative: an
/// inverted V) and half-widths (s) the search tries at each vertex time.
const SPANS: std::ops::RangeInclusive<i32> = -16..=18;
/// Step of [`SPANS`] (Hz).
const SPAN_STEP: f64 = 50.0;
const HALVES: [f64; 7] = [0.06, 0.08, 0.11, 0.15, 0.2, 0.27, 0.35];

/// How far (as a fraction of the seed's frequency) the vertex may lie from
/// it: the loudest tile sits near the vertex, where the sweep is slowest.
const REACH: f64 = 0.08;

/// Searches whistle shapes over a window of `n` samples at `fs` Hz.
pub struct WhistleSearch {
    fft: Arc<dyn Fft<f64>>,
    fs: f64,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl WhistleSearch {
    /// A search over windows of `n` samples at `fs` Hz.
    pub fn new(n: usize, fs: f64) -> WhistleSearch {
        let fft = FftPlanner::new().plan_fft_forward(n);
        let scratch = vec![Complex64::default(); fft.get_inplace_scratch_len()];
        WhistleSearch { fft, fs, buf: Vec::new(), scratch }
    }

    /// For a whistle with vertex at `dt` s from the window's centre, span
    /// `span` Hz and half-width `half` s, the vertex frequency within
    /// `reach` Hz of `f` that best matches the whitened data `d`, and that
    /// match as an SNR in unit-variance white noise (`|z| / √(Σ|a|²/2)`).
    pub fn tune(&mut self, d: &[f64], (dt, f, span, half): (f64, f64, f64, f64), reach: f64) -> (f64, f64) {
        self.scan_spans(d, (dt, f, half), (span, 0.0, 1), reach)[0]
    }

    /// [`WhistleSearch::tune`] for `count` spans `first, first + step, …`
    /// at one vertex time and half-width: one FFT per span, the product's
    /// chirp advanced by a per-sample rotation from one span to the next.
    pub fn scan_spans(
        &mut self,
        d: &[f64],
        (dt, f, half): (f64, f64, f64),
        (first, step, count): (f64, f64, usize),
        reach: f64,
    ) -> Vec<(f64, f64)> {
        let n = d.len();
        let centre = 0.5 * n as f64 / self.fs + dt;
        // Per sample: d_k e^{-u²} e^{−2πiτ(f + first·u²/3)} and the rotation
        // e^{−2πiτ step u²/3} that moves it to the next span.
        let mut product = Vec::with_capacity(n);
        let mut rotation = Vec::with_capacity(n);
        let mut norm = 0.0;
        for (k, v) in d.iter().enumerate() {
            let tau = k as f64 / self.fs - centre;
            let u = tau / half;
            if u.abs() > 3.0 {
                product.push(Complex64::default());
                rotation.push(Complex64::new(1.0, 0.0));
                continue;
            }
            let envelope = (-u * u).exp();
            norm += envelope * envelope;
            let chirp = -TAU * tau * u * u / 3.0;
            product.push(Complex64::from_polar(v * envelope, -TAU * tau * f + chirp * first));
            rotation.push(Complex64::from_polar(1.0, chirp * step));
        }
        let df = self.fs / n as f64;
        let bins = (reach / df).ceil() as i64;
        let snr_per_peak = if norm > 0.0 { 1.0 / (0.5 * norm).sqrt() } else { 0.0 };
        let mut out = Vec::with_capacity(count);
        for i in 0..count {
            if i > 0 {
                product.iter_mut().zip(&rotation).for_each(|(p, r)| *p *= r);
            }
            self.buf.clear();
            self.buf.extend_from_slice(&product);
            self.fft.process_with_scratch(&mut self.buf, &mut self.scratch);
            // Bin m holds the shift δ = m fs / n (negative shifts wrap around).
            let at = |m: i64| self.buf[m.rem_euclid(n as i64) as usize].norm();
            let (best, peak) = (-bins..=bins).map(|m| (m, at(m))).fold((0, -1.0), |b, c| if c.1 > b.1 { c } else { b });
            // A parabola through the peak and its neighbours places it between bins.
            let (l, r) = (at(best - 1), at(best + 1));
            let curvature = l - 2.0 * peak + r;
            let offset = if curvature < 0.0 { (0.5 * (l - r) / curvature).clamp(-0.5, 0.5) } else { 0.0 };
            out.push((f + (best as f64 + offset) * df, peak * snr_per_peak));
        }
        out
    }
}

/// Whistle starts from the data: at the vertex time the seed found (else
/// the loudest tile's) and the loudest tile's, every span and half-width
/// of a dense grid with its vertex frequency tuned within ±8 % of the
/// tile's frequency; the `keep` best matches as `(dt, [f_turn, span, half])`.
pub fn whistle_starts_from_data(d: &[f64], fs: f64, seed: &Seed, keep: usize) -> Vec<Start> {
    let mut search = WhistleSearch::new(d.len(), fs);
    let reach = REACH * seed.frequency;
    let mut found: Vec<(f64, Start)> = Vec::new();
    for dt in seed.vertex.into_iter().chain([seed.dt]) {
        for half in HALVES {
            let first = *SPANS.start() as f64 * SPAN_STEP;
            let count = SPANS.count();
            for (i, (f_turn, snr)) in
                search.scan_spans(d, (dt, seed.frequency, half), (first, SPAN_STEP, count), reach).into_iter().enumerate()
            {
                found.push((snr, (dt, vec![f_turn, first + i as f64 * SPAN_STEP, half])));
            }
        }
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    found.into_iter().take(keep).map(|(_, start)| start).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// A unit-amplitude whistle (std::glitch's formula) at `t0` s.
    fn whistle(n: usize, fs: f64, t0: f64, f: f64, span: f64, half: f64) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let tau = k as f64 / fs - t0;
                let u = tau / half;
                (-u * u).exp() * (TAU * tau * (f + span * u * u / 3.0) + 0.7).cos()
            })
            .collect()
    }

    #[test]
    fn the_vertex_frequency_is_found_from_a_start_15_hz_off() {
        // SNR 12 in unit white noise; the search starts 15 Hz below the
        // truth, three lobe-widths away, and must land within 0.5 Hz.
        let (n, fs) = (8192, 4096.0);
        let h = whistle(n, fs, 1.0 + 0.01, 589.1, 463.0, 0.16);
        let scale = 12.0 / h.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let d: Vec<f64> = h
            .iter()
            .map(|v| {
                let noise: f64 = StandardNormal.sample(&mut rng);
                v * scale + noise
            })
            .collect();
        let mut search = WhistleSearch::new(n, fs);
        let (f, snr) = search.tune(&d, (0.01, 574.0, 463.0, 0.16), 40.0);
        assert!((f - 589.1).abs() < 0.5, "vertex {f} Hz");
        assert!((10.0..14.0).contains(&snr), "match {snr}");
        // Off the true span by 200 Hz the match is lost wherever the vertex goes.
        let (_, off) = search.tune(&d, (0.01, 574.0, 263.0, 0.16), 40.0);
        assert!(off < 0.6 * snr, "match {off} at the wrong span");
        // Spans scanned by rotation match spans tuned one by one.
        let scanned = search.scan_spans(&d, (0.01, 574.0, 0.16), (263.0, 50.0, 5), 40.0);
        for (i, (f_i, snr_i)) in scanned.iter().enumerate() {
            let (f_1, snr_1) = search.tune(&d, (0.01, 574.0, 263.0 + 50.0 * i as f64, 0.16), 40.0);
            assert!((f_i - f_1).abs() < 1e-6 && (snr_i - snr_1).abs() < 1e-9 * snr_1, "span {i}: {f_i} {snr_i} against {f_1} {snr_1}");
        }
        assert!((scanned[4].0 - 589.1).abs() < 0.5, "{scanned:?}");
    }
}
