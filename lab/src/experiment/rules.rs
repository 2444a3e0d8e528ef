//! Classifier 1 of the glitch experiment (issue #7): traditional filtering,
//! no training.
//!
//! The whitened 1 s segments of [`crate::synth::glitches`] are
//! matched-filtered against a fixed bank (`lab/models/glitch/bank.gw`:
//! sine-Gaussians over 10 central frequencies × 3 quality factors, which
//! tile the time-frequency plane like a Q-transform, and 6 TaylorF2
//! chirps). Each row gives one SNR time series ρ_k(t) per template; a few
//! features are read off them ([`Features`]) and a short list of rules with
//! thresholds ([`Thresholds`]) names the class. [`RuleClassifier::tune`]
//! chooses the thresholds by a coordinate-wise grid search for the largest
//! macro F1 on labelled data (the "tuned baseline"); nothing is fitted by
//! gradients.
//!
//! Features (ρ² has mean 2 in white noise, since the complex SNR has two
//! unit-variance quadratures):
//! - the loudest sine-Gaussian (its ρ, time, Q, and its central frequency
//!   refined by a parabola through the neighbouring frequencies at that
//!   time) and the loudest chirp;
//! - extended excess power: per sine-Gaussian template of width τ ≤ 40 ms,
//!   the sum of ρ² − 2 within ±0.45 s of the loudest peak but outside its
//!   core (where a short burst's own response lives), as a z-score against
//!   the noise (the variance of such sums is calibrated once on white noise
//!   drawn in [`RuleClassifier::new`]); per bank frequency the largest z over
//!   Q, then the largest sum over 1-3 adjacent frequencies over the square
//!   root of their number, and those frequencies' z-weighted mean;
//! - a low-frequency head: the 32 and 49 Hz, Q = 3 templates' loudest ρ
//!   8–35 ms before the peak minus their loudest ρ 8–35 ms after it (the
//!   main burst's own leakage into those templates is symmetric in time; a
//!   Koi Fish's head is not).
use super::metrics::Confusion;
use crate::synth::GLITCH_CLASSES;
use gwml_runtime::dataset::Array;
use gwml_runtime::{Model, Outputs, Run, Scene, Value};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The filter bank scene.
const BANK: &str = include_str!("../../models/glitch/bank.gw");
/// Samples per row, and per second.
const SAMPLES: usize = 4096;
const RATE: f64 = 4096.0;
/// Sine-Gaussian templates wider than this are left out of the extended
/// excess power (their response to a short burst is itself long).
const TAU_MAX: f64 = 0.04;
/// Half-width of the region around the loudest peak searched for extended power.
const REACH: f64 = 0.45;
/// Class indices (positions in [`GLITCH_CLASSES`]).
const NONE: usize = 0;
const BLIP: usize = 1;
const KOI: usize = 2;
const WHISTLE: usize = 3;
const SCRATCHY: usize = 4;
const CHIRP: usize = 5;
const TOMTE: usize = 6;
const SCATTERED: usize = 7;
/// Every class: the thresholds maximise the macro F1 over all eight.
const ALL_CLASSES: [usize; 8] = [NONE, BLIP, KOI, WHISTLE, SCRATCHY, CHIRP, TOMTE, SCATTERED];

/// One template of the bank, as its output name describes it.
#[derive(Clone, Debug)]
enum Kind {
    /// A sine-Gaussian at central frequency `f0` (Hz) and quality factor `q`,
    /// of 1/e half-width `tau` (s).
    Sg { f0: f64, q: f64, tau: f64 },
    /// A TaylorF2 chirp (its chirp mass, in the name, is checked but not used).
    Chirp,
}

/// Reads a template's parameters from its output name (`sg_f114_q3`, `chirp_mc26`).
fn parse_template(name: &str) -> Result<Kind, String> {
    let bad = || format!("bank output `{name}` is neither sg_fF_qQ nor chirp_mcM");
    if let Some(rest) = name.strip_prefix("sg_f") {
        let (f, q) = rest.split_once("_q").ok_or_else(bad)?;
        let f0: f64 = f.parse().map_err(|_| bad())?;
        let q: f64 = q.parse().map_err(|_| bad())?;
        let tau = q / (std::f64::consts::SQRT_2 * std::f64::consts::PI * f0);
        Ok(Kind::Sg { f0, q, tau })
    } else if let Some(m) = name.strip_prefix("chirp_mc") {
        m.parse::<f64>().map_err(|_| bad())?;
        Ok(Kind::Chirp)
    } else {
        Err(bad())
    }
}

/// What the rules look at, per row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Features {
    /// Peak SNR of the loudest sine-Gaussian.
    pub rho_sg: f64,
    /// Its central frequency, refined between the bank's frequencies (Hz).
    pub f_sg: f64,
    /// Its quality factor.
    pub q_sg: f64,
    /// Peak SNR of the loudest chirp.
    pub rho_chirp: f64,
    /// Extended excess power: per bank frequency the largest z over Q, then
    /// the largest sum over 1-3 adjacent frequencies divided by the square
    /// root of their number (a Whistle sweeps across several).
    pub ext: f64,
    /// Frequency of the extended excess power (Hz): the mean log frequency
    /// of the frequencies that make up `ext`, weighted by their positive z.
    pub ext_f: f64,
    /// Low-frequency head before the peak minus after it (in SNR).
    pub head: f64,
}

/// The thresholds of the rules (see [`RuleClassifier::describe`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Thresholds {
    /// Below this peak SNR (of every template), and without extended power: None.
    pub detect: f64,
    /// Extended excess power (z) above which a signal is long.
    pub ext: f64,
    /// Extended power at or above this frequency (Hz) is a Whistle, below a Scratchy.
    pub ext_f: f64,
    /// A chirp wins when its peak SNR is at least this times the best sine-Gaussian's.
    pub chirp_margin: f64,
    /// A short signal at or above this frequency (Hz) is a Whistle.
    pub whistle_f: f64,
    /// Koi Fish band, lower edge (Hz).
    pub koi_lo: f64,
    /// Koi Fish band, upper edge (Hz).
    pub koi_hi: f64,
    /// Head score, as a fraction of the peak SNR, above which a short signal
    /// in the Koi Fish band is a Koi Fish (the head is 10-30 % of the amplitude).
    pub head: f64,
    /// Peak SNR below which a short signal is not a Koi Fish (Koi Fish are loud).
    pub koi_snr: f64,
    /// A short signal below this frequency (Hz) is a Tomte.
    pub tomte_f: f64,
    /// Extended power below this frequency (Hz) is Scattered Light.
    pub scatter_f: f64,
}

impl Default for Thresholds {
    /// Values from the class descriptions and the noise statistics, before tuning.
    fn default() -> Self {
        Thresholds {
            detect: 6.0,
            ext: 5.0,
            ext_f: 350.0,
            chirp_margin: 1.05,
            whistle_f: 300.0,
            koi_lo: 105.0,
            koi_hi: 170.0,
            head: 0.05,
            koi_snr: 15.0,
            tomte_f: 70.0,
            scatter_f: 60.0,
        }
    }
}

impl Thresholds {
    /// The class the rules give a row with features `f`.
    pub fn decide(&self, f: &Features) -> usize {
        let ext = f.ext;
        if f.rho_sg.max(f.rho_chirp) < self.detect && ext < self.ext {
            NONE
        } else if f.rho_chirp >= self.chirp_margin * f.rho_sg {
            CHIRP
        } else if f.f_sg >= self.koi_lo && f.f_sg <= self.koi_hi && f.head >= self.head * f.rho_sg && f.rho_sg >= self.koi_snr {
            // Before the extended power: a loud Koi Fish's head is itself
            // low-frequency power outside the peak.
            KOI
        } else if ext >= self.ext && f.ext_f >= self.ext_f {
            WHISTLE
        } else if ext >= self.ext && f.ext_f < self.scatter_f {
            SCATTERED
        } else if ext >= self.ext {
            SCRATCHY
        } else if f.f_sg >= self.whistle_f {
            WHISTLE
        } else if f.f_sg < self.tomte_f {
            TOMTE
        } else {
            BLIP
        }
    }
}

/// The rule-based classifier: a fixed filter bank (`lab/models/glitch/bank.gw`,
/// embedded with `include_str!`) and thresholds.
pub struct RuleClassifier {
    scene: Scene,
    kinds: Vec<Kind>,
    /// Per template, the noise variance per sample of sums of ρ² − 2 over
    /// long stretches (4 times the sum of the squared normalised
    /// autocorrelation, measured on white noise).
    var: Vec<f64>,
    /// The current thresholds.
    pub thresholds: Thresholds,
}

impl RuleClassifier {
    /// Compiles the bank and calibrates the noise statistics of extended
    /// excess power on seeded white noise; thresholds start at their defaults.
    pub fn new() -> Result<Self, String> {
        let model = Model::from_source("lab/models/glitch/bank.gw", BANK).map_err(|e| e.to_string())?;
        let scene = model.scene(Some("bank")).map_err(|e| e.to_string())?;
        let names: Vec<String> = scene.forward_ir().outputs.iter().map(|o| o.name.clone()).collect();
        let kinds = names.iter().map(|n| parse_template(n)).collect::<Result<Vec<_>, _>>()?;
        if !kinds.iter().any(|k| matches!(k, Kind::Chirp)) || !kinds.iter().any(|k| matches!(k, Kind::Sg { .. })) {
            return Err("the bank needs sine-Gaussian and chirp templates".into());
        }
        let mut c = RuleClassifier { scene, kinds, var: Vec::new(), thresholds: Thresholds::default() };
        c.var = c.calibrate(16, 0x5eed)?;
        Ok(c)
    }

    /// Measures each template's noise variance per sample of block sums of
    /// ρ² − 2 on `rows` rows of white noise (blocks of 512 samples, far
    /// longer than any template's correlation).
    fn calibrate(&self, rows: usize, seed: u64) -> Result<Vec<f64>, String> {
        let mut rng = Normal::new(seed);
        let mut run = self.scene.bind();
        let block = 512;
        let mut sums = vec![0.0; self.kinds.len()];
        let mut count = 0usize;
        for _ in 0..rows {
            let x: Vec<f64> = (0..SAMPLES).map(|_| rng.sample()).collect();
            let out = self.filter(&mut run, &x)?;
            for (k, s) in sums.iter_mut().enumerate() {
                let rho = series(&out, k)?;
                for chunk in rho.chunks(block) {
                    let e: f64 = chunk.iter().map(|r| r * r - 2.0).sum();
                    *s += e * e / block as f64;
                }
            }
            count += SAMPLES / block;
        }
        Ok(sums.into_iter().map(|s| s / count as f64).collect())
    }

    /// Runs the bank on one row.
    fn filter(&self, run: &mut Run<'_>, x: &[f64]) -> Result<Outputs, String> {
        run.input_real("x", x).map_err(|e| e.to_string())?;
        run.forward().map_err(|e| e.to_string())
    }

    /// The features of one row.
    fn features(&self, run: &mut Run<'_>, x: &[f64]) -> Result<Features, String> {
        let out = self.filter(run, x)?;
        let rhos = (0..self.kinds.len()).map(|k| series(&out, k)).collect::<Result<Vec<_>, _>>()?;
        let mut f = Features::default();
        // The loudest sine-Gaussian and chirp.
        let (mut best, mut t_best) = (usize::MAX, 0usize);
        for (k, (kind, rho)) in self.kinds.iter().zip(&rhos).enumerate() {
            let (t, peak) = argmax(rho);
            match kind {
                Kind::Sg { .. } if peak > f.rho_sg || best == usize::MAX => {
                    (f.rho_sg, best, t_best) = (peak, k, t);
                }
                Kind::Chirp => f.rho_chirp = f.rho_chirp.max(peak),
                _ => {}
            }
        }
        let Some(&Kind::Sg { f0, q, tau: tau_best }) = self.kinds.get(best) else {
            return Err("the row's matched-filter SNRs are not numbers (a row of NaN?)".into());
        };
        f.q_sg = q;
        f.f_sg = self.refine_frequency(&rhos, f0, q, t_best);
        // Extended excess power outside the peak's core.
        let reach = (REACH * RATE) as usize;
        let (lo, hi) = (t_best.saturating_sub(reach), (t_best + reach + 1).min(SAMPLES));
        let mut per_f: Vec<(f64, f64)> = Vec::new();
        for (k, kind) in self.kinds.iter().enumerate() {
            let Kind::Sg { f0, tau, .. } = *kind else { continue };
            if tau > TAU_MAX {
                continue;
            }
            let core = ((2.2 * (tau * tau + tau_best * tau_best).sqrt() + 0.002) * RATE) as usize;
            let (mut e, mut n) = (0.0, 0usize);
            for (t, r) in rhos[k].iter().enumerate().take(hi).skip(lo) {
                if t.abs_diff(t_best) > core {
                    e += r * r - 2.0;
                    n += 1;
                }
            }
            if n == 0 {
                continue;
            }
            let z = e / (n as f64 * self.var[k]).sqrt();
            match per_f.iter_mut().find(|(fr, _)| *fr == f0) {
                Some(entry) => entry.1 = entry.1.max(z),
                None => per_f.push((f0, z)),
            }
        }
        per_f.sort_by(|a, b| a.0.total_cmp(&b.0));
        f.ext = f64::NEG_INFINITY;
        let mut best_run: &[(f64, f64)] = &[];
        for len in 1..=3 {
            for run in per_f.windows(len) {
                let z = run.iter().map(|(_, z)| z).sum::<f64>() / (len as f64).sqrt();
                if z > f.ext {
                    (f.ext, best_run) = (z, run);
                }
            }
        }
        let (weight, log_f) = best_run.iter().filter(|(_, z)| *z > 0.0).fold((0.0, 0.0), |(w, l), (fr, z)| (w + z, l + z * fr.ln()));
        f.ext_f = if weight > 0.0 { (log_f / weight).exp() } else { 0.0 };
        // The low-frequency head: before the peak minus after it.
        let (near, far) = ((0.008 * RATE) as usize, (0.035 * RATE) as usize);
        f.head = f64::NEG_INFINITY;
        for (k, kind) in self.kinds.iter().enumerate() {
            let Kind::Sg { f0, q, .. } = *kind else { continue };
            if f0 > 55.0 || q > 3.5 {
                continue;
            }
            let rho = &rhos[k];
            let window_max = |from: usize, to: usize| rho[from.min(SAMPLES)..to.min(SAMPLES)].iter().fold(0.0f64, |a, b| a.max(*b));
            let before = window_max(t_best.saturating_sub(far), t_best.saturating_sub(near));
            let after = window_max(t_best + near, t_best + far);
            f.head = f.head.max(before - after);
        }
        Ok(f)
    }

    /// Central frequency of the loudest sine-Gaussian refined by a parabola
    /// in log frequency through its neighbours (same Q) at its peak time.
    fn refine_frequency(&self, rhos: &[&[f64]], f0: f64, q: f64, t: usize) -> f64 {
        let mut row: Vec<(f64, f64)> = self
            .kinds
            .iter()
            .zip(rhos)
            .filter_map(|(kind, rho)| match *kind {
                Kind::Sg { f0, q: qk, .. } if qk == q => Some((f0.ln(), rho[t])),
                _ => None,
            })
            .collect();
        row.sort_by(|a, b| a.0.total_cmp(&b.0));
        let Some(i) = row.iter().position(|(lf, _)| *lf == f0.ln()) else { return f0 };
        if i == 0 || i + 1 == row.len() {
            return f0;
        }
        let ((xa, a), (xb, b), (xc, c)) = (row[i - 1], row[i], row[i + 1]);
        // Vertex of the parabola through three points (uneven spacing).
        let num = (xb - xa).powi(2) * (b - c) - (xb - xc).powi(2) * (b - a);
        let den = (xb - xa) * (b - c) - (xb - xc) * (b - a);
        if den.abs() < 1e-12 {
            return f0;
        }
        let x = xb - 0.5 * num / den;
        x.clamp(xa, xc).exp()
    }

    /// The features of every row of `x` (rows of 4096 samples), spread over threads.
    pub fn features_of(&self, x: &Array) -> Result<Vec<Features>, String> {
        if x.shape.len() != 2 || x.row_len() != SAMPLES {
            return Err(format!("rows of {SAMPLES} samples are needed, but the array has shape {:?}", x.shape));
        }
        let rows = x.rows();
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(rows.max(1));
        let next = AtomicUsize::new(0);
        let parts = std::thread::scope(|s| {
            let handles: Vec<_> = (0..threads)
                .map(|_| {
                    s.spawn(|| {
                        let mut run = self.scene.bind();
                        let mut done = Vec::new();
                        loop {
                            let i = next.fetch_add(1, Ordering::Relaxed);
                            if i >= rows {
                                return Ok(done);
                            }
                            done.push((i, self.features(&mut run, x.row(i))?));
                        }
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().map_err(|_| "a feature thread panicked".to_string())?).collect::<Result<Vec<_>, String>>()
        })?;
        let mut features = vec![Features::default(); rows];
        for (i, f) in parts.into_iter().flatten() {
            features[i] = f;
        }
        Ok(features)
    }

    /// Chooses the thresholds (a small grid search maximising macro F1 on
    /// labelled data): the "tuned baseline". No gradient training.
    pub fn tune(&mut self, x: &Array, labels: &[usize]) -> Result<(), String> {
        if labels.len() != x.rows() {
            return Err(format!("{} labels for {} rows", labels.len(), x.rows()));
        }
        if let Some(l) = labels.iter().find(|l| **l >= GLITCH_CLASSES.len()) {
            return Err(format!("label {l} is not a class index (0..{})", GLITCH_CLASSES.len()));
        }
        let features = self.features_of(x)?;
        self.thresholds = tune_thresholds(&features, labels, self.thresholds.clone());
        Ok(())
    }

    /// Class index per row of `x` (rows of 4096 samples), rows spread over threads.
    pub fn classify(&self, x: &Array) -> Result<Vec<usize>, String> {
        Ok(self.features_of(x)?.iter().map(|f| self.thresholds.decide(f)).collect())
    }

    /// One line per rule, for the results README.
    pub fn describe(&self) -> String {
        let t = &self.thresholds;
        [
            format!("None: every template's peak SNR < {:.2} and extended excess power z < {:.2}", t.detect, t.ext),
            format!("Chirp: the loudest chirp's peak SNR ≥ {:.3} × the loudest sine-Gaussian's", t.chirp_margin),
            format!(
                "Koi Fish: loudest sine-Gaussian at {:.0}–{:.0} Hz, of peak SNR ≥ {:.0}, with a 20–50 Hz head score (SNR before − after the peak) ≥ {:.3} × its peak SNR",
                t.koi_lo, t.koi_hi, t.koi_snr, t.head
            ),
            format!("Whistle: otherwise, extended excess power z ≥ {:.2} (in any band) centred (z-weighted mean log frequency) at ≥ {:.0} Hz", t.ext, t.ext_f),
            format!("Scattered Light: extended excess power z ≥ {:.2} centred below {:.0} Hz", t.ext, t.scatter_f),
            format!("Scratchy: extended excess power z ≥ {:.2} centred at {:.0}–{:.0} Hz", t.ext, t.scatter_f, t.ext_f),
            format!("Whistle: otherwise, loudest sine-Gaussian at ≥ {:.0} Hz", t.whistle_f),
            format!("Tomte: otherwise, loudest sine-Gaussian below {:.0} Hz", t.tomte_f),
            "Blip: everything else (a short burst between the Tomte and Whistle frequencies)".to_string(),
        ]
        .join("\n")
    }
}

/// The SNR series of template `k` (outputs are in template order).
fn series(out: &Outputs, k: usize) -> Result<&[f64], String> {
    match out.values.get(k) {
        Some((_, Value::RealArray(v))) if v.len() == SAMPLES => Ok(v),
        _ => Err(format!("bank output {k} is not an SNR series of {SAMPLES} samples")),
    }
}

/// Index and value of the largest element.
fn argmax(v: &[f64]) -> (usize, f64) {
    v.iter().enumerate().fold((0, f64::NEG_INFINITY), |(i, m), (j, x)| if *x > m { (j, *x) } else { (i, m) })
}

/// Coordinate-wise grid search over the thresholds for the largest macro F1
/// (three passes; ties keep the earlier value).
fn tune_thresholds(features: &[Features], labels: &[usize], start: Thresholds) -> Thresholds {
    let score = |t: &Thresholds| {
        let pred: Vec<usize> = features.iter().map(|f| t.decide(f)).collect();
        Confusion::new(GLITCH_CLASSES.len(), labels, &pred).map_or(0.0, |c| c.macro_f1(&ALL_CLASSES))
    };
    let grid = |lo: f64, hi: f64, n: usize| -> Vec<f64> { (0..n).map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64).collect() };
    type Field = fn(&mut Thresholds) -> &mut f64;
    let axes: Vec<(Field, Vec<f64>)> = vec![
        (|t| &mut t.detect, grid(4.5, 9.0, 19)),
        (|t| &mut t.ext, grid(2.0, 12.0, 21)),
        (|t| &mut t.ext_f, grid(150.0, 600.0, 19)),
        (|t| &mut t.chirp_margin, grid(0.8, 1.4, 25)),
        (|t| &mut t.whistle_f, grid(200.0, 500.0, 13)),
        (|t| &mut t.koi_lo, grid(80.0, 130.0, 11)),
        (|t| &mut t.koi_hi, grid(150.0, 250.0, 11)),
        (|t| &mut t.head, grid(-0.2, 0.3, 51)),
        (|t| &mut t.koi_snr, grid(0.0, 60.0, 61)),
        (|t| &mut t.tomte_f, grid(40.0, 110.0, 15)),
        (|t| &mut t.scatter_f, grid(30.0, 150.0, 25)),
    ];
    let mut best = start;
    let mut best_score = score(&best);
    for _ in 0..3 {
        for (field, values) in &axes {
            for v in values {
                let mut t = best.clone();
                *field(&mut t) = *v;
                let s = score(&t);
                if s > best_score {
                    (best, best_score) = (t, s);
                }
            }
        }
    }
    best
}

/// Seeded standard normal draws (SplitMix64 and Box–Muller), for the noise
/// calibration only.
struct Normal {
    state: u64,
    spare: Option<f64>,
}

impl Normal {
    fn new(seed: u64) -> Self {
        Normal { state: seed, spare: None }
    }

    /// A uniform draw in (0, 1).
    fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn sample(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let (u, v) = (self.uniform(), self.uniform());
        let r = (-2.0 * u.ln()).sqrt();
        let a = std::f64::consts::TAU * v;
        self.spare = Some(r * a.sin());
        r * a.cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{glitches, GlitchOptions};

    fn data(n: usize, seed: u64, snr: Option<(f64, f64)>) -> (Array, Vec<usize>) {
        let mut d = glitches(&GlitchOptions { n, seed, snr, ..Default::default() }).unwrap();
        let x = d.arrays.remove("x").unwrap();
        let labels = d.arrays["label"].data.iter().map(|l| *l as usize).collect();
        (x, labels)
    }

    /// The classifier tuned on seed 100 (300 rows), shared by the tests.
    fn tuned() -> &'static RuleClassifier {
        static TUNED: std::sync::OnceLock<RuleClassifier> = std::sync::OnceLock::new();
        TUNED.get_or_init(|| {
            let (x, labels) = data(300, 100, None);
            let mut c = RuleClassifier::new().unwrap();
            c.tune(&x, &labels).unwrap();
            c
        })
    }

    fn recall(pred: &[usize], labels: &[usize], class: usize) -> f64 {
        let of_class: Vec<usize> = (0..labels.len()).filter(|i| labels[*i] == class).collect();
        of_class.iter().filter(|i| pred[**i] == class).count() as f64 / of_class.len() as f64
    }

    /// On held-out data (seed 101, 300 rows) most noise is left alone and
    /// the glitch classes are found. Measured on these seeds (the benchmark
    /// population, where three None rows in four carry a weak transient
    /// centred where signals are, signals start at SNR 6.5 and half the
    /// Blips and Tomtes are real fits' shapes): None recall 0.64 (0.73
    /// before Koi Fish went down to SNR 12: the tuned Koi Fish rule now
    /// fires on quieter bursts), macro recall over the seven signal classes
    /// 0.52 before that change. Chirp recall 0.88 with formula Tomtes up to
    /// 55 Hz, 0.73 with Tomtes up to 45 Hz: the tuner then wants the chirp's
    /// SNR 1.2 times the best sine-Gaussian's, not 1.1 (with 600 tuning rows
    /// too), and a quiet chirp whose loudest sine-Gaussian is low is called
    /// Tomte (None recall 0.73, macro recall 0.51).
    #[test]
    fn tuned_rules_work_on_held_out_data() {
        let c = tuned();
        let (x, labels) = data(300, 101, None);
        let pred = c.classify(&x).unwrap();
        let none = recall(&pred, &labels, NONE);
        assert!(none >= 0.6, "None recall {none}\n{}", c.describe());
        let macro_recall = (1..GLITCH_CLASSES.len()).map(|k| recall(&pred, &labels, k)).sum::<f64>() / 7.0;
        eprintln!("None recall {none}, macro recall {macro_recall}");
        assert!(macro_recall >= 0.45, "macro recall over glitch classes {macro_recall}\n{}", c.describe());
        // Chirps have a matched template of their own.
        let chirp = recall(&pred, &labels, CHIRP);
        assert!(chirp >= 0.7, "Chirp recall {chirp}");
    }

    /// Loud examples (SNR 40 for every class). Measured (seed 102, 180 rows,
    /// thresholds tuned on seed 100): recall None 0.62, Blip 0.22, Koi Fish
    /// 0.23, Whistle 1.00, Scratchy 0.92, Chirp 0.92, Tomte 0.63,
    /// Scattered Light 0.87 with Koi Fish from SNR 12, Blips from 70 Hz and
    /// Tomtes up to 55 Hz (the tuned Koi Fish rule takes loud Blips and
    /// Tomtes; with Tomtes up to 45 Hz: None 0.81, Blip 0.22, Koi Fish 0.23,
    /// Whistle 1.00, Scratchy 0.92, Chirp 0.80, Tomte 0.88, Scattered Light
    /// 0.91); before: None 0.81, Blip 0.52, Koi Fish
    /// 0.30, Whistle 1.00, Scratchy 0.92, Chirp 0.92 (0.72 on other data,
    /// when the tuned margin wanted the chirp templates 18 % above the
    /// sine-Gaussians, which short high-mass chirps miss), Tomte 0.88,
    /// Scattered Light 0.87. The long
    /// classes and the chirp are what the rules recognise; a
    /// Koi Fish's whitened head outweighs its core, so its loudest template
    /// is a low-frequency one and the rules call it a Tomte, and Blips split
    /// between Blip, Koi Fish and Whistle: the floors below hold the classes
    /// the rules do recognise.
    #[test]
    fn loud_long_glitches_and_chirps_are_recognised() {
        let c = tuned();
        let (x, labels) = data(180, 102, Some((40.0, 40.0)));
        let pred = c.classify(&x).unwrap();
        let recalls: Vec<f64> = (0..GLITCH_CLASSES.len()).map(|k| recall(&pred, &labels, k)).collect();
        eprintln!("recall at SNR 40: {recalls:?}\n{}", c.describe());
        for (k, floor) in [(WHISTLE, 0.9), (SCRATCHY, 0.9), (CHIRP, 0.65), (TOMTE, 0.55), (SCATTERED, 0.7)] {
            let r = recalls[k];
            assert!(r >= floor, "{}: recall {r} at SNR 40 (all: {recalls:?})\n{}", GLITCH_CLASSES[k], c.describe());
        }
    }

    #[test]
    fn the_rules_read_the_features_as_described() {
        let t = Thresholds::default();
        let quiet = Features { rho_sg: 4.5, f_sg: 600.0, q_sg: 3.0, rho_chirp: 4.0, ext: 1.0, ext_f: 500.0, head: 0.0 };
        assert_eq!(t.decide(&quiet), NONE);
        let chirp = Features { rho_sg: 10.0, rho_chirp: 13.0, f_sg: 40.0, ..quiet.clone() };
        assert_eq!(t.decide(&chirp), CHIRP);
        let long_high = Features { rho_sg: 5.0, ext: 12.0, ext_f: 700.0, ..quiet.clone() };
        assert_eq!(t.decide(&long_high), WHISTLE);
        let long_low = Features { ext_f: 120.0, ..long_high.clone() };
        assert_eq!(t.decide(&long_low), SCRATCHY);
        assert_eq!(t.decide(&Features { ext_f: 35.0, ..long_high.clone() }), SCATTERED);
        let blip = Features { rho_sg: 15.0, f_sg: 80.0, ..quiet.clone() };
        assert_eq!(t.decide(&blip), BLIP);
        assert_eq!(t.decide(&Features { f_sg: 45.0, ..blip.clone() }), TOMTE);
        let koi = Features { f_sg: 140.0, head: 3.0, ..blip.clone() };
        assert_eq!(t.decide(&koi), KOI);
        assert_eq!(t.decide(&Features { head: -1.0, ..koi.clone() }), BLIP);
        let loud = Thresholds { koi_snr: 20.0, ..t.clone() };
        assert_eq!(loud.decide(&koi), BLIP);
        assert_eq!(loud.decide(&Features { rho_sg: 25.0, ..koi.clone() }), KOI);
        assert_eq!(t.decide(&Features { f_sg: 800.0, ..blip }), WHISTLE);
    }

    #[test]
    fn template_names_carry_their_parameters() {
        let Kind::Sg { f0, q, tau } = parse_template("sg_f114_q8").unwrap() else { panic!("not a sine-Gaussian") };
        assert_eq!((f0, q), (114.0, 8.0));
        assert!((tau - 8.0 / (std::f64::consts::SQRT_2 * std::f64::consts::PI * 114.0)).abs() < 1e-15);
        assert!(matches!(parse_template("chirp_mc26"), Ok(Kind::Chirp)));
        for bad in ["sg_f114", "sg_fx_q3", "chirp_mcx", "blip"] {
            assert!(parse_template(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn bad_data_is_an_error() {
        let c = tuned();
        assert!(c.classify(&Array::new(vec![2, 100], vec![0.0; 200]).unwrap()).is_err());
        let mut c2 = RuleClassifier::new().unwrap();
        let x = Array::new(vec![1, SAMPLES], vec![0.0; SAMPLES]).unwrap();
        assert!(c2.tune(&x, &[8]).is_err());
        assert!(c2.tune(&x, &[0, 1]).is_err());
    }

    /// The bank's matched filter is `std::detector::snr_series`, rewritten.
    #[test]
    fn matched_filter_equals_std_snr_series() {
        let model = Model::from_source("bank.gw", BANK).unwrap();
        let scene = model.scene(Some("check")).unwrap();
        let (x, labels) = data(12, 5, Some((20.0, 20.0)));
        let mut run = scene.bind();
        for (i, label) in labels.iter().enumerate() {
            run.input_real("x", x.row(i)).unwrap();
            let out = run.forward().unwrap();
            for kind in ["sg", "chirp"] {
                let get = |name: String| match out.value(&name).unwrap() {
                    Value::RealArray(v) => v.clone(),
                    other => panic!("{name} is {other:?}"),
                };
                let (ours, std) = (get(format!("{kind}_ours")), get(format!("{kind}_std")));
                let peak = std.iter().fold(0.0f64, |a, b| a.max(*b));
                assert!(peak > 2.0, "class {label} row {i}: {kind} peak {peak}");
                for (a, b) in ours.iter().zip(&std) {
                    assert!((a - b).abs() < 1e-9 * peak, "{kind}: {a} vs {b}");
                }
            }
        }
    }

    #[test]
    #[ignore = "evaluation: tunes on seed 7 and prints per-class scores on seed SEED (default 8), N rows each (default 1200)"]
    fn evaluate() {
        let n: usize = std::env::var("N").ok().and_then(|s| s.parse().ok()).unwrap_or(1200);
        let (x, labels) = data(n, 7, None);
        let mut c = RuleClassifier::new().unwrap();
        c.tune(&x, &labels).unwrap();
        eprintln!("{}\n{:?}", c.describe(), c.thresholds);
        let seed: u64 = std::env::var("SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(8);
        let (x, labels) = data(n, seed, None);
        let t = std::time::Instant::now();
        let pred = c.classify(&x).unwrap();
        eprintln!("classify: {:.3} ms per row (all threads)", t.elapsed().as_secs_f64() * 1e3 / n as f64);
        report(&pred, &labels);
    }

    fn report(pred: &[usize], labels: &[usize]) {
        let c = Confusion::new(GLITCH_CLASSES.len(), labels, pred).unwrap();
        eprintln!("confusion (rows true, columns predicted): {:?}", GLITCH_CLASSES);
        for (k, row) in c.counts.iter().enumerate() {
            eprintln!("  {:>9} {:?}", GLITCH_CLASSES[k], row);
        }
        for (k, name) in GLITCH_CLASSES.iter().enumerate() {
            let s = c.score(k);
            eprintln!("  {name:>9} precision {:.3} recall {:.3}", s.precision, s.recall);
        }
        eprintln!("  accuracy {:.3} macro F1 {:.3}", c.accuracy(), c.macro_f1(&ALL_CLASSES));
    }
}
