//! Training end to end: a small CNN learns to detect bursts, a resumed run
//! equals an uninterrupted one bit for bit, and a physics param trains
//! together with network weights.

use gwml_lab::synth::{bursts, BurstOptions};
use gwml_runtime::optim::{Method, OptimConfig, Schedule};
use gwml_runtime::train::{TrainOptions, Trainer};
use gwml_runtime::Model;

fn options(epochs: usize, lr: f64) -> TrainOptions {
    TrainOptions {
        loss: "loss".into(),
        logits: "logits".into(),
        label: "label".into(),
        epochs,
        batch: 32,
        optim: OptimConfig { method: Method::adam(), lr, schedule: Schedule::Constant, clip_norm: Some(10.0) },
        seed: 7,
        threads: 2,
        patience: None,
        checkpoint_dir: None,
    }
}

fn cnn() -> Model {
    Model::from_file(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/burst_cnn.gw")).unwrap()
}

#[test]
fn a_small_cnn_learns_to_detect_bursts() {
    let train = bursts(&BurstOptions { n: 1200, seed: 1, ..Default::default() }).unwrap();
    let val = bursts(&BurstOptions { n: 400, seed: 2, ..Default::default() }).unwrap();
    let model = cnn();
    let scene = model.scene(None).unwrap();
    let mut trainer = Trainer::new(&scene, options(8, 3e-3)).unwrap();
    let before = trainer.evaluate(&val).unwrap();
    let reports = trainer.fit(&train, Some(&val), |_, _| {}, |r| eprintln!("{r:?}")).unwrap();
    let after = reports.last().unwrap().val.unwrap();
    assert!(before.accuracy.unwrap() < 0.7, "untrained accuracy {:?}", before.accuracy);
    assert!(after.accuracy.unwrap() >= 0.95, "validation accuracy after 8 epochs: {:?}", after.accuracy);
    assert!(after.loss < before.loss);
}

#[test]
fn resuming_from_a_checkpoint_equals_an_uninterrupted_run() {
    let train = bursts(&BurstOptions { n: 160, seed: 3, ..Default::default() }).unwrap();
    let val = bursts(&BurstOptions { n: 64, seed: 4, ..Default::default() }).unwrap();
    let model = cnn();
    let scene = model.scene(None).unwrap();
    let dir = std::env::temp_dir().join(format!("gwml-resume-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    // Uninterrupted: 4 epochs.
    let mut straight = Trainer::new(&scene, options(4, 1e-3)).unwrap();
    straight.fit(&train, Some(&val), |_, _| {}, |_| {}).unwrap();
    // Interrupted after 2 epochs (checkpoint written), then resumed in a new trainer.
    let mut first = Trainer::new(&scene, TrainOptions { checkpoint_dir: Some(dir.clone()), ..options(2, 1e-3) }).unwrap();
    first.fit(&train, Some(&val), |_, _| {}, |_| {}).unwrap();
    let mut resumed = Trainer::new(&scene, options(4, 1e-3)).unwrap();
    resumed.resume(&dir.join("last.safetensors")).unwrap();
    assert_eq!(resumed.epoch(), 2);
    let reports = resumed.fit(&train, Some(&val), |_, _| {}, |_| {}).unwrap();
    assert_eq!(reports.len(), 2, "only the remaining epochs run");
    assert_eq!(resumed.weights(), straight.weights(), "resumed weights differ from the uninterrupted run");
    assert!(dir.join("best.safetensors").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_physics_param_and_network_weights_train_together() {
    // Teacher: y = Σ_t sg(t; f0 = 24 Hz) n(t) + w_true · z for random noise
    // series n and vectors z. The student starts at f0 = 18 Hz and w = 0;
    // both must move toward the teacher.
    let src = "use std::burst::{sine_gaussian}\n\
               learned head(z) {\n    weight w: [1, 3] = zeros\n    dense(z, w)\n}\n\
               scene s {\n  grid t = times(rate: 128 Hz, duration: 0.5 s)\n  grid k = index(3)\n  grid one = index(1)\n  \
               param f0: Hz = 18.0 in 5.0..60.0\n  input n: real[t] = 0.0\n  input z: real[k] = 0.0\n  input y: real[one] = 0.0\n  \
               let sg = sine_gaussian(t, t0: 0.25 s, f0: f0, q: 4.0, amp: 1.0)\n  \
               output loss = sum((sum(sg * n) + head(z) - y) * (sum(sg * n) + head(z) - y))\n  grad loss wrt [f0, head]\n}\n";
    let model = Model::from_source("joint.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let (f0_true, w_true) = (24.0, [0.5, -1.0, 2.0]);
    let data = {
        use gwml_runtime::dataset::{Array, Dataset};
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let n_ex = 256;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let mut normal = |k: usize| -> Vec<f64> { (0..k).map(|_| StandardNormal.sample(&mut rng)).collect() };
        let (noise, z) = (normal(n_ex * 64), normal(n_ex * 3));
        let y: Vec<f64> = (0..n_ex)
            .map(|i| sum_sg_n(f0_true, &noise[i * 64..(i + 1) * 64]) + (0..3).map(|k| w_true[k] * z[3 * i + k]).sum::<f64>())
            .collect();
        let mut arrays = std::collections::BTreeMap::new();
        arrays.insert("n".to_string(), Array::new(vec![n_ex, 64], noise).unwrap());
        arrays.insert("z".to_string(), Array::new(vec![n_ex, 3], z).unwrap());
        arrays.insert("y".to_string(), Array::new(vec![n_ex, 1], y).unwrap());
        Dataset { arrays }
    };
    let mut trainer = Trainer::new(&scene, TrainOptions { batch: 16, ..options(30, 0.05) }).unwrap();
    trainer.fit(&data, None, |_, _| {}, |_| {}).unwrap();
    let f0 = trainer.param("f0").unwrap();
    let w = &trainer.weights()[0].1;
    let dist: f64 = w.iter().zip(&w_true).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
    let dist0: f64 = w_true.iter().map(|b| b * b).sum::<f64>().sqrt();
    assert!((f0 - f0_true).abs() < 0.5, "f0 moved from 18 to {f0}, truth {f0_true}");
    assert!(dist < 0.1 * dist0, "weights {w:?}, truth {w_true:?}");
}

/// Σ_t sg(t) n(t) for the scene's sine-Gaussian (t0 = 0.25 s, Q = 4, 128 Hz).
fn sum_sg_n(f0: f64, n: &[f64]) -> f64 {
    let tau = 4.0 / (std::f64::consts::SQRT_2 * std::f64::consts::PI * f0);
    n.iter()
        .enumerate()
        .map(|(j, v)| {
            let dt = j as f64 / 128.0 - 0.25;
            (-(dt / tau).powi(2)).exp() * (std::f64::consts::TAU * f0 * dt).cos() * v
        })
        .sum()
}

/// One example, `x` = 400 ones, and plain SGD of rate 1: one step moves
/// each weight by minus its gradient.
fn one_example_of_ones() -> (gwml_runtime::dataset::Dataset, OptimConfig) {
    let mut arrays = std::collections::BTreeMap::new();
    arrays.insert("x".to_string(), gwml_runtime::dataset::Array::new(vec![1, 400], vec![1.0; 400]).unwrap());
    let sgd = OptimConfig { method: Method::sgd(0.0), lr: 1.0, schedule: Schedule::Constant, clip_norm: None };
    (gwml_runtime::dataset::Dataset { arrays }, sgd)
}

#[test]
fn dropout_masks_apply_while_training_and_not_in_evaluation() {
    // loss = Σ dropout(w, 0.5) · x with x = 1: one SGD step of rate 1 from
    // w = 0 on one example moves each weight by -mask (0 or -2); evaluation
    // uses no mask, so the loss is then Σ w.
    let src = "learned net(x) {\n    weight w: [400] = zeros\n    sum(dropout(w, 0.5) * x)\n}\n\
               scene s {\n  grid g = index(400)\n  input x: real[g] = 0.0\n  output loss = net(x)\n  grad loss wrt net\n}\n";
    let model = Model::from_source("dropout.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    assert!(
        matches!(scene.ir().inputs.iter().find(|i| i.name == "net.dropout1").unwrap().role, gwml_compiler::ir::InputRole::DropoutMask(r) if r == 0.5)
    );
    let (data, sgd) = one_example_of_ones();
    let mut trainer = Trainer::new(&scene, TrainOptions { batch: 1, threads: 1, optim: sgd, ..options(1, 1.0) }).unwrap();
    trainer.fit(&data, None, |_, _| {}, |_| {}).unwrap();
    let w = &trainer.weights()[0].1;
    let dropped = w.iter().filter(|v| **v == 0.0).count();
    assert!(w.iter().all(|v| *v == 0.0 || *v == -2.0), "{w:?}");
    assert!((150..250).contains(&dropped), "{dropped} of 400 dropped at rate 0.5");
    let eval = trainer.evaluate(&data).unwrap();
    assert_eq!(eval.loss, w.iter().sum::<f64>());
}

#[test]
fn randn_draws_standard_normal_noise_while_training_and_zeros_in_evaluation() {
    // loss = Σ randn(400) · w · x with x = 1: one SGD step of rate 1 from
    // w = 0 on one example moves the weights to minus the draws, which must
    // look standard normal; evaluation binds no noise, so its loss is 0.
    let src = "learned net(x) {\n    weight w: [400] = zeros\n    sum(randn(400) * w * x)\n}\n\
               scene s {\n  grid g = index(400)\n  input x: real[g] = 0.0\n  output loss = net(x)\n  grad loss wrt net\n}\n";
    let model = Model::from_source("noise.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    assert_eq!(scene.ir().inputs.iter().find(|i| i.name == "net.noise1").unwrap().role, gwml_compiler::ir::InputRole::Noise);
    let (data, sgd) = one_example_of_ones();
    let mut trainer = Trainer::new(&scene, TrainOptions { batch: 1, threads: 1, optim: sgd, ..options(1, 1.0) }).unwrap();
    trainer.fit(&data, None, |_, _| {}, |_| {}).unwrap();
    let first = trainer.weights()[0].1.clone();
    let mean = first.iter().sum::<f64>() / 400.0;
    let sd = (first.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / 399.0).sqrt();
    assert!(mean.abs() < 0.2 && (0.85..1.15).contains(&sd), "draws: mean {mean}, sd {sd}");
    assert_eq!(trainer.evaluate(&data).unwrap().loss, 0.0, "evaluation binds no noise");
    // The next epoch draws again.
    let mut second = Trainer::new(&scene, TrainOptions { batch: 1, threads: 1, optim: sgd, ..options(2, 1.0) }).unwrap();
    second.fit(&data, None, |_, _| {}, |_| {}).unwrap();
    let step2: Vec<f64> = second.weights()[0].1.iter().zip(&first).map(|(a, b)| a - b).collect();
    let corr = step2.iter().zip(&first).map(|(a, b)| a * b).sum::<f64>() / 400.0;
    assert!(step2.iter().any(|v| v.abs() > 0.1) && corr.abs() < 0.2, "fresh draws each epoch (correlation {corr})");
}
