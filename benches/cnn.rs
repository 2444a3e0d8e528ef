//! Throughput of gwml's CNNs against `benches/peers/cnn_torch.py` (PyTorch CPU),
//! on two workloads:
//!
//! - `burst`: the small burst-detection CNN of `examples/burst_cnn.gw`
//!   (input 256 samples, conv 8×1×16 + ReLU, max pool 4, conv 16×8×8 +
//!   ReLU, global max pool, dense 2×16, cross-entropy), in f64 (the
//!   scene's own precision) and f32, on `gwml_lab::synth::bursts` data;
//! - `glitch`: `benches/glitch_cnn.gw`, the glitch experiment's first CNN
//!   (its `lab/models/glitch/cnn.gw` is now wider), the shape issue #4
//!   names (input 4,096 samples, four convolutions of 8–32
//!   channels with kernels of 16 and 8, ReLU, max pooling, a dense head of
//!   6 classes), in f32 (the scene's own precision) and f64, on unit white
//!   noise with random labels (the values do not change the work done).
//!
//! Run `cargo bench --bench cnn` for both workloads, or
//! `cargo bench --bench cnn -- glitch` for one of them.
//!
//! For each it measures the median wall time (`GWML_BENCH_REPS`
//! repetitions, default 7, after a warm-up) of
//! - `infer_loop`: the forward kernel over every example with one `Run` on
//!   this thread (bind `x` and `label`, `Run::forward`);
//! - `infer`: `Trainer::evaluate` (forward kernel, loss and accuracy) over
//!   the same examples on a pool of 1 and of 2 threads;
//! - `train`: one epoch of `Trainer::fit` (forward + backward + Adam step
//!   per batch of 32, lr 3e-3) on 1 and 2 threads, from the initial weights;
//!
//! and prints examples per second, plus the process's peak resident memory
//! (`VmHWM` of /proc/self/status, Linux only; run one workload per process
//! to compare it with PyTorch's).
//!
//! Lines starting with `gwml_` are machine-readable (`name value`).

use gwml_compiler::driver::Options;
use gwml_compiler::ir::Precision;
use gwml_lab::synth::{bursts, BurstOptions};
use gwml_lab::timing::median_us;
use gwml_runtime::dataset::{Array, Dataset};
use gwml_runtime::optim::{Method, OptimConfig, Schedule};
use gwml_runtime::train::{TrainOptions, Trainer};
use gwml_runtime::Model;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use std::hint::black_box;

const EXAMPLES: usize = 1024;
const BATCH: usize = 32;

fn options(threads: usize) -> TrainOptions {
    TrainOptions {
        loss: "loss".into(),
        logits: "logits".into(),
        label: "label".into(),
        epochs: 1,
        batch: BATCH,
        optim: OptimConfig { method: Method::adam(), lr: 3e-3, schedule: Schedule::Constant, clip_norm: None },
        seed: 7,
        threads,
        patience: None,
        checkpoint_dir: None,
    }
}

/// Peak resident set size in MiB (`VmHWM`), when /proc is there.
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn report(tag: &str, name: &str, us: f64) {
    let per_s = EXAMPLES as f64 / (us * 1e-6);
    println!("  {name:<22} {:>10.2} ms {per_s:>14.0} examples/s {:>10.2} µs/example", us / 1e3, us / EXAMPLES as f64);
    println!("gwml_{tag}_{name}_examples_per_s {per_s:.1}");
}

/// `n` rows of `samples` unit white-noise values with random labels in `0..classes`.
fn noise_data(n: usize, samples: usize, classes: usize, seed: u64) -> Dataset {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let x: Vec<f64> = (0..n * samples).map(|_| rng.sample(StandardNormal)).collect();
    let labels: Vec<f64> = (0..n).map(|_| rng.random_range(0..classes) as f64).collect();
    let mut data = Dataset::default();
    data.arrays.insert("x".into(), Array::new(vec![n, samples], x).expect("shape"));
    data.arrays.insert("label".into(), Array::new(vec![n], labels).expect("shape"));
    data
}

/// Times inference and one training epoch of the scene in `path` on `data`.
fn bench(tag: &str, path: &str, precision: Precision, classes: usize, data: &Dataset, reps: usize) {
    let model = Model::from_file(path).unwrap_or_else(|e| panic!("{e}"));
    let opts = Options { precision: Some(precision), ..Default::default() };
    let scene = model.scene_with(None, opts).unwrap_or_else(|e| panic!("{e}"));
    scene.gradient_kernel().unwrap_or_else(|e| panic!("{e}"));
    let samples = data.arrays["x"].shape[1];
    println!("{tag}: {EXAMPLES} examples of {samples} samples, {precision:?}, batch {BATCH}, median of {reps}");

    // Forward kernel in a plain loop over one Run (weights at their initial values).
    let (x, labels) = (&data.arrays["x"], &data.arrays["label"].data);
    let mut run = scene.bind();
    let onehot: Vec<Vec<f64>> = labels.iter().map(|&l| (0..classes).map(|c| f64::from(c as f64 == l)).collect()).collect();
    let infer_loop = median_us(reps, || {
        for (i, label) in onehot.iter().enumerate() {
            run.input_real("x", x.row(i)).unwrap();
            run.input_real("label", label).unwrap();
            black_box(run.forward().unwrap());
        }
    });
    report(tag, "infer_loop", infer_loop);

    for threads in [1, 2] {
        let trainer = Trainer::new(&scene, options(threads)).unwrap_or_else(|e| panic!("{e}"));
        let us = median_us(reps, || {
            black_box(trainer.evaluate(data).unwrap());
        });
        report(tag, &format!("infer_{threads}thread"), us);
    }
    let mut losses = Vec::new();
    for threads in [1, 2] {
        let us = median_us(reps, || {
            let mut trainer = Trainer::new(&scene, options(threads)).unwrap();
            let r = trainer.fit(data, None, |_, _| {}, |_| {}).unwrap();
            black_box(&r);
            losses.push((threads, r[0].train_loss));
        });
        report(tag, &format!("train_{threads}thread"), us);
    }
    let (l1, l2) = (losses.iter().find(|l| l.0 == 1).unwrap().1, losses.iter().find(|l| l.0 == 2).unwrap().1);
    println!("  epoch train loss: {l1:.6} (1 thread), {l2:.6} (2 threads)");
}

fn main() {
    let reps: usize = std::env::var("GWML_BENCH_REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(7);
    let which: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let wants = |w: &str| which.is_empty() || which.iter().any(|a| a == w);
    let root = env!("CARGO_MANIFEST_DIR");
    if wants("burst") {
        let data = bursts(&BurstOptions { n: EXAMPLES, seed: 1, ..Default::default() }).unwrap_or_else(|e| panic!("{e}"));
        // The scene's own precision (f64), and f32 to set beside PyTorch's f32.
        for (tag, precision) in [("cnn", Precision::F64), ("cnn_f32", Precision::F32)] {
            bench(tag, &format!("{root}/examples/burst_cnn.gw"), precision, 2, &data, reps);
        }
    }
    if wants("glitch") {
        let data = noise_data(EXAMPLES, 4096, 6, 1);
        for (tag, precision) in [("glitch_cnn_f32", Precision::F32), ("glitch_cnn_f64", Precision::F64)] {
            bench(tag, &format!("{root}/benches/glitch_cnn.gw"), precision, 6, &data, reps);
        }
    }
    if let Some(peak) = peak_rss_mib() {
        println!("  peak RSS: {peak:.1} MiB");
        println!("gwml_cnn_peak_rss_mib {peak:.1}");
    }
    println!("gwml_cnn_examples {EXAMPLES}");
    println!("gwml_cnn_reps {reps}");
}
