//! Starts found by heterodyning, for the two families whose match with
//! the data lives in lobes far narrower than any grid of starts.
//!
//! **Whistles.** A whistle's match with the data
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
//!
//! **Scratchy glitches.** A train of arches at `rate` on a carrier `f0`
//! whose frequency swings with them (`wobble`) is, by the Jacobi–Anger
//! expansion, a comb of lines at `f0 + m·rate` under one envelope:
//! `½(1 − cos θ) e^{iβ sin θ} = Σ_m c_m(β) e^{imθ}` with `θ = 2π rate τ`
//! and `β = wobble f0 / rate`. So one FFT of the enveloped data holds
//! every carrier and rate at once: the match is
//! `|Σ_m c_m e^{imψ} D(f0 + m rate)|`, `ψ` the arches' phase. A comb
//! search on `Σ_m c_m² |D|²` finds carrier and rate; the phase and `β`
//! are then scanned coherently around the best combs. The carrier must be
//! right to a fraction of a hertz over a second-long glitch.

use super::seeds::Seed;
use super::Start;
use num_complex::{Complex32, Complex64};
use realfft::RealFftPlanner;
use rustfft::{Fft, FftPlanner};
use std::collections::HashMap;
use std::f64::consts::TAU;
use std::sync::Arc;

/// Spans (Hz, from the vertex to the ends at ±`half`; negative: an
/// inverted V) and half-widths (s) the search tries at each vertex time.
const SPANS: std::ops::RangeInclusive<i32> = -16..=18;
/// Step of [`SPANS`] (Hz).
const SPAN_STEP: f64 = 50.0;
const HALVES: [f64; 7] = [0.06, 0.08, 0.11, 0.15, 0.2, 0.27, 0.35];

/// How far (as a fraction of the seed's frequency) the vertex may lie from
/// it beyond the span: the loudest tile sits near the vertex, where the
/// sweep is slowest, or on an arm — below the vertex of an inverted V, the
/// whitened arms being louder at lower frequencies — so the vertex is
/// looked for from the tile's frequency to a span past it.
const REACH: f64 = 0.12;

/// Half-widths (s) and the span step (Hz) of the coarse scan that ranks
/// the places (an origin's frequency at one of its vertex times) a whistle
/// is looked for from.
const COARSE_HALVES: [f64; 3] = [0.08, 0.15, 0.27];
const COARSE_SPAN_STEP: f64 = 100.0;
/// How many of the best places, beyond the loudest tile's, the full grid
/// of spans and widths searches.
const PLACES_SEARCHED: usize = 2;

/// Where a whistle's vertex is looked for from a tile at `f` Hz, below
/// and above `f`, for each span: a V's vertex lies at or below the tile,
/// an inverted V's at or above it.
fn whistle_reach(f: f64) -> impl Fn(f64) -> (f64, f64) {
    let margin = REACH * f;
    move |span: f64| (margin + span.max(0.0), margin + (-span).max(0.0))
}

/// How many of the best whistle shapes are searched again at vertex times
/// [`RETIME`] s away.
const SHAPES_RETIMED: usize = 4;
const RETIME: [f64; 7] = [-0.006, -0.004, -0.002, 0.0, 0.002, 0.004, 0.006];

/// Quartic wiggles (Hz; std::glitch's `wiggle`, the frequency's `u⁴`
/// term: a W when it bends a V's arms up, an M an inverted V's down) tried
/// around the best V's.
const WIGGLES: [f64; 12] = [-600.0, -500.0, -400.0, -300.0, -200.0, -100.0, 100.0, 200.0, 300.0, 400.0, 500.0, 600.0];
/// How many of the best V's are searched again with wiggles.
const SHAPES_WIGGLED: usize = 2;
/// The least match (an SNR in white noise) of the best V for W and M
/// shapes to be searched: the largest of a thousand V's in Gaussian noise
/// alone is ~4.5.
const WIGGLE_GATE: f64 = 6.0;

/// The V whose frequency track `f + s u²` is nearest (least squares
/// under the envelope's energy `e^{−2u²}`) to a whistle's `f_turn + span
/// u² + wiggle u⁴` has `s = span + 1.5 wiggle` (and `f = f_turn − 0.1875
/// wiggle`): the normal equations with the moments ⟨u²⟩ = 1/4, ⟨u⁴⟩ =
/// 3/16, ⟨u⁶⟩ = 15/64 of that weight. Shapes along that ridge match alike.
const SPAN_PER_WIGGLE: f64 = 1.5;
/// The fine grid around the best shapes: steps either side, and the
/// steps in wiggle and span (Hz).
const FINE_STEPS: i32 = 10;
const FINE_WIGGLE_STEP: f64 = 10.0;
const FINE_SPAN_STEP: f64 = 5.0;

/// Searches whistle shapes over windows sampled at `fs` Hz.
///
/// A template's product with the data is nonzero only where its envelope
/// is (`|u| ≤ 3`, 6 half-widths), so each scan transforms that stretch
/// alone, in the least FFT length of the form 2^a 3^b that holds it: its
/// bins, `1 / (6 half)` Hz apart, put ~2.7 bins in the 1/e half-width
/// (`0.45 / half` Hz) of a matched template's lobe in vertex frequency,
/// and a parabola through the logarithms of the peak's three places it
/// between them. Short templates cost a fraction of a whole window's FFT.
pub struct WhistleSearch {
    planner: FftPlanner<f32>,
    ffts: HashMap<usize, Arc<dyn Fft<f32>>>,
    fs: f64,
    buf: Vec<Complex32>,
    scratch: Vec<Complex32>,
}

impl WhistleSearch {
    /// A search over windows sampled at `fs` Hz.
    pub fn new(fs: f64) -> WhistleSearch {
        WhistleSearch { planner: FftPlanner::new(), ffts: HashMap::new(), fs, buf: Vec::new(), scratch: Vec::new() }
    }

    /// The forward FFT of length `len`, planned once.
    fn fft(&mut self, len: usize) -> Arc<dyn Fft<f32>> {
        let planner = &mut self.planner;
        self.ffts.entry(len).or_insert_with(|| planner.plan_fft_forward(len)).clone()
    }

    /// For a whistle with vertex at `dt` s from the window's centre, span
    /// `span` Hz, half-width `half` s and no wiggle, the vertex frequency
    /// within `reach` Hz of `f` that best matches the whitened data `d`,
    /// and that match as an SNR in unit-variance white noise
    /// (`|z| / √(Σ|a|²/2)`).
    pub fn tune(&mut self, d: &[f64], (dt, f, span, half): (f64, f64, f64, f64), reach: f64) -> (f64, f64) {
        self.scan_spans(d, (dt, f, half, 0.0), (span, 0.0, 1), |_| (reach, reach))[0]
    }

    /// [`WhistleSearch::tune`] for `count` spans `first, first + step, …`
    /// at one vertex time, half-width and quartic `wiggle` (Hz, as
    /// std::glitch's whistle has it), the vertex looked for from
    /// `reach(span).0` Hz below `f` to `reach(span).1` above: one FFT per
    /// span, the product's chirp advanced by a per-sample rotation from one
    /// span to the next.
    pub fn scan_spans(
        &mut self,
        d: &[f64],
        (dt, f, half, wiggle): (f64, f64, f64, f64),
        (first, step, count): (f64, f64, usize),
        reach: impl Fn(f64) -> (f64, f64),
    ) -> Vec<(f64, f64)> {
        let centre = 0.5 * d.len() as f64 / self.fs + dt;
        // The samples under the envelope (|u| ≤ 3).
        let first_k = ((centre - 3.0 * half) * self.fs).ceil().max(0.0) as usize;
        let last_k = (((centre + 3.0 * half) * self.fs).floor() as usize).min(d.len().saturating_sub(1));
        if last_k < first_k || half <= 0.0 {
            return (0..count).map(|_| (f, 0.0)).collect();
        }
        let len = fast_length(last_k - first_k + 1);
        // Per sample: d_k e^{-u²} e^{−2πiτ(f + first·u²/3 + wiggle·u⁴/5)} and
        // the rotation e^{−2πiτ step u²/3} that moves it to the next span
        // (zero past the envelope's stretch, up to the FFT's length).
        let mut product = vec![Complex32::default(); len];
        let mut rotation = vec![Complex32::new(1.0, 0.0); len];
        let mut norm = 0.0;
        for (j, k) in (first_k..=last_k).enumerate() {
            let tau = k as f64 / self.fs - centre;
            let u = tau / half;
            let envelope = (-u * u).exp();
            norm += envelope * envelope;
            let chirp = -TAU * tau * u * u / 3.0;
            let bend = -TAU * tau * wiggle * u.powi(4) / 5.0;
            product[j] = single_cis(d[k] * envelope, -TAU * tau * f + chirp * first + bend);
            rotation[j] = single_cis(1.0, chirp * step);
        }
        let fft = self.fft(len);
        self.scratch.resize(fft.get_inplace_scratch_len(), Complex32::default());
        let df = self.fs / len as f64;
        let half_n = (len / 2) as i64 - 1;
        let snr_per_peak = if norm > 0.0 { 1.0 / (0.5 * norm).sqrt() } else { 0.0 };
        let mut out = Vec::with_capacity(count);
        for i in 0..count {
            if i > 0 {
                product.iter_mut().zip(&rotation).for_each(|(p, r)| *p *= r);
            }
            self.buf.clear();
            self.buf.extend_from_slice(&product);
            fft.process_with_scratch(&mut self.buf, &mut self.scratch);
            // Bin m holds the shift δ = m fs / len (negative shifts wrap
            // around; the stretch's start only turns the phase).
            // Powers, not magnitudes: the peak is the same and no bin pays for a square root.
            let power = |m: i64| f64::from(self.buf[m.rem_euclid(len as i64) as usize].norm_sqr());
            let (below, above) = reach(first + i as f64 * step);
            let bins = ((-below / df).floor() as i64).max(-half_n)..=((above / df).ceil() as i64).min(half_n);
            let (best, peak) = bins.map(|m| (m, power(m))).fold((0, -1.0), |b, c| if c.1 > b.1 { c } else { b });
            // A matched template's lobe is a Gaussian in δ (the Fourier
            // transform of its energy envelope), so a parabola through the
            // logarithms of the peak's magnitude and its neighbours' places
            // it between bins and gives its height there.
            let (l, p, r) = (0.5 * power(best - 1).ln(), 0.5 * peak.ln(), 0.5 * power(best + 1).ln());
            let curvature = l - 2.0 * p + r;
            let offset = if curvature < 0.0 { (0.5 * (l - r) / curvature).clamp(-0.5, 0.5) } else { 0.0 };
            let height = (p - 0.25 * (l - r) * offset).exp();
            out.push((f + (best as f64 + offset) * df, height * snr_per_peak));
        }
        out
    }
}

/// `r e^{iφ}` in single precision, what the whistle search transforms in
/// (its matches rank shapes, and f32 FFTs take half the time of f64's):
/// φ reduced to ±π in double precision (a whistle's phases reach 10⁴
/// rad), its sine and cosine taken in single.
fn single_cis(r: f64, phi: f64) -> Complex32 {
    let reduced = (phi - TAU * (phi / TAU).round()) as f32;
    let (sin, cos) = reduced.sin_cos();
    let r = r as f32;
    Complex32::new(r * cos, r * sin)
}

/// The least `2^a 3^b ≥ n`: lengths rustfft transforms fastest.
fn fast_length(n: usize) -> usize {
    let mut best = n.next_power_of_two();
    let mut threes = 1;
    while threes < best {
        let mut length = threes;
        while length < n {
            length *= 2;
        }
        best = best.min(length);
        threes *= 3;
    }
    best
}

/// Whistle starts from the data: at the vertex time the seed found (else
/// the loudest tile's) and the loudest tile's, every span and half-width
/// of a dense grid with its vertex frequency tuned from 8 % beyond the
/// tile's frequency to a span past it (on the side the span puts the
/// vertex); the same from [`Seed::upper`] when there is one. Around the
/// best few: nearby vertex times and spans, then W and M shapes
/// ([`WIGGLES`]), then a fine grid of spans and wiggles. The `keep` best
/// matches, each once, as `(dt, [f_turn, span, half, wiggle])`.
pub fn whistle_starts_from_data(d: &[f64], fs: f64, seed: &Seed, keep: usize) -> Vec<Start> {
    let mut search = WhistleSearch::new(fs);
    // Every origin at each of its vertex times and its own time, ranked by
    // a coarse scan. The loudest tile at its best vertex time and its own
    // time are searched on the full grid (where the search looked before
    // it had other origins), then the best of the rest.
    let first = *SPANS.start() as f64 * SPAN_STEP;
    let count = SPANS.count();
    let mut found: Vec<(f64, Start)> = Vec::new();
    // (primary, coarse match, dt, frequency)
    let mut places: Vec<(bool, f64, f64, f64)> = Vec::new();
    for (k, origin) in seed.whistle.iter().enumerate() {
        let f = origin.frequency;
        for (j, dt) in origin.vertices.iter().copied().chain([origin.dt]).enumerate() {
            let mut best = f64::NEG_INFINITY;
            for half in COARSE_HALVES {
                let coarse = (first, COARSE_SPAN_STEP, count.div_ceil(2));
                for (i, (f_turn, snr)) in search.scan_spans(d, (dt, f, half, 0.0), coarse, whistle_reach(f)).into_iter().enumerate() {
                    found.push((snr, (dt, vec![f_turn, first + i as f64 * COARSE_SPAN_STEP, half, 0.0])));
                    best = best.max(snr);
                }
            }
            let primary = k == 0 && (j == 0 || j == origin.vertices.len());
            places.push((primary, best, dt, f));
        }
    }
    places.sort_by(|a, b| b.0.cmp(&a.0).then(b.1.total_cmp(&a.1)));
    let mut searched: Vec<(f64, f64)> = Vec::new();
    let mut extra = 0;
    for (primary, _, dt, f) in places {
        // A vertex time within a few ms of one searched, at a frequency near its own, is that place again.
        if searched.iter().any(|(t, g)| (t - dt).abs() < 0.003 && (g - f).abs() < REACH * g) {
            continue;
        }
        if !primary {
            if extra == PLACES_SEARCHED {
                break;
            }
            extra += 1;
        }
        searched.push((dt, f));
        for half in HALVES {
            for (i, (f_turn, snr)) in
                search.scan_spans(d, (dt, f, half, 0.0), (first, SPAN_STEP, count), whistle_reach(f)).into_iter().enumerate()
            {
                found.push((snr, (dt, vec![f_turn, first + i as f64 * SPAN_STEP, half, 0.0])));
            }
        }
    }
    // Around the best few shapes: the vertex time a few ms either way (a
    // sweep's arms slip by radians when it is off) and spans between the
    // grid's, the vertex frequency tuned near the one found.
    for (dt, x) in distinct_best(&mut found, SHAPES_RETIMED) {
        let (f_turn, span, half) = (x[0], x[1], x[2]);
        let margin = 0.02 * f_turn;
        for shift in RETIME {
            let first = span - SPAN_STEP;
            let scanned = search.scan_spans(d, (dt + shift, f_turn, half, 0.0), (first, SPAN_STEP / 2.0, 5), |_| (margin, margin));
            for (i, (f, snr)) in scanned.into_iter().enumerate() {
                found.push((snr, (dt + shift, vec![f, first + i as f64 * SPAN_STEP / 2.0, half, 0.0])));
            }
        }
    }
    // A W or an M is matched best, among V's, by a shorter one, or one
    // with another span and vertex frequency (below): when the best V
    // matches well enough for a whistle, at its time, width and the next
    // two wider, each wiggle of [`WIGGLES`] with every span of the grid,
    // the vertex tuned around the V's.
    if best_match(&found) >= WIGGLE_GATE {
        for (dt, x) in distinct_best(&mut found, SHAPES_WIGGLED) {
            let f_v = x[0];
            for half in HALVES.into_iter().filter(|h| *h >= x[2]).take(3) {
                for wiggle in WIGGLES {
                    let margin = 0.03 * f_v + 0.2 * wiggle.abs();
                    let first = *SPANS.start() as f64 * SPAN_STEP;
                    let scanned = search.scan_spans(d, (dt, f_v, half, wiggle), (first, SPAN_STEP, SPANS.count()), |_| (margin, margin));
                    for (i, (f, snr)) in scanned.into_iter().enumerate() {
                        found.push((snr, (dt, vec![f, first + i as f64 * SPAN_STEP, half, wiggle])));
                    }
                }
            }
        }
        // The best two shapes' match lobes are a few hertz wide in span and
        // wiggle, ten times narrower than the grids' steps above, and L-BFGS
        // stays in the lobe it starts in: a fine grid around each, along the
        // ridge of spans and wiggles that match alike.
        for (dt, x) in distinct_best(&mut found, SHAPES_WIGGLED) {
            let (f_turn, span, half, wiggle) = (x[0], x[1], x[2], x[3]);
            let margin = 0.01 * f_turn;
            for k in -FINE_STEPS..=FINE_STEPS {
                let w = wiggle + k as f64 * FINE_WIGGLE_STEP;
                let first = span - SPAN_PER_WIGGLE * (w - wiggle) - FINE_STEPS as f64 * FINE_SPAN_STEP;
                let count = 2 * FINE_STEPS as usize + 1;
                let scanned = search.scan_spans(d, (dt, f_turn, half, w), (first, FINE_SPAN_STEP, count), |_| (margin, margin));
                for (i, (f, snr)) in scanned.into_iter().enumerate() {
                    found.push((snr, (dt, vec![f, first + i as f64 * FINE_SPAN_STEP, half, w])));
                }
            }
        }
    }
    // The retimed scans repeat the grid's shapes at its own times: once each.
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut starts: Vec<Start> = Vec::with_capacity(keep);
    for (_, (dt, x)) in found {
        let repeat = |(t, y): &Start| *t == dt && y[1..] == x[1..] && (y[0] - x[0]).abs() < 0.5;
        if starts.len() == keep {
            break;
        }
        if !starts.iter().any(repeat) {
            starts.push((dt, x));
        }
    }
    starts
}

/// The best match in `found` (−∞ when empty).
fn best_match(found: &[(f64, Start)]) -> f64 {
    found.iter().map(|f| f.0).fold(f64::NEG_INFINITY, f64::max)
}

/// Sorts `found` best first and returns its `count` best shapes that
/// differ in vertex time (by 10 ms), vertex frequency (20 Hz) or width.
fn distinct_best(found: &mut [(f64, Start)], count: usize) -> Vec<Start> {
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut best: Vec<Start> = Vec::new();
    for (_, (dt, x)) in found.iter() {
        if best.len() == count {
            break;
        }
        if best.iter().all(|(t, y)| (t - dt).abs() > 0.01 || (y[0] - x[0]).abs() > 20.0 || y[2] != x[2]) {
            best.push((*dt, x.clone()));
        }
    }
    best
}

/// The scratchy scene's carrier bounds (Hz).
const SCRATCHY_F0: (f64, f64) = (20.0, 600.0);
/// Arch rates (Hz) the comb search tries.
const SCRATCHY_RATES: (f64, f64) = (8.0, 32.0);
/// Envelope durations (s) the search tries at each centre.
const SCRATCHY_DURATIONS: [f64; 2] = [1.0, 1.8];
/// Modulation indices `β` of the comb search's weights, and the step of the coherent scan.
const COMB_BETAS: [f64; 3] = [0.0, 2.0, 4.5];
const BETA_STEP: f64 = 0.5;
/// The largest `β` scanned: 0.4 swing on a 600 Hz carrier at 30 arches a second.
const MAX_BETA: f64 = 8.0;
/// Lines kept beyond `⌈β⌉` on each side of a comb: the `J_m(β)` past them
/// hold under 1e-4 of its power.
const COMB_MARGIN: i64 = 4;
/// The most lines on each side of any comb the search uses.
const MAX_M: i64 = MAX_BETA as i64 + COMB_MARGIN;
/// Arch phases the coherent scan tries.
const PHASES: usize = 16;
/// Combs per envelope refined coherently.
const COMBS_REFINED: usize = 6;

/// The Fourier coefficients `c_m`, `|m| ≤ M`, of one period of the
/// arches with their phase swing, `½(1 − cos θ) e^{iβ sin θ}` (real: the
/// function is Hermitian in θ), with `M = ⌈β⌉ +` [`COMB_MARGIN`]. Index `m + M`.
fn comb_coefficients(beta: f64) -> Vec<f64> {
    const SAMPLES: usize = 64;
    let m_max = beta.ceil() as i64 + COMB_MARGIN;
    (-m_max..=m_max)
        .map(|m| {
            let sum: f64 = (0..SAMPLES)
                .map(|j| {
                    let theta = TAU * j as f64 / SAMPLES as f64;
                    0.5 * (1.0 - theta.cos()) * (beta * theta.sin() - m as f64 * theta).cos()
                })
                .sum();
            sum / SAMPLES as f64
        })
        .collect()
}

/// Scratchy starts from the data: at a few envelope centres (the seed's
/// arches', the window's and ±0.15 s) and durations, the enveloped data's
/// spectrum (zero-padded to an eighth of a hertz); the combs of carriers
/// over the scene's bounds (a long, quiet train of arches seldom makes the
/// loudest tile: its frequency can be anywhere) and rates of 8–32 Hz that
/// hold the most power; around the best, the arches'
/// phase and the carrier's swing scanned coherently. The `keep` best
/// matches as `(dt, [f0, rate, duration, wobble])`.
pub fn scratchy_starts_from_data(d: &[f64], fs: f64, seed: &Seed, keep: usize) -> Vec<Start> {
    let n = d.len();
    let pad = (4 * n).next_power_of_two();
    let df = fs / pad as f64;
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(pad);
    let centre = 0.5 * n as f64 / fs;
    let (f_lo, f_hi) = (SCRATCHY_F0.0, SCRATCHY_F0.1.min(0.45 * fs));
    let (j_lo, j_hi) = ((f_lo / df).floor() as i64, (f_hi / df).ceil() as i64);
    let (r_lo, r_hi) = ((SCRATCHY_RATES.0 / df).round() as i64, (SCRATCHY_RATES.1 / df).round() as i64);
    // Per β of the comb search: the lines that hold its power, `(m, c_m² / Σ c²)`.
    let comb_weights: Vec<Vec<(i64, f64)>> = COMB_BETAS
        .iter()
        .map(|b| {
            let c = comb_coefficients(*b);
            let (m_max, total) = ((c.len() / 2) as i64, c.iter().map(|c| c * c).sum::<f64>());
            c.iter().enumerate().map(|(i, c)| (i as i64 - m_max, c * c / total)).filter(|(_, w)| *w > 1e-3).collect()
        })
        .collect();
    let reach = comb_weights.iter().flatten().map(|(m, _)| m.abs()).max().unwrap_or(0) * r_hi;
    let betas: Vec<(f64, Vec<f64>)> =
        (0..=(MAX_BETA / BETA_STEP) as usize).map(|i| i as f64 * BETA_STEP).map(|b| (b, comb_coefficients(b))).collect();
    // e^{imψ} for each arch phase ψ and |m| ≤ MAX_M (the largest β's comb).
    let turns: Vec<Vec<Complex64>> = (0..PHASES)
        .map(|p| (-MAX_M..=MAX_M).map(|m| Complex64::from_polar(1.0, m as f64 * TAU * p as f64 / PHASES as f64)).collect())
        .collect();
    let mut input = vec![0.0; pad];
    let mut spectrum = vec![Complex64::default(); pad / 2 + 1];
    // Bin j's phase from the padded series' start to the window's centre, e^{2πi j df centre}.
    let to_centre: Vec<Complex64> = (0..spectrum.len()).map(|j| Complex64::from_polar(1.0, TAU * j as f64 * df * centre)).collect();
    let last = (pad / 2) as i64;
    let bin = |j: i64| j.unsigned_abs().min(last as u64) as usize;
    let carriers = (j_hi - j_lo + 1) as usize;
    let (mut matched, mut best_of_betas) = (vec![0.0f64; carriers], vec![0.0f64; carriers]);
    let mut combs: Vec<(f64, i64, i64)> = Vec::with_capacity(carriers * (r_hi - r_lo + 2) as usize / 2);
    let mut found: Vec<(f64, Start)> = Vec::new();
    let centres = seed.arches.map(|a| a.dt).into_iter().chain([-0.15, 0.0, 0.15]);
    for dt_e in centres.map(|t: f64| t.clamp(-0.3, 0.3)) {
        for duration in SCRATCHY_DURATIONS {
            // The enveloped data and the template's norm (its arches average 3/8 in square).
            let mut norm = 0.0;
            for (k, (x, v)) in input.iter_mut().zip(d).enumerate() {
                let u = 2.0 * (k as f64 / fs - centre - dt_e) / duration;
                let envelope = (-u * u).exp();
                *x = v * envelope;
                norm += 0.375 * envelope * envelope;
            }
            input[n..].fill(0.0);
            fft.process(&mut input, &mut spectrum).expect("buffer lengths match the plan");
            // D(f) relative to the window's centre: bin j times e^{2πi f centre};
            // D(−f) is its conjugate (the data are real).
            spectrum.iter_mut().zip(&to_centre).for_each(|(v, turn)| *v *= turn);
            let at = |j: i64| if j < 0 { spectrum[bin(j)].conj() } else { spectrum[bin(j)] };
            // The comb search: per carrier and rate, the matched power for
            // each β (its noise is the same for all). `around[i + reach]` is
            // the power at bin `j_lo + i` for every bin a comb reaches. Per
            // rate and line, the weighted powers of every carrier at once
            // (contiguous runs of `around`, which vectorise).
            let around: Vec<f64> = (j_lo - reach..=j_hi + reach).map(|j| spectrum[bin(j)].norm_sqr()).collect();
            combs.clear();
            for r in (r_lo..=r_hi).step_by(2) {
                best_of_betas.fill(0.0);
                for weights in &comb_weights {
                    matched.fill(0.0);
                    for &(m, w) in weights {
                        let from = (reach + m * r) as usize;
                        matched.iter_mut().zip(&around[from..from + carriers]).for_each(|(sum, p)| *sum += w * p);
                    }
                    best_of_betas.iter_mut().zip(&matched).for_each(|(best, sum)| *best = best.max(*sum));
                }
                combs.extend(best_of_betas.iter().enumerate().map(|(i, best)| (*best, j_lo + i as i64, r)));
            }
            // The strongest few hundred, best first (neighbours of one comb crowd the top).
            let top = combs.len().min(256);
            combs.select_nth_unstable_by(top - 1, |a, b| b.0.total_cmp(&a.0));
            combs.truncate(top);
            combs.sort_by(|a, b| b.0.total_cmp(&a.0));
            let mut refined: Vec<(i64, i64)> = Vec::new();
            for &(_, j0, r) in &combs {
                if refined.len() == COMBS_REFINED {
                    break;
                }
                if refined.iter().all(|(j, q)| (j - j0).abs() > 4 || (q - r).abs() > 4) {
                    refined.push((j0, r));
                }
            }
            // The coherent scan around each: carrier ±2 bins, rate ±1 bin, β and the arches' phase.
            for (j0, r0) in refined {
                // (|z|², carrier bin, rate bin, β, ψ)
                let mut best = (0.0, 0, 0, 0.0, 0.0);
                for j in j0 - 2..=j0 + 2 {
                    for r in r0 - 1..=r0 + 1 {
                        for (beta, c) in &betas {
                            let m_max = (c.len() / 2) as i64;
                            let lines: Vec<Complex64> = (-m_max..=m_max).map(|m| at(j + m * r)).collect();
                            for (p, turn) in turns.iter().enumerate() {
                                // Σ_m c_m e^{imψ} D_m, e^{imψ} = turn[m + MAX_M].
                                let z: Complex64 = c
                                    .iter()
                                    .zip(&lines)
                                    .enumerate()
                                    .map(|(i, (c, line))| line * turn[(i as i64 - m_max + MAX_M) as usize] * *c)
                                    .sum();
                                if z.norm_sqr() > best.0 {
                                    best = (z.norm_sqr(), j, r, *beta, TAU * p as f64 / PHASES as f64);
                                }
                            }
                        }
                    }
                }
                let (power, j, r, beta, psi) = best;
                let match_ = power.sqrt();
                let (f0, rate) = (j as f64 * df, r as f64 * df);
                // ψ = 2π rate dt: the dt nearest the envelope's centre with that phase.
                let turns = psi / TAU - rate * dt_e;
                let dt = dt_e + (turns - turns.round()) / rate;
                // Past the scene's bound, the fit clamps it.
                let wobble = beta * rate / f0;
                let snr = if norm > 0.0 { match_ / (0.5 * norm).sqrt() } else { 0.0 };
                found.push((snr, (dt, vec![f0, rate, duration, wobble])));
            }
        }
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    found.into_iter().take(keep).map(|(_, start)| start).collect()
}

#[cfg(test)]
mod tests {
    use super::super::test_support::{at_snr_in_white_noise, scratchy};
    use super::super::WhistleOrigin;
    use super::*;

    /// A unit-amplitude whistle (std::glitch's formula) at `t0` s.
    fn whistle(n: usize, fs: f64, t0: f64, (f, span, half, wiggle): (f64, f64, f64, f64)) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let tau = k as f64 / fs - t0;
                let u = tau / half;
                (-u * u).exp() * (TAU * tau * (f + span * u * u / 3.0 + wiggle * u.powi(4) / 5.0) + 0.7).cos()
            })
            .collect()
    }

    #[test]
    fn a_w_shaped_whistle_is_found_with_its_wiggle() {
        // A W (f = 800 − 300u² + 300u⁴ Hz: down to 725 Hz at u² = ½ and up
        // to 1700 Hz) at SNR 15 in unit white noise, the loudest tile on
        // its dips. The best V's are short ones of the vertex alone; the
        // best start must be a W (span, wiggle and width trade off along a
        // ridge the fit then climbs), its vertex within 10 Hz.
        let (n, fs) = (8192, 4096.0);
        let truth = (800.0, -300.0, 0.18, 300.0);
        let d = at_snr_in_white_noise(&whistle(n, fs, 1.0 + 0.01, truth), 15.0, 7);
        let seed = Seed {
            dt: 0.03,
            frequency: 730.0,
            q: 20.0,
            arches: None,
            high: None,
            whistle: vec![WhistleOrigin { dt: 0.03, frequency: 730.0, vertices: vec![0.01] }],
        };
        let starts = whistle_starts_from_data(&d, fs, &seed, 3);
        let (dt, x) = &starts[0];
        assert!((dt - 0.01).abs() < 0.003, "vertex time {dt} s: {starts:?}");
        assert!((x[0] - truth.0).abs() < 10.0, "vertex {} Hz: {starts:?}", x[0]);
        assert!(x[1] < -150.0 && (150.0..=600.0).contains(&x[3]), "span {} Hz, wiggle {} Hz: {starts:?}", x[1], x[3]);
    }

    #[test]
    fn a_quiet_whistle_is_found_when_a_louder_burst_in_another_octave_has_the_loudest_tile() {
        // An inverted V from 1250 Hz at SNR 14 and, 0.1 s after its vertex,
        // a 500 Hz burst (Q 20) at SNR 9 whose compact tile outshines the
        // sweep's (passes at noise seeds 11-14): the whistle is looked for from its own octave's loudest
        // pixel, at one of its phase symmetry's best vertex times.
        let (n, fs) = (8192, 4096.0);
        let truth = (1250.0, -400.0, 0.25, 0.0);
        let sweep = whistle(n, fs, 1.0, truth);
        let burst: Vec<f64> = (0..n)
            .map(|k| {
                let tau = k as f64 / fs - 1.1;
                let width = 20.0 / (TAU * 500.0);
                (-(tau / width).powi(2)).exp() * (TAU * 500.0 * tau).cos()
            })
            .collect();
        let unit = |h: &[f64]| {
            let norm = h.iter().map(|v| v * v).sum::<f64>().sqrt();
            h.iter().map(|v| v / norm).collect::<Vec<f64>>()
        };
        let h: Vec<f64> = unit(&sweep).iter().zip(unit(&burst)).map(|(w, b)| 14.0 * w + 9.0 * b).collect();
        let d = at_snr_in_white_noise(&h, h.iter().map(|v| v * v).sum::<f64>().sqrt(), 11);
        let win = super::super::Window { gps_centre: 1.0, gps_start: 0.0, offset: 0, sample_rate: fs, d, psd: vec![1.0; n / 2 + 1] };
        let seed = super::super::seed_of(&win, fs, (20.0, 2000.0)).expect("a seed");
        assert!((seed.frequency - 500.0).abs() < 100.0, "the loudest tile is the burst's: {} Hz", seed.frequency);
        let starts = whistle_starts_from_data(&win.d, fs, &seed, 3);
        let (dt, x) = &starts[0];
        assert!(dt.abs() < 0.002, "vertex time {dt} s: {starts:?}");
        assert!((x[0] - truth.0).abs() < 5.0, "vertex {} Hz: {starts:?}", x[0]);
    }

    #[test]
    fn the_vertex_frequency_is_found_from_a_start_15_hz_off() {
        // SNR 12 in unit white noise; the search starts 15 Hz below the
        // truth, three lobe-widths away, and must land within 0.5 Hz.
        let (n, fs) = (8192, 4096.0);
        let h = whistle(n, fs, 1.0 + 0.01, (589.1, 463.0, 0.16, 0.0));
        let d = at_snr_in_white_noise(&h, 12.0, 3);
        let mut search = WhistleSearch::new(fs);
        let (f, snr) = search.tune(&d, (0.01, 574.0, 463.0, 0.16), 40.0);
        assert!((f - 589.1).abs() < 0.5, "vertex {f} Hz");
        assert!((10.0..14.0).contains(&snr), "match {snr}");
        // Off the true span by 200 Hz the match is lost wherever the vertex goes.
        let (_, off) = search.tune(&d, (0.01, 574.0, 263.0, 0.16), 40.0);
        assert!(off < 0.6 * snr, "match {off} at the wrong span");
        // Spans scanned by rotation match spans tuned one by one (to the
        // single precision the search transforms in: 1e-7 measured).
        let scanned = search.scan_spans(&d, (0.01, 574.0, 0.16, 0.0), (263.0, 50.0, 5), |_| (40.0, 40.0));
        for (i, (f_i, snr_i)) in scanned.iter().enumerate() {
            let (f_1, snr_1) = search.tune(&d, (0.01, 574.0, 263.0 + 50.0 * i as f64, 0.16), 40.0);
            assert!((f_i - f_1).abs() < 1e-4 && (snr_i - snr_1).abs() < 1e-5 * snr_1, "span {i}: {f_i} {snr_i} against {f_1} {snr_1}");
        }
        assert!((scanned[4].0 - 589.1).abs() < 0.5, "{scanned:?}");
    }

    #[test]
    fn fast_lengths_are_the_least_products_of_twos_and_threes_that_hold_n() {
        let lengths: Vec<usize> = [1, 2, 5, 7, 10, 13, 1475, 8192, 8193].map(fast_length).to_vec();
        assert_eq!(lengths, vec![1, 2, 6, 8, 12, 16, 1536, 8192, 8748]);
    }

    #[test]
    fn comb_coefficients_are_those_of_the_arches_and_sum_to_their_norm() {
        // Without a swing: ½ − ¼e^{iθ} − ¼e^{−iθ}.
        let c = comb_coefficients(0.0);
        assert_eq!(c.len(), 9);
        let expected = [0.0, 0.0, 0.0, -0.25, 0.5, -0.25, 0.0, 0.0, 0.0];
        assert!(c.iter().zip(expected).all(|(c, e)| (c - e).abs() < 1e-12), "{c:?}");
        // Parseval: Σ c_m² is the mean of |½(1 − cos θ)|², 3/8, whatever the
        // swing; the lines beyond ⌈β⌉ + COMB_MARGIN hold under 1e-4 of it.
        for beta in [1.0, 3.7, 8.0] {
            let c = comb_coefficients(beta);
            let sum: f64 = c.iter().map(|c| c * c).sum();
            assert!((sum - 0.375).abs() < 0.375e-4, "β {beta}: Σc² = {sum}");
        }
    }

    #[test]
    fn a_wobbling_scratchy_glitch_is_found_whatever_the_tile_says() {
        // SNR 12 in unit white noise, a phase swing of β = 0.12·187.3/17.6 =
        // 1.3 rad; the tile's frequency is 28 Hz below the carrier, and the
        // carrier is searched over the scene's whole range.
        let (n, fs) = (8192, 4096.0);
        let truth = (187.3, 17.6, 1.4, 0.12);
        let h = scratchy(n, fs, 1.0 + 0.07, truth);
        let d = at_snr_in_white_noise(&h, 12.0, 5);
        let seed = Seed { dt: 0.0, frequency: 160.0, q: 11.0, arches: None, high: None, whistle: Vec::new() };
        let starts = scratchy_starts_from_data(&d, fs, &seed, 3);
        let (dt, x) = &starts[0];
        assert!((x[0] - truth.0).abs() < 0.3, "carrier {} Hz: {starts:?}", x[0]);
        assert!((x[1] - truth.1).abs() < 0.2, "rate {} Hz: {starts:?}", x[1]);
        assert!((x[3] - truth.3).abs() < 0.04, "wobble {}: {starts:?}", x[3]);
        // The arches' phase: dt within a tenth of an arch of the truth, modulo arches.
        let arches = (dt - 0.07) * truth.1;
        assert!((arches - arches.round()).abs() < 0.1, "dt {dt} s: {starts:?}");
    }
}
