//! The shipped classifier as a scan runs it: its trained template params
//! compiled in as constants (`Options::frozen_params`).

use gwml_compiler::Options;
use gwml_runtime::checkpoint;
use gwml_runtime::{Model, Value};
use gwml_strain::classifier::{softmax, Classifier, Manifest};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_pcg::Pcg64;

/// A window of unit-variance noise with a sine-Gaussian of `amplitude` at 0.5 s.
fn window(n: usize, fs: f64, amplitude: f64) -> Vec<f64> {
    let mut rng = Pcg64::seed_from_u64(12345);
    (0..n)
        .map(|i| {
            let t = i as f64 / fs - 0.5;
            rng.sample::<f64, _>(StandardNormal) + amplitude * (-(t / 0.01).powi(2)).exp() * (2.0 * std::f64::consts::PI * 150.0 * t).sin()
        })
        .collect()
}

#[test]
fn the_shipped_classifier_compiles_its_params_in_and_classifies_as_with_them_bound() {
    let frozen = Classifier::shipped().unwrap();
    assert!(frozen.scene().ir().params.is_empty(), "every trained param is a constant");
    // The same model with its params bound at run time.
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let manifest = Manifest::read(&root.join("models/glitch-classifier/glitch-classifier.json")).unwrap();
    let model = Model::from_file(&manifest.model).unwrap();
    let options = Options { outputs: Some(vec![manifest.output.clone()]), ..Options::default() };
    let scene = model.scene_with(manifest.scene.as_deref(), options).unwrap();
    assert_eq!(scene.ir().params.len(), 38, "18 templates' frequency and Q, 2 chirp masses");
    let mut run = scene.bind();
    run.load_weights(&checkpoint::load(&manifest.weights).unwrap()).unwrap();
    let x = window(manifest.window(), manifest.sample_rate, 3.0);
    run.input_real(&manifest.input, &x).unwrap();
    let out = run.forward().unwrap();
    let Value::RealArray(logits) = out.value(&manifest.output).unwrap() else { panic!("logits are an array") };
    let bound = softmax(logits);
    let verdict = frozen.classify(&x).unwrap();
    // f32 kernels: the frozen templates are tables computed in f64.
    for (class, (p, q)) in manifest.classes.iter().zip(bound.iter().zip(&verdict.probabilities)) {
        assert!((p - q).abs() < 2e-3, "{class}: {p} bound, {q} frozen");
    }
    let top = bound.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap().0;
    assert_eq!(verdict.label, top);
    assert!(bound[top] > 0.5, "a loud glitch is not a toss-up: {bound:?}");
}

/// The shipped weights carry a deployment prior folded into the output bias
/// (`scripts/fold_prior.py`): with the fold taken back out, the same model's
/// posteriors reweighted by Bayes' rule to that prior are the shipped ones.
#[test]
fn the_shipped_weights_give_the_trained_posteriors_moved_to_their_stated_prior() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let manifest = Manifest::read(&root.join("models/glitch-classifier/glitch-classifier.json")).unwrap();
    let shipped = checkpoint::load(&manifest.weights).unwrap();
    let prior: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(&shipped.metadata["deployment_prior"]).expect("the prior is stated in the metadata");
    let prior: Vec<f64> = manifest.classes.iter().map(|c| prior[c].as_f64().unwrap()).collect();
    assert!((prior.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{prior:?}");
    assert!(prior[0] < 1.0 / 8.0, "noise is rarer among a scan's triggers than in training: {prior:?}");
    let k = prior.len() as f64;
    let bias = &shipped.metadata["prior_folded_into"];
    let mut trained = shipped.clone();
    let tensor = trained.tensors.iter_mut().find(|t| &t.name == bias).unwrap();
    tensor.data.iter_mut().zip(&prior).for_each(|(b, p)| *b -= (p * k).ln());

    let model = Model::from_file(&manifest.model).unwrap();
    let options = Options { outputs: Some(vec![manifest.output.clone()]), ..Options::default() };
    let scene = model.scene_with(manifest.scene.as_deref(), options).unwrap();
    // A faint burst, so no class's posterior is near 0 or 1.
    let x = window(manifest.window(), manifest.sample_rate, 0.4);
    let posteriors = |weights| {
        let mut run = scene.bind();
        run.load_weights(weights).unwrap();
        run.input_real(&manifest.input, &x).unwrap();
        let out = run.forward().unwrap();
        let Value::RealArray(logits) = out.value(&manifest.output).unwrap() else { panic!("logits are an array") };
        softmax(logits)
    };
    let moved: Vec<f64> = posteriors(&trained).iter().zip(&prior).map(|(p, q)| p * q * k).collect();
    let total: f64 = moved.iter().sum();
    let shipped = posteriors(&shipped);
    assert!(shipped[0] > 0.05 && shipped[0] < 0.95, "the window is a toss-up: {shipped:?}");
    for (class, (m, s)) in manifest.classes.iter().zip(moved.iter().zip(&shipped)) {
        assert!((m / total - s).abs() < 1e-6, "{class}: {} by Bayes' rule, {s} shipped", m / total);
    }
}
