//! The glitch classifier a scan runs on every trigger: a gwml scene that
//! takes `duration_s` seconds of whitened strain at `sample_rate` Hz as
//! input `x` and outputs `logits`, one per class, with its trained weights.
//!
//! Described by a manifest, `glitch-classifier.json`:
//!
//! ```json
//! { "model": "cnn.gw", "weights": "cnn.safetensors",
//!   "classes": ["None", "Blip", "Koi Fish", "Whistle", "Scratchy", "Chirp"],
//!   "sample_rate": 4096, "duration_s": 1.0, "band_hz": [20, 2000] }
//! ```
//!
//! `model` and `weights` are paths relative to the manifest; `band_hz` (the
//! whitening band of the training data; default 20–2000 Hz), `scene`,
//! `input` and `output` are optional.
//!
//! The shipped weights carry the class shares of a scan's windows (noise
//! 4 %) folded into their output bias by `scripts/fold_prior.py`, so every
//! user of them gets posteriors for that prior; their metadata
//! (`deployment_prior`) states it.

use crate::Error;
use gwml_compiler::Options;
use gwml_runtime::checkpoint::{self, Checkpoint};
use gwml_runtime::{Model, Run, Scene, Value};
use std::path::{Path, PathBuf};

/// The name of the column holding the probability of `class` in trigger
/// tables (`gwml scan`'s CSV, `gwml.scan`): `p_koi_fish` for "Koi Fish".
pub fn probability_column(class: &str) -> String {
    format!("p_{}", class.to_lowercase().replace(' ', "_"))
}

/// A classifier's manifest.
#[derive(Clone, Debug, PartialEq)]
pub struct Manifest {
    /// The `.gw` file.
    pub model: PathBuf,
    /// Its trained weights (safetensors).
    pub weights: PathBuf,
    /// Class names in logit order.
    pub classes: Vec<String>,
    /// Sample rate of the input in Hz.
    pub sample_rate: f64,
    /// Input length in seconds.
    pub duration_s: f64,
    /// Band (Hz) the input is whitened over.
    pub band_hz: (f64, f64),
    /// The scene (`None`: the file's only scene, or `classify`).
    pub scene: Option<String>,
    /// Input name.
    pub input: String,
    /// Output name.
    pub output: String,
}

/// The shipped classifier (`models/glitch-classifier/`), embedded so a scan
/// works from anywhere: its manifest, model source and trained weights.
const SHIPPED_MANIFEST: &str = include_str!("../../models/glitch-classifier/glitch-classifier.json");
const SHIPPED_MODEL: &str = include_str!("../../lab/models/glitch/template_net.gw");
const SHIPPED_WEIGHTS: &[u8] = include_bytes!("../../models/glitch-classifier/template_net.safetensors");
const SHIPPED_PATH: &str = "models/glitch-classifier/glitch-classifier.json";

impl Manifest {
    /// The shipped classifier's manifest (its classes, sample rate and band
    /// are also the conventions for a bare model given with its weights).
    pub fn shipped() -> Result<Manifest, Error> {
        Manifest::parse(SHIPPED_MANIFEST, Path::new(SHIPPED_PATH))
    }

    /// Reads a manifest; relative paths are resolved against its folder.
    pub fn read(path: &Path) -> Result<Manifest, Error> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
        Manifest::parse(&text, path)
    }

    /// Parses a manifest's text; `path` is where it lives (errors name it,
    /// relative paths are resolved against its folder).
    pub fn parse(text: &str, path: &Path) -> Result<Manifest, Error> {
        let json: serde_json::Value = serde_json::from_str(text).map_err(|e| Error::file(path, format!("not valid JSON: {e}")))?;
        let field = |name: &str| json.get(name).ok_or_else(|| Error::file(path, format!("missing field `{name}`")));
        let string = |name: &str| -> Result<String, Error> {
            field(name)?.as_str().map(str::to_string).ok_or_else(|| Error::file(path, format!("field `{name}` must be a string")))
        };
        let number = |name: &str| -> Result<f64, Error> {
            let v = field(name)?.as_f64().ok_or_else(|| Error::file(path, format!("field `{name}` must be a number")))?;
            if v > 0.0 && v.is_finite() {
                Ok(v)
            } else {
                Err(Error::file(path, format!("field `{name}` must be positive, got {v}")))
            }
        };
        let base = path.parent().unwrap_or(Path::new("."));
        let classes: Vec<String> = field("classes")?
            .as_array()
            .and_then(|a| a.iter().map(|c| c.as_str().map(str::to_string)).collect::<Option<Vec<_>>>())
            .ok_or_else(|| Error::file(path, "field `classes` must be a list of names"))?;
        if classes.is_empty() {
            return Err(Error::file(path, "field `classes` is empty"));
        }
        let band_hz = match json.get("band_hz") {
            None => (20.0, 2000.0),
            Some(v) => match v.as_array().map(|a| a.iter().map(|x| x.as_f64()).collect::<Vec<_>>()).as_deref() {
                Some([Some(lo), Some(hi)]) if *lo >= 0.0 && hi > lo => (*lo, *hi),
                _ => return Err(Error::file(path, "field `band_hz` must be [low, high] in Hz, increasing")),
            },
        };
        let optional = |name: &str, default: &str| json.get(name).and_then(|v| v.as_str()).unwrap_or(default).to_string();
        Ok(Manifest {
            model: base.join(string("model")?),
            weights: base.join(string("weights")?),
            classes,
            sample_rate: number("sample_rate")?,
            duration_s: number("duration_s")?,
            band_hz,
            scene: json.get("scene").and_then(|v| v.as_str()).map(str::to_string),
            input: optional("input", "x"),
            output: optional("output", "logits"),
        })
    }

    /// Samples in one input window.
    pub fn window(&self) -> usize {
        (self.sample_rate * self.duration_s).round() as usize
    }
}

/// A compiled classifier with its weights.
pub struct Classifier {
    /// What it was built from.
    pub manifest: Manifest,
    scene: Scene,
    weights: Checkpoint,
}

/// One window's classification.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// Index of the most probable class.
    pub label: usize,
    /// Softmax probability per class, in manifest order.
    pub probabilities: Vec<f64>,
}

impl Classifier {
    /// The shipped classifier, compiled with its trained weights.
    pub fn shipped() -> Result<Classifier, Error> {
        let weights = checkpoint::parse(SHIPPED_WEIGHTS, "the shipped classifier's weights").map_err(|e| Error::Data(e.to_string()))?;
        Classifier::build(Manifest::shipped()?, SHIPPED_MODEL, weights)
    }

    /// Compiles the manifest's model and loads its weights.
    pub fn load(manifest: Manifest) -> Result<Classifier, Error> {
        let source = std::fs::read_to_string(&manifest.model).map_err(|e| Error::file(&manifest.model, format!("cannot read: {e}")))?;
        let weights = checkpoint::load(&manifest.weights).map_err(|e| Error::file(&manifest.weights, e.render(false)))?;
        Classifier::build(manifest, &source, weights)
    }

    /// A classifier from its manifest, the model's source text and its
    /// weights (the shipped classifier is embedded in the binary this way).
    pub fn build(manifest: Manifest, source: &str, weights: Checkpoint) -> Result<Classifier, Error> {
        let compile = |e: gwml_runtime::Error| Error::file(&manifest.model, e.render(false));
        let model = Model::from_source(&manifest.model.display().to_string(), source).map_err(compile)?;
        let scene_name = manifest.scene.clone().or_else(|| {
            let names = model.program.scene_names();
            (names.len() > 1).then(|| "classify".to_string())
        });
        // Only the logits: a training scene's loss and gradient are not
        // needed. The trained params are fixed for a classifier's life, so
        // they are compiled in as constants: what they alone determine
        // (the template bank's spectra) becomes tables instead of work on
        // every window.
        let params = &model.program.scene_ir(scene_name.as_deref()).map_err(|e| Error::file(&manifest.model, e))?.params;
        let frozen_params = weights
            .tensors
            .iter()
            .filter(|t| t.shape.is_empty() && params.iter().any(|p| p.name == t.name))
            .map(|t| (t.name.clone(), t.data[0]))
            .collect();
        let options = Options { outputs: Some(vec![manifest.output.clone()]), frozen_params, ..Options::default() };
        let scene = model.scene_with(scene_name.as_deref(), options).map_err(compile)?;
        let classifier = Classifier { manifest, scene, weights };
        // One trial run checks the input's length, the output's and the weights.
        let verdict = classifier.classify(&vec![0.0; classifier.manifest.window()])?;
        if verdict.probabilities.len() != classifier.manifest.classes.len() {
            return Err(Error::file(
                &classifier.manifest.model,
                format!(
                    "`{}` has {} values but the manifest names {} classes",
                    classifier.manifest.output,
                    verdict.probabilities.len(),
                    classifier.manifest.classes.len()
                ),
            ));
        }
        Ok(classifier)
    }

    /// The compiled scene (its trained params are constants in it).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Classifies one window of whitened strain.
    pub fn classify(&self, window: &[f64]) -> Result<Verdict, Error> {
        self.classify_with(&mut self.bind()?, window)
    }

    /// The classifier's scene bound with its weights, for
    /// [`Classifier::classify_with`]: binding copies every weight, so a
    /// scan binds once per worker rather than once per window.
    pub fn bind(&self) -> Result<Run<'_>, Error> {
        let mut run = self.scene.bind();
        run.load_weights(&self.weights).map_err(|e| Error::file(&self.manifest.weights, e.render(false)))?;
        Ok(run)
    }

    /// [`Classifier::classify`] with a run from [`Classifier::bind`].
    pub fn classify_with(&self, run: &mut Run<'_>, window: &[f64]) -> Result<Verdict, Error> {
        let m = &self.manifest;
        let fail = |e: gwml_runtime::Error| Error::file(&m.model, e.render(false));
        run.input_real(&m.input, window).map_err(fail)?;
        let out = run.forward().map_err(fail)?;
        let logits = match out.value(&m.output).map_err(fail)? {
            Value::RealArray(v) => v.clone(),
            Value::Real(v) => vec![*v],
            _ => return Err(Error::file(&m.model, format!("output `{}` must be real", m.output))),
        };
        let probabilities = softmax(&logits);
        if probabilities.iter().any(|p| !p.is_finite()) {
            return Err(Error::Data(format!("the classifier's logits are not finite: {logits:?}")));
        }
        let label = probabilities.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).map_or(0, |(i, _)| i);
        Ok(Verdict { label, probabilities })
    }
}

/// `exp(l_i) / Σ exp(l_j)`, shifted by the largest logit so it cannot overflow.
pub fn softmax(logits: &[f64]) -> Vec<f64> {
    let top = logits.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = logits.iter().map(|l| (l - top).exp()).collect();
    let sum: f64 = e.iter().sum();
    e.iter().map(|v| v / sum).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn softmax_is_a_distribution_even_for_huge_logits() {
        let p = softmax(&[1000.0, 999.0, -1000.0]);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!((p[0] / p[1] - std::f64::consts::E).abs() < 1e-12);
    }
}
