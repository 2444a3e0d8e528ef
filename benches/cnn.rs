//! Throughput of the small burst-detection CNN of `examples/burst_cnn.gw`
//! (input 256 samples, conv 8×1×16 + ReLU, max pool 4, conv 16×8×8 + ReLU,
//! global max pool, dense 2×16, cross-entropy), f64, on
//! `gwml_runtime::synth::bursts` data.
//!
//!     cargo bench --bench cnn
//!
//! Measures the median wall time (`GWML_BENCH_REPS` repetitions, default 7,
//! after a warm-up) of
//! - `infer_loop`: the forward kernel over every example with one `Run` on
//!   this thread (bind `x` and `label`, `Run::forward`);
//! - `infer`: `Trainer::evaluate` (forward kernel, loss and accuracy) over
//!   the same examples on a pool of 1 and of 2 threads;
//! - `train`: one epoch of `Trainer::fit` (forward + backward + Adam step
//!   per batch of 32, lr 3e-3) on 1 and 2 threads, from the initial weights;
//!
//! and prints examples per second, plus the process's peak resident memory
//! (`VmHWM` of /proc/self/status, Linux only). The CPU bench of the same
//! network in PyTorch is `bench/cnn_torch.py`.
//!
//! Lines starting with `gwml_` are machine-readable (`name value`).

use gwml::timing::median_us;
use gwml_runtime::optim::{Method, OptimConfig, Schedule};
use gwml_runtime::synth::{bursts, BurstOptions};
use gwml_runtime::train::{TrainOptions, Trainer};
use gwml_runtime::Model;
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

fn report(name: &str, us: f64) {
    let per_s = EXAMPLES as f64 / (us * 1e-6);
    println!("  {name:<22} {:>10.2} ms {per_s:>14.0} examples/s {:>10.2} µs/example", us / 1e3, us / EXAMPLES as f64);
    println!("gwml_cnn_{name}_examples_per_s {per_s:.1}");
}

fn main() {
    let reps: usize = std::env::var("GWML_BENCH_REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(7);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/burst_cnn.gw");
    let model = Model::from_file(path).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(None).unwrap_or_else(|e| panic!("{e}"));
    scene.gradient_kernel().unwrap_or_else(|e| panic!("{e}"));
    let data = bursts(&BurstOptions { n: EXAMPLES, seed: 1, ..Default::default() }).unwrap_or_else(|e| panic!("{e}"));
    let rss_setup = peak_rss_mib();
    println!("burst_cnn: {EXAMPLES} examples of 256 samples, f64, batch {BATCH}, median of {reps}");

    // Forward kernel in a plain loop over one Run (weights at their initial values).
    let (x, labels) = (&data.arrays["x"], &data.arrays["label"].data);
    let mut run = scene.bind();
    let onehot: Vec<[f64; 2]> = labels.iter().map(|l| if *l == 1.0 { [0.0, 1.0] } else { [1.0, 0.0] }).collect();
    let infer_loop = median_us(reps, || {
        for (i, label) in onehot.iter().enumerate() {
            run.input_real("x", x.row(i)).unwrap();
            run.input_real("label", label).unwrap();
            black_box(run.forward().unwrap());
        }
    });
    report("infer_loop", infer_loop);

    for threads in [1, 2] {
        let trainer = Trainer::new(&scene, options(threads)).unwrap_or_else(|e| panic!("{e}"));
        let us = median_us(reps, || {
            black_box(trainer.evaluate(&data).unwrap());
        });
        report(&format!("infer_{threads}thread"), us);
    }
    let mut losses = Vec::new();
    for threads in [1, 2] {
        let us = median_us(reps, || {
            let mut trainer = Trainer::new(&scene, options(threads)).unwrap();
            let r = trainer.fit(&data, None, |_, _| {}, |_| {}).unwrap();
            black_box(&r);
            losses.push((threads, r[0].train_loss));
        });
        report(&format!("train_{threads}thread"), us);
    }
    let (l1, l2) = (losses.iter().find(|l| l.0 == 1).unwrap().1, losses.iter().find(|l| l.0 == 2).unwrap().1);
    println!("  epoch train loss: {l1:.6} (1 thread), {l2:.6} (2 threads)");
    if let (Some(setup), Some(peak)) = (rss_setup, peak_rss_mib()) {
        println!("  peak RSS: {peak:.1} MiB (after compiling and drawing the data: {setup:.1} MiB)");
        println!("gwml_cnn_peak_rss_mib {peak:.1}");
    }
    println!("gwml_cnn_examples {EXAMPLES}");
    println!("gwml_cnn_reps {reps}");
}
