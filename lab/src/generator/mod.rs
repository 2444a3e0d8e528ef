//! `gwml generator`: the glitch generator of the pipeline, which draws new
//! whitened glitches like the examples it was fitted to. Two kinds:
//! [`learned`] (a class-conditional variational autoencoder written in
//! `lab/models/glitch/vae.gw` and trained by gwml's trainer: it learns the
//! examples' shapes, for every class it is given) and [`parametric`] (a multivariate normal over the
//! params of one `std::glitch` formula, estimated from each example by
//! matched filtering: it can only draw that formula). This module owns the
//! command line, the example files and the draws' output.

pub mod learned;
pub mod parametric;
pub mod realism;

use crate::parse_range;
use crate::plot::lines_plot;
use crate::render;
use crate::synth::{glitch_class, glitches, GlitchClass, GlitchOptions, GLITCH_CLASSES};
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
    /// Fit a generator to example glitches: a variational autoencoder
    /// conditioned on the class, trained on the examples of every class
    /// asked for (--kind learned), or a multivariate normal over one
    /// family formula's params estimated from each example by matched
    /// filtering (--kind parametric). Writes the generator as JSON.
    Fit(GeneratorFitArgs),
    /// Draw whitened glitches from a fitted generator into an .npz (`x`,
    /// n × 4096, `label`, and one array per drawn param).
    Sample(GeneratorSampleArgs),
}

#[derive(clap::Args)]
pub struct GeneratorFitArgs {
    /// The glitch families to model, comma-separated (e.g. blip or
    /// blip,whistle) [default: every class in the examples' `label` array;
    /// without --examples, every glitch class of the library]. The learned
    /// generator models them all, conditioned on the class; the parametric
    /// one models one family.
    #[arg(long, value_enum, value_delimiter = ',')]
    pub family: Vec<GlitchClass>,
    /// What the generator is: a variational autoencoder that learns the
    /// shapes of the examples, or a distribution over the params of the
    /// family's `std::glitch` formula (the baseline).
    #[arg(long, value_enum, default_value_t = Kind::Learned)]
    pub kind: Kind,
    /// Training epochs of the learned generator (the realism tables of
    /// `results/generator/realism/` are at 150; 200 measured no better).
    #[arg(long, default_value_t = 150)]
    pub epochs: usize,
    /// Hold this fraction of each class's examples (its last rows) out of
    /// the fit and measure the generator's realism against them: a classifier
    /// two-sample test of draws against their clean shapes (array `clean`
    /// of the examples file) at SNR 20 and 40.
    #[arg(long, default_value_t = 0.0)]
    pub holdout: f64,
    /// Example glitches: an .npz with `x` (rows of 4096 whitened samples at
    /// 4096 Hz) and optionally `label` (each row's class: 0–7 are the
    /// library's classes in `gwml data glitch` order, 8–15 any others; only
    /// the rows of --family are used), or an .npy of such rows; without
    /// labels, the rows are of the one --family [default: draw --n examples
    /// of each family as `gwml data glitch --class FAMILY --snr LO..HI`
    /// does].
    #[arg(long, value_name = "PATH")]
    pub examples: Option<PathBuf>,
    /// Examples per family to draw when --examples is not given.
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
    /// The class to draw, by name (blip, koi_fish, ...) or label (0–15)
    /// [default: every class the generator models, in proportion to its
    /// training examples].
    #[arg(long, value_name = "CLASS")]
    pub class: Option<String>,
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
    /// Each row's class label.
    pub labels: Vec<usize>,
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

    /// The class labels it draws.
    pub fn classes(&self) -> Result<Vec<usize>, String> {
        match self {
            Generator::Learned(g) => Ok(g.class_labels()),
            Generator::Parametric(g) => Ok(vec![g.class()?]),
        }
    }

    /// Draws `n` whitened glitches of `class`, or of any of its classes
    /// when `None` (the same seed draws the same glitches).
    pub fn sample(&self, n: usize, seed: u64, class: Option<usize>) -> Result<Draws, String> {
        match self {
            Generator::Learned(g) => g.sample(n, seed, class).map_err(render),
            Generator::Parametric(g) => match class {
                Some(c) if c != g.class()? => Err(format!("this generator draws {}, not {}", class_name(g.class()?), class_name(c))),
                _ => g.sample(n, seed),
            },
        }
    }
}

/// The name of class label `class`: the library's name for labels 0–7
/// (`GLITCH_CLASSES`), `class N` for others.
pub fn class_name(class: usize) -> String {
    GLITCH_CLASSES.get(class).map_or_else(|| format!("class {class}"), |n| n.to_string())
}

/// The label of a class given by name or by number (0–15), or why there is none.
pub fn parse_class(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(k) if k < learned::CLASS_SLOTS => Ok(k),
        Ok(k) => Err(format!("class label {k}: labels go from 0 to {}", learned::CLASS_SLOTS - 1)),
        Err(_) => glitch_class(text),
    }
}

/// Glitch shapes for `gwml data glitch|strain --generator`: fitted
/// generators, at most one per class, drawn in batches as rows are needed.
pub struct GeneratorShapes {
    generators: Vec<Generator>,
    sources: Vec<ShapeSource>,
    seed: u64,
    /// The chance that a row of a generated class takes the generator's
    /// shape (otherwise its formula's or a real fit's).
    share: f64,
    /// Decides each row's source, on a stream of its own.
    pick: rand_pcg::Pcg64Mcg,
}

/// Where [`GeneratorShapes`] draws one class from, and its drawn rows not
/// yet handed out.
struct ShapeSource {
    class: usize,
    generator: usize,
    buffer: Vec<Vec<f64>>,
    batches: u64,
}

/// Glitch shapes a [`GeneratorShapes`] draws at a time.
const SHAPE_BATCH: usize = 256;

impl GeneratorShapes {
    /// Reads the generator files (at most one per class); `seed` seeds the
    /// draws; `share` (in 0..=1) is the chance that a row of a generated
    /// class takes the generator's shape.
    pub fn open(paths: &[PathBuf], seed: u64, share: f64) -> Result<GeneratorShapes, String> {
        if !(0.0..=1.0).contains(&share) {
            return Err(format!("error: the generator share {share} must be within 0..1"));
        }
        let (mut generators, mut sources) = (Vec::new(), Vec::<ShapeSource>::new());
        for path in paths {
            let g = Generator::read(path)?;
            for class in g.classes()? {
                if sources.iter().any(|s| s.class == class) {
                    return Err(format!("error: two --generator files draw {}: give one per class", class_name(class)));
                }
                sources.push(ShapeSource { class, generator: generators.len(), buffer: Vec::new(), batches: 0 });
            }
            generators.push(g);
        }
        let pick = rand::SeedableRng::seed_from_u64(seed ^ 0x5EED_5A4E);
        Ok(GeneratorShapes { generators, sources, seed, share, pick })
    }

    /// The next clean whitened shape of `class` (4096 samples at 4096 Hz),
    /// or `None` when no generator draws that class.
    pub fn shape(&mut self, class: usize) -> Result<Option<Vec<f64>>, gwml_runtime::Error> {
        let seed = self.seed;
        let Some(s) = self.sources.iter_mut().find(|s| s.class == class) else { return Ok(None) };
        if self.share < 1.0 && !rand::Rng::random_bool(&mut self.pick, self.share) {
            return Ok(None);
        }
        if s.buffer.is_empty() {
            let batch_seed = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ ((class as u64) << 32) ^ s.batches;
            let g = &self.generators[s.generator];
            s.buffer = g.sample(SHAPE_BATCH, batch_seed, Some(class)).map_err(gwml_runtime::Error::Bind)?.rows;
            s.buffer.reverse();
            s.batches += 1;
        }
        Ok(s.buffer.pop())
    }
}

/// Example glitches: whitened rows as a detector sees them, and, when the
/// file holds them, the same glitches without noise.
pub struct Examples {
    /// Rows of 4096 whitened samples (glitch plus noise).
    pub noisy: Vec<Vec<f64>>,
    /// The glitches alone, row for row (array `clean` of the file).
    pub clean: Option<Vec<Vec<f64>>>,
    /// Each row's class label.
    pub labels: Vec<usize>,
}

/// The example rows of a dataset file: `x` (and `clean`, if present), with
/// each row's class from its `label` array, cut to the rows of `families`
/// (all rows when it is empty); without labels, every row is of the one
/// family in `families`. A single `.npy` array is taken as the rows.
pub fn read_examples(path: &Path, families: &[usize]) -> Result<Examples, String> {
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
    let labels: Vec<usize> = match (ds.arrays.get("label"), families) {
        (Some(l), _) => {
            if l.rows() != x.rows() || l.row_len() != 1 {
                return Err(format!(
                    "error: {}: `label` must hold one class per row of `x` ({} rows), got shape {:?}",
                    path.display(),
                    x.rows(),
                    l.shape
                ));
            }
            l.data
                .iter()
                .enumerate()
                .map(|(i, v)| match *v {
                    v if v >= 0.0 && v.fract() == 0.0 && v < learned::CLASS_SLOTS as f64 => Ok(v as usize),
                    v => Err(format!(
                        "error: {}: `label` row {i} is {v}: labels are class numbers 0–{}",
                        path.display(),
                        learned::CLASS_SLOTS - 1
                    )),
                })
                .collect::<Result<_, _>>()?
        }
        (None, [family]) => vec![*family; x.rows()],
        (None, _) => {
            return Err(format!(
                "error: {} has no `label` array: name the one family of its rows with --family (e.g. --family blip)",
                path.display()
            ))
        }
    };
    let keep: Vec<usize> = (0..x.rows()).filter(|i| families.is_empty() || families.contains(&labels[*i])).collect();
    if keep.is_empty() {
        let names: Vec<String> = families.iter().map(|c| class_name(*c)).collect();
        let mut present = labels.clone();
        present.sort_unstable();
        present.dedup();
        let present: Vec<String> = present.into_iter().map(|c| format!("{c} ({})", class_name(c))).collect();
        return Err(format!(
            "error: {} has no examples of {}: its `label` array holds {} (labels 0–7 are the classes of `gwml data glitch`, in its order)",
            path.display(),
            names.join(" or "),
            present.join(", ")
        ));
    }
    let clean = match ds.arrays.get("clean") {
        Some(c) if c.shape != x.shape => {
            return Err(format!("error: {}: `clean` has shape {:?} but `x` has {:?}", path.display(), c.shape, x.shape));
        }
        Some(c) => Some(keep.iter().map(|&i| c.row(i).to_vec()).collect()),
        None => None,
    };
    Ok(Examples { noisy: keep.iter().map(|&i| x.row(i).to_vec()).collect(), clean, labels: keep.iter().map(|&i| labels[i]).collect() })
}

/// Quantiles of `xs` at the given fractions (nearest rank).
pub fn quantiles(xs: &[f64], at: &[f64]) -> Vec<f64> {
    let mut v: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    at.iter().map(|q| v.get(((v.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(f64::NAN)).collect()
}

/// The examples of `gwml generator fit`: the file's rows of the families,
/// or `--n` draws of each family of the library's own.
fn examples(a: &GeneratorFitArgs, families: &[usize]) -> Result<Examples, String> {
    match &a.examples {
        Some(path) => read_examples(path, families),
        None => {
            let (lo, hi) = parse_range(&a.snr)?;
            let all: Vec<usize> = (1..GLITCH_CLASSES.len()).collect();
            let mut e = Examples { noisy: Vec::new(), clean: None, labels: Vec::new() };
            for &class in if families.is_empty() { &all } else { families } {
                // Every family at the stated SNR, Koi Fish included.
                let options = GlitchOptions { n: a.n, seed: a.seed, snr: Some((lo, hi)), class: Some(class), ..Default::default() };
                let ds = glitches(&options).map_err(render)?;
                let x = &ds.arrays["x"];
                e.noisy.extend((0..x.rows()).map(|i| x.row(i).to_vec()));
                e.labels.extend(std::iter::repeat_n(class, x.rows()));
            }
            Ok(e)
        }
    }
}

/// `gwml generator fit`.
pub fn fit_command(a: GeneratorFitArgs) -> Result<(), String> {
    let families: Vec<usize> = a.family.iter().map(|f| f.label()).collect();
    if a.kind == Kind::Parametric && families.len() != 1 {
        return Err("error: the parametric generator models one family: name it with --family (e.g. --family blip)".into());
    }
    if !(0.0..0.9).contains(&a.holdout) {
        return Err(format!("error: --holdout must be a fraction in [0, 0.9), got {}", a.holdout));
    }
    let examples = examples(&a, &families)?;
    let mut classes = examples.labels.clone();
    classes.sort_unstable();
    classes.dedup();
    // Each class's last rows are held out.
    let (mut fitted, mut held): (Vec<usize>, Vec<(usize, Vec<usize>)>) = (Vec::new(), Vec::new());
    for &class in &classes {
        let rows: Vec<usize> = (0..examples.labels.len()).filter(|&i| examples.labels[i] == class).collect();
        let n_held = (a.holdout * rows.len() as f64).round() as usize;
        fitted.extend_from_slice(&rows[..rows.len() - n_held]);
        if n_held > 0 {
            held.push((class, rows[rows.len() - n_held..].to_vec()));
        }
    }
    fitted.sort_unstable();
    let clean = match (&examples.clean, held.is_empty()) {
        (_, true) => None,
        (Some(clean), false) => Some(clean),
        (None, false) => {
            return Err("error: --holdout measures realism against the held-out examples' clean shapes: the examples file needs an array \
                        `clean` (the glitches without noise, row for row)"
                .into())
        }
    };
    let threads = a.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())).max(1);
    let rows: Vec<Vec<f64>> = fitted.iter().map(|&i| examples.noisy[i].clone()).collect();
    let labels: Vec<usize> = fitted.iter().map(|&i| examples.labels[i]).collect();
    match a.kind {
        Kind::Parametric => parametric::fit_command(&a, families[0], &rows, threads)?,
        Kind::Learned => learned::fit_command(&a, &rows, &labels, threads)?,
    }
    if let Some(clean) = clean {
        let g = Generator::read(&a.out)?;
        for (class, rows) in &held {
            let held_out: Vec<Vec<f64>> = rows.iter().map(|&i| clean[i].clone()).collect();
            let draws = g.sample(held_out.len(), a.seed.wrapping_add(1), Some(*class))?.rows;
            let mut line = format!(
                "realism on {} held-out {} examples (two-sample accuracy; 0.5 = indistinguishable):",
                held_out.len(),
                class_name(*class)
            );
            for snr in REALISM_SNRS {
                let o = realism::TwoSampleOptions { snr, seed: a.seed, epochs: 40, threads };
                let acc = realism::two_sample_accuracy(&draws, &held_out, &o).map_err(render)?;
                line += &format!(" SNR {snr}: {acc:.3};");
            }
            println!("{}", line.trim_end_matches(';'));
            println!("{:<20} {:>30} {:>30} {:>6}", "property", "held out: median [5%, 95%]", "draws: median [5%, 95%]", "KS");
            for d in realism::feature_distances(&held_out, &draws) {
                let q = |x: [f64; 3]| format!("{:.4} [{:.4}, {:.4}]", x[1], x[0], x[2]);
                println!("{:<20} {:>30} {:>30} {:>6.3}", d.name, q(d.quantiles[0]), q(d.quantiles[1]), d.ks);
            }
        }
    }
    Ok(())
}

/// The SNRs `--holdout` measures realism at (issue #30's).
const REALISM_SNRS: [f64; 2] = [20.0, 40.0];

/// `gwml generator sample`.
pub fn sample_command(a: GeneratorSampleArgs) -> Result<(), String> {
    let g = Generator::read(&a.model)?;
    let class = a.class.as_deref().map(parse_class).transpose().map_err(|e| format!("error: --class: {e}"))?;
    let start = std::time::Instant::now();
    let Draws { mut rows, labels, names, params: draws } =
        g.sample(a.n, a.seed, class).map_err(|e| format!("error: {}: {e}", a.model.display()))?;
    let seconds = start.elapsed().as_secs_f64();
    if a.noise {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(a.seed.wrapping_add(1));
        for row in &mut rows {
            row.iter_mut().for_each(|v| *v += Distribution::<f64>::sample(&StandardNormal, &mut rng));
        }
    }
    let mut arrays = BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![a.n, SAMPLES], rows.concat()).map_err(render)?);
    arrays.insert("label".to_string(), Array::new(vec![a.n], labels.iter().map(|&l| l as f64).collect()).map_err(render)?);
    for (i, name) in names.iter().enumerate() {
        arrays.insert(name.clone(), Array::new(vec![a.n], draws.iter().map(|d| d[i]).collect()).map_err(render)?);
    }
    dataset::write_npz(&a.out, &Dataset { arrays }).map_err(render)?;
    println!(
        "drew {} glitches in {seconds:.2} s ({:.0} per second); wrote {}: x ({} × {SAMPLES}, whitened, 4096 Hz{}), label, and the drawn {}",
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
        let legends: Vec<String> = draws
            .iter()
            .zip(&labels)
            .take(shown.len())
            .map(|(d, l)| {
                let values = names.iter().zip(d).filter(|(n, _)| *n != "t0").map(|(n, v)| format!("{n} {v:.3}"));
                std::iter::once(class_name(*l)).chain(values).collect::<Vec<_>>().join(", ")
            })
            .collect();
        let series: Vec<(&str, &[f64], &[f64])> =
            legends.iter().zip(&offset).map(|(l, y)| (l.as_str(), times.as_slice(), y.as_slice())).collect();
        let mut drawn: Vec<usize> = labels.iter().take(shown.len()).copied().collect();
        drawn.sort_unstable();
        drawn.dedup();
        let names: Vec<String> = drawn.into_iter().map(class_name).collect();
        let title = format!("{} generator: {} draws (seed {})", names.join(" + "), shown.len(), a.seed);
        lines_plot(path, &title, "time (s)", "whitened strain, offset per draw", &series)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
