//! `gwml generator fit` and `gwml generator sample` end to end: examples of
//! one family are written with `gwml data glitch --class`, a generator is
//! fitted to them and writes its plot, and its draws are written with one
//! row per glitch at the drawn SNR; a learned generator fitted to several
//! classes draws the class `--class` names.

#[path = "common/cli.rs"]
mod cli;
use cli::gwml;
use gwml::runtime::dataset::Dataset;
use std::path::Path;

#[test]
fn fit_a_blip_generator_and_sample_from_it() {
    let dir = std::env::temp_dir().join(format!("gwml-generator-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = |name: &str| dir.join(name).display().to_string();

    let (ok, out, err) =
        gwml(&["data", "glitch", "--class", "blip", "--n", "24", "--snr", "25..40", "--seed", "4", "--out", &p("blips.npz")]);
    assert!(ok, "{err}");
    assert!(out.contains("24 Blip"), "{out}");
    let (ok, out, err) = gwml(&[
        "generator",
        "fit",
        "--family",
        "blip",
        "--kind",
        "parametric",
        "--examples",
        &p("blips.npz"),
        "--out",
        &p("blip.json"),
        "--plot",
        &p("fit.png"),
        "--threads",
        "2",
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("generator to") && out.contains("of 24 examples"), "{out}");
    // The summary compares the examples' estimates with the generator's
    // draws, one row per param; the drawn examples have Q in 2..6.
    let q_row = out.lines().find(|l| l.starts_with("q ")).unwrap_or_else(|| panic!("no q row in {out}"));
    let median: f64 = q_row.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!((2.0..6.0).contains(&median), "{q_row}");
    assert!(std::fs::metadata(p("fit.png")).unwrap().len() > 10_000);

    let (ok, out, err) = gwml(&[
        "generator",
        "sample",
        "--model",
        &p("blip.json"),
        "--n",
        "5",
        "--seed",
        "3",
        "--out",
        &p("draws.npz"),
        "--plot",
        &p("draws.png"),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("x (5 × 4096"), "{out}");
    let ds = Dataset::read(Path::new(&p("draws.npz"))).unwrap();
    assert_eq!(ds.arrays["x"].shape, vec![5, 4096]);
    for i in 0..5 {
        let norm = ds.arrays["x"].row(i).iter().map(|v| v * v).sum::<f64>().sqrt();
        let snr = ds.arrays["snr"].data[i];
        assert!((norm / snr - 1.0).abs() < 1e-9, "row {i}: norm {norm}, drawn SNR {snr}");
        let f0 = ds.arrays["f0"].data[i];
        assert!((20.0..400.0).contains(&f0), "f0 {f0}");
    }
    assert!(std::fs::metadata(p("draws.png")).unwrap().len() > 10_000);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The learned generator (the default kind) trains on the examples, writes
/// its JSON and weights and a plot, and draws rows whose `snr` is their
/// norm and whose `t0` is where their energy is centred.
#[test]
fn fit_a_learned_generator_and_sample_from_it() {
    let dir = std::env::temp_dir().join(format!("gwml-generator-learned-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = |name: &str| dir.join(name).display().to_string();
    let (ok, out, err) = gwml(&[
        "generator",
        "fit",
        "--family",
        "blip",
        "--n",
        "48",
        "--snr",
        "20..30",
        "--epochs",
        "100",
        "--out",
        &p("vae.json"),
        "--plot",
        &p("fit.png"),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("trained a Blip generator on 48 examples") && out.contains("vae.safetensors"), "{out}");
    assert!(std::fs::metadata(p("fit.png")).unwrap().len() > 10_000);
    let (ok, out, err) = gwml(&["generator", "sample", "--model", &p("vae.json"), "--n", "4", "--seed", "2", "--out", &p("draws.npz")]);
    assert!(ok, "{err}");
    assert!(out.contains("the drawn t0, snr"), "{out}");
    let ds = Dataset::read(Path::new(&p("draws.npz"))).unwrap();
    assert_eq!(ds.arrays["x"].shape, vec![4, 4096]);
    for i in 0..4 {
        let row = ds.arrays["x"].row(i);
        assert!(row.iter().all(|v| v.is_finite()));
        let norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((norm / ds.arrays["snr"].data[i] - 1.0).abs() < 1e-9);
        assert!(norm > 0.0, "a draw is not silent");
    }
    let (ok, out2, _) = gwml(&["generator", "sample", "--model", &p("vae.json"), "--n", "4", "--seed", "2", "--out", &p("again.npz")]);
    assert!(ok, "{out2}");
    assert_eq!(Dataset::read(Path::new(&p("again.npz"))).unwrap().arrays["x"].data, ds.arrays["x"].data, "the same seed draws the same");
    // `gwml data glitch --generator` draws that class's shapes from it.
    let data = |out: &str, extra: &[&str]| {
        let mut args = vec!["data", "glitch", "--class", "blip", "--n", "6", "--seed", "4", "--snr", "20..20", "--out", out];
        args.extend_from_slice(extra);
        gwml(&args)
    };
    let (ok, out, err) = data(&p("gen.npz"), &["--generator", &p("vae.json")]);
    assert!(ok && out.contains("6 Blip"), "{out}{err}");
    let (ok, _, err) = data(&p("formula.npz"), &[]);
    assert!(ok, "{err}");
    let (generated, formula) = (Dataset::read(Path::new(&p("gen.npz"))).unwrap(), Dataset::read(Path::new(&p("formula.npz"))).unwrap());
    assert_eq!(generated.arrays["x"].shape, vec![6, 4096]);
    assert_ne!(generated.arrays["x"].data, formula.arrays["x"].data, "the generator's shapes, not the formula's");
    // `--generator-share` mixes them: at 0 every row keeps its formula's
    // shape, on the same random stream as without a generator.
    let (ok, _, err) = data(&p("none.npz"), &["--generator", &p("vae.json"), "--generator-share", "0"]);
    assert!(ok, "{err}");
    assert_eq!(Dataset::read(Path::new(&p("none.npz"))).unwrap().arrays["x"].data, formula.arrays["x"].data, "share 0 is the formula");
    let (ok, _, err) = data(&p("bad.npz"), &["--generator", &p("vae.json"), "--generator-share", "1.5"]);
    assert!(!ok && err.contains("the generator share 1.5 must be within 0..1"), "{err}");
    // `gwml data strain --generator` colours them by the PSD; the scan
    // finds them where the truth says, at their SNR.
    let (ok, out, err) = gwml(&[
        "data",
        "strain",
        "--duration",
        "128",
        "--glitch-rate",
        "10",
        "--classes",
        "blip",
        "--snr",
        "20..30",
        "--seed",
        "3",
        "--generator",
        &p("vae.json"),
        "--out",
        &p("s.hdf5"),
        "--truth",
        &p("truth.csv"),
    ]);
    assert!(ok, "{out}{err}");
    let (ok, out, err) = gwml(&["scan", &p("s.hdf5"), "--out", &p("triggers.csv"), "--no-classify"]);
    assert!(ok, "{out}{err}");
    let times = |path: &str| -> Vec<f64> {
        std::fs::read_to_string(path).unwrap().lines().skip(1).map(|l| l.split(',').next().unwrap().parse().unwrap()).collect()
    };
    let (truth, triggers) = (times(&p("truth.csv")), times(&p("triggers.csv")));
    assert!(truth.len() >= 8, "{} injections", truth.len());
    let found = truth.iter().filter(|t| triggers.iter().any(|g| (g - *t).abs() < 0.05)).count();
    assert!(found * 10 >= truth.len() * 9, "found {found} of {} generated glitches in strain", truth.len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--holdout` fits to the first rows and measures realism against the
/// clean shapes of the rest; without clean shapes it is an error.
#[test]
fn holdout_measures_realism_against_clean_shapes() {
    use gwml::runtime::dataset::{write_npz, Array};
    let dir = std::env::temp_dir().join(format!("gwml-generator-holdout-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = |name: &str| dir.join(name).display().to_string();
    // 40 damped sinusoids at 0.5 s, SNR 20, in deterministic pseudo-noise.
    let (n, rows) = (4096, 40);
    let mut state = 7u64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 3.4641 - 1.7321
    };
    let mut clean = Vec::new();
    for r in 0..rows {
        let f = 100.0 + 5.0 * r as f64;
        let s: Vec<f64> = (0..n)
            .map(|i| {
                let u = i as f64 / 4096.0 - 0.5;
                if u < 0.0 {
                    0.0
                } else {
                    (-u / 0.01).exp() * (std::f64::consts::TAU * f * u).sin()
                }
            })
            .collect();
        let norm = s.iter().map(|v| v * v).sum::<f64>().sqrt();
        clean.extend(s.iter().map(|v| 20.0 * v / norm));
    }
    let noisy: Vec<f64> = clean.iter().map(|v| v + noise()).collect();
    let mut arrays = std::collections::BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![rows, n], noisy.clone()).unwrap());
    arrays.insert("clean".to_string(), Array::new(vec![rows, n], clean).unwrap());
    write_npz(Path::new(&p("set.npz")), &Dataset { arrays }).unwrap();
    let (ok, out, err) = gwml(&[
        "generator",
        "fit",
        "--family",
        "blip",
        "--examples",
        &p("set.npz"),
        "--holdout",
        "0.25",
        "--epochs",
        "5",
        "--out",
        &p("g.json"),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("trained a Blip generator on 30 examples"), "{out}");
    let line = out.lines().find(|l| l.starts_with("realism on 10 held-out Blip examples")).unwrap_or_else(|| panic!("{out}"));
    let accuracies: Vec<f64> =
        line.split("SNR ").skip(1).map(|s| s.split(": ").nth(1).unwrap().trim().trim_end_matches(';').parse().unwrap()).collect();
    assert_eq!(accuracies.len(), 2, "{line}");
    assert!(accuracies.iter().all(|a| (0.0..=1.0).contains(a)), "{line}");
    // Without clean shapes there is nothing to measure against.
    let mut arrays = std::collections::BTreeMap::new();
    arrays.insert("x".to_string(), Array::new(vec![rows, n], noisy).unwrap());
    write_npz(Path::new(&p("noisy.npz")), &Dataset { arrays }).unwrap();
    let (ok, _, err) =
        gwml(&["generator", "fit", "--family", "blip", "--examples", &p("noisy.npz"), "--holdout", "0.25", "--out", &p("h.json")]);
    assert!(!ok && err.contains("needs an array `clean`"), "{err}");
    let (ok, _, err) =
        gwml(&["generator", "fit", "--family", "blip", "--examples", &p("set.npz"), "--holdout", "1.5", "--out", &p("h.json")]);
    assert!(!ok && err.contains("--holdout must be a fraction"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_generator_inputs_are_clear_errors() {
    let scratch = tempfile::Builder::new().prefix("gwml-generator-bad-").tempdir().unwrap();
    let dir = scratch.path();
    let p = |name: &str| dir.join(name).display().to_string();
    let (ok, _, err) = gwml(&["generator", "fit", "--family", "chirp", "--kind", "parametric", "--out", &p("g.json")]);
    assert!(!ok && err.contains("Chirp is not one"), "{err}");
    std::fs::write(p("bad.json"), "{\"family\": \"blip\"}").unwrap();
    let (ok, _, err) = gwml(&["generator", "sample", "--model", &p("bad.json"), "--out", &p("d.npz")]);
    assert!(!ok && err.contains("not a gwml generator file"), "{err}");
    let learned = |band: &str| {
        let (means, sds) = (serde_json::json!([vec![0.0; 16]]), serde_json::json!([vec![1.0; 16]]));
        format!(
            "{{\"kind\": \"learned\", \"classes\": [{{\"class\": 1, \"centres\": [0.5], \"band_hz\": {band}, \"posterior_means\": {means}, \
             \"posterior_sds\": {sds}}}], \"weights\": \"gone.safetensors\"}}"
        )
    };
    std::fs::write(p("learned.json"), learned("[20, 2000]")).unwrap();
    let (ok, _, err) = gwml(&["generator", "sample", "--model", &p("learned.json"), "--out", &p("d.npz")]);
    assert!(!ok && err.contains("gone.safetensors"), "a missing weights file is named: {err}");
    std::fs::write(p("learned.json"), learned("[500, 100]")).unwrap();
    let (ok, _, err) = gwml(&["generator", "sample", "--model", &p("learned.json"), "--out", &p("d.npz")]);
    assert!(!ok && err.contains("classes[0]: `band_hz` must be two frequencies within 20–2000 Hz"), "a reversed band is refused: {err}");
    let (ok, _, err) = gwml(&["data", "glitch", "--generator", &p("missing.json"), "--out", &p("g.npz")]);
    assert!(!ok && err.contains("cannot read") && err.contains("missing.json"), "{err}");
    let (ok, _, err) = gwml(&["data", "bursts", "--class", "blip", "--out", &p("b.npz")]);
    assert!(!ok && err.contains("--class applies to glitch data only"), "{err}");
    let (ok, _, err) = gwml(&["data", "bursts", "--generator-share", "0.5", "--out", &p("b.npz")]);
    assert!(!ok && err.contains("--generator-share applies to glitch data only"), "{err}");
}

/// One learned generator fitted to the Blips and Whistles of a file of every
/// class draws either class by `--class`, both in proportion without it,
/// and serves `gwml data glitch --generator` for each; what it was not
/// fitted to, and files it cannot read, are clear errors.
#[test]
fn a_conditional_generator_draws_the_class_asked_for() {
    use gwml::runtime::dataset::{write_npz, Array};
    let dir = std::env::temp_dir().join(format!("gwml-generator-conditional-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = |name: &str| dir.join(name).display().to_string();
    let (ok, _, err) = gwml(&["data", "glitch", "--n", "160", "--snr", "20..30", "--seed", "5", "--out", &p("all.npz")]);
    assert!(ok, "{err}");
    let (all, model) = (p("all.npz"), p("c.json"));
    let fit = |extra: &[&str]| {
        let mut args = vec!["generator", "fit", "--examples", &all, "--epochs", "10", "--out", &model];
        args.extend_from_slice(extra);
        gwml(&args)
    };
    let (ok, out, err) = fit(&["--family", "blip,whistle"]);
    assert!(ok, "{err}");
    assert!(out.contains("trained a Blip + Whistle generator"), "{out}");
    assert!(out.contains("  Blip: ") && out.contains("  Whistle: "), "one line per class: {out}");
    let labels = |name: &str| Dataset::read(Path::new(&p(name))).unwrap().arrays["label"].data.clone();
    let sample = |extra: &[&str], out: &str| {
        let mut args = vec!["generator", "sample", "--model", &model, "--n", "12", "--seed", "3", "--out", out];
        args.extend_from_slice(extra);
        gwml(&args)
    };
    let (ok, _, err) = sample(&["--class", "whistle"], &p("w.npz"));
    assert!(ok, "{err}");
    assert!(labels("w.npz").iter().all(|l| *l == 3.0), "{:?}", labels("w.npz"));
    let (ok, _, err) = sample(&["--class", "1"], &p("b.npz"));
    assert!(ok, "{err}");
    assert!(labels("b.npz").iter().all(|l| *l == 1.0));
    let (ok, _, err) = sample(&[], &p("both.npz"));
    assert!(ok, "{err}");
    assert!(labels("both.npz").iter().all(|l| *l == 1.0 || *l == 3.0));
    let (ok, _, err) = sample(&["--class", "koi_fish"], &p("k.npz"));
    assert!(!ok && err.contains("draws Blip, Whistle, not Koi Fish"), "{err}");
    let (ok, _, err) = sample(&["--class", "17"], &p("k.npz"));
    assert!(!ok && err.contains("--class") && err.contains("0 to 15"), "{err}");
    let (ok, out, err) =
        gwml(&["data", "glitch", "--class", "whistle", "--n", "4", "--seed", "4", "--generator", &p("c.json"), "--out", &p("g.npz")]);
    assert!(ok && out.contains("4 Whistle"), "{out}{err}");
    // The parametric generator models one family.
    let (ok, _, err) = fit(&["--family", "blip,whistle", "--kind", "parametric"]);
    assert!(!ok && err.contains("models one family"), "{err}");
    let (ok, _, err) = fit(&["--family", "chirp,tomte"]);
    assert!(ok, "{err}");
    // Rows without labels need the one family they are of; labels must be
    // class numbers.
    let rows = Array::new(vec![2, 4096], vec![0.0; 2 * 4096]).unwrap();
    let write = |name: &str, label: Option<Vec<f64>>| {
        let mut arrays = std::collections::BTreeMap::new();
        arrays.insert("x".to_string(), rows.clone());
        if let Some(l) = label {
            arrays.insert("label".to_string(), Array::new(vec![2], l).unwrap());
        }
        write_npz(Path::new(&p(name)), &Dataset { arrays }).unwrap();
    };
    write("unlabelled.npz", None);
    write("fractional.npz", Some(vec![1.0, 2.5]));
    write("labelled.npz", Some(vec![1.0, 2.0]));
    let (ok, _, err) = gwml(&["generator", "fit", "--examples", &p("unlabelled.npz"), "--out", &p("u.json")]);
    assert!(!ok && err.contains("no `label` array") && err.contains("--family"), "{err}");
    let (ok, _, err) = gwml(&["generator", "fit", "--examples", &p("fractional.npz"), "--out", &p("u.json")]);
    assert!(!ok && err.contains("fractional.npz: `label` row 1 is 2.5"), "{err}");
    let (ok, _, err) = gwml(&["generator", "fit", "--family", "tomte", "--examples", &p("labelled.npz"), "--out", &p("u.json")]);
    assert!(!ok && err.contains("no examples of Tomte: its `label` array holds 1 (Blip), 2 (Koi Fish)"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
