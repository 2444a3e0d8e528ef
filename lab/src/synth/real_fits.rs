//! Glitch shapes drawn from real glitches' fitted parameters.
//!
//! antiglitch (A. Lundgren et al., <https://github.com/andrew-lundgren/antiglitch>,
//! `data/all_PE_v3.json`, MIT licence) fitted 3,874 O3 glitches of H1, L1
//! and V1 with Gravity Spy labels by a quasi-physical model: a strain
//! spectrum Gaussian in log frequency, `h(f) = A exp(-gbw/2 ln²(f/f0))
//! e^{-2πift}`, whitened by the detector's ASD. For Blips and Tomtes the
//! fit leaves a residual of ~1 per degree of freedom: the model is what
//! these glitches look like; for Koi Fish it leaves ~4 per degree of
//! freedom (median; more the louder they are): it takes their loud,
//! broadband core but not all of their shape. `lab/data/real_glitch_fits.csv` keeps the fits
//! (label, detector, f0, gbw, SNR, ...); `lab/data/o3_asd.csv` the O3-like
//! ASD the shapes are whitened with (LALSimulation's aLIGO 140 Mpc curve,
//! LIGO-T1800545); both written by `scripts/real_glitch_fits.py`.
//!
//! A Koi Fish is a loud glitch: its fits' SNRs are 30 / 150 / 780 at the
//! 5th / 50th / 95th percentile, against 9 / 17 / 75 for Blips, and
//! Gravity Spy names a broadband burst of that loudness Koi Fish (Zevin et
//! al. 2017). A Koi Fish fit's shape therefore keeps its own fitted SNR
//! (within the class's range, [`super::population::snr_range`]): at a
//! drawn SNR, a quiet one would be a Blip with another label.
//!
//! Only LIGO's fits (H1, L1) are used: f0 and gbw describe the strain
//! spectrum, and whitening a Virgo glitch by a LIGO ASD would move its
//! peak (V1 Blips peak at 42–82 Hz whitened by Virgo's own ASD, among the
//! Tomtes). The fits of each class are split by their order in the file: even
//! positions feed the benchmark's training population ([`Half::Train`]),
//! odd ones are kept for checks ([`Half::Check`], also used by
//! `scripts/blip_realism.py`), so a classifier is checked on real
//! parameter sets it never saw.

use super::glitch::{Shape, RATE, SAMPLES};
use super::population::{snr_range, BLIP, KOI_FISH, TOMTE};
use rand::Rng;
use realfft::num_complex::Complex64;
use realfft::RealFftPlanner;
use std::f64::consts::{PI, TAU};
use std::sync::OnceLock;

const FITS_CSV: &str = include_str!("../../data/real_glitch_fits.csv");
const ASD_CSV: &str = include_str!("../../data/o3_asd.csv");
/// The whitening band, as for the formula shapes (Hz).
const BAND: (usize, usize) = (20, 2000);

/// Which half of the real fits to draw from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Half {
    /// Even positions within a class: the training population.
    Train,
    /// Odd positions: held out for checks.
    Check,
}

/// One real glitch's fitted shape parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    /// Centre of the log-Gaussian strain spectrum (Hz).
    pub f0: f64,
    /// Its inverse variance in ln f.
    pub gbw: f64,
    /// The fitted glitch's SNR.
    pub snr: f64,
}

/// The LIGO fits of the labels used, in file order.
struct Table {
    blip: Vec<Fit>,
    koi_fish: Vec<Fit>,
    tomte: Vec<Fit>,
    /// ASD at 1 Hz steps over [`BAND`].
    asd: Vec<f64>,
}

fn table() -> &'static Table {
    static TABLE: OnceLock<Table> = OnceLock::new();
    TABLE.get_or_init(|| {
        let (mut blip, mut koi_fish, mut tomte) = (Vec::new(), Vec::new(), Vec::new());
        for line in FITS_CSV.lines().skip(1) {
            let cols: Vec<&str> = line.split(',').collect();
            let number = |i: usize| cols.get(i).and_then(|c| c.parse::<f64>().ok());
            let (Some(f0), Some(gbw), Some(snr)) = (number(2), number(3), number(4)) else { continue };
            if !matches!(cols.get(1), Some(&"H1") | Some(&"L1")) {
                continue;
            }
            let fit = Fit { f0, gbw, snr };
            match cols[0] {
                "Blip" => blip.push(fit),
                "Koi_Fish" => koi_fish.push(fit),
                "Tomte" => tomte.push(fit),
                _ => {}
            }
        }
        let asd = ASD_CSV.lines().skip(1).filter_map(|l| l.split(',').nth(1)?.parse::<f64>().ok()).collect();
        Table { blip, koi_fish, tomte, asd }
    })
}

/// Every LIGO fit of `class`, in file order (empty but for Blip, Koi Fish
/// and Tomte).
fn class_fits(class: usize) -> &'static [Fit] {
    match class {
        BLIP => &table().blip,
        KOI_FISH => &table().koi_fish,
        TOMTE => &table().tomte,
        _ => &[],
    }
}

impl Half {
    /// Position of this half's first fit (the halves alternate).
    fn first(self) -> usize {
        match self {
            Half::Train => 0,
            Half::Check => 1,
        }
    }
}

/// The real fits of `class` (Blip, Koi Fish and Tomte have them) in `half`.
pub fn fits(class: usize, half: Half) -> Vec<Fit> {
    class_fits(class).iter().skip(half.first()).step_by(2).copied().collect()
}

/// A random fit of `class` in `half`, whitened at a random phase and
/// peaking mid-row, with its own SNR for a Koi Fish; `None` when the half
/// has none.
fn random_shape<R: Rng>(rng: &mut R, class: usize, half: Half) -> Option<Shape> {
    let all = class_fits(class);
    let count = all.len().saturating_sub(half.first()).div_ceil(2);
    if count == 0 {
        return None;
    }
    let fit = all[half.first() + 2 * rng.random_range(0..count)];
    let samples = whitened_shape(fit, rng.random_range(0.0..TAU), 0.5);
    let (lo, hi) = snr_range(class);
    Some(Shape { samples, snr: (class == KOI_FISH).then(|| fit.snr.clamp(lo, hi)) })
}

/// The whitened shape of a fit in a 1 s row at 4096 Hz: the log-Gaussian
/// spectrum over the O3-like ASD, band-limited to 20–2000 Hz, with one
/// phase `phi` across the band (a constant phase is what the model fits)
/// and its peak at `t0` seconds; unnormalised.
pub fn whitened_shape(fit: Fit, phi: f64, t0: f64) -> Vec<f64> {
    let asd = &table().asd;
    let mut spectrum = vec![Complex64::new(0.0, 0.0); SAMPLES / 2 + 1];
    for (k, bin) in spectrum.iter_mut().enumerate().take(BAND.1 + 1).skip(BAND.0) {
        let f = k as f64 * RATE / SAMPLES as f64;
        let l = (f / fit.f0).ln();
        let amplitude = (-0.5 * fit.gbw * l * l).exp() / asd[k - BAND.0];
        *bin = Complex64::from_polar(amplitude, phi - 2.0 * PI * f * t0);
    }
    let mut out = vec![0.0; SAMPLES];
    static IFFT: OnceLock<std::sync::Arc<dyn realfft::ComplexToReal<f64>>> = OnceLock::new();
    let ifft = IFFT.get_or_init(|| RealFftPlanner::<f64>::new().plan_fft_inverse(SAMPLES));
    // DC and Nyquist are outside the band, so zero: the transform cannot fail.
    if ifft.process(&mut spectrum, &mut out).is_err() {
        return vec![0.0; SAMPLES];
    }
    out
}

/// Chance that a Blip, Koi Fish or Tomte of the benchmark population takes
/// a real fit's shape rather than its formula's.
pub const REAL_SHARE: f64 = 0.5;

/// With chance [`REAL_SHARE`], a Blip, Koi Fish or Tomte shape from a
/// random training-half fit at a random phase, peaking mid-row; `None` for
/// other classes and the other draws.
pub fn draw<R: Rng>(rng: &mut R, class: usize) -> Option<Shape> {
    if class_fits(class).is_empty() || !rng.random_bool(REAL_SHARE) {
        return None;
    }
    random_shape(rng, class, Half::Train)
}

/// Always a Blip, Koi Fish or Tomte shape from a random *held-out* fit
/// ([`Half::Check`]) at a random phase, peaking mid-row; `None` for other
/// classes: a test set of real morphologies no training row was drawn from.
pub fn draw_held_out<R: Rng>(rng: &mut R, class: usize) -> Option<Shape> {
    random_shape(rng, class, Half::Check)
}

/// A seeded source of [`draw`]s on its own random stream (for callers
/// whose other draws must not shift, as `gwml data strain`'s).
pub struct RealShapes(rand_pcg::Pcg64Mcg);

impl RealShapes {
    /// The source of seed `seed`.
    pub fn new(seed: u64) -> RealShapes {
        RealShapes(rand::SeedableRng::seed_from_u64(seed))
    }

    /// A real fit's shape for half the Blips, Koi Fish and Tomtes; `None`
    /// otherwise.
    pub fn draw(&mut self, class: usize) -> Option<Shape> {
        draw(&mut self.0, class)
    }
}

#[cfg(test)]
mod tests {
    use super::super::population::WHISTLE;
    use super::*;

    /// The tables parse whole (942 H1 and L1 Blips, 1,000 Koi Fish and 635
    /// Tomtes of antiglitch's 3,874 glitches; 1,981 ASD bins), and the
    /// halves split them.
    #[test]
    fn the_real_fits_and_the_asd_are_read_whole() {
        assert_eq!(table().blip.len(), 942);
        assert_eq!(table().koi_fish.len(), 1000);
        assert_eq!(table().tomte.len(), 635);
        assert_eq!(table().asd.len(), BAND.1 - BAND.0 + 1);
        assert_eq!(fits(BLIP, Half::Train).len() + fits(BLIP, Half::Check).len(), 942);
        assert!(fits(WHISTLE, Half::Train).is_empty());
    }

    /// A whitened Blip is short and peaks where antiglitch's whitened fits
    /// do: over the training half the median peak frequency of the
    /// spectrum is 80–150 Hz (antiglitch measured 107 Hz for H1, 130 Hz for
    /// L1 with the detectors' own ASDs) and 90 % of the energy lies within
    /// 50 ms of the peak time.
    #[test]
    fn whitened_blips_are_short_and_peak_near_the_measured_frequencies() {
        let mut peaks = Vec::new();
        let mut planner = RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(SAMPLES);
        for fit in fits(BLIP, Half::Train).iter().step_by(5) {
            let mut s = whitened_shape(*fit, 0.3, 0.5);
            let energy: f64 = s.iter().map(|v| v * v).sum();
            let near: f64 = s[(0.45 * RATE) as usize..(0.55 * RATE) as usize].iter().map(|v| v * v).sum();
            assert!(near > 0.9 * energy, "f0 {} gbw {}: {:.2} of the energy within 50 ms", fit.f0, fit.gbw, near / energy);
            let mut spectrum = fft.make_output_vec();
            fft.process(&mut s, &mut spectrum).unwrap();
            let peak = spectrum.iter().enumerate().max_by(|a, b| a.1.norm().total_cmp(&b.1.norm())).unwrap().0;
            peaks.push(peak as f64);
        }
        peaks.sort_by(f64::total_cmp);
        let median = peaks[peaks.len() / 2];
        assert!((80.0..=150.0).contains(&median), "median whitened peak frequency {median} Hz");
    }

    /// Half the Blips, Koi Fish and Tomtes take a real shape, no other
    /// class does; only a Koi Fish brings its SNR, within the class's range.
    #[test]
    fn draws_replace_half_the_blips_koi_fish_and_tomtes() {
        let mut rng = rand_pcg::Pcg64Mcg::new(5);
        let real = (0..400).filter_map(|_| draw(&mut rng, BLIP)).inspect(|s| assert_eq!(s.snr, None)).count();
        assert!((160..=240).contains(&real), "{real} of 400 Blips took a real shape");
        let koi: Vec<f64> = (0..400).filter_map(|_| draw(&mut rng, KOI_FISH)?.snr).collect();
        assert!((160..=240).contains(&koi.len()), "{} of 400 Koi Fish took a real shape", koi.len());
        assert!(koi.iter().all(|s| (12.0..=400.0).contains(s)), "{koi:?}");
        // Loud as the fits are: the median fitted SNR is ~150.
        let louder = koi.iter().filter(|s| **s > 100.0).count();
        assert!(louder > koi.len() / 2, "{louder} of {} above SNR 100", koi.len());
        assert!((0..100).all(|_| draw(&mut rng, super::super::population::SCRATCHY).is_none()));
        assert!((0..50).all(|_| draw_held_out(&mut rng, TOMTE).is_some() && draw_held_out(&mut rng, WHISTLE).is_none()));
    }
}
