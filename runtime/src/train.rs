//! Training: minimises a scene's loss output over the weights of its
//! learned components (and the params the loss's `grad` names) by
//! mini-batch gradient descent over a labelled dataset.
//!
//! Each example binds one row of every dataset array to the scene input of
//! the same name (a 1-D array of class indices is expanded to one-hot rows
//! when the input has one element per class). A batch is split into one
//! contiguous chunk per thread; each thread runs the fused value-and-gradient
//! kernel on its examples with its own [`Run`] and sums in example order, and
//! the chunk sums are added in chunk order: with the same thread count a
//! run is bit-for-bit reproducible, which is what makes `resume` exact.
//!
//! Checkpoints (safetensors, see [`crate::checkpoint`]) hold every weight
//! under its scene name (`component.weight`) with its shape, the trained
//! params as 0-D tensors, the optimiser's moments, and in the metadata the
//! epoch, step and early-stopping state.

use crate::checkpoint::{self, Checkpoint, Tensor};
use crate::dataset::{Array, Dataset};
use crate::optim::{OptimConfig, OptimState, Optimizer};
use crate::{Error, Outputs, Run, Scene, Value};
use gwml_compiler::ir::{Function, InputRole, Shape};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// How to train.
#[derive(Clone, Debug)]
pub struct TrainOptions {
    /// The output to minimise (a real scalar with a `grad ... wrt`).
    pub loss: String,
    /// An array output whose largest element is the predicted class
    /// (accuracy is reported when it and `label` exist).
    pub logits: String,
    /// The input holding one-hot labels.
    pub label: String,
    /// Passes over the training data.
    pub epochs: usize,
    /// Examples per gradient step.
    pub batch: usize,
    /// Optimiser, learning rate, schedule and clipping.
    pub optim: OptimConfig,
    /// Seed of the per-epoch shuffles.
    pub seed: u64,
    /// Worker threads (results depend on this number only through summation order).
    pub threads: usize,
    /// Stop after this many epochs without a lower validation loss.
    pub patience: Option<usize>,
    /// Directory for `last.safetensors` (every epoch) and `best.safetensors`.
    pub checkpoint_dir: Option<PathBuf>,
}

/// What one epoch measured.
#[derive(Clone, Debug, PartialEq)]
pub struct EpochReport {
    /// Epoch number, from 1.
    pub epoch: usize,
    /// Mean training loss over the epoch's batches (at the weights each batch saw).
    pub train_loss: f64,
    /// Training accuracy over the epoch (when the scene has logits and labels).
    pub train_accuracy: Option<f64>,
    /// Validation metrics at the end of the epoch.
    pub val: Option<Metrics>,
    /// Learning rate of the epoch's last step.
    pub lr: f64,
    /// Whether early stopping ends training after this epoch.
    pub stop: bool,
}

/// Loss and accuracy over a dataset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Mean loss.
    pub loss: f64,
    /// Fraction of examples whose largest logit is the labelled class.
    pub accuracy: Option<f64>,
}

/// One trainable block of the flat parameter vector.
#[derive(Clone, Debug)]
enum Slot {
    /// A weight tensor: a trainable input.
    Weight { name: String, dims: Vec<usize>, offset: usize, len: usize },
    /// A scene param (declared units), kept inside its bounds.
    Param { name: String, offset: usize, bounds: Option<(f64, f64)> },
}

/// A model being trained: the current values, the optimiser and the epoch.
pub struct Trainer<'s> {
    scene: &'s Scene,
    opts: TrainOptions,
    slots: Vec<Slot>,
    values: Vec<f64>,
    /// Inputs drawn afresh per example and step (dropout masks and
    /// `randn` noise): (input name, role, elements).
    draws: Vec<(String, InputRole, usize)>,
    optim: Optimizer,
    epoch: usize,
    best_val: f64,
    bad_epochs: usize,
    pool: rayon::ThreadPool,
}

/// This process's place among processes that train one model together:
/// each computes its share of every batch, and `sum` adds a vector over all
/// of them (an allreduce), so every process takes the same step.
pub struct Group<'g> {
    /// This process, from 0.
    pub rank: usize,
    /// Number of processes.
    pub size: usize,
    /// Sums `values` elementwise over the processes, in place, on all of them.
    pub sum: &'g dyn Fn(&mut [f64]),
}

impl Group<'_> {
    /// This process's contiguous part of `indices`.
    fn share<'i>(&self, indices: &'i [usize]) -> &'i [usize] {
        &indices[indices.len() * self.rank / self.size..indices.len() * (self.rank + 1) / self.size]
    }

    /// `part` summed over the processes.
    fn reduce(&self, part: &mut Partial) {
        let mut flat = Vec::with_capacity(3 + part.grad_sum.len());
        flat.extend([part.loss_sum, part.correct as f64, part.counted as f64]);
        flat.extend(&part.grad_sum);
        (self.sum)(&mut flat);
        (part.loss_sum, part.correct, part.counted) = (flat[0], flat[1] as usize, flat[2] as usize);
        part.grad_sum.copy_from_slice(&flat[3..]);
    }
}

impl<'s> Trainer<'s> {
    /// Prepares to train `scene` from its initial weights and param defaults.
    pub fn new(scene: &'s Scene, opts: TrainOptions) -> Result<Trainer<'s>, Error> {
        let func = scene.ir();
        let oi = func
            .outputs
            .iter()
            .position(|o| o.name == opts.loss)
            .ok_or_else(|| crate::unknown("output", &opts.loss, func.outputs.iter().map(|o| o.name.as_str())))?;
        let mut slots = Vec::new();
        let mut values = Vec::new();
        for g in func.input_grads.iter().filter(|g| g.output == oi) {
            let input = &func.inputs[g.input];
            let dims = match input.ty.shape {
                Shape::Grid(gid) => func.grid(gid).dims.clone(),
                Shape::Scalar => vec![],
            };
            let init = input.default.as_ref().ok_or_else(|| Error::Bind(format!("weight `{}` has no initial value", input.name)))?;
            slots.push(Slot::Weight { name: input.name.clone(), dims, offset: values.len(), len: init.len() });
            values.extend(init.iter().map(|z| z.re));
        }
        for g in func.grads.iter().filter(|g| g.output == oi) {
            let p = &func.params[g.param];
            let v = p.default.ok_or_else(|| Error::Bind(format!("param `{}` has no default to start training from", p.name)))?;
            slots.push(Slot::Param { name: p.name.clone(), offset: values.len(), bounds: p.bounds });
            values.push(v);
        }
        if slots.is_empty() {
            return Err(Error::Bind(format!(
                "scene `{}` declares no gradient of `{}`: add `grad {} wrt [COMPONENT, ...]`",
                func.name, opts.loss, opts.loss
            )));
        }
        if opts.batch == 0 || opts.threads == 0 {
            return Err(Error::Bind("the batch size and the thread count must be at least 1".into()));
        }
        let draws = func
            .inputs
            .iter()
            .filter(|i| matches!(i.role, InputRole::DropoutMask(_) | InputRole::Noise))
            .map(|i| (i.name.clone(), i.role, func.len_of(i.ty.shape)))
            .collect();
        let optim = Optimizer::new(opts.optim, values.len())?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(opts.threads)
            .build()
            .map_err(|e| Error::Bind(format!("cannot start {} training threads: {e}", opts.threads)))?;
        Ok(Trainer { scene, opts, slots, values, draws, optim, epoch: 0, best_val: f64::INFINITY, bad_epochs: 0, pool })
    }

    /// Epochs completed so far.
    pub fn epoch(&self) -> usize {
        self.epoch
    }

    /// The current value of each weight tensor, by scene name.
    pub fn weights(&self) -> Vec<(String, Vec<f64>)> {
        self.slots
            .iter()
            .filter_map(|s| match s {
                Slot::Weight { name, offset, len, .. } => Some((name.clone(), self.values[*offset..offset + len].to_vec())),
                Slot::Param { .. } => None,
            })
            .collect()
    }

    /// The current value of trained param `name` (declared unit).
    pub fn param(&self, name: &str) -> Option<f64> {
        self.slots.iter().find_map(|s| match s {
            Slot::Param { name: n, offset, .. } if n == name => Some(self.values[*offset]),
            _ => None,
        })
    }

    /// Trains for the remaining epochs (up to [`TrainOptions::epochs`]),
    /// calling `on_batch(done, total)` after each step and `on_epoch` after
    /// each epoch; writes checkpoints when a directory is set.
    pub fn fit(
        &mut self,
        train: &Dataset,
        val: Option<&Dataset>,
        on_batch: impl FnMut(usize, usize),
        on_epoch: impl FnMut(&EpochReport),
    ) -> Result<Vec<EpochReport>, Error> {
        self.fit_in(None, train, val, on_batch, on_epoch)
    }

    /// [`Trainer::fit`] as one of the processes of `group`, which share
    /// every batch and validation pass: each computes its contiguous part,
    /// the partial losses, counts and gradients are summed over all (an
    /// allreduce) and all take the same step, so `size` processes at batch
    /// B follow one process at batch B up to summation order. Only rank 0
    /// writes checkpoints.
    pub fn fit_in(
        &mut self,
        group: Option<&Group<'_>>,
        train: &Dataset,
        val: Option<&Dataset>,
        mut on_batch: impl FnMut(usize, usize),
        mut on_epoch: impl FnMut(&EpochReport),
    ) -> Result<Vec<EpochReport>, Error> {
        let train_data = Examples::new(self.scene.ir(), train, &self.opts)?;
        let val_data = val.map(|v| Examples::new(self.scene.ir(), v, &self.opts)).transpose()?;
        let n = train_data.len;
        if n == 0 {
            return Err(Error::Bind("the training set is empty".into()));
        }
        let mut reports = Vec::new();
        while self.epoch < self.opts.epochs {
            let mut order: Vec<usize> = (0..n).collect();
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(self.opts.seed ^ (self.epoch as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            order.shuffle(&mut rng);
            let (mut loss_sum, mut correct, mut counted, mut lr) = (0.0, 0usize, 0usize, self.opts.optim.lr);
            let batches = n.div_ceil(self.opts.batch);
            for (bi, batch) in order.chunks(self.opts.batch).enumerate() {
                let step = self.batch_step(&train_data, batch, group)?;
                loss_sum += step.loss_sum;
                correct += step.correct;
                counted += step.counted;
                let mean: Vec<f64> = step.grad_sum.iter().map(|g| g / batch.len() as f64).collect();
                let info = self.optim.step(&mut self.values, &mean)?;
                lr = info.lr;
                self.clamp_params();
                on_batch(bi + 1, batches);
            }
            self.epoch += 1;
            let val_metrics = val_data.as_ref().map(|v| self.evaluate_examples(v, group)).transpose()?;
            let mut stop = false;
            let mut improved = false;
            if let Some(m) = val_metrics {
                if m.loss < self.best_val {
                    self.best_val = m.loss;
                    self.bad_epochs = 0;
                    improved = true;
                } else {
                    self.bad_epochs += 1;
                    stop = self.opts.patience.is_some_and(|p| self.bad_epochs >= p);
                }
            }
            let report = EpochReport {
                epoch: self.epoch,
                train_loss: loss_sum / n as f64,
                train_accuracy: (counted > 0).then(|| correct as f64 / counted as f64),
                val: val_metrics,
                lr,
                stop,
            };
            let writer = group.is_none_or(|g| g.rank == 0);
            if let Some(dir) = self.opts.checkpoint_dir.as_ref().filter(|_| writer) {
                let ck = self.checkpoint();
                checkpoint::save(&dir.join("last.safetensors"), &ck)?;
                if improved || val_metrics.is_none() {
                    checkpoint::save(&dir.join("best.safetensors"), &ck)?;
                }
            }
            on_epoch(&report);
            reports.push(report);
            if stop {
                break;
            }
        }
        Ok(reports)
    }

    /// Loss and accuracy of the current weights over `data` (forward only).
    pub fn evaluate(&self, data: &Dataset) -> Result<Metrics, Error> {
        let ex = Examples::new(self.scene.ir(), data, &self.opts)?;
        self.evaluate_examples(&ex, None)
    }

    fn evaluate_examples(&self, ex: &Examples<'_>, group: Option<&Group<'_>>) -> Result<Metrics, Error> {
        let all: Vec<usize> = (0..ex.len).collect();
        let parts = self.run_chunks(ex, group.map_or(&all[..], |g| g.share(&all)), false)?;
        let (loss, correct, counted) = parts.iter().fold((0.0, 0, 0), |(l, c, k), p| (l + p.loss_sum, c + p.correct, k + p.counted));
        let mut total = Partial { loss_sum: loss, correct, counted, grad_sum: Vec::new() };
        if let Some(g) = group {
            g.reduce(&mut total);
        }
        let Partial { loss_sum: loss, correct, counted, .. } = total;
        Ok(Metrics { loss: loss / ex.len.max(1) as f64, accuracy: (counted > 0).then(|| correct as f64 / counted as f64) })
    }

    /// Value and gradient summed over the examples `batch` (over the
    /// group's processes, each computing its share).
    fn batch_step(&self, ex: &Examples<'_>, batch: &[usize], group: Option<&Group<'_>>) -> Result<Partial, Error> {
        let parts = self.run_chunks(ex, group.map_or(batch, |g| g.share(batch)), true)?;
        let mut total = Partial { loss_sum: 0.0, correct: 0, counted: 0, grad_sum: vec![0.0; self.values.len()] };
        for p in parts {
            total.loss_sum += p.loss_sum;
            total.correct += p.correct;
            total.counted += p.counted;
            for (t, g) in total.grad_sum.iter_mut().zip(&p.grad_sum) {
                *t += g;
            }
        }
        if let Some(g) = group {
            g.reduce(&mut total);
        }
        Ok(total)
    }

    /// The predicted class of every example of `data`, in order: the index
    /// of the largest element of the logits output (forward only, over all
    /// threads).
    pub fn predict_classes(&self, data: &Dataset) -> Result<Vec<usize>, Error> {
        let ex = Examples::new(self.scene.ir(), data, &self.opts)?;
        let all: Vec<usize> = (0..ex.len).collect();
        let parts = self.in_chunks(&all, |chunk| {
            let mut run = self.scene.bind();
            self.bind_values(&mut run)?;
            let mut classes = Vec::with_capacity(chunk.len());
            for &i in chunk {
                ex.bind(&mut run, i)?;
                let out = run.forward()?;
                match out.value(&self.opts.logits)? {
                    Value::RealArray(z) => classes.push(argmax(z)),
                    _ => return Err(Error::Bind(format!("output `{}` is not a real array of logits", self.opts.logits))),
                }
            }
            Ok(classes)
        })?;
        Ok(parts.into_iter().flatten().collect())
    }

    /// Runs `indices` in one contiguous chunk per thread; results in chunk order.
    fn run_chunks(&self, ex: &Examples<'_>, indices: &[usize], grad: bool) -> Result<Vec<Partial>, Error> {
        self.in_chunks(indices, |c| self.run_chunk(ex, c, grad))
    }

    /// Splits `indices` into one contiguous chunk per thread and maps `f`
    /// over the chunks in the trainer's pool; results in chunk order.
    fn in_chunks<R: Send>(&self, indices: &[usize], f: impl Fn(&[usize]) -> Result<R, Error> + Sync) -> Result<Vec<R>, Error> {
        let size = indices.len().div_ceil(self.opts.threads).max(1);
        let chunks: Vec<&[usize]> = indices.chunks(size).collect();
        let out: Vec<Result<R, Error>> = self.pool.install(|| {
            use rayon::prelude::*;
            chunks.par_iter().map(|c| f(c)).collect()
        });
        out.into_iter().collect()
    }

    fn run_chunk(&self, ex: &Examples<'_>, chunk: &[usize], grad: bool) -> Result<Partial, Error> {
        let mut run = self.scene.bind();
        self.bind_values(&mut run)?;
        let mut part =
            Partial { loss_sum: 0.0, correct: 0, counted: 0, grad_sum: if grad { vec![0.0; self.values.len()] } else { vec![] } };
        for &i in chunk {
            ex.bind(&mut run, i)?;
            if grad {
                self.bind_draws(&mut run, i)?;
            }
            let out = if grad { run.value_and_grad()? } else { run.forward()? };
            part.loss_sum += out.scalar(&self.opts.loss)?;
            if let Some(hit) = ex.correct(&out, &self.opts, i) {
                part.counted += 1;
                part.correct += hit as usize;
            }
            if grad {
                self.add_grads(&out, &mut part.grad_sum)?;
            }
        }
        Ok(part)
    }

    /// Fresh dropout masks and `randn` noise for example `i` of this epoch,
    /// from a generator seeded by (seed, epoch, example), so resumed runs
    /// draw the same values.
    fn bind_draws(&self, run: &mut Run<'_>, i: usize) -> Result<(), Error> {
        if self.draws.is_empty() {
            return Ok(());
        }
        let seed =
            self.opts.seed ^ (self.epoch as u64).wrapping_mul(0xD1B5_4A32_D192_ED03) ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        for (name, role, len) in &self.draws {
            let values: Vec<f64> = match *role {
                InputRole::DropoutMask(rate) => {
                    let keep = 1.0 / (1.0 - rate);
                    (0..*len).map(|_| if rng.random_bool(rate) { 0.0 } else { keep }).collect()
                }
                _ => (0..*len).map(|_| rng.sample::<f64, _>(rand_distr::StandardNormal)).collect(),
            };
            run.input_real(name, &values)?;
        }
        Ok(())
    }

    fn add_grads(&self, out: &Outputs, sum: &mut [f64]) -> Result<(), Error> {
        for slot in &self.slots {
            match slot {
                Slot::Weight { name, offset, len, .. } => {
                    let g = out.input_grad(&self.opts.loss, name)?;
                    for (s, x) in sum[*offset..offset + len].iter_mut().zip(g) {
                        *s += x;
                    }
                }
                Slot::Param { name, offset, .. } => sum[*offset] += out.grad(&self.opts.loss, name)?,
            }
        }
        Ok(())
    }

    /// Binds the current weights and params to `run`.
    fn bind_values(&self, run: &mut Run<'_>) -> Result<(), Error> {
        for slot in &self.slots {
            match slot {
                Slot::Weight { name, offset, len, .. } => {
                    run.input_real(name, &self.values[*offset..offset + len])?;
                }
                Slot::Param { name, offset, .. } => {
                    run.param(name, self.values[*offset])?;
                }
            }
        }
        Ok(())
    }

    fn clamp_params(&mut self) {
        for slot in &self.slots {
            if let Slot::Param { offset, bounds: Some((lo, hi)), .. } = slot {
                self.values[*offset] = self.values[*offset].clamp(*lo, *hi);
            }
        }
    }

    /// The current state as a checkpoint.
    pub fn checkpoint(&self) -> Checkpoint {
        let mut tensors = Vec::new();
        for slot in &self.slots {
            match slot {
                Slot::Weight { name, dims, offset, len } => {
                    tensors.push(Tensor { name: name.clone(), shape: dims.clone(), data: self.values[*offset..offset + len].to_vec() })
                }
                Slot::Param { name, offset, .. } => {
                    tensors.push(Tensor { name: name.clone(), shape: vec![], data: vec![self.values[*offset]] })
                }
            }
        }
        let state = self.optim.state();
        for (name, data) in [("optimizer.first_moment", state.first_moment), ("optimizer.second_moment", state.second_moment)] {
            if !data.is_empty() {
                tensors.push(Tensor { name: name.into(), shape: vec![data.len()], data });
            }
        }
        let mut metadata = BTreeMap::new();
        metadata.insert("format".to_string(), "gwml-checkpoint-1".to_string());
        metadata.insert("scene".to_string(), self.scene.ir().name.clone());
        metadata.insert("epoch".to_string(), self.epoch.to_string());
        metadata.insert("step".to_string(), state.step.to_string());
        metadata.insert("best_val_loss".to_string(), format!("{:e}", self.best_val));
        metadata.insert("bad_epochs".to_string(), self.bad_epochs.to_string());
        Checkpoint { tensors, metadata }
    }

    /// Continues from a checkpoint written by [`Trainer::fit`]: weights,
    /// params, optimiser state, epoch and early-stopping state.
    pub fn resume(&mut self, path: &Path) -> Result<(), Error> {
        let ck = checkpoint::load(path)?;
        self.load_values(&ck, path)?;
        let meta = |k: &str| {
            ck.metadata
                .get(k)
                .ok_or_else(|| Error::Io(format!("{} is not a gwml training checkpoint (no `{k}` in its metadata)", path.display())))
        };
        let parse_err = |k: &str| Error::Io(format!("{}: bad `{k}` in the checkpoint metadata", path.display()));
        self.epoch = meta("epoch")?.parse().map_err(|_| parse_err("epoch"))?;
        let step: u64 = meta("step")?.parse().map_err(|_| parse_err("step"))?;
        self.best_val = meta("best_val_loss")?.parse().map_err(|_| parse_err("best_val_loss"))?;
        self.bad_epochs = meta("bad_epochs")?.parse().map_err(|_| parse_err("bad_epochs"))?;
        let moment = |name: &str| ck.get(name).map(|t| t.data.clone()).unwrap_or_default();
        self.optim.restore(OptimState {
            step,
            first_moment: moment("optimizer.first_moment"),
            second_moment: moment("optimizer.second_moment"),
        })
    }

    /// Sets every weight and trained param from `ck` (shapes must match).
    pub fn load_values(&mut self, ck: &Checkpoint, path: &Path) -> Result<(), Error> {
        for slot in &self.slots {
            let (name, offset, want) = match slot {
                Slot::Weight { name, dims, offset, .. } => (name, *offset, dims.clone()),
                Slot::Param { name, offset, .. } => (name, *offset, vec![]),
            };
            let t = ck.get(name).ok_or_else(|| Error::Io(format!("{} has no tensor `{name}`", path.display())))?;
            if t.shape != want {
                return Err(Error::Io(format!("{}: tensor `{name}` has shape {:?}, the scene needs {want:?}", path.display(), t.shape)));
            }
            self.values[offset..offset + t.data.len()].copy_from_slice(&t.data);
        }
        Ok(())
    }
}

/// Sums over some examples.
struct Partial {
    loss_sum: f64,
    correct: usize,
    counted: usize,
    grad_sum: Vec<f64>,
}

/// How each scene input gets its value for example `i`.
enum Source<'d> {
    /// Row `i` of an array with one value per input element.
    Rows(&'d Array),
    /// Class index `data[i]` as a one-hot row of `classes` values.
    OneHot(&'d Array, usize),
}

/// A dataset matched to a scene's inputs.
struct Examples<'d> {
    len: usize,
    sources: Vec<(String, Source<'d>)>,
    label: Option<usize>,
}

impl<'d> Examples<'d> {
    fn new(func: &Function, data: &'d Dataset, opts: &TrainOptions) -> Result<Examples<'d>, Error> {
        let len = data.examples()?;
        let mut sources = Vec::new();
        for input in func.inputs.iter().filter(|i| i.role == InputRole::Data) {
            let want = func.len_of(input.ty.shape);
            let a = match data.get(&input.name) {
                Ok(a) => a,
                Err(_) if input.default.is_some() => continue,
                Err(e) => return Err(e),
            };
            let row = a.row_len();
            let source = if row == want {
                Source::Rows(a)
            } else if a.shape.len() == 1 && want > 1 {
                if let Some(k) = a.data.iter().position(|c| !(c.fract() == 0.0 && *c >= 0.0 && (*c as usize) < want)) {
                    return Err(Error::Bind(format!("`{}`: label {} at row {k} is not a class index in 0..{want}", input.name, a.data[k])));
                }
                Source::OneHot(a, want)
            } else {
                return Err(Error::Bind(format!(
                    "`{}` in the data has rows of {row} values, but the scene's input has {want} (shape {:?} given)",
                    input.name, a.shape
                )));
            };
            sources.push((input.name.clone(), source));
        }
        let label = sources.iter().position(|(n, _)| *n == opts.label);
        Ok(Examples { len, sources, label })
    }

    fn bind(&self, run: &mut Run<'_>, i: usize) -> Result<(), Error> {
        for (name, source) in &self.sources {
            match source {
                Source::Rows(a) => {
                    run.input_real(name, a.row(i))?;
                }
                Source::OneHot(a, classes) => {
                    let mut row = vec![0.0; *classes];
                    row[a.data[i] as usize] = 1.0;
                    run.input_real(name, &row)?;
                }
            }
        }
        Ok(())
    }

    /// Whether the largest logit is the labelled class (`None` without both).
    fn correct(&self, out: &Outputs, opts: &TrainOptions, i: usize) -> Option<bool> {
        let label = self.label?;
        let Ok(Value::RealArray(logits)) = out.value(&opts.logits) else { return None };
        let predicted = argmax(logits);
        let truth = match &self.sources[label].1 {
            Source::Rows(a) => argmax(a.row(i)),
            Source::OneHot(a, _) => a.data[i] as usize,
        };
        Some(predicted == truth)
    }
}

/// Index of the first largest element.
pub fn argmax(x: &[f64]) -> usize {
    let mut best = 0;
    for (i, v) in x.iter().enumerate() {
        if *v > x[best] {
            best = i;
        }
    }
    best
}
