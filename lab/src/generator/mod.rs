//! `gwml generator`: the glitch generator of the pipeline, which draws new
//! whitened glitches like the examples it was fitted to. Two kinds:
//! [`learned`] (a variational autoencoder written in
//! `lab/models/glitch/vae.gw` and trained by gwml's trainer: it learns the
//! examples' shapes) and [`parametric`] (a multivariate normal over the
//! params of one `std::glitch` formula, estimated from each example by
//! matched filtering: it can only draw that formula). This module owns the
//! command line, the example files and the draws' output.

pub mod learned;
pub mod parametric;
pub mod realism;

use crate::parse_range;
use crate::plot::lines_plot;
use crate::render;
use crate::synth::{glitches, GlitchClass, GlitchOptions, GLITCH_CLASSES};
use gwml_runtime::dataset::{self, Array, Dataset};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a generator is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// A variational autoencoder that learns the examples' shapes.
    Learned,
    /// A distribution over the params of the family's formula.
    Parametric,
}

/// `gwml generator` subcommands.
#[derive(clap::Subcommand)]
pub enum GeneratorCommand {
    /// Fit a generator of one glitch family to example glitches: a
    /// variational autoencoder trained on the examples (--kind learned), or
    /// a multivariate normal over the family formula's params estimated
    /// from each example by matched filtering (--kind parametric). Writes
    /// the generator as JSON.
    Fit(GeneratorFitArgs),
    /// Draw whitened glitches from a fitted generator into an .npz (`x`,
    /// n × 4096, and one array per drawn param).
    Sample(GeneratorSampleArgs),
}

#[derive(clap::Args)]
pub struct GeneratorFitArgs {
    /// The glitch family to model (blip, koi-fish, whistle or scratchy).
    #[arg(long, value_enum)]
    pub family: GlitchClass,
    /// What the generator is: a variational autoencoder that learns the
    /// shapes of the examples, or a distribution over the params of the
    /// family's `std::glitch` formula (the baseline).
    #[arg(long, value_enum, default_value_t = Kind::Learned)]
    pub kind: Kind,
    /// Training epochs of the learned generator.
    #[arg(long, default_value_t = 200)]
    pub epochs: usize,
    /// Hold this fraction of the examples (the last rows) out of the fit
    /// and measure the generator's realism against them: a classifier
    /// two-sample test of draws against their clean shapes (array `clean`
    /// of the examples file) at SNR 20 and 40.
    #[arg(long, default_value_t = 0.0)]
    pub holdout: f64,
    /// Example glitches: an .npz with `x` (rows of 4096 whitened samples at
    /// 4096 Hz; with a `label` array, only the family's rows are used) or an
    /// .npy of such rows [default: draw --n examples of the family as
    /// `gwml data glitch --class FAMILY --snr LO..HI` does].
    #[arg(long, value_name = "PATH")]
    pub examples: Option<PathBuf>,
    /// Examples to draw when --examples is not given.
    #[arg(long, default_value_t = 200)]
    pub n: usize,
    /// Seed of the drawn examples.
    #[arg(long, default_value_t = 11)]
    pub seed: u64,
    /// SNR range of the drawn examples (Koi Fish included).
    #[arg(long, default_value = "15..40")]
    pub snr: String,
    /// Where to write the generator (a learned one writes its weights
    /// beside it, PATH.safetensors).
    #[arg(long, value_name = "PATH.json")]
    pub out: PathBuf,
    /// Plot the examples' estimates and the generator's draws of the first
    /// two shape params as a PNG.
    #[arg(long, value_name = "PATH.png")]
    pub plot: Option<PathBuf>,
    /// Worker threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
}

#[derive(clap::Args)]
pub struct GeneratorSampleArgs {
    /// A generator written by `gwml generator fit`.
    #[arg(long, value_name = "PATH.json")]
    pub model: PathBuf,
    /// Glitches to draw.
    #[arg(long, default_value_t = 6)]
    pub n: usize,
    /// Seed: the same seed draws the same glitches.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Add unit-variance white noise (whitened detector noise), as in
    /// `gwml data glitch`.
    #[arg(long)]
    pub noise: bool,
    /// Where to write the draws.
    #[arg(long, value_name = "PATH.npz")]
    pub out: PathBuf,
    /// Plot the first (up to six) draws as a PNG.
    #[arg(long, value_name = "PATH.png")]
    pub plot: Option<PathBuf>,
}

/// Samples per whitened example (1 s at 4096 Hz).
pub const SAMPLES: usize = 4096;

/// Sample rate of the examples in Hz.
pub const SAMPLE_RATE: f64 = 4096.0;

/// Glitches drawn from a generator.
#[derive(Clone, Debug, PartialEq)]
pub struct Draws {
    /// Rows of 4096 whitened samples (the glitch alone, in units of the
    /// unit-variance white noise it would sit in).
    pub rows: Vec<Vec<f64>>,
    /// The names of the per-row values in `params`.
    pub names: Vec<String>,
    /// Each row's drawn values (shape params, time, SNR, ...).
    pub params: Vec<Vec<f64>>,
}

/// A generator read from its JSON file.
pub enum Generator {
    /// A variational autoencoder.
    Learned(learned::LearnedGenerator),
    /// A distribution over a formula's params.
    Parametric(parametric::Generator),
}

impl Generator {
    /// Reads a generator written by `gwml generator fit` (a file without a
    /// `kind` is parametric, as every file was before the learned kind).
    /// Errors are one line naming the file.
    pub fn read(path: &Path) -> Result<Generator, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("error: cannot read {}: {e}", path.display()))?;
        let parsed =
            serde_json::from_str::<serde_json::Value>(&text).map_err(|e| e.to_string()).and_then(|json| match json["kind"].as_str() {
                Some("learned") => learned::LearnedGenerator::from_json(&json, path).map(Generator::Learned),
                None | Some("parametric") => parametric::Generator::from_json(&json).map(Generator::Parametric),
                Some(other) => Err(format!("unknown generator kind `{other}`")),
            });
        parsed.map_err(|e| format!("error: {}: {e}", path.display()))
    }

    /// The glitch class it draws.
    pub fn class(&self) -> Result<usize, String> {
        match self {
            Generator::Learned(g) => Ok(g.class),
            Generator::Parametric(g) => g.class(),
        }
    }

    /// Draws `n` whitened glitches (the same seed draws the same glitches).
    pub fn sample(&self, n: usize, seed: u64) -> Result<Draws, String> {
        match self {
            Generator::Learned(g) => g.sample(n, seed).map_err(render),
            Generator::Parametric(g) => g.sample(n, seed),
        }
    }
}

/// Glitch shapes for `gwml data glitch|strain --generator`: one fitted
/// generator per class, drawn in batches as rows are needed.
pub struct GeneratorShapes {
    sources: Vec<(usize, Generator, Vec<Vec<f64>>, u64)>,
    seed: u64,
}

/// Glitch shapes a [`GeneratorShapes`] draws at a time.
const SHAPE_BATCH: usize = 256;

impl GeneratorShapes {
    /// Reads the generator files (at most one per class); `seed` seeds the
    /// draws.
    pub fn open(paths: &[PathBuf], seed: u64) -> Result<GeneratorShapes, String> {
        let mut sources: Vec<(usize, Generator, Vec<Vec<f64>>, u64)> = Vec::new();
        for path in paths {
            let g = Generator::read(path)?;
            let class = g.class()?;
            if sources.iter().any(|s| s.0 == class) {
                return Err(format!("error: two --generator files draw {}: give one per class", GLITCH_CLASSES[class]));
            }
            sources.push((class, g, Vec::new(), 0));
        }
        Ok(GeneratorShapes { sources, seed })
    }

    /// The next clean whitened shape of `class` (4096 samples at 4096 Hz),
    /// or `None` when no generator draws that class.
    pub fn shape(&mut self, class: usize) -> Result<Option<Vec<f64>>, gwml_runtime::Error> {
        let seed = self.seed;
        let Some((_, g, buffer, batches)) = self.sources.iter_mut().find(|s| s.0 == class) else { return Ok(None) };
        if buffer.is_empty() {
            let batch_seed = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ ((class as u64) << 32) ^ *batches;
            *buffer = g.sample(SHAPE_BATCH, batch_seed).map_err(gwml_runtime::Error::Bind)?.rows;
            buffer.reverse();
            *batches += 1;
        }
        Ok(buffer.pop())
    }
}

/// Example glitches: whitened rows as a detector sees them, and, when the
/// file holds them, the same glitches without noise.
pub struct Examples {
    /// Rows of 4096 whitened samples (glitch plus noise).
    pub noisy: Vec<Vec<f64>>,
    /// The glitches alone, row for row (array `clean` of the file).
    pub clean: Option<Vec<Vec<f64>>>,
}

/// The example rows of a dataset file: `x` (and `clean`, if present), cut
/// to the family's rows when a `label` array is present; a single `.npy`
/// array is taken as the rows.
pub fn read_examples(path: &Path, class: usize) -> Result<Examples, String> {
    let ds = Dataset::read(path).map_err(render)?;
    let x = match ds.arrays.get("x") {
        Some(x) => x,
        None if ds.arrays.len() == 1 => ds.arrays.values().next().expect("one array"),
        None => return Err(format!("error: {} has no array `x` of examples", path.display())),
    };
    if x.shape.len() != 2 || x.row_len() != SAMPLES {
        return Err(format!(
            "error: {}: the examples must be rows of {SAMPLES} whitened samples (1 s at 4096 Hz), got shape {:?}",
            path.display(),
            x.shape
        ));
    }
    let labels = ds.arrays.get("label").filter(|l| l.rows() == x.rows());
    let keep: Vec<usize> = (0..x.rows()).filter(|i| labels.is_none_or(|l| l.data[*i] == class as f64)).collect();
    let clean = match ds.arrays.get("clean") {
        Some(c) if c.shape != x.shape => {
            return Err(format!("error: {}: `clean` has shape {:?} but `x` has {:?}", path.display(), c.shape, x.shape));
        }
        Some(c) => Some(keep.iter().map(|&i| c.row(i).to_vec()).collect()),
        None => None,
    };
    Ok(Examples { noisy: keep.iter().map(|&i| x.row(i).to_vec()).collect(), clean })
}

/// Quantiles of `xs` at the given fractions (nearest rank).
pub fn quantiles(xs: &[f64], at: &[f64]) -> Vec<f64> {
    let mut v: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    at.iter().map(|q| v.get(((v.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(f64::NAN)).collect()
}

/// The examples of `gwml generator fit`: the file's rows of the family, or
/// `--n` draws of the library's own.
fn examples(a: &GeneratorFitArgs, class: usize) -> Result<Examples, String> {
    match &a.examples {
        Some(path) => read_examples(path, class),
        None => {
            let (lo, hi) = parse_range(&a.snr)?;
            // Every family at the stated SNR, Koi Fish included.
            let options = GlitchOptions { n: a.n, seed: a.seed, snr: Some((lo, hi)), class: Some(class), ..Default::default() };
            let ds = glitches(&options).map_err(render)?;
            let x = &ds.arrays["x"];
            Ok(Examples { noisy: (0..x.rows()).map(|i| x.row(i).to_vec()).collect(), clean: None })
        }
    }
}

/// `gwml generator fit`.
pub fn fit_command(a: GeneratorFitArgs) -> Result<(), String> {
    let class = a.family.label();
    let examples = examples(&a, class)?;
    if !(0.0..0.9).contains(&a.holdout) {
        return Err(format!("error: --holdout must be a fraction in [0, 0.9), got {}", a.holdout));
    }
    let held = (a.holdout * examples.noisy.len() as f64).round() as usize;
    let fitted = examples.noisy.len() - held;
    let held_clean = match (&examples.clean, held) {
        (_, 0) => None,
        (Some(clean), _) => Some(&clean[fitted..]),
        (None, _) => {
            return Err("error: --holdout measures realism against the held-out examples' clean shapes: the examples file needs an array \
                        `clean` (the glitches without noise, row for row)"
                .into())
        }
    };
    let threads = a.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())).max(1);
    let rows = &examples.noisy[..fitted];
    match a.kind {
        Kind::Parametric => parametric::fit_command(&a, class, rows, threads)?,
        Kind::Learned => learned::fit_command(&a, class, rows, threads)?,
    }
    if let Some(held_out) = held_clean {
        let g = Generator::read(&a.out)?;
        let draws = g.sample(held_out.len(), a.seed.wrapping_add(1))?.rows;
        let mut line = format!("realism on {} held-out examples (two-sample accuracy; 0.5 = indistinguishable):", held_out.len());
        for snr in REALISM_SNRS {
            let o = realism::TwoSampleOptions { snr, seed: a.seed, epochs: 40, threads };
            let acc = realism::two_sample_accuracy(&draws, held_out, &o).map_err(render)?;
            line += &format!(" SNR {snr}: {acc:.3};");
        }
        println!("{}", line.trim_end_matches(';'));
        println!("{:<20} {:>30} {:>30} {:>6}", "property", "held out: median [5%, 95%]", "draws: median [5%, 95%]", "KS");
        for d in realism::feature_distances(held_out, &draws) {
            let q = |x: [f64; 3]| format!("{:.4} [{:.4}, {:.4}]", x[1], x[0], x[2]);
            println!("{:<20} {:>30} {:>30} {:>6.3}", d.name, q(d.quantiles[0]), q(d.quantiles[1]), d.ks);
        }
    }
    Ok(())
}

/// The SNRs `--holdout` measures realism at (issue #30's).
const REALISM_SNRS: [f64; 2] = [20.0, 40.0];

/// `gwml generator sample`.
pub fn sample_command(a: GeneratorSampleArgs) -> Result<(), String> {
    let g = Generator::read(&a.model)?;
    let start = std::time::Instant::now();
    let Draws { mut rows, names, params: draws } = g.sample(a.n, a.seed).map_err(|e| format!("error: {e}"))?;
    let seconds = start.elapsed().as_secs_f64();
    if a.noise {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(a.seed.wrapping_add(1));
        for row in &mut rows {
            row.iter_mut().for_each(|v| *v += Distribution::<f64>::sample(&StandardNormal, &mut rng));
        }
    }
    let mut arrays = BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![a.n, SAMPLES], rows.concat()).map_err(render)?);
    for (i, name) in names.iter().enumerate() {
        arrays.insert(name.clone(), Array::new(vec![a.n], draws.iter().map(|d| d[i]).collect()).map_err(render)?);
    }
    dataset::write_npz(&a.out, &Dataset { arrays }).map_err(render)?;
    println!(
        "drew {} glitches in {seconds:.2} s ({:.0} per second); wrote {}: x ({} × {SAMPLES}, whitened, 4096 Hz{}), and the drawn {}",
        a.n,
        a.n as f64 / seconds.max(1e-9),
        a.out.display(),
        a.n,
        if a.noise { ", in white noise" } else { "" },
        names.join(", ")
    );
    if let Some(path) = &a.plot {
        let shown = &rows[..rows.len().min(6)];
        let spacing = 2.2 * shown.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
        let times: Vec<f64> = (0..SAMPLES).map(|j| j as f64 / SAMPLE_RATE).collect();
        let offset: Vec<Vec<f64>> = shown.iter().enumerate().map(|(k, r)| r.iter().map(|v| v - spacing * k as f64).collect()).collect();
        let labels: Vec<String> = draws
            .iter()
            .take(shown.len())
            .map(|d| names.iter().zip(d).filter(|(n, _)| *n != "t0").map(|(n, v)| format!("{n} {v:.3}")).collect::<Vec<_>>().join(", "))
            .collect();
        let series: Vec<(&str, &[f64], &[f64])> =
            labels.iter().zip(&offset).map(|(l, y)| (l.as_str(), times.as_slice(), y.as_slice())).collect();
        let title = format!("{} generator: {} draws (seed {})", GLITCH_CLASSES[g.class()?], shown.len(), a.seed);
        lines_plot(path, &title, "time (s)", "whitened strain, offset per draw", &series)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
