//! `gwml experiment glitch`: the reference experiment of the glitch
//! pipeline. Three classifiers see the same synthetic data
//! ([`crate::synth::glitches`]: whitened 1 s segments of eight
//! classes) and are scored on the same test sets:
//!
//! 1. [`rules::RuleClassifier`]: a fixed matched-filter bank with tuned
//!    thresholds (`lab/models/glitch/bank.gw`), no gradient training;
//! 2. a 1-D CNN on the whitened strain (`lab/models/glitch/cnn.gw`), and
//!    a Gravity Spy-style 2-D CNN on Q-transform images of it
//!    (`lab/models/glitch/gravity_spy.gw`, images from [`qimages`]);
//! 3. the differentiable model: a trainable template bank feeding a small
//!    network behind a learned noise component (a PSD correction, positive
//!    and smooth by construction), trained end to end
//!    (`lab/models/glitch/template_net.gw`); and two ablations at the
//!    reference size: the template params frozen at their initial values
//!    (the learned components train), and the PSD correction replaced by an
//!    unconstrained per-bin one.
//!
//! Training sets of several sizes (prefixes of one seed's draw) give the
//! learning curves; validation, test and the three shifted test sets (lower
//! SNR; excess low-frequency noise the whitening does not model; every
//! Blip and Tomte from the held-out real fits) use their own seeds, so
//! every split is disjoint by seed. Each learner is
//! trained from several training seeds (initial weights and batch order)
//! per size, and the tables give the mean ± sd over them; per-class
//! tables, confusion matrices and details come from the first seed.
//! Results go to Markdown, CSV and PNG files in the output directory.

pub mod leak;
pub mod metrics;
pub mod qimages;
pub mod rules;

use crate::plot;
use crate::render;
use crate::synth::{glitches, glitches_with, real_fits, GlitchOptions, GLITCH_CLASSES};
use gwml_runtime::dataset::Dataset;
use gwml_runtime::optim::{Method, OptimConfig, Schedule};
use gwml_runtime::train::{TrainOptions, Trainer};
use gwml_runtime::Model;
use indicatif::{ProgressBar, ProgressStyle};
use metrics::{csv_table, markdown_table, percent, percent_spread, Confusion};
use rand::SeedableRng;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The CNN of method 2.
const CNN_SOURCE: &str = include_str!("../../models/glitch/cnn.gw");
/// The Gravity Spy-style CNN on Q-transform images of method 2.
const GRAVITY_SPY_SOURCE: &str = include_str!("../../models/glitch/gravity_spy.gw");
/// Sample rate of the examples (Hz).
const SAMPLE_RATE: f64 = 4096.0;
/// The differentiable model of method 3.
const TEMPLATE_NET_SOURCE: &str = include_str!("../../models/glitch/template_net.gw");

/// Classes whose glitches are longer than a row (Scratchy, Scattered Light),
/// left out of the leak probe's position check.
const LONG_CLASSES: [usize; 2] = [4, 7];

/// Classes scored in the macro averages: every class but None.
const GLITCH_LIKE: [usize; 7] = [1, 2, 3, 4, 5, 6, 7];

/// Seeds of the splits (training sets of every size are prefixes of one draw).
const TRAIN_SEED: u64 = 1;
const VAL_SEED: u64 = 2;
const TEST_SEED: u64 = 3;
const LOW_SNR_SEED: u64 = 4;
const SHIFTED_PSD_SEED: u64 = 5;
const HELD_OUT_FITS_SEED: u64 = 6;
/// A validation draw with the shifted PSD, for design only (never scored).
#[cfg(test)]
const VAL_SHIFTED_PSD_SEED: u64 = 7;

/// The standard SNRs (each class's own range), and the one range of the
/// low-SNR generalisation check.
const SNR: Option<(f64, f64)> = None;
const LOW_SNR: Option<(f64, f64)> = Some((5.0, 12.0));
/// Knee of the shifted PSD (see [`GlitchOptions::psd_knee`]).
const SHIFTED_PSD_KNEE: f64 = 60.0;

/// How large a run of `gwml experiment glitch` is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Budget {
    /// Every method, table and plot at small sizes and few steps: a check
    /// that the pipeline runs end to end, in about 2 minutes on 2 cores.
    /// Its numbers are not the benchmark's.
    Quick,
    /// Training sets of 500, 1,500 and 5,000, two seeds: the README's
    /// tables (~15 minutes on 2 cores).
    Standard,
    /// Training sets up to 50,000, five seeds (hours).
    Full,
}

impl Budget {
    /// The command line that runs this budget.
    pub fn command(self) -> &'static str {
        match self {
            Budget::Quick => "gwml experiment glitch --quick",
            Budget::Standard => "gwml experiment glitch --standard",
            Budget::Full => "gwml experiment glitch",
        }
    }
}

/// Options of `gwml experiment glitch`.
pub struct GlitchExperiment {
    /// How large the run is.
    pub budget: Budget,
    /// Where the tables and plots go.
    pub out: PathBuf,
    /// Worker threads.
    pub threads: usize,
}

/// How large a run is.
struct Plan {
    /// Training-set sizes of the learning curves, increasing.
    sizes: Vec<usize>,
    /// The size whose models fill the main tables and the generalisation check.
    reference: usize,
    /// Examples in the validation set and in each test set.
    val: usize,
    test: usize,
    /// Examples the rule thresholds are tuned on.
    tune: usize,
    /// Gradient steps per training run, whatever the training-set size
    /// (epochs are rounded up, between `min_epochs` and `max_epochs`).
    steps: usize,
    min_epochs: usize,
    max_epochs: usize,
    /// Training seeds per learner and size.
    seeds: u64,
}

impl Plan {
    fn new(budget: Budget) -> Plan {
        match budget {
            Budget::Quick => Plan {
                sizes: vec![300, 1000],
                reference: 1000,
                val: 300,
                test: 400,
                tune: 500,
                steps: 100,
                min_epochs: 2,
                max_epochs: 6,
                seeds: 2,
            },
            Budget::Standard => Plan {
                sizes: vec![500, 1500, 5000],
                reference: 5000,
                val: 600,
                test: 1200,
                tune: 1500,
                steps: 600,
                min_epochs: 6,
                max_epochs: 20,
                seeds: 2,
            },
            Budget::Full => Plan {
                sizes: vec![500, 1500, 5000, 15000, 50000],
                reference: 5000,
                val: 1200,
                test: 3000,
                tune: 5000,
                steps: 3000,
                min_epochs: 4,
                max_epochs: 60,
                seeds: 5,
            },
        }
    }

    fn epochs(&self, n: usize, batch: usize) -> usize {
        (self.steps * batch).div_ceil(n.max(1)).clamp(self.min_epochs, self.max_epochs)
    }
}

/// A trained method's settings.
struct Learner {
    /// Short name used in file names.
    key: &'static str,
    /// Name in the tables.
    title: &'static str,
    source: &'static str,
    lr: f64,
    batch: usize,
    /// The shipped model, or one of its ablations (trained only at the
    /// reference size).
    variant: Variant,
    /// What the model reads.
    input: Input,
}

/// Which form of a learner's model is trained.
#[derive(Clone, Copy, PartialEq)]
enum Variant {
    /// The `.gw` file as written.
    Shipped,
    /// The template params stay at their initial values
    /// ([`frozen_front_end`]).
    FrozenFrontEnd,
    /// The constrained noise component replaced by its unconstrained
    /// version ([`unconstrained`]).
    Unconstrained,
}

impl Variant {
    /// The source this variant trains.
    fn source(self, shipped: &str) -> Result<String, String> {
        match self {
            Variant::Shipped => Ok(shipped.to_string()),
            Variant::FrozenFrontEnd => frozen_front_end(shipped),
            Variant::Unconstrained => unconstrained(shipped),
        }
    }
}

/// A learner's input.
#[derive(Clone, Copy, PartialEq)]
enum Input {
    /// The whitened strain of each example.
    Strain,
    /// Its Q-transform images ([`qimages::q_images`]).
    QImages,
}

const LEARNERS: [Learner; 5] = [
    Learner { key: "cnn", title: "CNN", source: CNN_SOURCE, lr: 3e-3, batch: 32, variant: Variant::Shipped, input: Input::Strain },
    Learner {
        key: "gravity_spy",
        title: "Gravity Spy-style CNN on Q-scans",
        source: GRAVITY_SPY_SOURCE,
        lr: 3e-3,
        batch: 32,
        variant: Variant::Shipped,
        input: Input::QImages,
    },
    Learner {
        key: "template_net",
        title: "Differentiable template bank + head",
        source: TEMPLATE_NET_SOURCE,
        lr: 3e-3,
        batch: 32,
        variant: Variant::Shipped,
        input: Input::Strain,
    },
    Learner {
        key: "template_net_frozen",
        title: "Template bank frozen + head (ablation)",
        source: TEMPLATE_NET_SOURCE,
        lr: 3e-3,
        batch: 32,
        variant: Variant::FrozenFrontEnd,
        input: Input::Strain,
    },
    Learner {
        key: "template_net_unconstrained",
        title: "Unconstrained PSD correction (ablation)",
        source: TEMPLATE_NET_SOURCE,
        lr: 3e-3,
        batch: 32,
        variant: Variant::Unconstrained,
        input: Input::Strain,
    },
];

/// `source` with the params cut from its `grad loss wrt [...]` list: the
/// template params keep their declared values while the learned
/// components (the head, the noise component) train.
fn frozen_front_end(source: &str) -> Result<String, String> {
    // The last one: the file's comments mention the statement too.
    let start = source.rfind("grad loss wrt [").ok_or("the template net has no `grad loss wrt [...]`")? + "grad loss wrt [".len();
    let end = start + source[start..].find(']').ok_or("unclosed `grad loss wrt [`")?;
    let learned: Vec<&str> =
        source[start..end].split(',').map(str::trim).filter(|name| !source.contains(&format!("param {name} "))).collect();
    Ok(format!("{}{}{}", &source[..start], learned.join(", "), &source[end..]))
}

/// `source` with its scene's `psd_correction` (positive and smooth by
/// construction, `std::constrained`) replaced by `psd_correction_free`,
/// the file's unconstrained version of it.
fn unconstrained(source: &str) -> Result<String, String> {
    let scene = source.find("\nscene ").ok_or("the template net has no scene")?;
    let (head, body) = source.split_at(scene);
    if !head.contains("learned psd_correction_free(") || !body.contains("psd_correction(") {
        return Err("the template net has no `psd_correction` call and `psd_correction_free` component".into());
    }
    Ok(format!("{head}{}", body.replace("psd_correction(", "psd_correction_free(").replace("psd_correction]", "psd_correction_free]")))
}

/// The test sets every method is scored on.
struct TestSets {
    standard: Dataset,
    low_snr: Dataset,
    shifted_psd: Dataset,
    /// Every Blip and Tomte from a held-out real fit (none in training).
    held_out_fits: Dataset,
}

/// Names of the test sets, in [`TestSets::all`] order.
const TEST_SET_NAMES: [&str; 4] =
    ["standard", "low SNR (5–12)", "shifted PSD (knee 60 Hz)", "Blips, Koi Fish and Tomtes from held-out real fits"];

impl TestSets {
    fn all(&self) -> [&Dataset; 4] {
        [&self.standard, &self.low_snr, &self.shifted_psd, &self.held_out_fits]
    }

    /// Every set as `f` maps it.
    fn map(&self, f: impl Fn(&Dataset) -> Result<Dataset, String>) -> Result<TestSets, String> {
        Ok(TestSets {
            standard: f(&self.standard)?,
            low_snr: f(&self.low_snr)?,
            shifted_psd: f(&self.shifted_psd)?,
            held_out_fits: f(&self.held_out_fits)?,
        })
    }
}

/// The training, validation and test sets as one input.
struct Splits {
    train: Dataset,
    val: Dataset,
    tests: TestSets,
}

/// One method's predictions on the three test sets, for one training size.
struct Scored {
    method: String,
    key: String,
    train_examples: usize,
    /// Training seed (0 for the rules, which have none).
    seed: u64,
    /// Confusion on each test set, in [`TestSets::all`] order.
    confusions: Vec<Confusion>,
    seconds: f64,
    /// What the method ended up as (the tuned rules), for the results page.
    details: Option<String>,
}

/// Runs the experiment and writes its results.
pub fn glitch(o: &GlitchExperiment) -> Result<(), String> {
    run_plan(o, &Plan::new(o.budget))?;
    println!("{}", std::fs::read_to_string(o.out.join("README.md")).unwrap_or_default());
    Ok(())
}

fn run_plan(o: &GlitchExperiment, plan: &Plan) -> Result<(), String> {
    let start = Instant::now();
    std::fs::create_dir_all(&o.out).map_err(|e| format!("error: cannot create {}: {e}", o.out.display()))?;
    let largest = *plan.sizes.last().expect("at least one size");

    eprintln!("drawing data: {largest} training, {} validation, 4 × {} test examples", plan.val, plan.test);
    let draw = |n, seed, snr, psd_knee| glitches(&GlitchOptions { n, seed, snr, psd_knee, ..Default::default() }).map_err(render);
    let train = draw(largest, TRAIN_SEED, SNR, 0.0)?;
    let val = draw(plan.val, VAL_SEED, SNR, 0.0)?;
    let tests = TestSets {
        standard: draw(plan.test, TEST_SEED, SNR, 0.0)?,
        low_snr: draw(plan.test, LOW_SNR_SEED, LOW_SNR, 0.0)?,
        shifted_psd: draw(plan.test, SHIFTED_PSD_SEED, SNR, SHIFTED_PSD_KNEE)?,
        held_out_fits: {
            let mut shapes = rand_pcg::Pcg64Mcg::seed_from_u64(HELD_OUT_FITS_SEED);
            let o = GlitchOptions { n: plan.test, seed: HELD_OUT_FITS_SEED, ..Default::default() };
            glitches_with(&o, &mut |class| Ok(real_fits::draw_held_out(&mut shapes, class))).map_err(render)?
        },
    };
    let data_seconds = start.elapsed().as_secs_f64();
    eprintln!("  ({data_seconds:.1} s)");
    let probe_train = train.head(plan.tune);
    let probes = leak::probe(&probe_train, &val, GLITCH_CLASSES.len(), &LONG_CLASSES)?;

    let mut scored = Vec::new();
    scored.push(run_rules(plan, &train, &tests)?);
    let t0 = Instant::now();
    eprintln!("Q-transform images of every example ({} views of {}×{})", qimages::DURATIONS.len(), qimages::ROWS, qimages::COLUMNS);
    let images = |d: &Dataset| qimages::q_images(d, SAMPLE_RATE, o.threads);
    let q_splits = Splits { train: images(&train)?, val: images(&val)?, tests: tests.map(images)? };
    eprintln!("  ({:.1} s)", t0.elapsed().as_secs_f64());
    let strain = Splits { train, val, tests };
    for learner in &LEARNERS {
        let data = if learner.input == Input::QImages { &q_splits } else { &strain };
        for &n in plan.sizes.iter().filter(|n| learner.variant == Variant::Shipped || **n == plan.reference) {
            let subset = data.train.head(n);
            for seed in 0..plan.seeds {
                scored.push(run_learner(learner, plan, &subset, &data.val, &data.tests, o.threads, seed)?);
            }
        }
    }
    let total = start.elapsed().as_secs_f64();
    write_results(o, plan, &scored, &probes, data_seconds, total)
}

/// Labels of a dataset as class indices.
fn labels(d: &Dataset) -> Result<Vec<usize>, String> {
    Ok(d.get("label").map_err(render)?.data.iter().map(|&l| l as usize).collect())
}

fn run_rules(plan: &Plan, train: &Dataset, tests: &TestSets) -> Result<Scored, String> {
    let t0 = Instant::now();
    eprintln!("rule-based classifier: tuning thresholds on {} examples", plan.tune);
    let mut rules = rules::RuleClassifier::new()?;
    let tune = train.head(plan.tune);
    rules.tune(tune.get("x").map_err(render)?, &labels(&tune)?)?;
    let mut confusions = Vec::new();
    for set in tests.all() {
        let predicted = rules.classify(set.get("x").map_err(render)?)?;
        confusions.push(Confusion::new(GLITCH_CLASSES.len(), &labels(set)?, &predicted)?);
    }
    let seconds = t0.elapsed().as_secs_f64();
    eprintln!("  macro P/R {} ({seconds:.1} s)", macro_line(&confusions[0]));
    Ok(Scored {
        method: "Rule-based filtering".into(),
        key: "rules".into(),
        train_examples: 0,
        seed: 0,
        confusions,
        seconds,
        details: Some(rules.describe()),
    })
}

#[allow(clippy::too_many_arguments)]
fn run_learner(
    l: &Learner,
    plan: &Plan,
    train: &Dataset,
    val: &Dataset,
    tests: &TestSets,
    threads: usize,
    seed: u64,
) -> Result<Scored, String> {
    let t0 = Instant::now();
    let n = train.examples().map_err(render)?;
    let epochs = plan.epochs(n, l.batch);
    let source = l.variant.source(l.source)?;
    let model = Model::from_source(&format!("lab/models/glitch/{}.gw", l.key), &source).map_err(render)?;
    let scene = model.scene(None).map_err(render)?;
    let steps_per_epoch = n.div_ceil(l.batch) as u64;
    let opts = TrainOptions {
        loss: "loss".into(),
        logits: "logits".into(),
        label: "label".into(),
        epochs,
        batch: l.batch,
        optim: OptimConfig {
            method: Method::adam(),
            lr: l.lr,
            schedule: Schedule::Cosine { total: epochs as u64 * steps_per_epoch, min_lr: 0.0 },
            clip_norm: Some(10.0),
        },
        seed,
        threads,
        patience: None,
        checkpoint_dir: None,
    };
    let mut trainer = Trainer::new(&scene, opts).map_err(render)?;
    let bar = ProgressBar::new(epochs as u64 * steps_per_epoch);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} steps, eta {eta}")
            .map_err(|e| format!("error: {e}"))?
            .progress_chars("=> "),
    );
    bar.set_message(format!("{} on {n}, seed {seed}", l.title));
    let done_epochs = std::cell::Cell::new(0u64);
    // No validation between epochs: nothing stops early, and the
    // validation accuracy is reported once, after the last epoch.
    trainer
        .fit(
            train,
            None,
            |done, _| bar.set_position(done_epochs.get() * steps_per_epoch + done as u64),
            |_| done_epochs.set(done_epochs.get() + 1),
        )
        .map_err(render)?;
    bar.finish_and_clear();
    let val_confusion = Confusion::new(GLITCH_CLASSES.len(), &labels(val)?, &trainer.predict_classes(val).map_err(render)?)?;
    let params: Vec<String> = scene
        .ir()
        .params
        .iter()
        .filter_map(|p| trainer.param(&p.name).map(|v| format!("{} = {v:.4} (from {:.4})", p.name, p.default.unwrap_or(f64::NAN))))
        .collect();
    let trained_params = if l.variant == Variant::FrozenFrontEnd {
        Some("template params frozen at their initial values; only the learned components train".to_string())
    } else {
        (!params.is_empty()).then(|| params.join(", "))
    };
    let mut confusions = Vec::new();
    for set in tests.all() {
        let predicted = trainer.predict_classes(set).map_err(render)?;
        confusions.push(Confusion::new(GLITCH_CLASSES.len(), &labels(set)?, &predicted)?);
    }
    let seconds = t0.elapsed().as_secs_f64();
    let val_acc = percent(val_confusion.accuracy());
    eprintln!(
        "{} on {n} examples, seed {seed}, {epochs} epochs: validation accuracy {val_acc} %, test macro P/R {} ({seconds:.1} s)",
        l.title,
        macro_line(&confusions[0])
    );
    Ok(Scored { method: l.title.into(), key: l.key.into(), train_examples: n, seed, confusions, seconds, details: trained_params })
}

fn macro_line(c: &Confusion) -> String {
    let (p, r) = c.macro_scores(&GLITCH_LIKE);
    format!("{} / {} %", percent(p), percent(r))
}

/// The rows of the main table: the rule-based classifier and each learner
/// at the reference size (and at the largest size, when larger).
/// The runs the per-class tables, confusion matrices and generalisation
/// check compare: the rule-based classifier and each learner at the
/// reference size.
fn compared<'a>(plan: &'a Plan, scored: &'a [Scored]) -> impl Iterator<Item = &'a Scored> {
    scored.iter().filter(|s| (s.key == "rules" || s.train_examples == plan.reference) && s.seed == 0)
}

/// The runs of each method and size (one per seed), in run order.
fn by_seed(scored: &[Scored], keep: impl Fn(&Scored) -> bool) -> Vec<Vec<&Scored>> {
    let mut groups: Vec<Vec<&Scored>> = Vec::new();
    for s in scored.iter().filter(|s| keep(s)) {
        match groups.iter_mut().find(|g| g[0].key == s.key && g[0].train_examples == s.train_examples) {
            Some(g) => g.push(s),
            None => groups.push(vec![s]),
        }
    }
    groups
}

/// The main table's runs: the rules, each learner at the reference size and
/// at the largest size, grouped over seeds.
fn headline<'a>(plan: &Plan, scored: &'a [Scored]) -> Vec<Vec<&'a Scored>> {
    let largest = *plan.sizes.last().expect("at least one size");
    by_seed(scored, |s| s.key == "rules" || s.train_examples == plan.reference || s.train_examples == largest)
}

/// Macro precision, macro recall and accuracy on test set `set` as
/// "mean ± sd" over a group's seeds, and the mean seconds per run.
fn spread_cells(group: &[&Scored], set: usize) -> [String; 4] {
    let scores: Vec<(f64, f64)> = group.iter().map(|s| s.confusions[set].macro_scores(&GLITCH_LIKE)).collect();
    let precision: Vec<f64> = scores.iter().map(|x| x.0).collect();
    let recall: Vec<f64> = scores.iter().map(|x| x.1).collect();
    let accuracy: Vec<f64> = group.iter().map(|s| s.confusions[set].accuracy()).collect();
    let seconds = group.iter().map(|s| s.seconds).sum::<f64>() / group.len() as f64;
    [percent_spread(&precision), percent_spread(&recall), percent_spread(&accuracy), format!("{seconds:.0}")]
}

fn write_file(dir: &Path, name: &str, text: &str) -> Result<(), String> {
    let path = dir.join(name);
    std::fs::write(&path, text).map_err(|e| format!("error: cannot write {}: {e}", path.display()))
}

fn write_results(
    o: &GlitchExperiment,
    plan: &Plan,
    scored: &[Scored],
    probes: &[leak::Probe],
    data_seconds: f64,
    total: f64,
) -> Result<(), String> {
    let rows_main: Vec<Vec<String>> = headline(plan, scored)
        .iter()
        .map(|g| {
            let s = g[0];
            let n = if s.train_examples == 0 {
                "0 (tuned on ".to_string() + &plan.tune.to_string() + ")"
            } else {
                s.train_examples.to_string()
            };
            let [p, r, a, seconds] = spread_cells(g, 0);
            vec![s.method.clone(), p, r, a, n, g.len().to_string(), seconds]
        })
        .collect();
    let main_header = ["method", "macro precision %", "macro recall %", "accuracy %", "training examples", "seeds", "seconds per run"];

    let per_class_header = ["method", "training examples", "class", "precision %", "recall %", "false-positive rate %", "support"];
    let mut per_class = Vec::new();
    for s in headline(plan, scored).iter().map(|g| g[0]) {
        for (c, name) in GLITCH_CLASSES.iter().enumerate() {
            let k = s.confusions[0].score(c);
            per_class.push(vec![
                s.method.clone(),
                s.train_examples.to_string(),
                name.to_string(),
                percent(k.precision),
                percent(k.recall),
                percent(k.false_positive_rate),
                k.support.to_string(),
            ]);
        }
    }

    let gen_header = ["method", "training examples", "test set", "macro precision %", "macro recall %", "drop in recall (points)"];
    let mut generalisation = Vec::new();
    for g in by_seed(scored, |s| s.key == "rules" || s.train_examples == plan.reference) {
        let recall = |set: usize| g.iter().map(|s| s.confusions[set].macro_scores(&GLITCH_LIKE).1).sum::<f64>() / g.len() as f64;
        for (set, name) in TEST_SET_NAMES.iter().enumerate() {
            let [p, r, _, _] = spread_cells(&g, set);
            let drop = format!("{:.1}", 100.0 * (recall(0) - recall(set)));
            generalisation.push(vec![g[0].method.clone(), g[0].train_examples.to_string(), name.to_string(), p, r, drop]);
        }
    }

    let curve_header = ["method", "training examples", "seeds", "macro precision %", "macro recall %", "seconds per run"];
    let curve: Vec<Vec<String>> = by_seed(scored, |s| s.key != "rules")
        .iter()
        .map(|g| {
            let [p, r, _, seconds] = spread_cells(g, 0);
            vec![g[0].method.clone(), g[0].train_examples.to_string(), g.len().to_string(), p, r, seconds]
        })
        .collect();

    let mut confusion_header = vec!["method", "training examples", "true class"];
    confusion_header.extend(GLITCH_CLASSES.iter().copied());
    let mut confusion_rows = Vec::new();
    for s in compared(plan, scored) {
        for (c, row) in s.confusions[0].counts.iter().enumerate() {
            let mut cells = vec![s.method.clone(), s.train_examples.to_string(), GLITCH_CLASSES[c].to_string()];
            cells.extend(row.iter().map(|k| k.to_string()));
            confusion_rows.push(cells);
        }
    }

    write_file(&o.out, "summary.csv", &csv_table(&main_header, &rows_main))?;
    write_file(&o.out, "confusion.csv", &csv_table(&confusion_header, &confusion_rows))?;
    write_file(&o.out, "per_class.csv", &csv_table(&per_class_header, &per_class))?;
    write_file(&o.out, "generalisation.csv", &csv_table(&gen_header, &generalisation))?;
    write_file(&o.out, "learning_curve.csv", &csv_table(&curve_header, &curve))?;
    let (probe_md, probe_csv) = leak::tables(probes);
    write_file(&o.out, "leak_probe.csv", &probe_csv)?;

    // Plots: learning curves and the confusion matrices at the reference size.
    // Means over seeds.
    let points = |key: &str| -> Vec<(f64, f64, f64)> {
        by_seed(scored, |s| s.key == key)
            .iter()
            .map(|g| {
                let (p, r) = g.iter().map(|s| s.confusions[0].macro_scores(&GLITCH_LIKE)).fold((0.0, 0.0), |a, x| (a.0 + x.0, a.1 + x.1));
                let k = g.len() as f64;
                (g[0].train_examples as f64, 100.0 * p / k, 100.0 * r / k)
            })
            .collect()
    };
    let curves: Vec<_> = LEARNERS.iter().map(|l| (l.title, points(l.key))).collect();
    let refs: Vec<plot::Curve> = curves.iter().map(|(name, points)| (*name, points.as_slice())).collect();
    plot::learning_curve_plot(
        &o.out.join("learning_curve.png"),
        "glitch classification: learning curves",
        "macro % (glitch classes)",
        &refs,
    )?;
    let names: Vec<&str> = GLITCH_CLASSES.to_vec();
    for s in compared(plan, scored) {
        let title = if s.train_examples == 0 { s.method.clone() } else { format!("{} ({} examples)", s.method, s.train_examples) };
        plot::confusion_plot(&o.out.join(format!("confusion_{}.png", s.key)), &title, &names, &s.confusions[0].counts)?;
    }

    let mut md = String::new();
    let mode = o.budget.command();
    let _ = writeln!(md, "# Glitch experiment results\n");
    let _ = writeln!(
        md,
        "Written by `{mode}` in {total:.0} s ({data_seconds:.0} s drawing data) on {} threads. Test sets of {} examples each \
         (eight classes drawn uniformly: {}); macro averages over the seven \
         classes other than None. Training sets are prefixes of one draw (seed {TRAIN_SEED}); validation seed {VAL_SEED}, \
         test seed {TEST_SEED}, low-SNR test seed {LOW_SNR_SEED}, shifted-PSD test seed {SHIFTED_PSD_SEED}, held-out-fits test seed \
         {HELD_OUT_FITS_SEED} (every Blip, Koi Fish and Tomte there from the real fits that training never draws). Each learner is \
         trained from {} seeds (initial weights and batch order) per size: tables give mean ± sd over them; per-class \
         tables, confusion matrices and learned values are the first seed's.\n",
        o.threads,
        plan.test,
        GLITCH_CLASSES.join(", "),
        plan.seeds
    );
    let _ = writeln!(
        md,
        "## Leak probe\n\nOne-feature classifiers ({} quantile bins, the majority class per bin) fitted on {} training \
         examples and scored on the validation split. The time of the peak, without the classes longer than a row, must not \
         beat the majority class by more than {} points.\n\n{probe_md}",
        leak::BINS,
        plan.tune,
        leak::POSITION_ALLOWANCE
    );
    let _ = writeln!(md, "## Methods\n\n{}\n", markdown_table(&main_header, &rows_main));
    let _ = writeln!(md, "## Per class (standard test set)\n\n{}\n", markdown_table(&per_class_header, &per_class));
    let _ = writeln!(md, "## Generalisation\n\n{}\n", markdown_table(&gen_header, &generalisation));
    let _ = writeln!(md, "## Learning curves\n\n{}\n![learning curves](learning_curve.png)\n", markdown_table(&curve_header, &curve));
    let _ = writeln!(md, "## What the methods learned\n");
    for s in compared(plan, scored).filter(|s| s.details.is_some()) {
        let _ = writeln!(md, "{}:\n\n```\n{}\n```\n", s.method, s.details.as_deref().unwrap_or_default());
    }
    let _ = writeln!(md, "## Confusion matrices (standard test set)\n");
    for s in compared(plan, scored) {
        let _ = writeln!(md, "![{}](confusion_{}.png)", s.method, s.key);
    }
    write_file(&o.out, "README.md", &md)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The frozen ablation's source trains only the learned components.
    #[test]
    fn the_frozen_front_end_trains_only_the_learned_components() {
        let frozen = frozen_front_end(TEMPLATE_NET_SOURCE).unwrap();
        let model = Model::from_source("frozen.gw", &frozen).unwrap();
        let scene = model.scene(None).unwrap();
        assert!(scene.ir().grads.is_empty(), "no template param is differentiated: {:?}", scene.ir().grads);
        let trained: Vec<&str> = scene.ir().input_grads.iter().map(|g| scene.ir().inputs[g.input].name.as_str()).collect();
        assert!(trained.iter().any(|w| w.starts_with("head.")), "the head's weights are: {trained:?}");
        assert!(trained.iter().any(|w| w.starts_with("psd_correction.")), "so are the noise component's: {trained:?}");
        assert!(frozen_front_end("scene s {}").is_err());
    }

    /// The unconstrained ablation trains the file's free correction in
    /// place of `std::constrained`'s, and nothing else changes.
    #[test]
    fn the_unconstrained_ablation_swaps_only_the_psd_correction() {
        let free = unconstrained(TEMPLATE_NET_SOURCE).unwrap();
        let weights = |src: &str| -> Vec<String> {
            let model = Model::from_source("t.gw", src).unwrap();
            let scene = model.scene(None).unwrap();
            scene.ir().inputs.iter().filter(|i| i.is_weight()).map(|i| i.name.clone()).collect()
        };
        let (shipped, ablation) = (weights(TEMPLATE_NET_SOURCE), weights(&free));
        assert!(shipped.contains(&"psd_correction.w".to_string()), "{shipped:?}");
        assert!(ablation.contains(&"psd_correction_free.w".to_string()) && !ablation.iter().any(|w| w.starts_with("psd_correction.")));
        let others = |w: &[String]| w.iter().filter(|n| !n.starts_with("psd_correction")).cloned().collect::<Vec<_>>();
        assert_eq!(others(&shipped), others(&ablation));
        assert!(unconstrained("scene s {}").is_err());
    }

    /// Design of a learner, on validation splits only: trains each `.gw`
    /// file named in `GWML_MODELS` (comma-separated; the shipped one by
    /// default) as learner `GWML_LEARNER` (`gravity_spy` by default) on the
    /// `--standard` reference set with the `--standard` budget, two seeds, and
    /// prints accuracy on the validation split and on a validation draw
    /// with the shifted PSD (seed [`VAL_SHIFTED_PSD_SEED`], not a test
    /// set's); `GWML_QNORM=median` normalises Q-scan rows by their own
    /// median.
    #[test]
    #[ignore = "design: GWML_LEARNER=template_net GWML_MODELS=A.gw,B.gw prints each variant's validation accuracy"]
    fn learner_variants_on_the_validation_split() {
        let plan = Plan::new(Budget::Standard);
        let key = std::env::var("GWML_LEARNER").unwrap_or_else(|_| "gravity_spy".into());
        let shipped = LEARNERS.iter().find(|l| l.key == key).unwrap_or_else(|| panic!("no learner `{key}`"));
        let draw = |n, seed, psd_knee| glitches(&GlitchOptions { n, seed, snr: SNR, psd_knee, ..Default::default() }).unwrap();
        let (mut train, mut val, mut shifted) =
            (draw(plan.reference, TRAIN_SEED, 0.0), draw(plan.val, VAL_SEED, 0.0), draw(plan.val, VAL_SHIFTED_PSD_SEED, SHIFTED_PSD_KNEE));
        if shipped.input == Input::QImages {
            // GWML_QNORM=median draws the images with each row's own median.
            let norm = match std::env::var("GWML_QNORM").as_deref() {
                Ok("median") => gwml_strain::qimage::TileNorm::Median,
                _ => qimages::NORM,
            };
            let images = |d: &Dataset| qimages::q_images_with(d, SAMPLE_RATE, 2, norm).unwrap();
            (train, val, shifted) = (images(&train), images(&val), images(&shifted));
        }
        let files = std::env::var("GWML_MODELS").unwrap_or_default();
        let sources: Vec<(String, String)> = match files.as_str() {
            "" => vec![("shipped".into(), shipped.source.into())],
            list => list.split(',').map(|f| (f.to_string(), std::fs::read_to_string(f).unwrap())).collect(),
        };
        for (name, source) in sources {
            let learner = Learner { source: Box::leak(source.into_boxed_str()), ..*shipped };
            for seed in 0..plan.seeds {
                let val_only =
                    TestSets { standard: val.clone(), low_snr: val.head(1), shifted_psd: shifted.clone(), held_out_fits: val.head(1) };
                let s = run_learner(&learner, &plan, &train, &val, &val_only, 2, seed).unwrap();
                println!(
                    "{name}, seed {seed}: validation accuracy {} % (shifted PSD {} %), macro P/R {} (shifted PSD {})",
                    percent(s.confusions[0].accuracy()),
                    percent(s.confusions[2].accuracy()),
                    macro_line(&s.confusions[0]),
                    macro_line(&s.confusions[2])
                );
            }
        }
    }

    /// The whole pipeline at a toy size: every method trains and is scored
    /// on every test set, and every table and plot is written with its rows.
    #[test]
    fn a_tiny_run_writes_every_table_and_plot() {
        let out = std::env::temp_dir().join(format!("gwml-experiment-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        let plan =
            Plan { sizes: vec![30, 60], reference: 60, val: 30, test: 60, tune: 60, steps: 2, min_epochs: 1, max_epochs: 1, seeds: 2 };
        let o = GlitchExperiment { budget: Budget::Quick, out: out.clone(), threads: 2 };
        run_plan(&o, &plan).unwrap();
        let read = |name: &str| std::fs::read_to_string(out.join(name)).unwrap();
        // Rules, then each learner and the two ablations at the reference size
        // (the largest), over two seeds (mean ± sd).
        let summary = read("summary.csv");
        assert_eq!(summary.lines().count(), 1 + 6, "{summary}");
        assert_eq!(summary.lines().filter(|l| l.contains(" ± ") && l.contains(",2,")).count(), 5, "{summary}");
        for method in ["Rule-based filtering", "CNN,", "Gravity Spy-style CNN on Q-scans", "template bank"] {
            assert!(summary.contains(method), "{method}: {summary}");
        }
        // Eight classes for each of the six methods.
        assert_eq!(read("per_class.csv").lines().count(), 1 + 6 * 8);
        // A row per true class for each method, a column per predicted class.
        let confusion = read("confusion.csv");
        assert_eq!(confusion.lines().count(), 1 + 6 * 8);
        assert!(confusion.lines().all(|l| l.split(',').count() == 3 + 8), "{confusion}");
        // A probe row per feature: energy, time of peak (all classes, short
        // ones), seven bands.
        assert_eq!(read("leak_probe.csv").lines().count(), 1 + 10);
        // Four test sets for each method.
        assert_eq!(read("generalisation.csv").lines().count(), 1 + 6 * 4);
        // Two sizes for each learner, the two ablations at the reference
        // size, each over two seeds.
        let curve = read("learning_curve.csv");
        assert_eq!(curve.lines().count(), 1 + 3 * 2 + 2);
        assert!(curve.lines().skip(1).all(|l| l.contains(",2,")), "{curve}");
        for png in [
            "learning_curve.png",
            "confusion_rules.png",
            "confusion_cnn.png",
            "confusion_gravity_spy.png",
            "confusion_template_net.png",
            "confusion_template_net_frozen.png",
            "confusion_template_net_unconstrained.png",
        ] {
            let bytes = std::fs::read(out.join(png)).unwrap();
            assert!(bytes.starts_with(b"\x89PNG"), "{png} is not a PNG");
        }
        let readme = read("README.md");
        assert!(readme.contains("## Generalisation") && readme.contains("None: every template"), "{readme}");
        // The ablation's template params stay where they start; the full
        // model's move.
        let learned =
            |title: &str| readme.split(&format!("{title}:\n\n```\n")).nth(1).and_then(|r| r.split("```").next()).unwrap_or("").to_string();
        let frozen = learned("Template bank frozen + head (ablation)");
        assert!(frozen.contains("frozen at their initial values"), "{readme}");
        let full = learned("Differentiable template bank + head");
        assert!(full.contains("lf1 = ") && !full.contains("lf1 = 3.5550 (from 3.5550)"), "{readme}");
        let _ = std::fs::remove_dir_all(&out);
    }
}
