//! `gwml fit` end to end: inject a 3.5PN TaylorF2 signal
//! (examples/chirp_fit_pn.gw) into seeded coloured Gaussian noise, fit chirp
//! mass, mass ratio, tc and phic, and check the estimate against the
//! Fisher-matrix uncertainty.

use gwml::{Model, Scene, Value};
use gwml_runtime::fit::{fit_run, Algorithm, SceneFit, Settings};
use gwml_runtime::noise;
use num_complex::Complex64 as C64;
use std::process::Command;

const EXAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/chirp_fit_pn.gw");
/// The injection (the parameters of the example's noise-free default data).
const TRUTH: [(&str, f64); 4] = [("mc", 3.0), ("q", 0.5), ("tc", 0.0), ("phic", 0.4)];
/// Where the fits start: within about one σ of the truth in each param.
const START: [(&str, f64); 4] = [("mc", 3.0003), ("q", 0.51), ("tc", 5e-5), ("phic", 0.3)];
const DF: f64 = 0.25;

fn scene() -> Scene {
    Model::from_file(EXAMPLE).expect("example compiles").scene(None).expect("one scene")
}

/// The model strain at the truth, and the PSD, from the scene's outputs.
fn injection(scene: &Scene) -> (Vec<C64>, Vec<f64>) {
    let mut run = scene.bind();
    for (n, v) in TRUTH {
        run.param(n, v).unwrap();
    }
    let out = run.forward().unwrap();
    let Value::ComplexArray(h) = out.value("h").unwrap().clone() else { panic!("h is a complex array") };
    let Value::RealArray(psd) = out.value("psd").unwrap().clone() else { panic!("psd is a real array") };
    (h, psd)
}

fn data(h: &[C64], psd: &[f64], seed: u64) -> Vec<C64> {
    let n = noise::colored_noise(psd, DF, seed).unwrap();
    h.iter().zip(&n).map(|(h, n)| h + n).collect()
}

fn fit(scene: &Scene, d: &[C64]) -> SceneFit {
    let mut run = scene.bind();
    run.input_complex("d", d).unwrap();
    for (n, v) in START {
        run.param(n, v).unwrap();
    }
    fit_run(&mut run, None, &Settings::new(Algorithm::Lbfgs), |_| {}).unwrap()
}

#[test]
fn fit_recovers_chirp_mass_within_fisher_sigma() {
    let scene = scene();
    let (h, psd) = injection(&scene);
    let snr = noise::inner(&h, &h, &psd, DF).sqrt();
    eprintln!("injection: {} bins, optimal SNR {snr:.2}", h.len());
    assert!((20.0..30.0).contains(&snr), "SNR {snr}");
    for seed in 1..=4u64 {
        let r = fit(&scene, &data(&h, &psd, seed));
        assert_eq!(r.output, "loss");
        let names: Vec<&str> = r.free.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["mc", "q", "tc", "phic"]);
        assert_eq!(r.fixed, [("dist".to_string(), 400.0)]);
        assert!(r.minimum.stop.converged(), "seed {seed}: {:?}", r.minimum);
        let cov = r.covariance.as_ref().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let mut line = format!("seed {seed}: loss {:.2} ({} steps)", r.minimum.loss, r.minimum.steps);
        for (i, (name, truth)) in TRUTH.iter().enumerate() {
            let (x, s) = (r.minimum.x[i], cov.sigma[i]);
            assert!(s.is_finite() && s > 0.0, "seed {seed}: σ_{name} = {s}");
            line += &format!(", {name} {x:.6} ± {s:.2e} (pull {:+.2})", (x - truth) / s);
        }
        eprintln!("{line}");
        let (mc, s_mc) = (r.minimum.x[0], cov.sigma[0]);
        assert!((mc - 3.0).abs() < 3.0 * s_mc, "seed {seed}: mc = {mc} ± {s_mc}, truth 3");
        // The residual is noise: 2 L ~ χ² with 2N - 4 degrees of freedom.
        let n = h.len() as f64;
        assert!((2.0 * r.minimum.loss - 2.0 * n).abs() < 6.0 * (4.0 * n).sqrt(), "seed {seed}: loss {}", r.minimum.loss);
    }
}

fn gwml(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_gwml")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().expect("gwml runs");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

fn temp_dir(tag: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("gwml-fit-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn cli_fit_with_npy_data_matches_the_library() {
    let scene = scene();
    let (h, psd) = injection(&scene);
    let d = data(&h, &psd, 5);
    let lib = fit(&scene, &d);
    let dir = temp_dir("cli");
    let path = dir.join("d.npy");
    gwml::npy::write_complex(&path, &d).unwrap();
    let input = format!("d={}", path.display());
    let mut args = vec!["fit", "examples/chirp_fit_pn.gw", "--input", &input, "--format", "json"];
    let sets: Vec<String> = START.iter().map(|(n, v)| format!("{n}={v}")).collect();
    for s in &sets {
        args.extend(["--set", s]);
    }
    let (ok, stdout, stderr) = gwml(&args);
    assert!(ok, "gwml fit failed: {stderr}");
    assert!(stderr.contains("step"), "progress lines on stderr: {stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
    assert_eq!(j["output"], "loss");
    assert_eq!(j["converged"], true);
    assert_eq!(j["fisher"]["positive_definite"], true);
    let mc = j["params"]["mc"]["value"].as_f64().unwrap();
    let s = j["params"]["mc"]["sigma"].as_f64().unwrap();
    eprintln!("cli, seed 5: mc {mc:.6} ± {s:.2e} (pull {:+.2})", (mc - 3.0) / s);
    assert!(s.is_finite() && s > 0.0);
    assert!((mc - 3.0).abs() < 3.0 * s, "mc = {mc} ± {s}");
    // Same algorithm, same data, same start: the same answer.
    let c = lib.covariance.as_ref().unwrap();
    assert!((mc - lib.minimum.x[0]).abs() < 1e-3 * c.sigma[0], "cli {mc} vs library {}", lib.minimum.x[0]);
    assert!((s / c.sigma[0] - 1.0).abs() < 1e-3);
    let corr = &j["fisher"]["correlation"];
    for i in 0..4 {
        assert!((corr[i][i].as_f64().unwrap() - 1.0).abs() < 1e-9);
    }
    // Text output and quiet mode.
    let (ok, stdout, stderr) = gwml(&["fit", "examples/chirp_fit_pn.gw", "--input", &input, "--quiet"]);
    assert!(ok, "{stderr}");
    assert!(stderr.is_empty(), "--quiet prints no progress: {stderr}");
    assert!(stdout.contains("mc   = ") && stdout.contains(" ± ") && stdout.contains("correlation:"), "{stdout}");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn cli_fit_reports_choice_errors_and_a_singular_fisher_matrix() {
    let dir = temp_dir("errors");
    let two = dir.join("two.gw");
    std::fs::write(
        &two,
        "scene s {
            param a = 1.0 in -5.0..5.0
            output l1 = (a - 2.0) ^ 2.0
            output l2 = (a + 1.0) ^ 2.0
            grad l1 wrt [a]
            grad l2 wrt [a]
        }",
    )
    .unwrap();
    let two = two.display().to_string();
    let (ok, _, stderr) = gwml(&["fit", &two, "--quiet"]);
    assert!(!ok && stderr.contains("several") && stderr.contains("--output"), "{stderr}");
    let (ok, stdout, stderr) = gwml(&["fit", &two, "--quiet", "--output", "l2", "--format", "json"]);
    assert!(ok, "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!((j["params"]["a"]["value"].as_f64().unwrap() + 1.0).abs() < 1e-6, "{j}");
    // Loss 0.5 (a+1)^2 / 0.5: Hessian 2, σ = 1/sqrt(2).
    assert!((j["params"]["a"]["sigma"].as_f64().unwrap() - 0.5f64.sqrt()).abs() < 1e-6, "{j}");
    let (ok, _, stderr) = gwml(&["fit", &two, "--quiet", "--output", "nope"]);
    assert!(!ok && stderr.contains("no output `nope`"), "{stderr}");

    // `b` does not change the loss: the Fisher matrix is singular.
    let flat = dir.join("flat.gw");
    std::fs::write(
        &flat,
        "scene s {
            param a = 1.0
            param b = 0.5 in 0.0..1.0
            output loss = (a - 2.0) ^ 2.0 + 0.0 * b
            grad loss wrt [a, b]
        }",
    )
    .unwrap();
    let flat = flat.display().to_string();
    let (ok, stdout, stderr) = gwml(&["fit", &flat, "--quiet"]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("no uncertainties") && stdout.contains("not positive definite") && !stdout.contains("NaN"), "{stdout}");
    let (ok, stdout, _) = gwml(&["fit", &flat, "--quiet", "--format", "json", "--optimizer", "adam"]);
    assert!(ok);
    let j: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(j["fisher"]["positive_definite"], false);
    assert!(j["params"]["a"]["sigma"].is_null());
    assert!((j["params"]["a"]["value"].as_f64().unwrap() - 2.0).abs() < 1e-3, "{j}");
    std::fs::remove_dir_all(dir).ok();
}
