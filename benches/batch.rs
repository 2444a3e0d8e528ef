//! Batches of the standard workload W1 over both cores: 1,024 TaylorF2
//! 3.5PN waveforms (m1 = 36, m2 = 29 Msun, non-spinning, 400 Mpc,
//! 20..1024 Hz at df = 1/8 Hz, 8,033 bins, f64) whose chirp mass varies by
//! ±1% around the W1 value (q = 29/36 fixed), through `Scene::batch`.
//!
//!     cargo bench --bench batch
//!
//! Measures the median wall time of one whole batch (`GWML_BENCH_REPS`
//! batches, default 7, after one warm-up) for
//! - `strain`: forward, the complex strain of every item (8,033 complex
//!   values copied out per item, as `Outputs` holds them);
//! - `loss`: forward, the likelihood 0.5 (d-h|d-h) alone;
//! - `value_and_grad`: that likelihood and its gradient w.r.t.
//!   (mc, q, tc, phic), one fused kernel call per item;
//!
//! each with a plain loop over one `Run` on this thread (no batch), a batch
//! on 1 thread, and a batch on a local pool of 2 threads; and prints the
//! speed-up of 2 threads over 1. The data and PSD are those of
//! `benches/taylorf2.rs`. Results of 1 and 2 threads are checked to be
//! identical bit for bit.
//!
//! Lines starting with `gwml_` are machine-readable (`name value`).

use gwml::batch::{Batch, Mode};
use gwml::{Model, Outputs, Scene, Value};
use gwml_lab::timing::median_us;
use num_complex::Complex64 as C64;
use std::hint::black_box;

/// Scenes `w1_strain` and `w1_fit`.
const SOURCE: &str = include_str!("w1.gw");

/// W1's chirp mass: (m1 m2)^(3/5) / (m1 + m2)^(1/5) for 36 and 29 Msun.
const MC_W1: f64 = 28.09555579546043;
const ITEMS: usize = 1024;

fn bits(outs: &[Outputs]) -> Vec<u64> {
    let mut b = Vec::new();
    for o in outs {
        for (_, v) in &o.values {
            match v {
                Value::Real(x) => b.push(x.to_bits()),
                Value::ComplexArray(a) => b.extend(a.iter().flat_map(|z| [z.re.to_bits(), z.im.to_bits()])),
                other => panic!("unexpected output {other:?}"),
            }
        }
        b.extend(o.grads.iter().map(|g| g.2.to_bits()));
    }
    b
}

/// Times one workload three ways; returns (loop, 1 thread, 2 threads) in ms per batch.
fn measure(name: &str, scene: &Scene, d: Option<&[C64]>, mcs: &[f64], mode: Mode, reps: usize) -> (f64, f64, f64) {
    let batch = |threads| {
        let b = Batch::new(&["mc"], mcs).mode(mode).threads(Some(threads));
        match d {
            Some(d) => b.input_complex("d", d),
            None => b,
        }
    };
    let (one, two) = (batch(1), batch(2));
    assert_eq!(
        bits(&scene.batch(&one).unwrap_or_else(|e| panic!("{e}"))),
        bits(&scene.batch(&two).unwrap_or_else(|e| panic!("{e}"))),
        "{name}: 1 and 2 threads differ"
    );
    let mut run = scene.bind();
    if let Some(d) = d {
        run.input_complex("d", d).unwrap();
    }
    let plain = median_us(reps, || {
        for mc in mcs {
            run.param("mc", *mc).unwrap();
            black_box(match mode {
                Mode::Forward => run.forward().unwrap(),
                Mode::ValueAndGrad => run.value_and_grad().unwrap(),
            });
        }
    }) / 1e3;
    let t1 = median_us(reps, || {
        black_box(scene.batch(&one).unwrap());
    }) / 1e3;
    let t2 = median_us(reps, || {
        black_box(scene.batch(&two).unwrap());
    }) / 1e3;
    println!("  {name:<16} {plain:>10.1} ms {t1:>10.1} ms {t2:>10.1} ms {:>9.2}x {:>10.1} µs", t1 / t2, t2 * 1e3 / ITEMS as f64);
    println!("gwml_batch_{name}_loop_ms {plain:.3}");
    println!("gwml_batch_{name}_1thread_ms {t1:.3}");
    println!("gwml_batch_{name}_2threads_ms {t2:.3}");
    (plain, t1, t2)
}

fn main() {
    let reps: usize = std::env::var("GWML_BENCH_REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(7);
    let model = Model::from_source("batch_w1.gw", SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let strain = model.scene(Some("w1_strain")).unwrap_or_else(|e| panic!("{e}"));
    let fit = model.scene(Some("w1_fit")).unwrap_or_else(|e| panic!("{e}"));
    let d = match strain.bind().forward().unwrap().value("h").unwrap() {
        Value::ComplexArray(h) => h.clone(),
        other => panic!("strain output is not a complex array: {other:?}"),
    };
    // Chirp masses spread evenly over ±1% of W1's.
    let mcs: Vec<f64> = (0..ITEMS).map(|i| MC_W1 * (0.99 + 0.02 * i as f64 / (ITEMS - 1) as f64)).collect();
    println!(
        "batch W1: {ITEMS} TaylorF2 3.5PN waveforms (mc {:.3}..{:.3} Msun, q = 29/36), {} bins, f64, median of {reps} batches",
        mcs[0],
        mcs[ITEMS - 1],
        d.len()
    );
    println!("  {:<16} {:>13} {:>13} {:>13} {:>10} {:>13}", "per batch", "Run loop", "1 thread", "2 threads", "speed-up", "2 thr./item");
    measure("strain", &strain, None, &mcs, Mode::Forward, reps);
    measure("loss", &fit, Some(&d), &mcs, Mode::Forward, reps);
    measure("value_and_grad", &fit, Some(&d), &mcs, Mode::ValueAndGrad, reps);
    println!("gwml_batch_items {ITEMS}");
    println!("gwml_batch_reps {reps}");
}
