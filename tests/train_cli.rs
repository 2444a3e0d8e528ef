//! `gwml data`, `gwml train` and `gwml predict` end to end: a dataset is
//! written, a CNN is trained with checkpoints and resumed, and predictions
//! are written with one row per example.

#[path = "common/cli.rs"]
mod cli;
use cli::gwml;
use gwml::runtime::dataset::Dataset;
use std::path::Path;

#[test]
fn data_train_resume_and_predict() {
    let dir = std::env::temp_dir().join(format!("gwml-train-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = |name: &str| dir.join(name).display().to_string();
    let (train, val, ck) = (p("train.npz"), p("val.npz"), p("ck"));
    for (path, seed, n) in [(&train, "1", "96"), (&val, "2", "32")] {
        let (ok, out, err) = gwml(&["data", "bursts", "--n", n, "--seed", seed, "--out", path]);
        assert!(ok, "{err}");
        assert!(out.contains(&format!("x ({n} × 256")), "{out}");
    }
    let ds = Dataset::read(Path::new(&train)).unwrap();
    assert_eq!(ds.arrays["x"].shape, vec![96, 256]);
    let train_args = |epochs: &'static str| {
        vec![
            "train",
            "examples/burst_cnn.gw",
            "--data",
            &train,
            "--val",
            &val,
            "--epochs",
            epochs,
            "--batch",
            "16",
            "--checkpoint",
            &ck,
            "--threads",
            "2",
        ]
    };
    let (ok, out, err) = gwml(&train_args("1"));
    assert!(ok, "{err}");
    assert!(out.contains("epoch 1/1") && out.contains("val loss") && out.contains("cnn.k2: 1024 values"), "{out}");
    let (ok, out, err) = gwml(&[train_args("2"), vec!["--resume", "--plot", &p("curves.png"), "--history", &p("curve.csv")]].concat());
    assert!(ok, "{err}");
    assert!(err.contains("resumed from") && err.contains("after epoch 1"), "{err}");
    assert!(out.contains("epoch 2/2"), "{out}");
    assert!(Path::new(&p("curves.png")).exists());
    // The loss curve of the epochs run, in full precision.
    let curve = std::fs::read_to_string(p("curve.csv")).unwrap();
    let rows: Vec<Vec<&str>> = curve.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(curve.lines().next(), Some("epoch,train_loss,train_accuracy,val_loss,val_accuracy,lr"), "{curve}");
    assert_eq!(rows.len(), 1, "one epoch after resuming: {curve}");
    assert_eq!(rows[0][0], "2");
    let printed = out.lines().find(|l| l.starts_with("epoch 2/2")).unwrap();
    let loss: f64 = rows[0][1].parse().unwrap();
    assert!(printed.contains(&format!("train loss {loss:.4e}")), "{printed} vs {loss:e}");
    // Predict on the first rows of the validation set.
    let x: Vec<f64> = Dataset::read(Path::new(&val)).unwrap().arrays["x"].data[..3 * 256].to_vec();
    let xs = gwml::runtime::dataset::Array::new(vec![3, 256], x).unwrap();
    gwml::runtime::dataset::write_npy(Path::new(&p("x.npy")), &xs).unwrap();
    let (ok, out, err) = gwml(&[
        "predict",
        "examples/burst_cnn.gw",
        "--weights",
        &format!("{ck}/best.safetensors"),
        "--input",
        &format!("x={}", p("x.npy")),
        "--output",
        &format!("logits={}", p("logits.npy")),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("(3 × 2)"), "{out}");
    let logits = Dataset::read(Path::new(&p("logits.npy"))).unwrap();
    assert_eq!(logits.arrays["logits"].shape, vec![3, 2]);
    assert!(logits.arrays["logits"].data.iter().all(|v| v.is_finite()));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn training_errors_are_clear() {
    let (ok, _, err) = gwml(&["train", "examples/burst_cnn.gw", "--data", "missing.npz", "--epochs", "1"]);
    assert!(!ok && err.contains("missing.npz"), "{err}");
    let (ok, _, err) = gwml(&["train", "examples/burst_cnn.gw", "--data", "missing.npz", "--resume"]);
    assert!(!ok, "{err}");
    let (ok, _, err) = gwml(&["train", "examples/chirp_fit.gw", "--data", "examples/chirp_fit.gw"]);
    assert!(!ok && err.starts_with("error:"), "{err}");
}

#[test]
fn glitch_data_has_eight_classes_of_whitened_segments() {
    let path = std::env::temp_dir().join(format!("gwml-glitch-data-{}.npz", std::process::id()));
    let (ok, out, err) = gwml(&["data", "glitch", "--n", "24", "--seed", "5", "--out", &path.display().to_string()]);
    assert!(ok, "{err}");
    assert!(out.contains("x (24 × 4096") && out.contains("Koi Fish") && out.contains("Scattered Light"), "{out}");
    let ds = Dataset::read(&path).unwrap();
    assert_eq!(ds.arrays["x"].shape, vec![24, 4096]);
    assert!(ds.arrays["label"].data.iter().all(|l| (0.0..8.0).contains(l) && l.fract() == 0.0));
    let _ = std::fs::remove_file(&path);
    let (ok, _, err) = gwml(&["data", "glitch", "--n", "2", "--snr", "30..8", "--out", "/tmp/never.npz"]);
    assert!(!ok && err.contains("SNR range"), "{err}");
    // A shifted PSD is for glitch data, and its knee cannot be negative.
    let (ok, _, err) = gwml(&["data", "bursts", "--n", "2", "--psd-knee", "60", "--out", "/tmp/never.npz"]);
    assert!(!ok && err.contains("glitch data only"), "{err}");
    let (ok, _, err) = gwml(&["data", "glitch", "--n", "2", "--psd-knee=-5", "--out", "/tmp/never.npz"]);
    assert!(!ok && err.contains("knee"), "{err}");
    // So is ideal noise; the Koi Fish loudness factor is gone (each class
    // has its own SNR range).
    let (ok, _, err) = gwml(&["data", "bursts", "--n", "2", "--ideal-noise", "--out", "/tmp/never.npz"]);
    assert!(!ok && err.contains("glitch data only"), "{err}");
    let (ok, _, err) = gwml(&["data", "glitch", "--n", "2", "--koi-fish-loudness", "2", "--out", "/tmp/never.npz"]);
    assert!(!ok && err.contains("--koi-fish-loudness"), "{err}");
}

/// `gwml predict --input x=data.npz` takes the array `x` of what `gwml data
/// glitch` writes (it used to take the first array, `label`, and fail on
/// its length); `FILE.npz:ARRAY` names another; a missing one is an error
/// listing what the file holds.
#[test]
fn predict_takes_an_npz_array_by_name() {
    let scratch = tempfile::Builder::new().prefix("gwml-predict-npz-").tempdir().unwrap();
    let dir = scratch.path();
    let p = |name: &str| dir.join(name).display().to_string();
    let (ok, _, err) = gwml(&["data", "glitch", "--n", "4", "--seed", "3", "--out", &p("d.npz")]);
    assert!(ok, "{err}");
    let predict = |input: &str, out: &str| {
        gwml(&[
            "predict",
            "lab/models/glitch/template_net.gw",
            "--scene",
            "classify",
            "--weights",
            "models/glitch-classifier/template_net.safetensors",
            "--input",
            input,
            "--output",
            &format!("logits={}", p(out)),
        ])
    };
    let (ok, _, err) = predict(&format!("x={}", p("d.npz")), "a.npy");
    assert!(ok, "{err}");
    let (ok, _, err) = predict(&format!("x={}:x", p("d.npz")), "b.npy");
    assert!(ok, "{err}");
    let logits = |f: &str| Dataset::read(Path::new(&p(f))).unwrap().arrays.into_values().next().unwrap();
    let (a, b) = (logits("a.npy"), logits("b.npy"));
    assert_eq!(a.shape, vec![4, 8]);
    assert_eq!(a.data, b.data);
    let (ok, _, err) = predict(&format!("x={}:signal", p("d.npz")), "c.npy");
    assert!(!ok && err.contains("no array `signal`") && err.contains("label, x"), "{err}");
}
