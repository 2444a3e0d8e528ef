//! The learned glitch generator (issue #30, `gwml generator fit --kind
//! learned`): a variational autoencoder over whitened glitch examples,
//! conditioned on their class, written in `lab/models/glitch/vae.gw` and
//! trained by gwml's own [`Trainer`]. One network models every class it is
//! fitted to; each class keeps its own band, centre times and latent
//! posteriors ([`ClassPart`]).
//!
//! Fitting: each example is centred on its excess energy ([`energy_centre`],
//! a circular shift, which keeps white noise white), so the network learns
//! shapes rather than positions; each class's band is read off its
//! examples' mean power ([`family_band`]) and the decoder's output for the
//! class is confined to it; the VAE is trained on the centred rows by
//! Adam, its loss the negative evidence lower bound with the whitened-data
//! likelihood ½‖x − decoder(z, class)‖². The generator keeps the decoder's
//! weights and, per class, the band and the examples' centre times.
//!
//! Sampling a class: z from the encoder's posterior of a random training
//! example of the class (the class's aggregate posterior), through the
//! compiled `sample` scene (the decoder alone), each draw shifted to a
//! centre time drawn from the class's examples'.

use super::{class_name, quantiles, Draws, GeneratorFitArgs, SAMPLES, SAMPLE_RATE};
use crate::render;
use gwml_runtime::checkpoint::{self, Checkpoint, Tensor};
use gwml_runtime::dataset::{Array, Dataset};
use gwml_runtime::optim::{Method, OptimConfig, Schedule};
use gwml_runtime::train::{EpochReport, TrainOptions, Trainer};
use gwml_runtime::{Error, Model, Value};
use indicatif::{ProgressBar, ProgressStyle};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use realfft::RealFftPlanner;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The variational autoencoder: scenes `train` and `sample`.
pub const VAE_SOURCE: &str = include_str!("../../models/glitch/vae.gw");

/// Dimensions of the latent space (the `latent` grid of `vae.gw`).
pub const LATENT: usize = 16;

/// Class slots of the VAE's `onehot` input (the `classes` grid of
/// `vae.gw`): class labels 0–15, the library's and any others.
pub const CLASS_SLOTS: usize = 16;

/// Samples of the moving average of the squared data that locates a glitch
/// (15.6 ms at 4096 Hz).
const SMOOTHING: usize = 64;

/// Examples per Adam step.
const BATCH: usize = 16;

/// Adam's initial learning rate (decayed along a cosine to 5 % of it).
const LEARNING_RATE: f64 = 2e-3;

/// A fitted learned generator.
#[derive(Clone, Debug, PartialEq)]
pub struct LearnedGenerator {
    /// The classes it draws, in label order.
    pub classes: Vec<ClassPart>,
    /// The decoder's weight tensors, by scene input name (`decoder.k1`, ...).
    pub weights: Vec<(String, Vec<f64>)>,
    /// Training epochs.
    pub epochs: usize,
    /// Mean negative ELBO per example after the last epoch.
    pub final_loss: f64,
}

/// What a learned generator keeps of one class's training examples.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassPart {
    /// The class label (an index of `GLITCH_CLASSES` for the library's
    /// classes; any label below [`CLASS_SLOTS`]).
    pub class: usize,
    /// The examples' centre times in seconds from the start of their row.
    pub centres: Vec<f64>,
    /// The band (Hz) the decoder's output for the class is confined to:
    /// [`family_band`] of its examples.
    pub band: (f64, f64),
    /// The encoder's posterior over the latent space for each training
    /// example: its mean and standard deviations ([`LATENT`] each). Draws
    /// come from their mixture, the aggregate posterior, which is where the
    /// decoder was trained (sampling the prior N(0, I) instead, or one
    /// Gaussian fitted to the means, leaves holes: Ghosh et al. 2020,
    /// arXiv:1903.12436).
    pub posteriors: Vec<Posterior>,
}

/// The encoder's diagonal Gaussian posterior for one example: means and
/// standard deviations over the latent space.
pub type Posterior = (Vec<f64>, Vec<f64>);

/// Settings of [`fit`].
#[derive(Clone, Copy, Debug)]
pub struct LearnedOptions {
    /// Passes over the examples.
    pub epochs: usize,
    /// Seed of the shuffles and the reparameterisation noise.
    pub seed: u64,
    /// Worker threads.
    pub threads: usize,
}

/// Where the excess energy of whitened `x` is centred, in seconds from its
/// start: the energy-weighted mean time of the moving average of x² above
/// what unit-variance noise reaches (its mean plus four standard
/// deviations); the loudest moment when nothing rises above that.
pub fn energy_centre(x: &[f64]) -> f64 {
    let n = x.len();
    let half = SMOOTHING / 2;
    let mut prefix = vec![0.0; n + 1];
    for (i, v) in x.iter().enumerate() {
        prefix[i + 1] = prefix[i] + v * v;
    }
    let smooth: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half).min(n));
            (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect();
    let floor = 1.0 + 4.0 * (2.0 / SMOOTHING as f64).sqrt();
    let (mut sum, mut weighted) = (0.0, 0.0);
    for (i, s) in smooth.iter().enumerate() {
        let w = (s - floor).max(0.0);
        sum += w;
        weighted += w * i as f64;
    }
    let at = if sum > 0.0 {
        weighted / sum
    } else {
        smooth.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).map_or(n as f64 / 2.0, |(i, _)| i as f64)
    };
    at / SAMPLE_RATE
}

/// The band of the whitening (Hz): the widest a generator's band can be.
pub const WHITENED_BAND: (f64, f64) = (20.0, 2000.0);

/// The family's band (Hz) as whitened examples `rows` show it: the span of
/// the frequencies where their mean power, smoothed over 17 bins (1 Hz
/// each), rises above white noise's by more than four standard deviations
/// of that mean, widened by a quarter (and 16 Hz) on each side and kept
/// within [`WHITENED_BAND`]; the whole of it when no frequency does.
/// Outside the family's band the examples hold only noise, which the
/// decoder would otherwise learn example by example (issue #30: the draws'
/// spectra were eight times too broad). The widening keeps a broadband
/// family's weak high-frequency tail, which a 350-example mean cannot show
/// above noise (real-fit Blips: 2.9 % of their energy lies above the
/// unwidened edge, 880 Hz); widening by 0, ¼ and ½ measured alike on the
/// design sets (`results/generator/realism/design-log.txt`).
pub fn family_band(rows: &[Vec<f64>]) -> (f64, f64) {
    const HALF: usize = 8;
    let Some(n) = rows.first().map(Vec::len).filter(|n| *n > 2 * HALF + 1) else {
        return WHITENED_BAND;
    };
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut mean = vec![0.0; n / 2 + 1];
    let mut spectrum = fft.make_output_vec();
    for row in rows {
        let mut input = row.clone();
        if fft.process(&mut input, &mut spectrum).is_err() {
            return WHITENED_BAND;
        }
        for (m, c) in mean.iter_mut().zip(&spectrum) {
            // Unit-variance white noise gives 1 per bin in the mean.
            *m += c.norm_sqr() / (n as f64 * rows.len() as f64);
        }
    }
    let df = SAMPLE_RATE / n as f64;
    // Each bin's power in white noise is exponential with unit mean and
    // variance: the mean over rows and 17 bins has this deviation.
    let sigma = 1.0 / ((rows.len() * (2 * HALF + 1)) as f64).sqrt();
    let loud: Vec<f64> = (HALF..mean.len() - HALF)
        .filter(|&k| mean[k - HALF..=k + HALF].iter().sum::<f64>() / (2 * HALF + 1) as f64 > 1.0 + 4.0 * sigma)
        .map(|k| k as f64 * df)
        .filter(|f| (WHITENED_BAND.0..=WHITENED_BAND.1).contains(f))
        .collect();
    match (loud.first(), loud.last()) {
        (Some(lo), Some(hi)) => ((lo / 1.25 - 16.0).max(WHITENED_BAND.0), (hi * 1.25 + 16.0).min(WHITENED_BAND.1)),
        _ => WHITENED_BAND,
    }
}

/// The 0/1 mask over the `sample` and `train` scenes' frequency grid (1 Hz
/// bins from 0 to 2048 Hz) that is 1 within `band`.
fn passband(band: (f64, f64)) -> Vec<f64> {
    let df = SAMPLE_RATE / SAMPLES as f64;
    (0..=SAMPLES / 2).map(|k| if (band.0..=band.1).contains(&(k as f64 * df)) { 1.0 } else { 0.0 }).collect()
}

/// The `onehot` input of class `class`.
fn onehot(class: usize) -> Vec<f64> {
    (0..CLASS_SLOTS).map(|k| if k == class { 1.0 } else { 0.0 }).collect()
}

/// `x` shifted circularly by `by` samples (positive: later).
pub fn roll(x: &[f64], by: i64) -> Vec<f64> {
    let n = x.len() as i64;
    (0..n).map(|i| x[(i - by).rem_euclid(n) as usize]).collect()
}

/// The row of `x` centred: its [`energy_centre`] moved to the middle.
pub fn centred(x: &[f64]) -> (Vec<f64>, f64) {
    let c = energy_centre(x);
    let by = ((0.5 - c) * SAMPLE_RATE).round() as i64;
    (roll(x, by), c)
}

/// The VAE's model (`lab/models/glitch/vae.gw`).
pub fn vae_model() -> Result<Model, Error> {
    Model::from_source("lab/models/glitch/vae.gw", VAE_SOURCE)
}

/// Trains the VAE on `examples` (rows of 4096 whitened samples), example
/// `i` of class `labels[i]`; `on_epoch` sees each epoch's report.
pub fn fit(
    examples: &[Vec<f64>],
    labels: &[usize],
    o: LearnedOptions,
    on_epoch: impl FnMut(&EpochReport),
) -> Result<(LearnedGenerator, Vec<EpochReport>), Error> {
    if examples.len() < 2 {
        return Err(Error::Bind(format!("{} examples are too few to train a generator", examples.len())));
    }
    if labels.len() != examples.len() {
        return Err(Error::Bind(format!("{} labels for {} examples", labels.len(), examples.len())));
    }
    if let Some(bad) = labels.iter().find(|l| **l >= CLASS_SLOTS) {
        return Err(Error::Bind(format!("class label {bad}: the generator models class labels 0–{}", CLASS_SLOTS - 1)));
    }
    let (rows, centres): (Vec<Vec<f64>>, Vec<f64>) = examples.iter().map(|x| centred(x)).unzip();
    let mut classes: Vec<usize> = labels.to_vec();
    classes.sort_unstable();
    classes.dedup();
    let of_class = |c: usize| (0..rows.len()).filter(move |&i| labels[i] == c);
    let bands: Vec<(f64, f64)> = classes.iter().map(|&c| family_band(&of_class(c).map(|i| rows[i].clone()).collect::<Vec<_>>())).collect();
    let masks: Vec<Vec<f64>> = bands.iter().map(|b| passband(*b)).collect();
    let slot = |i: usize| classes.binary_search(&labels[i]).expect("a class of the examples");
    // The trainer takes a scene's data inputs row by row: each row's class
    // and its class's band.
    let row_masks: Vec<&[f64]> = (0..rows.len()).map(|i| masks[slot(i)].as_slice()).collect();
    let row_onehots: Vec<Vec<f64>> = labels.iter().map(|&c| onehot(c)).collect();
    let mut arrays = BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![rows.len(), SAMPLES], rows.concat())?);
    arrays.insert("passband".to_string(), Array::new(vec![rows.len(), SAMPLES / 2 + 1], row_masks.concat())?);
    arrays.insert("onehot".to_string(), Array::new(vec![rows.len(), CLASS_SLOTS], row_onehots.concat())?);
    let data = Dataset { arrays };
    let model = vae_model()?;
    let scene = model.scene(Some("train"))?;
    let steps = (o.epochs * rows.len().div_ceil(BATCH)).max(1) as u64;
    let options = TrainOptions {
        loss: "loss".into(),
        logits: String::new(),
        label: String::new(),
        epochs: o.epochs,
        batch: BATCH,
        optim: OptimConfig {
            method: Method::adam(),
            lr: LEARNING_RATE,
            schedule: Schedule::Cosine { total: steps, min_lr: 0.05 * LEARNING_RATE },
            clip_norm: Some(100.0),
        },
        seed: o.seed,
        threads: o.threads,
        patience: None,
        checkpoint_dir: None,
    };
    let mut trainer = Trainer::new(&scene, options)?;
    let reports = trainer.fit(&data, None, |_, _| {}, on_epoch)?;
    let all = trainer.weights();
    let mut parts = Vec::with_capacity(classes.len());
    for (k, &class) in classes.iter().enumerate() {
        let members: Vec<usize> = of_class(class).collect();
        let class_rows: Vec<&[f64]> = members.iter().map(|&i| rows[i].as_slice()).collect();
        parts.push(ClassPart {
            class,
            centres: members.iter().map(|&i| centres[i]).collect(),
            band: bands[k],
            posteriors: latent_posteriors(&scene, &all, &class_rows, class, &masks[k])?,
        });
    }
    let weights = all.into_iter().filter(|(name, _)| name.starts_with("decoder.")).collect();
    let final_loss = reports.last().map_or(f64::NAN, |r| r.train_loss);
    Ok((LearnedGenerator { classes: parts, weights, epochs: o.epochs, final_loss }, reports))
}

/// The encoder's posterior (means, standard deviations) for each of `rows`,
/// examples of class `class` (band-passed to `passband`).
fn latent_posteriors(
    scene: &gwml_runtime::Scene,
    weights: &[(String, Vec<f64>)],
    rows: &[&[f64]],
    class: usize,
    passband: &[f64],
) -> Result<Vec<Posterior>, Error> {
    let mut run = scene.bind();
    for (name, w) in weights {
        run.input_real(name, w)?;
    }
    run.input_real("passband", passband)?;
    run.input_real("onehot", &onehot(class))?;
    let mut out = Vec::with_capacity(rows.len());
    for x in rows {
        run.input_real("x", x)?;
        let o = run.forward()?;
        match (o.value("latent_mean")?, o.value("latent_logvar")?) {
            (Value::RealArray(m), Value::RealArray(lv)) => out.push((m.clone(), lv.iter().map(|v| (0.5 * v).exp()).collect())),
            _ => return Err(Error::Bind("the VAE's latent mean and log-variance are not real arrays".into())),
        }
    }
    Ok(out)
}

impl LearnedGenerator {
    /// The class labels it draws.
    pub fn class_labels(&self) -> Vec<usize> {
        self.classes.iter().map(|p| p.class).collect()
    }

    /// Draws `n` glitches of `class`, or of its classes in proportion to
    /// their training examples when `class` is `None`: the decoder at
    /// latents from the class's aggregate posterior, each shifted to a
    /// centre time drawn from the class's examples'. The per-row values are
    /// `t0` (the centre, s) and `snr` (the draw's norm).
    pub fn sample(&self, n: usize, seed: u64, class: Option<usize>) -> Result<Draws, Error> {
        let parts: Vec<&ClassPart> = self.classes.iter().filter(|p| class.is_none_or(|c| p.class == c)).collect();
        if parts.is_empty() {
            let names: Vec<String> = self.classes.iter().map(|p| class_name(p.class)).collect();
            return Err(Error::Bind(format!(
                "this generator draws {}, not {}",
                names.join(", "),
                class.map_or_else(String::new, class_name)
            )));
        }
        let model = vae_model()?;
        let scene = model.scene(Some("sample"))?;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        let masks: Vec<Vec<f64>> = parts.iter().map(|p| passband(p.band)).collect();
        let onehots: Vec<Vec<f64>> = parts.iter().map(|p| onehot(p.class)).collect();
        // A random training example of the drawn classes picks the class,
        // so classes come in proportion to their examples.
        let examples: Vec<(usize, usize)> =
            parts.iter().enumerate().flat_map(|(k, p)| (0..p.posteriors.len()).map(move |i| (k, i))).collect();
        let plan: Vec<(usize, Vec<f64>, f64)> = (0..n)
            .map(|_| {
                let (k, i) = examples[rng.random_range(0..examples.len())];
                let (mean, sd) = &parts[k].posteriors[i];
                let z = mean.iter().zip(sd).map(|(m, s)| m + s * Distribution::<f64>::sample(&StandardNormal, &mut rng)).collect();
                (k, z, parts[k].centres[rng.random_range(0..parts[k].centres.len())])
            })
            .collect();
        let rows: Vec<Result<Vec<f64>, Error>> = plan
            .par_iter()
            .map_init(
                || {
                    let mut run = scene.bind();
                    for (name, w) in &self.weights {
                        run.input_real(name, w)?;
                    }
                    Ok((run, usize::MAX))
                },
                |bound: &mut Result<(gwml_runtime::Run, usize), Error>, (k, z, centre)| {
                    let (run, set) = bound.as_mut().map_err(|e| Error::Bind(e.to_string()))?;
                    if *set != *k {
                        run.input_real("passband", &masks[*k])?;
                        run.input_real("onehot", &onehots[*k])?;
                        *set = *k;
                    }
                    run.input_real("z", z)?;
                    let out = run.forward()?;
                    let Value::RealArray(g) = out.value("glitch")? else {
                        return Err(Error::Bind("the sample scene's `glitch` is not a real array".into()));
                    };
                    Ok(roll(g, ((centre - 0.5) * SAMPLE_RATE).round() as i64))
                },
            )
            .collect();
        let rows = rows.into_iter().collect::<Result<Vec<_>, _>>()?;
        let params = rows.iter().zip(&plan).map(|(r, (_, _, c))| vec![*c, r.iter().map(|v| v * v).sum::<f64>().sqrt()]).collect();
        let labels = plan.iter().map(|(k, _, _)| parts[*k].class).collect();
        Ok(Draws { rows, labels, names: vec!["t0".into(), "snr".into()], params })
    }

    /// The weights file beside a generator's JSON file.
    pub fn weights_path(json: &Path) -> PathBuf {
        json.with_extension("safetensors")
    }

    /// Writes the generator: JSON at `path`, the decoder's weights beside it.
    pub fn write(&self, path: &Path) -> Result<(), String> {
        let weights = Self::weights_path(path);
        let tensors =
            self.weights.iter().map(|(name, data)| Tensor { name: name.clone(), shape: vec![data.len()], data: data.clone() }).collect();
        checkpoint::save(&weights, &Checkpoint { tensors, metadata: BTreeMap::new() }).map_err(render)?;
        let classes: Vec<serde_json::Value> = self
            .classes
            .iter()
            .map(|p| {
                serde_json::json!({
                    "class": p.class,
                    "name": class_name(p.class),
                    "centres": p.centres,
                    "band_hz": [p.band.0, p.band.1],
                    "posterior_means": p.posteriors.iter().map(|q| &q.0).collect::<Vec<_>>(),
                    "posterior_sds": p.posteriors.iter().map(|q| &q.1).collect::<Vec<_>>(),
                })
            })
            .collect();
        let json = serde_json::json!({
            "kind": "learned",
            "model": "lab/models/glitch/vae.gw (embedded in gwml)",
            "latent": LATENT,
            "weights": weights.file_name().map(|f| f.to_string_lossy().into_owned()),
            "epochs": self.epochs,
            "final_loss": self.final_loss,
            "classes": classes,
        });
        let text = serde_json::to_string_pretty(&json).map_err(|e| format!("error: {e}"))?;
        std::fs::write(path, text + "\n").map_err(|e| format!("error: cannot write {}: {e}", path.display()))
    }

    /// Reads a generator written by [`LearnedGenerator::write`] from `path`
    /// (its weights from the file named beside it).
    pub fn from_json(v: &serde_json::Value, path: &Path) -> Result<LearnedGenerator, String> {
        let bad = |what: &str| format!("not a learned gwml generator: {what}");
        let entries = v["classes"].as_array().filter(|c| !c.is_empty()).ok_or_else(|| bad("no `classes`"))?;
        let mut classes: Vec<ClassPart> = Vec::with_capacity(entries.len());
        for (k, c) in entries.iter().enumerate() {
            let part = ClassPart::from_json(c).map_err(|e| bad(&format!("classes[{k}]: {e}")))?;
            if classes.iter().any(|p| p.class == part.class) {
                return Err(bad(&format!("class {} appears twice in `classes`", part.class)));
            }
            classes.push(part);
        }
        classes.sort_by_key(|p| p.class);
        let file = v["weights"].as_str().ok_or_else(|| bad("no `weights` file"))?;
        let weights_path = path.parent().unwrap_or(Path::new(".")).join(file);
        let ck = checkpoint::load(&weights_path).map_err(|e| e.render(false))?;
        let weights: Vec<(String, Vec<f64>)> = ck.tensors.into_iter().map(|t| (t.name, t.data)).collect();
        // The weights must fit the decoder gwml embeds.
        let model = vae_model().map_err(render)?;
        let scene = model.scene(Some("sample")).map_err(render)?;
        let mut run = scene.bind();
        for (name, w) in &weights {
            run.input_real(name, w).map_err(|e| format!("{}: {}", weights_path.display(), e.render(false)))?;
        }
        let missing: Vec<&str> = scene
            .ir()
            .inputs
            .iter()
            .filter(|i| i.is_weight() && !weights.iter().any(|(n, _)| *n == i.name))
            .map(|i| i.name.as_str())
            .collect();
        if !missing.is_empty() {
            return Err(format!("{}: no weights for {}", weights_path.display(), missing.join(", ")));
        }
        Ok(LearnedGenerator {
            classes,
            weights,
            epochs: v["epochs"].as_u64().unwrap_or(0) as usize,
            final_loss: v["final_loss"].as_f64().unwrap_or(f64::NAN),
        })
    }
}

impl ClassPart {
    /// Reads one entry of a learned generator's `classes`.
    fn from_json(v: &serde_json::Value) -> Result<ClassPart, String> {
        let class =
            v["class"].as_u64().filter(|c| (*c as usize) < CLASS_SLOTS).ok_or_else(|| format!("no `class` label below {CLASS_SLOTS}"))?
                as usize;
        let centres: Vec<f64> = v["centres"]
            .as_array()
            .ok_or("no `centres`")?
            .iter()
            .map(|c| c.as_f64().filter(|c| (0.0..=1.0).contains(c)).ok_or("a centre outside 0..1 s"))
            .collect::<Result<_, _>>()?;
        if centres.is_empty() {
            return Err("no centres".into());
        }
        let band = match v["band_hz"].as_array().map(|b| b.iter().map(|f| f.as_f64()).collect::<Vec<_>>()).as_deref() {
            Some([Some(lo), Some(hi)]) if WHITENED_BAND.0 <= *lo && lo < hi && *hi <= WHITENED_BAND.1 => (*lo, *hi),
            _ => return Err(format!("`band_hz` must be two frequencies within {}–{} Hz, lowest first", WHITENED_BAND.0, WHITENED_BAND.1)),
        };
        let rows = |key: &str| -> Result<Vec<Vec<f64>>, String> {
            let rows = v[key].as_array().ok_or_else(|| format!("no `{key}`"))?;
            rows.iter()
                .map(|r| {
                    let xs: Vec<f64> = r.as_array().map(|a| a.iter().filter_map(|x| x.as_f64()).collect()).unwrap_or_default();
                    if xs.len() != LATENT || xs.iter().any(|x| !x.is_finite()) {
                        return Err(format!("each row of `{key}` must hold {LATENT} finite numbers"));
                    }
                    Ok(xs)
                })
                .collect()
        };
        let (means, sds) = (rows("posterior_means")?, rows("posterior_sds")?);
        if means.is_empty() || means.len() != sds.len() {
            return Err("`posterior_means` and `posterior_sds` must be non-empty and as long as each other".into());
        }
        Ok(ClassPart { class, centres, band, posteriors: means.into_iter().zip(sds).collect() })
    }
}

/// `gwml generator fit --kind learned` on `examples`, example `i` of class
/// `labels[i]`.
pub fn fit_command(a: &GeneratorFitArgs, examples: &[Vec<f64>], labels: &[usize], threads: usize) -> Result<(), String> {
    let bar = ProgressBar::new(a.epochs as u64);
    bar.set_style(
        ProgressStyle::with_template("training [{bar:30}] epoch {pos}/{len}, {msg}, eta {eta}")
            .map_err(|e| format!("error: {e}"))?
            .progress_chars("=> "),
    );
    let start = Instant::now();
    let options = LearnedOptions { epochs: a.epochs, seed: a.seed, threads };
    let (g, _) = fit(examples, labels, options, |r| {
        bar.set_message(format!("loss {:.1}", r.train_loss));
        bar.inc(1);
    })
    .map_err(render)?;
    bar.finish_and_clear();
    g.write(&a.out)?;
    let names: Vec<String> = g.classes.iter().map(|p| class_name(p.class)).collect();
    println!(
        "trained a {} generator on {} examples in {:.1} s ({} epochs, {threads} threads; final loss {:.1} per example); wrote {} and {}",
        names.join(" + "),
        examples.len(),
        start.elapsed().as_secs_f64(),
        a.epochs,
        g.final_loss,
        a.out.display(),
        LearnedGenerator::weights_path(&a.out).display()
    );
    for (p, name) in g.classes.iter().zip(&names) {
        let c = quantiles(&p.centres, &[0.05, 0.5, 0.95]);
        println!(
            "  {name}: {} examples; centres {:.3} s [5 %: {:.3}, 95 %: {:.3}]; band {:.0}–{:.0} Hz",
            p.centres.len(),
            c[1],
            c[0],
            c[2],
            p.band.0,
            p.band.1
        );
    }
    if let Some(path) = &a.plot {
        plot_examples_and_draws(path, &g, examples, labels)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Centred examples above centred draws, offset per row: three of each for
/// one class, one of each for up to four classes.
fn plot_examples_and_draws(path: &Path, g: &LearnedGenerator, examples: &[Vec<f64>], labels: &[usize]) -> Result<(), String> {
    let shown = &g.classes[..g.classes.len().min(4)];
    let each = if shown.len() == 1 { 3 } else { 1 };
    let mut rows: Vec<(String, Vec<f64>)> = Vec::new();
    for p in shown {
        let name = class_name(p.class);
        let of_class = examples.iter().zip(labels).filter(|(_, l)| **l == p.class).take(each);
        rows.extend(of_class.enumerate().map(|(i, (x, _))| (format!("{name} example {}", i + 1), centred(x).0)));
        let draws = g.sample(each, 1, Some(p.class)).map_err(render)?;
        rows.extend(draws.rows.iter().enumerate().map(|(i, x)| (format!("{name} draw {} (no noise)", i + 1), centred(x).0)));
    }
    let spacing = 2.2 * rows.iter().flat_map(|r| &r.1).fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
    let times: Vec<f64> = (0..SAMPLES).map(|j| j as f64 / SAMPLE_RATE - 0.5).collect();
    let offset: Vec<Vec<f64>> = rows.iter().enumerate().map(|(k, (_, r))| r.iter().map(|v| v - spacing * k as f64).collect()).collect();
    let series: Vec<(&str, &[f64], &[f64])> =
        rows.iter().zip(&offset).map(|((l, _), y)| (l.as_str(), times.as_slice(), y.as_slice())).collect();
    let names: Vec<String> = shown.iter().map(|p| class_name(p.class)).collect();
    let title = format!("{} generator: examples and draws, centred", names.join(" + "));
    crate::plot::lines_plot(path, &title, "time from the centre (s)", "whitened strain, offset per row", &series)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{unit_signal, GlitchSignals};

    fn noisy_blip(t0: f64, snr: f64, seed: u64) -> Vec<f64> {
        let signals = GlitchSignals::new().unwrap();
        let mut run = signals.bind();
        let w = unit_signal(&mut run, 1, &[("f0", 150.0), ("q", 4.0), ("t0", t0), ("phi", 0.3)]).unwrap();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        w.iter().map(|v| snr * v + Distribution::<f64>::sample(&StandardNormal, &mut rng)).collect()
    }

    #[test]
    fn a_glitch_in_noise_is_centred_where_it_is() {
        for (t0, seed) in [(0.21, 1), (0.5, 2), (0.83, 3)] {
            let x = noisy_blip(t0, 15.0, seed);
            let c = energy_centre(&x);
            assert!((c - t0).abs() < 0.005, "centre {c} s for a blip at {t0} s");
            let (moved, at) = centred(&x);
            assert_eq!(at, c);
            assert!((energy_centre(&moved) - 0.5).abs() < 0.005);
            // A circular shift keeps every sample.
            assert!((moved.iter().map(|v| v * v).sum::<f64>() - x.iter().map(|v| v * v).sum::<f64>()).abs() < 1e-9);
        }
    }

    #[test]
    fn the_family_band_spans_the_examples_power_and_is_whole_for_noise() {
        // Blips at 150 Hz, Q 4 (power spectrum a Gaussian of deviation
        // f0/(√2 Q) ≈ 27 Hz about 150 Hz) at SNR 15 in white noise.
        let blips: Vec<Vec<f64>> = (0..200).map(|i| centred(&noisy_blip(0.5, 15.0, 100 + i)).0).collect();
        let (lo, hi) = family_band(&blips);
        assert!(lo < 100.0 && (150.0..400.0).contains(&hi), "band {lo}–{hi} Hz");
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let noise: Vec<Vec<f64>> =
            (0..200).map(|_| (0..SAMPLES).map(|_| Distribution::<f64>::sample(&StandardNormal, &mut rng)).collect()).collect();
        assert_eq!(family_band(&noise), WHITENED_BAND);
        let mask = passband((lo, hi));
        assert_eq!(mask.len(), SAMPLES / 2 + 1);
        assert_eq!(mask[150], 1.0);
        assert_eq!(mask[hi.ceil() as usize], 0.0);
    }

    #[test]
    fn roll_shifts_later_and_wraps() {
        assert_eq!(roll(&[1.0, 2.0, 3.0, 4.0], 1), [4.0, 1.0, 2.0, 3.0]);
        assert_eq!(roll(&[1.0, 2.0, 3.0, 4.0], -5), [2.0, 3.0, 4.0, 1.0]);
    }
}
