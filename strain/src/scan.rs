//! `gwml scan`: strain in, classified glitch triggers out.
//!
//! Per good-data segment ([`crate::series::good_segments`]), in chunks of
//! `chunk` seconds with `pad` seconds of margin on each side, in parallel:
//! 1. the noise PSD by Welch's method ([`crate::psd`]) over the
//!    `psd_stretch` seconds around the chunk, so a drifting PSD is followed;
//! 2. whitening by that PSD with the gwml scene `models/whiten.gw` (a Tukey
//!    taper over the outer half of each margin; the margins are discarded);
//! 3. the Q-transform of the whitened chunk ([`crate::qtransform`]) and the
//!    tiles in the chunk's kept middle above `tile_threshold`;
//! 4. tiles clustered into triggers ([`crate::triggers`]), kept when the
//!    loudest tile reaches `snr_threshold`;
//! 5. the classifier on `duration_s` of strain whitened over its band,
//!    centred on each trigger.
//!
//! Triggers that meet across a chunk boundary are merged.

use crate::classifier::{Classifier, Verdict};
use crate::psd::{Welch, WelchOptions};
use crate::qtransform::{tile_snr, ExcessPower, QOptions, QTiling, RowBuffers, RowEnergies};
use crate::series::{good_segments, Segment, Series, SkipReason, Skipped};
use crate::triggers::{absorbed_into, cluster, Threshold, Tile, Trigger};
use crate::whitening::{whiten_spectrum_with, WhitenOptions, Whitener};
use crate::Error;
use gwml_runtime::Scene;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::f64::consts::{LN_2, PI};

/// Durations (s) over which tile energies are summed as excess power, in
/// every Q plane: long glitches spread their energy (Scratchy's arches, a
/// Whistle's sweep), and a narrow row of the Q 45 plane holds a Scratchy's
/// carrier for its whole 1-2.5 s. The 2 s window and the Q 45 plane found
/// 1.3-1.5 % more of the injections of `gwml data strain` files (seed 42:
/// 94.2 → 95.2 %, mostly Scratchies at SNR 8-12), with
/// [`EXCESS_POWER_MAX_DOF`] keeping the noise triggers where they were
/// (README, "Scanning real strain").
const EXCESS_POWER_WINDOWS: [f64; 5] = [0.125, 0.25, 0.5, 1.0, 2.0];

/// A window is summed only where it holds at most this many independent
/// tiles' worth of noise (`window / τ_c`). In a broad row over a long
/// window (a 1 s sum at 1.2 kHz and Q 5.7 holds ~700) noise spreads the sum
/// so far that only a glitch of SNR ≳ 17 could pass, and such a glitch is
/// louder still in a shorter window or a narrower row; those windows only
/// added trials: capping them at 150 (a glitch of SNR ≳ 12 can pass)
/// halved the noise triggers above SNR 8 and lost no injection.
const EXCESS_POWER_MAX_DOF: f64 = 150.0;

/// Rows of planes below this Q (the scan's Q 2.8 plane, under gwpy's
/// range) sum excess power over at most [`BROADBAND_LONGEST_WINDOW`]: they
/// are there for short broadband bursts (a Koi Fish's body and head within
/// ~0.1 s), while a sum over seconds of a band ~100 Hz wide takes in the
/// wandering amplitude of lines, such as the 60 Hz mains in real strain
/// (GW150914's H1 file: a trigger of SNR 9.9 at 60 Hz over 2.2 s, which
/// `gwml explain` names noise). On the three simulated 4,096 s files and
/// the noise files the cap changed no recovery figure (0.25 s lost one Koi
/// Fish on seed 43); on the real-fit file, one Scattered Light of 390.
const BROADBAND_Q: f64 = 4.0;
/// See [`BROADBAND_Q`] (s).
const BROADBAND_LONGEST_WINDOW: f64 = 0.5;

/// The relative variance of a Welch median PSD estimate per frequency bin
/// is about this over the number of segments K: the median of K
/// exponential periodogram values has variance 1/K around ln 2, i.e.
/// 1/(K ln²2) ≈ 2.1/K relative, and half-overlapping Hann segments are
/// correlated (≈ ×1.3). Whitening by the estimate leaves that ripple on the
/// whitened spectrum, which widens the spread of long excess-power sums by
/// the same factor; their significance is computed with it
/// (a 64 s estimate made ~20 % more noise triggers above 1 kHz than a
/// 128 s one without it).
const PSD_MEDIAN_SPREAD: f64 = 2.8;

/// Tile energies are normalised by the median of every this-many-th tile
/// of their row in the chunk ([`crate::qtransform::QRow::single_energies`]).
const MEDIAN_STRIDE: usize = 8;

/// The relative variance of a row's median-normalised energy level is
/// about this over the number of tiles the median is taken from: the
/// sample median of M exponential values has variance 1/M around ln 2,
/// i.e. 1/(M ln²2) ≈ 2.08/M relative. An excess-power sum of ν
/// independent tiles' worth of noise carries that error ν times, so its
/// variance is ν (1 + 2.08 ν/M) instead of ν: it matters where ν is a
/// sizeable fraction of M, in long windows over broad rows and in the
/// narrow rows of the Q 45 plane (few tiles per chunk). With it, noise
/// triggers above SNR 8 fell from 0.59-0.61 to 0.44-0.49 per 100 s
/// (before [`EXCESS_POWER_MAX_DOF`]; noise seeds 42 and 43).
const MEDIAN_LEVEL_SPREAD: f64 = 1.0 / (LN_2 * LN_2);

/// Scan settings.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanOptions {
    /// Triggers whose most significant tile has a lower SNR are dropped (Gravity Spy: 7.5).
    pub snr_threshold: f64,
    /// A trigger's most significant tile must also be this significant
    /// (see [`Threshold`]): the false-alarm control for excess-power windows.
    /// 5.5 by default: in Gaussian noise 0.39-0.44 triggers per 100 s above
    /// SNR 8 (issue #23 allows 1; 0.34-0.39 before the Q 2.8 plane), where
    /// 5.4 made 0.49-0.59 (before that plane) for one more injection found
    /// in ~1,200 (README, "Scanning real strain").
    pub min_significance: f64,
    /// Tiles this significant join clusters (they extend a trigger in time and frequency).
    pub tile_threshold: f64,
    /// Frequency band searched, in Hz (Gravity Spy: 10–2048 Hz).
    pub f_range: (f64, f64),
    /// Q range of the tiling. 2–64 by default: gwpy's planes (Q 5.7, 11.3,
    /// 22.6, 45.3 from its 4–64) and one at Q 2.8 below them, whose window
    /// is cut at 0 Hz ([`QTiling`]). A burst of Q 1.2 (the broadest Blips,
    /// drawn at Q 1.2–6; Koi Fish bodies are drawn at 1–2.5) keeps 0.73 of
    /// its SNR in the best tile of the Q 5.7 plane and up and 0.88 in the
    /// Q 2.8 plane's (a unit test of `qtransform`), so below SNR ~10 it
    /// fell under the 7.5 threshold: the plane found 1.0–2.1 % more of the
    /// 4,096 s files' injections, for 0.39–0.44 noise triggers per 100 s
    /// above SNR 8 against 0.34–0.39 (README, "Scanning real strain"); a
    /// second plane at Q 1.4 found 2 more of 1,244 and took ~12 % longer.
    pub q_range: (f64, f64),
    /// Tile mismatch.
    pub mismatch: f64,
    /// Welch segment length in seconds.
    pub fft_length: f64,
    /// Seconds of data around each chunk its PSD is estimated from.
    pub psd_stretch: f64,
    /// Seconds of data each chunk adds to the scan (whole seconds).
    pub chunk: f64,
    /// Margin on each side of a chunk in seconds (whole seconds).
    pub pad: f64,
    /// Tiles this close (s) belong to one trigger.
    pub cluster_gap: f64,
}

impl ScanOptions {
    /// The margin (s) at each end of a segment that is not searched.
    pub fn margin(&self) -> f64 {
        self.pad
    }

    /// Shortest good-data segment worth whitening, in seconds.
    pub fn min_segment(&self) -> f64 {
        2.0 * self.pad + (2.0 * self.fft_length).max(8.0)
    }
}

impl Default for ScanOptions {
    fn default() -> Self {
        ScanOptions {
            snr_threshold: 7.5,
            min_significance: 5.5,
            tile_threshold: 5.0,
            f_range: (10.0, 2048.0),
            q_range: (2.0, 64.0),
            mismatch: 0.2,
            fft_length: 4.0,
            psd_stretch: 128.0,
            chunk: 64.0,
            pad: 4.0,
            cluster_gap: 0.1,
        }
    }
}

/// One trigger with its classification.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Where and what.
    pub trigger: Trigger,
    /// The classifier's verdict (`None` without a classifier).
    pub verdict: Option<Verdict>,
}

/// What a scan found and what it left out.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Detector.
    pub ifo: String,
    /// Triggers in time order.
    pub rows: Vec<Row>,
    /// Seconds whose tiles were searched.
    pub scanned_seconds: f64,
    /// Seconds not searched, with why.
    pub skipped: Vec<Skipped>,
    /// The frequency band actually tiled (the top is limited by Q and Nyquist).
    pub tiled_band: (f64, f64),
    /// CPU seconds per stage, summed over chunks and threads.
    pub stage_seconds: StageSeconds,
}

/// CPU seconds spent in each stage of a scan (summed over threads).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageSeconds {
    /// Welch PSD estimates.
    pub psd: f64,
    /// Whitening (the gwml scene, both bands).
    pub whiten: f64,
    /// Q tiles, excess power and clustering.
    pub tiles: f64,
    /// The classifier.
    pub classify: f64,
}

/// Nanoseconds per stage, added to from every worker.
#[derive(Default)]
struct StageClock([std::sync::atomic::AtomicU64; 4]);

impl StageClock {
    fn add(&self, stage: usize, since: std::time::Instant) {
        self.0[stage].fetch_add(since.elapsed().as_nanos() as u64, std::sync::atomic::Ordering::Relaxed);
    }
    fn seconds(&self) -> StageSeconds {
        let s = |i: usize| self.0[i].load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-9;
        StageSeconds { psd: s(0), whiten: s(1), tiles: s(2), classify: s(3) }
    }
}

impl Report {
    /// Skipped seconds summed per reason.
    pub fn skipped_by_reason(&self) -> BTreeMap<SkipReason, f64> {
        let mut out = BTreeMap::new();
        for s in &self.skipped {
            *out.entry(s.reason).or_insert(0.0) += s.seconds;
        }
        out
    }
}

/// One chunk of a segment: samples from `start` (of the series) for the
/// chunk's length, of which `keep_from..keep_to` are searched.
#[derive(Clone, Copy, Debug)]
struct Chunk {
    segment: Segment,
    start: usize,
    samples: usize,
    keep_from: usize,
    keep_to: usize,
}

/// A configured scanner: the whitening scenes compiled per chunk length.
pub struct Scanner {
    options: ScanOptions,
    classifier: Option<Classifier>,
    /// The band of the whitened windows the classifier is given (Hz).
    classifier_band: (f64, f64),
    whitener: Whitener,
    /// Compiled scenes and tilings by (sample rate in mHz, chunk samples).
    prepared: std::sync::Mutex<BTreeMap<(u64, usize), std::sync::Arc<Prepared>>>,
}

impl Scanner {
    /// Checks the options and compiles what does not depend on the data.
    pub fn new(options: ScanOptions, classifier: Option<Classifier>) -> Result<Scanner, Error> {
        let o = &options;
        let positive = [
            ("--snr-threshold", o.snr_threshold),
            ("tile threshold", o.tile_threshold),
            ("--min-significance", o.min_significance),
            ("FFT length", o.fft_length),
            ("PSD stretch", o.psd_stretch),
            ("chunk", o.chunk),
            ("pad", o.pad),
        ];
        if let Some((name, v)) = positive.iter().find(|(_, v)| !(*v > 0.0 && v.is_finite())) {
            return Err(Error::Data(format!("{name} must be positive and finite, got {v}")));
        }
        if !(o.f_range.0 >= 0.0 && o.f_range.1 > o.f_range.0) {
            return Err(Error::Data(format!("--fmin {} must be below --fmax {}", o.f_range.0, o.f_range.1)));
        }
        if o.chunk.fract() != 0.0 || o.pad.fract() != 0.0 {
            return Err(Error::Data("chunk and pad lengths must be whole seconds".into()));
        }
        let classifier_band = classifier.as_ref().map_or(NO_CLASSIFIER_BAND, |c| c.manifest.band_hz);
        Ok(Scanner { options, classifier, classifier_band, whitener: Whitener::new()?, prepared: Default::default() })
    }

    /// Replaces the classifier. With [`Scanner::expect_classifier_band`]
    /// first, the whitening scenes can be compiled ([`Scanner::warm_up`])
    /// while the classifier compiles on another thread. Scenes compiled for
    /// another classifier band are dropped.
    pub fn set_classifier(&mut self, classifier: Option<Classifier>) {
        self.expect_classifier_band(classifier.as_ref().map(|c| c.manifest.band_hz));
        self.classifier = classifier;
    }

    /// Sets the classifier band the whitening scenes are compiled for, ahead
    /// of [`Scanner::set_classifier`] with a classifier of this band.
    pub fn expect_classifier_band(&mut self, band: Option<(f64, f64)>) {
        let band = band.unwrap_or(NO_CLASSIFIER_BAND);
        if band != self.classifier_band {
            self.prepared.get_mut().expect("no panics while locked").clear();
            self.classifier_band = band;
        }
    }

    /// The classifier, if any.
    pub fn classifier(&self) -> Option<&Classifier> {
        self.classifier.as_ref()
    }

    /// The settings it scans with.
    pub fn options(&self) -> &ScanOptions {
        &self.options
    }

    /// Scans one series; `progress` is told the seconds of each chunk done.
    pub fn scan(&self, series: &Series, progress: &(dyn Fn(f64) + Sync)) -> Result<Report, Error> {
        self.scan_block(series, (false, false), progress)
    }

    /// Scans a block of a longer stretch: an end marked open continues in a
    /// neighbouring block that overlaps this one by twice the margin
    /// ([`ScanOptions::margin`]), so its margin is searched there and is not
    /// reported as skipped. Merge the blocks' rows with [`merge_rows`].
    pub fn scan_block(&self, series: &Series, open: (bool, bool), progress: &(dyn Fn(f64) + Sync)) -> Result<Report, Error> {
        let o = &self.options;
        let fs = series.sample_rate;
        if !(fs > 0.0 && fs.is_finite()) || (fs.fract() != 0.0) {
            return Err(Error::Data(format!("{}: the sample rate {fs} Hz must be a positive whole number", series.source)));
        }
        if let Some(c) = &self.classifier {
            if c.manifest.sample_rate != fs {
                return Err(Error::Data(format!(
                    "{} is sampled at {fs} Hz but the classifier {} expects {} Hz",
                    series.source,
                    c.manifest.model.display(),
                    c.manifest.sample_rate
                )));
            }
        }
        let (segments, mut skipped) = good_segments(series, o.min_segment());
        let rate = fs as usize;
        let pad = o.pad as usize * rate;
        let mut chunks = Vec::new();
        for seg in &segments {
            let length = seg.end - seg.start;
            let window = (((o.chunk + 2.0 * o.pad) as usize) * rate).min(length / rate * rate);
            let keep = window - 2 * pad;
            let mut start = seg.start;
            let mut kept_to = seg.start + pad;
            loop {
                let start_at = start.min(seg.end - window);
                let keep_from = kept_to.max(start_at + pad);
                let keep_to = start_at + pad + keep;
                if keep_to > keep_from {
                    chunks.push(Chunk { segment: *seg, start: start_at, samples: window, keep_from, keep_to });
                    kept_to = keep_to;
                }
                if start_at + window >= seg.end {
                    break;
                }
                start += keep;
            }
            let n_all = series.samples.len();
            for (from, to) in [(seg.start, seg.start + pad), (seg.end - pad, seg.end)] {
                if (from == 0 && open.0) || (to == n_all && open.1) {
                    continue;
                }
                skipped.push(Skipped {
                    gps_start: series.gps_start + from as f64 / fs,
                    seconds: (to - from) as f64 / fs,
                    reason: SkipReason::SegmentEdges,
                });
            }
        }
        skipped.sort_by(|a, b| a.gps_start.total_cmp(&b.gps_start));
        // One whitening scene and Q tiling per chunk length.
        let mut lengths: Vec<usize> = chunks.iter().map(|c| c.samples).collect();
        lengths.sort_unstable();
        lengths.dedup();
        let mut prepared = BTreeMap::new();
        for &n in &lengths {
            prepared.insert(n, self.prepared(n, fs)?);
        }
        let welch = Welch::new(fs, WelchOptions::seconds(o.fft_length, fs))?;
        let clock = StageClock::default();
        let failing_sums = FailingSums::default();
        let results: Vec<Result<Vec<Row>, Error>> = chunks
            .par_iter()
            .map_init(
                || {
                    // Per worker: a whitening run per chunk length and a
                    // classifier run (an error binding it is the first
                    // window's, from `Classifier::classify`).
                    let whitening = prepared.iter().map(|(n, p)| (*n, p.whiten.bind())).collect::<BTreeMap<_, _>>();
                    (whitening, self.classifier.as_ref().and_then(|c| c.bind().ok()))
                },
                |(runs, classifier_run), chunk| {
                    let prep = &prepared[&chunk.samples];
                    let run = runs.get_mut(&chunk.samples).expect("a run per chunk length");
                    let runs = (run, classifier_run.as_mut());
                    let rows = self.scan_chunk(series, chunk, prep, runs, (&welch, &failing_sums), &clock);
                    progress((chunk.keep_to - chunk.keep_from) as f64 / fs);
                    rows
                },
            )
            .collect();
        let mut rows = Vec::new();
        for r in results {
            rows.extend(r?);
        }
        let tiled_band = prepared.values().next().map_or((o.f_range.0, o.f_range.1), |p| p.tiling.f_range);
        Ok(Report {
            ifo: series.detector.clone(),
            rows: merge_rows(rows, o.cluster_gap),
            // 0.0 + …: an empty sum of floats is -0.0.
            scanned_seconds: 0.0 + chunks.iter().map(|c| (c.keep_to - c.keep_from) as f64 / fs).sum::<f64>(),
            skipped,
            tiled_band,
            stage_seconds: clock.seconds(),
        })
    }

    /// Compiles the whitening scene for full chunks of data at `sample_rate`
    /// ahead of [`Scanner::scan`] (e.g. while the strain is being read).
    pub fn warm_up(&self, sample_rate: f64) -> Result<(), Error> {
        let n = ((self.options.chunk + 2.0 * self.options.pad) * sample_rate).round() as usize;
        self.prepared(n, sample_rate).map(|_| ())
    }

    /// The whitening scene and tiling for chunks of `n` samples, compiled
    /// once.
    fn prepared(&self, n: usize, fs: f64) -> Result<std::sync::Arc<Prepared>, Error> {
        let key = ((fs * 1000.0).round() as u64, n);
        if let Some(p) = self.prepared.lock().expect("no panics while locked").get(&key) {
            return Ok(p.clone());
        }
        let p = std::sync::Arc::new(self.prepare(n, fs)?);
        self.prepared.lock().expect("no panics while locked").insert(key, p.clone());
        Ok(p)
    }

    /// The whitening scene and tiling for chunks of `n` samples.
    fn prepare(&self, n: usize, fs: f64) -> Result<Prepared, Error> {
        let o = &self.options;
        let duration = n as f64 / fs;
        let whiten = self.whitener.spectrum_scene(
            n,
            fs,
            &WhitenOptions { taper: o.pad / 2.0, band: o.f_range, classifier_band: self.classifier_band },
        )?;
        let q = QOptions { q_range: o.q_range, f_range: o.f_range, mismatch: o.mismatch, smooth_sizes: true, plane_nyquist: true };
        Ok(Prepared { whiten, tiling: QTiling::new(duration, fs, &q)? })
    }

    fn scan_chunk(
        &self,
        series: &Series,
        chunk: &Chunk,
        prep: &Prepared,
        (run, mut classifier_run): (&mut gwml_runtime::Run, Option<&mut gwml_runtime::Run>),
        (welch, failing_sums): (&Welch, &FailingSums),
        clock: &StageClock,
    ) -> Result<Vec<Row>, Error> {
        let mut since = std::time::Instant::now();
        let o = &self.options;
        let fs = series.sample_rate;
        let n = chunk.samples;
        let x = &series.samples[chunk.start..chunk.start + n];
        // The PSD from the stretch around the chunk, inside its segment.
        let half = (o.psd_stretch * fs / 2.0) as usize;
        let centre = chunk.start + n / 2;
        let (mut a, mut b) = (centre.saturating_sub(half).max(chunk.segment.start), (centre + half).min(chunk.segment.end));
        if b - a < n {
            (a, b) = (chunk.start, chunk.start + n);
        }
        let psd = welch.estimate(&series.samples[a..b])?;
        let noise_inflation = 1.0 + PSD_MEDIAN_SPREAD / welch.segments(b - a).max(1) as f64;
        clock.add(0, since);
        since = std::time::Instant::now();
        // The whitened data's spectrum, tiled below (Q tiles are normalised
        // by their rows' medians, so its scale does not matter).
        let (spectrum, w_clf) = whiten_spectrum_with(run, x, &psd, (fs, series.gps_start + chunk.start as f64 / fs, &series.source))?;
        let duration = n as f64 / fs;
        clock.add(1, since);
        since = std::time::Instant::now();
        let t0 = series.gps_start + chunk.start as f64 / fs;
        let (keep_from, keep_to) = ((chunk.keep_from - chunk.start) as f64 / fs, (chunk.keep_to - chunk.start) as f64 / fs);
        let mut tiles = Vec::new();
        let mut buffers = RowBuffers::default();
        let mut prefix = Vec::new();
        let mut passing = Vec::new();
        // A tile passes when tile_snr(z) ≥ threshold, i.e. z ≥ this.
        let z_pass = (1.0 + 0.5 * o.tile_threshold * o.tile_threshold) / LN_2;
        for plane in &prep.tiling.planes {
            for row in &plane.rows {
                let energies = row.single_energies(&spectrum, &mut buffers, MEDIAN_STRIDE);
                let dt = duration / row.tiles as f64;
                let bandwidth = 2.0 * PI.sqrt() * row.frequency / row.q;
                let kept = |t: f64| t >= keep_from && t < keep_to;
                excess_prefix_sums(&energies, z_pass, &mut prefix, &mut passing);
                // The single tiles that pass, in the blocks that hold one.
                for &first in &passing {
                    let block = (first..(first + PASS_BLOCK).min(energies.len())).map(|k| (k, energies.get(k)));
                    for (k, z) in block.filter(|(_, z)| *z >= z_pass) {
                        let t = k as f64 * dt;
                        if kept(t) {
                            let (snr, duration) = (tile_snr(z), row.tile_duration());
                            tiles.push(Tile {
                                time: t0 + t,
                                frequency: row.frequency,
                                q: row.q,
                                snr,
                                significance: snr,
                                duration,
                                bandwidth,
                            });
                        }
                    }
                }
                // Excess power over windows of several durations.
                let tau = row.correlation_time();
                let median_tiles = energies.len().div_ceil(MEDIAN_STRIDE) as f64;
                let longest = if row.q < BROADBAND_Q { BROADBAND_LONGEST_WINDOW } else { f64::INFINITY };
                let windows = EXCESS_POWER_WINDOWS.iter().filter(|w| **w >= 4.0 * tau && **w <= (EXCESS_POWER_MAX_DOF * tau).min(longest));
                for &window in windows {
                    let n = (window / dt).round() as usize;
                    if n < 2 || n >= energies.len() {
                        continue;
                    }
                    let stride = ((window / 4.0) / dt).round().max(1.0) as usize;
                    let level_spread = MEDIAN_LEVEL_SPREAD * (n as f64 * dt / tau) / median_tiles;
                    let excess = ExcessPower::new(dt, tau * (noise_inflation + level_spread), n as f64 * dt, o.tile_threshold);
                    let fails_below = failing_sums.get(&excess);
                    for s in (0..energies.len() - n).step_by(stride) {
                        let sum = prefix[s + n] - prefix[s];
                        if sum <= fails_below {
                            continue;
                        }
                        let centre = (s as f64 + 0.5 * n as f64) * dt;
                        if !kept(centre) {
                            continue;
                        }
                        if let Some((snr, significance)) = excess.test(sum) {
                            // The time of the excess energy within the window,
                            // iterated (finer than its stride, and centred on
                            // a long glitch whose envelope is flatter than the
                            // window). Over ±window, a 2 s window's centroid
                            // reached a loud neighbour 2 s away.
                            let mut time = centre;
                            for _ in 0..3 {
                                time = excess_centroid(&energies, dt, time - 0.5 * window, time + 0.5 * window).unwrap_or(time);
                            }
                            tiles.push(Tile {
                                time: t0 + time,
                                frequency: row.frequency,
                                q: row.q,
                                snr,
                                significance,
                                duration: n as f64 * dt,
                                bandwidth,
                            });
                        }
                    }
                }
            }
        }
        let triggers =
            cluster(tiles, o.cluster_gap, Threshold { snr: o.snr_threshold, significance: o.min_significance.min(o.snr_threshold) });
        clock.add(2, since);
        since = std::time::Instant::now();
        let rows = triggers
            .into_iter()
            .map(|trigger| {
                let verdict = match &self.classifier {
                    None => None,
                    Some(c) => {
                        let len = c.manifest.window().min(n);
                        let centre = ((trigger.time - t0) * fs).round() as i64;
                        let start = (centre - len as i64 / 2).clamp(0, (n - len) as i64) as usize;
                        let window = &w_clf[start..start + len];
                        Some(match classifier_run.as_deref_mut() {
                            Some(run) => c.classify_with(run, window)?,
                            None => c.classify(window)?,
                        })
                    }
                };
                Ok(Row { trigger, verdict })
            })
            .collect();
        clock.add(3, since);
        rows
    }
}

/// The `w_clf` band of the whitening scene when no classifier reads it (Hz).
const NO_CLASSIFIER_BAND: (f64, f64) = (20.0, 2000.0);

/// Tiles per block in which [`excess_prefix_sums`] looks for passing tiles.
const PASS_BLOCK: usize = 16;

/// Prefix sums of the mean-normalised excess energies `z ln 2 − 1` of a
/// row into `prefix` (`prefix[j]` sums the first `j` tiles), and into
/// `passing` the first tile of every block of [`PASS_BLOCK`] tiles that
/// holds a tile of energy ≥ `z_pass`: one pass over the row. Summed in
/// blocks of four whose own running sums do not wait on the total, so the
/// chain of dependent additions is a quarter as long. (Not inlined, so a
/// profile shows this pass on its own; inlined it measured the same.)
#[inline(never)]
fn excess_prefix_sums(energies: &RowEnergies, z_pass: f64, prefix: &mut Vec<f64>, passing: &mut Vec<usize>) {
    let len = energies.len();
    prefix.resize(len + 1, 0.0);
    prefix[0] = 0.0;
    passing.clear();
    let mut total = 0.0;
    let whole = len - len % PASS_BLOCK;
    for (first, sums) in (0..whole).step_by(PASS_BLOCK).zip(prefix[1..].chunks_exact_mut(PASS_BLOCK)) {
        let z: [f64; PASS_BLOCK] = energies.block(first);
        // A fold, not `any`: no branch per tile, so it vectorises.
        if z.iter().fold(false, |above, z| above | (*z >= z_pass)) {
            passing.push(first);
        }
        for (z, sum) in z.chunks_exact(4).zip(sums.chunks_exact_mut(4)) {
            let e: [f64; 4] = std::array::from_fn(|i| z[i] * LN_2 - 1.0);
            let (s1, s2) = (e[0] + e[1], e[2] + e[3]);
            sum.copy_from_slice(&[total + e[0], total + s1, total + (s1 + e[2]), total + (s1 + s2)]);
            total += s1 + s2;
        }
    }
    for k in whole..len {
        let z = energies.get(k);
        total += z * LN_2 - 1.0;
        prefix[k + 1] = total;
    }
    if (whole..len).any(|k| energies.get(k) >= z_pass) {
        passing.push(whole);
    }
}

/// The centroid in time of a row's strong excess energy (median-normalised
/// energies `z`, every `dt` s) between `from` and `to` s: each tile weighted
/// by how far its mean-normalised energy exceeds twice the noise mean, so
/// noise tiles barely pull it. `None` without such tiles.
fn excess_centroid(energies: &RowEnergies, dt: f64, from: f64, to: f64) -> Option<f64> {
    let a = (from / dt).ceil().max(0.0) as usize;
    let b = ((to / dt).floor().max(0.0) as usize + 1).min(energies.len());
    let (mut w, mut wt) = (0.0, 0.0);
    for k in a..b {
        let excess = (energies.get(k) * LN_2 - 2.0).max(0.0);
        w += excess;
        wt += excess * k as f64 * dt;
    }
    (w > 0.0).then(|| wt / w)
}

/// [`ExcessPower::failing_sum`] of each excess-power test a scan makes,
/// computed once (the tests repeat from chunk to chunk) and shared by the
/// threads: most windows of noise are then skipped by one comparison
/// instead of a tail probability (this halved the excess-power time).
#[derive(Default)]
struct FailingSums(std::sync::Mutex<std::collections::HashMap<ExcessPower, f64>>);

impl FailingSums {
    fn get(&self, test: &ExcessPower) -> f64 {
        if let Some(sum) = self.0.lock().expect("no panics while locked").get(test) {
            return *sum;
        }
        let sum = test.failing_sum();
        self.0.lock().expect("no panics while locked").insert(test.clone(), sum);
        sum
    }
}

/// A chunk length's compiled whitening scene and tiling.
struct Prepared {
    whiten: std::sync::Arc<Scene>,
    tiling: QTiling,
}

/// Merges rows of neighbouring chunks (or blocks) where a trigger was cut by
/// a boundary: a trigger whose peak lies in a more significant one's peak
/// tile (± `gap`) joins it ([`absorbed_into`]), whose verdict stands.
pub fn merge_rows(rows: Vec<Row>, gap: f64) -> Vec<Row> {
    let triggers: Vec<Trigger> = rows.iter().map(|r| r.trigger.clone()).collect();
    let into = absorbed_into(&triggers, gap);
    let mut out: Vec<Option<Row>> = rows.into_iter().map(Some).collect();
    for (i, target) in into.iter().enumerate() {
        if let Some(k) = *target {
            let t = out[i].take().expect("absorbed once").trigger;
            out[k].as_mut().expect("targets are kept").trigger.join(&t);
        }
    }
    let mut out: Vec<Row> = out.into_iter().flatten().collect();
    out.sort_by(|a, b| a.trigger.time.total_cmp(&b.trigger.time));
    out
}
