//! Scattered-light starts found in the data.
//!
//! Light scattered off a surface moving as `X sin ωτ` (`ω = 2π f_motion`,
//! `τ` from an arch's top) comes back with the phase `p = A sin ωτ`,
//! `A = f_fringe / f_motion`: hundreds of radians for a slow surface. The
//! fit's likelihood then lives in lobes a fraction of a percent wide in
//! `f_fringe` and `f_motion` and a few ms wide in time, far narrower than
//! any grid of starts the fits can afford. Two stages find them:
//!
//! 1. **Tracks** (incoherent, coarse). In a spectrogram of the whitened
//!    data the fringes and their second harmonic follow
//!    `f = h f_fringe |cos ωτ|`. The power summed along every track of a
//!    coarse grid (6 % in `f_fringe`, 8 % in `f_motion`, 25 ms in time)
//!    ranks candidates: pixels of noise have mean 1, so a track's excess
//!    over its pixel count, over the count's square root, is a z-score.
//!    The best track of each band of surface speeds goes on.
//! 2. **Fringes** (coherent, fine). For one motion and arch time the phase
//!    is `A s` with `s = sin ωτ ∈ [−1, 1]`, so the match at every `A` is a
//!    Fourier transform in `s`: the enveloped data spread onto a uniform
//!    grid in `s` (linear weights), one FFT gives the match at every
//!    `f_fringe` at once, and its second harmonic at twice the bin. Around
//!    each candidate the motion (0.5 % steps) and the arch time (2 ms, or
//!    4 ms when the window holds one arch) are scanned this way.
//!
//! The templates are not whitened (the whitened data carry no fringes
//! below the band, and the whitening's slope over an arch only weighs its
//! top more); the fit proper, whitened, takes over from the starts.

use super::rates::downsample;
use super::Start;
use realfft::RealFftPlanner;
use std::f64::consts::{PI, TAU};

/// The rate both stages run at (Hz): room for the second harmonic of the
/// highest fringe frequency.
const SEARCH_RATE: f64 = 512.0;
/// `f_fringe` searched (Hz): the scattered-light scene's bounds.
const FRINGE: (f64, f64) = (15.0, 100.0);
/// `f_motion` searched (Hz): the scene's bounds.
const MOTION: (f64, f64) = (0.1, 3.0);
/// How far an arch's top may lie from the window's centre (s): the
/// scene's bound on `dt`.
const REACH: f64 = 0.3;
/// Fringes below this frequency (Hz) are whitened away.
const F_LOW: f64 = 20.0;
/// Spectrogram segment and hop (samples at [`SEARCH_RATE`]): 125 ms, 8 Hz bins.
const SEGMENT: usize = 64;
const HOP: usize = 16;
/// Track grid: ratios between neighbouring `f_fringe` and `f_motion`, and the time step (s).
const FRINGE_RATIO: f64 = 1.06;
const MOTION_RATIO: f64 = 1.08;
const TIME_STEP: f64 = 0.025;
/// The fewest spectrogram pixels a track is scored on.
const MIN_PIXELS: usize = 4;
/// Tracks refined coherently.
const CANDIDATES: usize = 8;
/// The ratio of `f_motion` over which one track is refined.
const MOTION_BAND: f64 = 1.16;
/// Coherent scan: `f_motion` in relative steps of 0.5 % to ±5 %, the arch
/// time to ±14 ms in 2 ms steps when the window can hold two arch tops (at
/// 2 ms off, fringes of 40 Hz slip by 2π·40·0.002·2 = 1 rad from one arch
/// to the next) and 4 ms when it holds one (the slip, 2π f_fringe δ
/// (1 − cos ωτ), vanishes at the top), `f_fringe` within 12 % of the
/// track's or of twice it.
const MOTION_FINE: (f64, i32) = (0.005, 10);
const TIME_FINE: (f64, f64) = (0.002, 0.014);
const FRINGE_REACH: f64 = 1.12;
/// The largest phase step (rad) between neighbouring `s` cells at the
/// highest harmonic scanned: linear spreading loses at most
/// `1 − cos(0.35)` ≈ 6 % of the match.
const CELL_PHASE: f64 = 0.7;
/// The envelope's 1/e full width (s) the coherent stage weighs the data by.
const SEARCH_DURATION: f64 = 2.5;
/// Bins of `|cos ωτ|` over which the match's noise is tallied.
const COS_BINS: usize = 64;
/// The least part of the envelope's energy over which a harmonic must be
/// in band to count: a harmonic that reaches the band only at the arch's
/// top is a few samples whose noise the tally cannot place.
const IN_BAND: f64 = 0.05;
/// Each candidate's starts: bounces and durations (s).
const BOUNCES: [f64; 2] = [0.1, 0.35];
const DURATIONS: [f64; 3] = [1.5, 2.5, 4.0];

/// A spectrogram of whitened data, each pixel's power divided by the
/// noise's mean.
struct Spectrogram {
    /// Each column's time from the window's centre (s).
    times: Vec<f64>,
    /// Bins per column.
    bins: usize,
    /// Bin spacing (Hz).
    df: f64,
    /// Power, column after column.
    power: Vec<f64>,
}

impl Spectrogram {
    /// Hann-windowed segments of `x` (at `fs` Hz), normalised by the median
    /// in-band pixel (noise pixels are exponential with mean 1: median ln 2).
    fn of(x: &[f64], fs: f64) -> Spectrogram {
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(SEGMENT);
        let window: Vec<f64> = (0..SEGMENT).map(|k| (PI * (k as f64 + 0.5) / SEGMENT as f64).sin().powi(2)).collect();
        let bins = SEGMENT / 2 + 1;
        let columns = if x.len() >= SEGMENT { (x.len() - SEGMENT) / HOP + 1 } else { 0 };
        let centre = 0.5 * x.len() as f64 / fs;
        let (mut input, mut spectrum) = (fft.make_input_vec(), fft.make_output_vec());
        let mut power = Vec::with_capacity(columns * bins);
        let mut times = Vec::with_capacity(columns);
        for c in 0..columns {
            let start = c * HOP;
            input.iter_mut().zip(&x[start..start + SEGMENT]).zip(&window).for_each(|((i, v), w)| *i = v * w);
            fft.process(&mut input, &mut spectrum).expect("buffers sized by the plan");
            power.extend(spectrum.iter().map(|v| v.norm_sqr()));
            times.push((start as f64 + 0.5 * SEGMENT as f64) / fs - centre);
        }
        let df = fs / SEGMENT as f64;
        let in_band = |b: usize| b as f64 * df > F_LOW && b + 1 < bins;
        let mut band: Vec<f64> = power.iter().enumerate().filter(|(i, _)| in_band(i % bins)).map(|(_, p)| *p).collect();
        if !band.is_empty() {
            let middle = band.len() / 2;
            let median = *band.select_nth_unstable_by(middle, f64::total_cmp).1;
            if median > 0.0 {
                power.iter_mut().for_each(|p| *p *= std::f64::consts::LN_2 / median);
            }
        }
        Spectrogram { times, bins, df, power }
    }

    /// Column `c`'s power at `f` Hz (linear between bins).
    fn at(&self, c: usize, f: f64) -> f64 {
        let b = f / self.df;
        let i = b as usize;
        let frac = b - i as f64;
        let column = &self.power[c * self.bins..(c + 1) * self.bins];
        column[i] * (1.0 - frac) + column[i + 1] * frac
    }

    /// The highest frequency [`Spectrogram::at`] reads (Hz).
    fn top(&self) -> f64 {
        (self.bins - 2) as f64 * self.df
    }
}

/// `lo, lo·ratio, lo·ratio², …` up to `hi`.
fn geometric(lo: f64, hi: f64, ratio: f64) -> Vec<f64> {
    std::iter::successors(Some(lo), |v| Some(v * ratio)).take_while(|v| *v <= hi * (1.0 + 1e-9)).collect()
}

/// A scattered-light shape: `(score, dt, f_fringe, f_motion)`.
type Shape = (f64, f64, f64, f64);

/// Stage 1: every track of the coarse grid, scored (a z-score).
fn tracks(s: &Spectrogram) -> Vec<Shape> {
    let fringes = geometric(FRINGE.0, FRINGE.1, FRINGE_RATIO);
    let top = s.top();
    let mut scored = Vec::new();
    for fm in geometric(MOTION.0, MOTION.1, MOTION_RATIO) {
        // |cos ωτ| repeats every half period: arch tops beyond a quarter
        // period from the centre are the same tracks as nearer ones.
        let reach = REACH.min(0.25 / fm);
        let steps = (reach / TIME_STEP).floor() as i32;
        for i in -steps..=steps {
            let dt = i as f64 * TIME_STEP;
            let x: Vec<f64> = s.times.iter().map(|t| (TAU * fm * (t - dt)).cos().abs()).collect();
            for &ff in &fringes {
                let (mut sum, mut count) = ([0.0; 2], [0usize; 2]);
                for (c, xc) in x.iter().enumerate() {
                    for h in 0..2 {
                        let f = (h + 1) as f64 * ff * xc;
                        if (F_LOW..=top).contains(&f) {
                            sum[h] += s.at(c, f);
                            count[h] += 1;
                        }
                    }
                }
                let z = |sum: f64, n: usize| if n >= MIN_PIXELS { (sum - n as f64) / (n as f64).sqrt() } else { f64::NEG_INFINITY };
                let score = z(sum[0], count[0]).max(z(sum[1], count[1])).max(z(sum[0] + sum[1], count[0] + count[1]));
                scored.push((score, dt, ff, fm));
            }
        }
    }
    scored
}

/// The best `n` of `shapes`, at most one per band of [`MOTION_BAND`] in
/// `f_motion`: the tracks of a low arch, whose fringes are in band near
/// its top only, hardly tell one surface speed from another, and the
/// coherent stage must see several.
fn by_motion(shapes: Vec<Shape>, n: usize) -> Vec<Shape> {
    let band = |s: &Shape| ((s.3 / MOTION.0).ln() / MOTION_BAND.ln()).floor() as i64;
    let mut best: Vec<(i64, Shape)> = Vec::new();
    for s in shapes.into_iter().filter(|s| s.0.is_finite()) {
        match best.iter_mut().find(|(b, _)| *b == band(&s)) {
            Some((_, kept)) if kept.0 >= s.0 => {}
            Some((_, kept)) => *kept = s,
            None => best.push((band(&s), s)),
        }
    }
    best.sort_by(|a, b| b.1 .0.total_cmp(&a.1 .0));
    best.into_iter().take(n).map(|(_, s)| s).collect()
}

/// Stage 2: the coherent match of `x` (at `fs` Hz) around a track, over
/// motions, arch times and every fringe frequency near it. Returns the
/// best shape, scored by the matched power of both harmonics over its
/// noise's.
fn refine(x: &[f64], fs: f64, planner: &mut RealFftPlanner<f64>, (_, dt_c, ff_c, fm_c): Shape) -> Shape {
    let window = x.len() as f64 / fs;
    let centre = 0.5 * window;
    let tau: Vec<f64> = (0..x.len()).map(|k| k as f64 / fs - centre).collect();
    // The data under an envelope at the track's time, and the envelope's square.
    let envelope: Vec<f64> = tau.iter().map(|t| (-(2.0 * (t - dt_c) / SEARCH_DURATION).powi(2)).exp()).collect();
    let g: Vec<f64> = x.iter().zip(&envelope).map(|(v, e)| v * e).collect();
    let mut best: Shape = (f64::NEG_INFINITY, dt_c, ff_c, fm_c);
    for jm in -MOTION_FINE.1..=MOTION_FINE.1 {
        let fm = fm_c * (1.0 + MOTION_FINE.0 * jm as f64);
        if !(MOTION.0..=MOTION.1).contains(&fm) {
            continue;
        }
        let omega = TAU * fm;
        // The track may follow the second harmonic of fringes at half its frequency.
        let (a_lo, a_hi) = ((ff_c / FRINGE_REACH).max(FRINGE.0) / fm, (2.0 * ff_c * FRINGE_REACH).min(FRINGE.1) / fm);
        // Cells of `s` fine enough for the second harmonic at the highest A.
        let cells = (2.0 * 2.0 * a_hi / CELL_PHASE).ceil() as usize + 1;
        let ds = 2.0 / (cells - 1) as f64;
        let len = (2 * cells).next_power_of_two();
        let fft = planner.plan_fft_forward(len);
        let (mut grid, mut spectrum) = (fft.make_input_vec(), fft.make_output_vec());
        let (sin_wt, cos_wt): (Vec<f64>, Vec<f64>) = tau.iter().map(|t| (omega * t).sin_cos()).unzip();
        // Bin j of the FFT holds A = 2π j / (len · ds).
        let a_of = |j: usize| TAU * j as f64 / (len as f64 * ds);
        let j_range = (a_lo / a_of(1)).ceil() as usize..=((a_hi / a_of(1)).floor() as usize).min(len / 4 - 1);
        let step = if 2.0 * fm * window >= 1.0 { TIME_FINE.0 } else { 2.0 * TIME_FINE.0 };
        let steps = (TIME_FINE.1 / step).round() as i32;
        for jt in -steps..=steps {
            let dt = dt_c + step * jt as f64;
            if dt.abs() > REACH {
                continue;
            }
            let (sin_0, cos_0) = (omega * dt).sin_cos();
            grid.fill(0.0);
            let mut by_cos = [0.0; COS_BINS + 1];
            for k in 0..x.len() {
                // sin and cos of ω(τ − dt).
                let s = sin_wt[k] * cos_0 - cos_wt[k] * sin_0;
                let c = cos_wt[k] * cos_0 + sin_wt[k] * sin_0;
                let u = ((s + 1.0) / ds).clamp(0.0, (cells - 1) as f64);
                let i = (u as usize).min(cells - 2);
                let frac = u - i as f64;
                grid[i] += g[k] * (1.0 - frac);
                grid[i + 1] += g[k] * frac;
                by_cos[(c.abs() * COS_BINS as f64) as usize] += envelope[k] * envelope[k];
            }
            fft.process(&mut grid, &mut spectrum).expect("buffers sized by the plan");
            // Noise of the match at A: the envelope's energy where the
            // fringes A f_motion |cos ωτ| are in band.
            for b in (0..COS_BINS).rev() {
                by_cos[b] += by_cos[b + 1];
            }
            // (A harmonic in band over less than a twentieth of it is left out.)
            let noise = |a: f64| {
                let lowest = F_LOW / (a * fm);
                let n = if lowest >= 1.0 { 0.0 } else { by_cos[(lowest * COS_BINS as f64) as usize] };
                if n > IN_BAND * by_cos[0] {
                    n
                } else {
                    0.0
                }
            };
            let score = |j: usize| {
                let a = a_of(j);
                [(j, noise(a)), (2 * j, noise(2.0 * a))]
                    .iter()
                    .filter(|(_, n)| *n > 0.0)
                    .map(|(j, n)| spectrum[*j].norm_sqr() / n)
                    .sum::<f64>()
            };
            for j in j_range.clone() {
                let v = score(j);
                if v > best.0 {
                    // A parabola through the neighbours places the peak between bins.
                    let (l, r) = (score(j.saturating_sub(1)), score(j + 1));
                    let curvature = l - 2.0 * v + r;
                    let offset = if curvature < 0.0 { (0.5 * (l - r) / curvature).clamp(-0.5, 0.5) } else { 0.0 };
                    best = (v, dt, (a_of(j) + offset * a_of(1)) * fm, fm);
                }
            }
        }
    }
    best
}

/// Scattered-light starts from the whitened window `d` (at `fs` Hz): the
/// [`CANDIDATES`] best tracks of the spectrogram, each refined coherently;
/// the `keep` best as `(dt, [f_fringe, f_motion, bounce, duration])` with
/// a few bounces and durations each.
pub fn scattered_light_starts_from_data(d: &[f64], fs: f64, keep: usize) -> Vec<Start> {
    let factor = ((fs / SEARCH_RATE).round() as usize).max(1);
    let (x, fs) = if factor > 1 && d.len().is_multiple_of(factor) { (downsample(d, factor), fs / factor as f64) } else { (d.to_vec(), fs) };
    let spectrogram = Spectrogram::of(&x, fs);
    if spectrogram.times.is_empty() || spectrogram.top() < 2.0 * F_LOW {
        return Vec::new();
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let mut refined: Vec<Shape> =
        by_motion(tracks(&spectrogram), CANDIDATES).into_iter().map(|c| refine(&x, fs, &mut planner, c)).collect();
    refined.sort_by(|a, b| b.0.total_cmp(&a.0));
    refined
        .into_iter()
        .take(keep)
        .flat_map(|(_, dt, ff, fm)| {
            BOUNCES.into_iter().flat_map(move |bounce| DURATIONS.into_iter().map(move |duration| (dt, vec![ff, fm, bounce, duration])))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::test_support::at_snr_in_white_noise;
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    use realfft::num_complex::Complex64;
    use std::f64::consts::FRAC_PI_2;

    /// std::glitch's scattered-light shape, its arch top `t0` s from the
    /// start, whitened by the aLIGO design PSD over 20 Hz and up (as the
    /// data the search sees), with unit norm.
    fn shape(n: usize, fs: f64, t0: f64, (ff, fm, bounce, duration): (f64, f64, f64, f64), phi: f64) -> Vec<f64> {
        let mut h: Vec<f64> = (0..n)
            .map(|k| {
                let tau = k as f64 / fs - t0;
                let u = 2.0 * tau / duration;
                let p = ff / fm * (TAU * fm * tau).sin();
                (-u * u).exp() * ((p + phi).sin() + bounce * (2.0 * p + phi).sin() + bounce * bounce * (3.0 * p + phi).sin())
            })
            .collect();
        let psd = crate::strain::psd_curve(&crate::strain::NoiseCurve::Aligo).unwrap();
        let asd = |f: f64| {
            let i = psd.freqs.partition_point(|g| *g <= f).clamp(1, psd.freqs.len() - 1);
            let w = (f - psd.freqs[i - 1]) / (psd.freqs[i] - psd.freqs[i - 1]);
            (psd.psd[i - 1] * (1.0 - w) + psd.psd[i] * w).sqrt()
        };
        let mut planner = RealFftPlanner::<f64>::new();
        let (forward, inverse) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
        let mut spectrum = forward.make_output_vec();
        forward.process(&mut h, &mut spectrum).unwrap();
        for (j, v) in spectrum.iter_mut().enumerate() {
            let f = j as f64 * fs / n as f64;
            *v = if f < F_LOW { Complex64::default() } else { *v / asd(f) };
        }
        inverse.process(&mut spectrum, &mut h).unwrap();
        let norm = h.iter().map(|v| v * v).sum::<f64>().sqrt();
        h.iter().map(|v| v / norm).collect()
    }

    #[test]
    fn arches_are_found_inside_the_fits_lobe() {
        // A 2 s window at 1024 Hz (the scene's rate), SNR 12: a slow
        // surface (one arch, ~280 rad of phase), a fast one (seven arch
        // tops in the window), a middling one with a strong second harmonic
        // and low fringes (in band near the tops only). The best start's
        // template must match the truth's to 0.7 (over the phase): inside
        // the lobe the fit climbs.
        let (n, fs) = (2048, 1024.0);
        let cases = [(0.023, (47.3, 0.17, 0.1, 3.2)), (-0.11, (38.6, 1.73, 0.2, 2.6)), (0.2, (27.9, 0.61, 0.45, 1.8))];
        for (i, (t0, truth)) in cases.into_iter().enumerate() {
            let h = shape(n, fs, 1.0 + t0, truth, 0.9);
            let d = at_snr_in_white_noise(&h, 12.0, 7 + i as u64);
            let starts = scattered_light_starts_from_data(&d, fs, 2);
            assert_eq!(starts.len(), 2 * BOUNCES.len() * DURATIONS.len());
            let (dt, x) = &starts[0];
            let found = (x[0], x[1], truth.2, truth.3);
            let (a, b) = (shape(n, fs, 1.0 + dt, found, 0.0), shape(n, fs, 1.0 + dt, found, FRAC_PI_2));
            let dot = |u: &[f64]| u.iter().zip(&h).map(|(u, v)| u * v).sum::<f64>();
            let overlap = dot(&a).hypot(dot(&b));
            assert!(overlap > 0.7, "case {i}: overlap {overlap:.3} at {dt} s, {x:?}, truth {t0} s, {truth:?}");
        }
    }

    #[test]
    fn noise_alone_gives_starts_inside_the_bounds() {
        let (n, fs) = (2048, 1024.0);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let d: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
        let starts = scattered_light_starts_from_data(&d, fs, 3);
        assert_eq!(starts.len(), 3 * BOUNCES.len() * DURATIONS.len());
        for (dt, x) in starts {
            let inside = dt.abs() <= REACH && (FRINGE.0..=FRINGE.1).contains(&x[0]) && (MOTION.0..=MOTION.1).contains(&x[1]);
            assert!(inside, "{dt} {x:?}");
        }
    }
}
