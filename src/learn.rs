//! `gwml train`, `gwml predict` and `gwml data`: training learned
//! components on NumPy datasets, applying trained weights, and writing
//! synthetic datasets.

use crate::commands::{options, render, split_pair};
use crate::{DataArgs, PredictArgs, ScheduleArg, TrainArgs, TrainOptimizerArg};
use gwml::runtime::checkpoint;
use gwml::runtime::dataset::{self, Array, Dataset};
use gwml::runtime::optim::{Method, OptimConfig, Schedule};
use gwml::runtime::train::{EpochReport, Group, TrainOptions, Trainer};
use gwml::{Model, Value};
use gwml_lab::generator::GeneratorShapes;
use gwml_lab::parse_range;
use gwml_lab::synth::{bursts, glitches_with, BurstOptions, GlitchOptions, Shape, CENTRED, GLITCH_CLASSES};

use crate::cluster::World;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use std::time::Instant;

fn read_dataset(path: &Path) -> Result<Dataset, String> {
    Dataset::read(path).map_err(render)
}

/// The array a `--input NAME=PATH` names: a `.npy`'s one array; from a
/// `.npz`, the array `KEY` of `PATH.npz:KEY`, else the one called `NAME`
/// (so `--input x=data.npz` takes `x` from what `gwml data` writes), else
/// its only array.
fn input_array(name: &str, path: &str) -> Result<Array, String> {
    let (file, key) = match path.rsplit_once(':') {
        Some((file, key)) if file.ends_with(".npz") && !key.is_empty() => (file, Some(key)),
        _ => (path, None),
    };
    let mut ds = read_dataset(Path::new(file))?;
    let names = || ds.arrays.keys().cloned().collect::<Vec<_>>().join(", ");
    let wanted = key.or_else(|| ds.arrays.contains_key(name).then_some(name));
    match wanted {
        Some(k) => {
            let listed = names();
            ds.arrays.remove(k).ok_or_else(|| format!("error: {file} has no array `{k}` (it holds {listed})"))
        }
        None if ds.arrays.len() == 1 => Ok(ds.arrays.into_values().next().expect("one array")),
        None if ds.arrays.is_empty() => Err(format!("error: {file} holds no array")),
        None => Err(format!("error: {file} holds {}: none is called `{name}`; name one with --input {name}={file}:ARRAY", names())),
    }
}

/// `gwml train`.
pub fn train(a: TrainArgs) -> Result<(), String> {
    let world = World::new(a.mpi)?;
    // Other ranks train in step with rank 0, which alone prints and writes.
    let quiet = a.quiet || !world.is_root();
    let model = Model::from_file(&a.file).map_err(render)?;
    let scene = model.scene_with(a.scene.as_deref(), options(a.knobs)?).map_err(render)?;
    let train = read_dataset(&a.data)?;
    let val = a.val.as_deref().map(read_dataset).transpose()?;
    let method = match a.optimizer {
        TrainOptimizerArg::Adam => Method::adam(),
        TrainOptimizerArg::Adamw => Method::adamw(a.weight_decay),
        TrainOptimizerArg::Sgd => Method::sgd(a.momentum),
    };
    let batches_per_epoch = train.examples().map_err(render)?.div_ceil(a.batch.max(1)) as u64;
    let schedule = match a.schedule {
        ScheduleArg::Constant => Schedule::Constant,
        ScheduleArg::Step => Schedule::Step { every: a.step_epochs.max(1) as u64 * batches_per_epoch, gamma: a.gamma },
        ScheduleArg::Cosine => Schedule::Cosine { total: a.epochs as u64 * batches_per_epoch, min_lr: 0.0 },
    };
    if a.resume && a.checkpoint.is_none() {
        return Err("error: --resume needs --checkpoint DIR (it continues from DIR/last.safetensors)".into());
    }
    let threads = a.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let opts = TrainOptions {
        loss: a.loss.clone(),
        logits: a.logits.clone(),
        label: a.label.clone(),
        epochs: a.epochs,
        batch: a.batch,
        optim: OptimConfig { method, lr: a.lr, schedule, clip_norm: a.clip },
        seed: a.seed,
        threads,
        patience: a.patience,
        checkpoint_dir: a.checkpoint.clone(),
    };
    let mut trainer = Trainer::new(&scene, opts).map_err(render)?;
    let sum = |values: &mut [f64]| world.sum(values);
    let group = Group { rank: world.rank(), size: world.size(), sum: &sum };
    if a.resume {
        let last = a.checkpoint.as_ref().expect("checked above").join("last.safetensors");
        trainer.resume(&last).map_err(render)?;
        if world.is_root() {
            eprintln!("resumed from {} after epoch {}", last.display(), trainer.epoch());
        }
    }
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(batches_per_epoch) };
    bar.set_style(
        ProgressStyle::with_template("epoch {msg} [{bar:30}] {pos}/{len} batches, {per_sec}, eta {eta}")
            .map_err(|e| format!("error: {e}"))?
            .progress_chars("=> "),
    );
    let t0 = Instant::now();
    let epochs = a.epochs;
    let first_epoch = trainer.epoch() + 1;
    let epochs_done = std::cell::Cell::new(0usize);
    let reports = trainer
        .fit_in(
            (world.size() > 1).then_some(&group),
            &train,
            val.as_ref(),
            |done, total| {
                if done == 1 {
                    bar.set_length(total as u64);
                    bar.set_message(format!("{}/{epochs}", first_epoch + epochs_done.get()));
                }
                bar.set_position(done as u64);
            },
            |r| {
                bar.finish_and_clear();
                bar.reset();
                if !quiet {
                    eprintln!("{}  ({:.1} s)", epoch_line(r, epochs), t0.elapsed().as_secs_f64());
                }
                epochs_done.set(epochs_done.get() + 1);
            },
        )
        .map_err(render)?;
    if !world.is_root() {
        return Ok(());
    }
    if reports.is_empty() {
        println!("nothing to do: {} of {} epochs were already done", trainer.epoch(), a.epochs);
        return Ok(());
    }
    let last = reports.last().expect("not empty");
    println!("{}", epoch_line(last, a.epochs));
    for (name, values) in trainer.weights() {
        let norm = values.iter().map(|v| v * v).sum::<f64>().sqrt();
        println!("  {name}: {} values, L2 norm {norm:.4e}", values.len());
    }
    for slot in scene.ir().params.iter().filter_map(|p| trainer.param(&p.name).map(|v| (p, v))) {
        println!("  {} = {:.6e} {}", slot.0.name, slot.1, slot.0.unit);
    }
    if let Some(dir) = &a.checkpoint {
        println!(
            "checkpoints: {} (last) and {} (lowest validation loss)",
            dir.join("last.safetensors").display(),
            dir.join("best.safetensors").display()
        );
    }
    if let Some(path) = &a.history {
        std::fs::write(path, history_csv(&reports)).map_err(|e| format!("error: cannot write {}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(path) = &a.plot {
        let xs: Vec<f64> = reports.iter().map(|r| r.epoch as f64).collect();
        let train_loss: Vec<f64> = reports.iter().map(|r| r.train_loss).collect();
        let val_loss: Vec<f64> = reports.iter().map(|r| r.val.map_or(f64::NAN, |m| m.loss)).collect();
        gwml_lab::plot::lines_plot(path, "training", "epoch", &a.loss, &[("train", &xs, &train_loss), ("validation", &xs, &val_loss)])?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The loss curve as CSV; empty fields where a metric does not exist.
fn history_csv(reports: &[EpochReport]) -> String {
    let opt = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:e}"));
    let mut out = String::from("epoch,train_loss,train_accuracy,val_loss,val_accuracy,lr\n");
    for r in reports {
        out += &format!(
            "{},{:e},{},{},{},{:e}\n",
            r.epoch,
            r.train_loss,
            opt(r.train_accuracy),
            opt(r.val.map(|m| m.loss)),
            opt(r.val.and_then(|m| m.accuracy)),
            r.lr
        );
    }
    out
}

fn epoch_line(r: &EpochReport, epochs: usize) -> String {
    let pct = |x: Option<f64>| x.map(|a| format!("  acc {:.1} %", 100.0 * a)).unwrap_or_default();
    let val = r.val.map(|m| format!("  val loss {:.4e}{}", m.loss, pct(m.accuracy))).unwrap_or_default();
    let stop = if r.stop { "  (early stop)" } else { "" };
    format!("epoch {}/{epochs}  train loss {:.4e}{}{val}  lr {:.2e}{stop}", r.epoch, r.train_loss, pct(r.train_accuracy), r.lr)
}

/// `gwml predict`.
pub fn predict(a: PredictArgs) -> Result<(), String> {
    let model = Model::from_file(&a.file).map_err(render)?;
    let scene = model.scene_with(a.scene.as_deref(), options(a.knobs)?).map_err(render)?;
    let ck = checkpoint::load(&a.weights).map_err(render)?;
    let mut run = scene.bind();
    run.load_weights(&ck).map_err(|e| format!("{} (in {})", render(e), a.weights.display()))?;
    let mut inputs: Vec<(String, Array)> = Vec::new();
    for s in &a.input {
        let (name, path) = split_pair(s, "--input")?;
        inputs.push((name.to_string(), input_array(name, path)?));
    }
    let n = inputs.first().map_or(1, |(_, a)| a.rows());
    if let Some((name, arr)) = inputs.iter().find(|(_, a)| a.rows() != n) {
        return Err(format!("error: --input {name} has {} rows, but the first input has {n}", arr.rows()));
    }
    let mut outputs: Vec<(String, &Path, Vec<f64>, usize)> = Vec::new();
    for s in &a.output {
        let (name, path) = split_pair(s, "--output")?;
        outputs.push((name.to_string(), Path::new(path), Vec::new(), 0));
    }
    if outputs.is_empty() {
        return Err("error: give at least one --output NAME=PATH.npy".into());
    }
    for i in 0..n {
        for (name, arr) in &inputs {
            run.input_real(name, arr.row(i)).map_err(render)?;
        }
        let out = run.forward().map_err(|e| format!("row {i}: {}", render(e)))?;
        for (name, _, data, width) in &mut outputs {
            let values = match out.value(name).map_err(render)? {
                Value::Real(x) => vec![*x],
                Value::RealArray(v) => v.clone(),
                _ => return Err(format!("error: output `{name}` is complex; predict writes real outputs")),
            };
            *width = values.len();
            data.extend(values);
        }
    }
    for (_, path, data, width) in outputs {
        dataset::write_npy(path, &Array::new(vec![n, width], data).map_err(render)?).map_err(render)?;
        println!("wrote {} ({n} × {width})", path.display());
    }
    Ok(())
}

/// `gwml data`.
pub fn data(a: DataArgs, glitch: bool) -> Result<(), String> {
    match glitch {
        false => {
            if a.psd_knee != 0.0 {
                return Err("error: --psd-knee applies to glitch data only".into());
            }
            if a.class.is_some() {
                return Err("error: --class applies to glitch data only".into());
            }
            if a.ideal_noise {
                return Err("error: --ideal-noise applies to glitch data only".into());
            }
            if a.centred {
                return Err("error: --centred applies to glitch data only".into());
            }
            if !a.generator.is_empty() {
                return Err("error: --generator applies to glitch data only".into());
            }
            if a.generator_share != 1.0 {
                return Err("error: --generator-share applies to glitch data only".into());
            }
            let (lo, hi) = parse_range(a.snr.as_deref().unwrap_or("6..15"))?;
            let ds = bursts(&BurstOptions { n: a.n, seed: a.seed, snr: (lo, hi), ..Default::default() }).map_err(render)?;
            dataset::write_npz(&a.out, &ds).map_err(render)?;
            let ones = ds.arrays["label"].data.iter().filter(|l| **l == 1.0).count();
            println!(
                "wrote {}: x ({} × 256, 256 Hz, white noise of unit variance), label ({ones} bursts, {} noise)",
                a.out.display(),
                a.n,
                a.n - ones
            );
        }
        true => {
            let snr = a.snr.as_deref().map(parse_range).transpose()?;
            let mut shapes = GeneratorShapes::open(&a.generator, a.seed, a.generator_share)?;
            let ds = glitches_with(
                &GlitchOptions {
                    n: a.n,
                    seed: a.seed,
                    snr,
                    psd_knee: a.psd_knee,
                    class: a.class.map(|c| c.label()),
                    position: if a.centred { CENTRED } else { GlitchOptions::default().position },
                    ideal_noise: a.ideal_noise,
                },
                &mut |class| Ok(shapes.shape(class)?.map(Shape::from)),
            )
            .map_err(render)?;
            dataset::write_npz(&a.out, &ds).map_err(render)?;
            let counts: Vec<String> = GLITCH_CLASSES
                .iter()
                .enumerate()
                .map(|(c, name)| format!("{} {name}", ds.arrays["label"].data.iter().filter(|l| **l == c as f64).count()))
                .collect();
            println!("wrote {}: x ({} × 4096, whitened, 4096 Hz), label ({})", a.out.display(), a.n, counts.join(", "));
        }
    }
    Ok(())
}
