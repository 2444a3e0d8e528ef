//! End-to-end tests: run the `gwml` binary on the examples and compare with
//! independently computed values.

mod common;

use common::chirp_reference as reference;
#[path = "common/cli.rs"]
mod cli;

use cli::{gwml, json};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1e-12)
}

#[test]
fn run_chirp_fit_matches_hand_written_loss_and_gradient() {
    let data = reference::default_data();
    for (mc, tc, phic) in [(28.0, 0.0, 0.0), (30.5, 0.0021, 0.25), (12.0, -0.01, 1.0)] {
        let (mcs, tcs, phics) = (format!("mc={mc}"), format!("tc={tc}"), format!("phic={phic}"));
        let j = json(&["run", "examples/chirp_fit.gw", "--grad", "--format", "json", "--set", &mcs, "--set", &tcs, "--set", &phics]);
        let (loss, grad) = reference::loss_and_grad(&data, mc, tc, phic);
        let got = j["outputs"]["loss"].as_f64().unwrap();
        assert!(close(got, loss, 1e-9), "loss {got} vs {loss}");
        assert!(close(loss, reference::loss(&data, mc, tc, phic), 1e-12));
        for (i, p) in ["mc", "tc", "phic"].iter().enumerate() {
            let g = j["grads"]["loss"][p].as_f64().unwrap();
            assert!(close(g, grad[i], 1e-7), "d/d{p}: {g} vs {}", grad[i]);
        }
        assert_eq!(j["params"]["mc"].as_f64(), Some(mc));
    }
}

#[test]
fn run_with_npy_input_and_output() {
    let scratch = tempfile::Builder::new().prefix("gwml-cli-").tempdir().unwrap();
    let dir = scratch.path();
    let src = dir.join("model.gw");
    std::fs::write(
        &src,
        "scene s {
            grid t = times(rate: 8 Hz, duration: 1 s)
            input x: real[t]
            param a = 2.0
            output y = a * x * x
            output total = sum(y)
            grad total wrt [a]
        }",
    )
    .unwrap();
    let xs: Vec<f64> = (0..8).map(|i| i as f64 * 0.5).collect();
    let inp = dir.join("x.npy");
    gwml::npy::write_real(&inp, &xs).unwrap();
    let outp = dir.join("y.npy");
    let j = json(&[
        "run",
        src.to_str().unwrap(),
        "--input",
        &format!("x={}", inp.display()),
        "--output",
        &format!("y={}", outp.display()),
        "--grad",
        "--format",
        "json",
    ]);
    let sum_sq: f64 = xs.iter().map(|x| x * x).sum();
    assert!(close(j["outputs"]["total"].as_f64().unwrap(), 2.0 * sum_sq, 1e-14));
    assert!(close(j["grads"]["total"]["a"].as_f64().unwrap(), sum_sq, 1e-14));
    let y = gwml::npy::read(&outp).unwrap();
    assert_eq!(y.values.len(), 8);
    for (x, yv) in xs.iter().zip(&y.values) {
        assert!(close(yv.re, 2.0 * x * x, 1e-15));
    }
}

/// `--set` takes values with units, converted to the param's declared unit
/// (`tc` is declared in s, `mc` in Msun); a unit of another dimension or an
/// unknown unit is a one-line error.
#[test]
fn set_accepts_units() {
    let j = json(&["run", "examples/chirp_fit.gw", "--format", "json", "--set", "tc=2 ms", "--set", "mc=30 Msun"]);
    assert_eq!((j["params"]["tc"].as_f64(), j["params"]["mc"].as_f64()), (Some(0.002), Some(30.0)), "{j}");
    let plain = json(&["run", "examples/chirp_fit.gw", "--format", "json", "--set", "tc=0.002"]);
    assert_eq!(plain["outputs"]["loss"], json(&["run", "examples/chirp_fit.gw", "--format", "json", "--set", "tc=2ms"])["outputs"]["loss"]);
    let (ok, _, err) = gwml(&["run", "examples/chirp_fit.gw", "--set", "tc=2 Hz"]);
    assert!(!ok && err.trim().lines().count() == 1);
    assert!(err.contains("--set tc=2 Hz") && err.contains("param `tc` is in s") && err.contains("Hz"), "{err}");
    let (ok, _, err) = gwml(&["run", "examples/chirp_fit.gw", "--set", "tc=2 furlongs"]);
    assert!(!ok && err.contains("`furlongs` is not a unit"), "{err}");
}

#[test]
fn errors_are_reported_not_panics() {
    let (ok, _, err) = gwml(&["run", "examples/chirp_fit.gw", "--set", "mcc=3"]);
    assert!(!ok);
    assert!(err.contains("no param `mcc`") && err.contains("did you mean `mc`"), "{err}");
    let (ok, _, err) = gwml(&["run", "examples/chirp_fit.gw", "--set", "mc=500"]);
    assert!(!ok);
    assert!(err.contains("outside its bounds"), "{err}");
    let (ok, _, err) = gwml(&["run", "does/not/exist.gw"]);
    assert!(!ok);
    assert!(err.contains("cannot read"), "{err}");
    let (ok, _, err) = gwml(&["compile", "examples/chirp_fit.gw", "--scene", "chirp_fti"]);
    assert!(!ok);
    assert!(err.contains("did you mean `chirp_fit`"), "{err}");
    // One budget per experiment run.
    let (ok, _, err) = gwml(&["experiment", "glitch", "--quick", "--standard", "--out", "/nonexistent/never-written"]);
    assert!(!ok);
    assert!(err.contains("cannot be used with"), "{err}");
}

#[test]
fn compile_emits_every_stage_and_stats() {
    for emit in ["ast", "ir", "adjoint", "clif", "asm"] {
        let (ok, out, err) = gwml(&["compile", "examples/chirp_fit.gw", "--emit", emit]);
        assert!(ok, "{err}");
        assert!(!out.trim().is_empty(), "--emit {emit} printed nothing");
    }
    let (ok, out, _) = gwml(&["compile", "examples/chirp_fit.gw", "--stats"]);
    assert!(ok);
    assert!(out.contains("ops: checked") && out.contains("fused loop") && out.contains("time:"), "{out}");
    assert!(!out.contains("split at"), "chirp_fit has no cut, yet a loop is split:\n{out}");
    // std::taylorf2's ISCO cut splits both kernels' loop.
    let (ok, out, _) = gwml(&["compile", "examples/taylorf2_tradeoff.gw", "--stats"]);
    assert!(ok);
    assert_eq!(out.matches("1 split at an interval condition").count(), 2, "{out}");
    let (ok, out, _) = gwml(&["compile", "examples/chirp_fit.gw", "--precision", "f32"]);
    assert!(ok && out.contains("precision f32"), "{out}");
}

/// `--emit asm` lists the machine code of the kernel that runs: on x86-64
/// its fused loop is vectorised, packed doubles (`…pd`) in f64 and packed
/// singles (`…ps`) in f32.
#[cfg(target_arch = "x86_64")]
#[test]
fn compile_emits_the_vectorised_machine_code() {
    let packed = |out: &str, suffix: &str| {
        out.lines().filter(|l| l.split_whitespace().next().is_some_and(|op| op.starts_with('v') && op.ends_with(suffix))).count()
    };
    let (ok, f64_asm, err) = gwml(&["compile", "examples/chirp_fit.gw", "--emit", "asm"]);
    assert!(ok, "{err}");
    assert!(f64_asm.contains("block0"), "no block labels:\n{f64_asm}");
    assert!(packed(&f64_asm, "pd") > 10, "f64 kernel has no packed-double loop:\n{f64_asm}");
    let (ok, f32_asm, err) = gwml(&["compile", "examples/chirp_fit.gw", "--emit", "asm", "--precision", "f32"]);
    assert!(ok, "{err}");
    assert!(packed(&f32_asm, "ps") > 10, "f32 kernel has no packed-single loop:\n{f32_asm}");
}

/// `--knob NAME=VALUE` sets a scene's `knob`: the grid step of the W1
/// likelihood (so its arrays shrink) or the template's PN order; a knob the
/// scene lacks is refused with its name.
#[test]
fn run_with_knob_overrides() {
    let base = json(&["run", "examples/taylorf2_tradeoff.gw", "--format", "json"]);
    let coarse = json(&["run", "examples/taylorf2_tradeoff.gw", "--format", "json", "--knob", "df=0.5 Hz"]);
    let pn6 = json(&["run", "examples/taylorf2_tradeoff.gw", "--format", "json", "--knob", "pn_order=6"]);
    let len = |j: &serde_json::Value| j["outputs"]["psd"]["len"].as_u64();
    assert_eq!((len(&base), len(&coarse)), (Some(8033), Some(2009)));
    let loss = |j: &serde_json::Value| j["outputs"]["loss"].as_f64().unwrap();
    assert!(loss(&coarse) != loss(&base) && loss(&pn6) != loss(&base));
    let (ok, _, err) = gwml(&["run", "examples/taylorf2_tradeoff.gw", "--knob", "grid_step=1 Hz"]);
    assert!(!ok && err.contains("has no knob `grid_step`"), "{err}");
}

#[test]
fn f32_run_agrees_with_f64() {
    let a = json(&["run", "examples/chirp_fit.gw", "--grad", "--format", "json"]);
    let b = json(&["run", "examples/chirp_fit.gw", "--grad", "--format", "json", "--precision", "f32"]);
    let (x, y) = (a["outputs"]["loss"].as_f64().unwrap(), b["outputs"]["loss"].as_f64().unwrap());
    assert!(close(y, x, 1e-3), "f32 loss {y} vs f64 {x}");
}

/// `--precision mixed --emit adjoint` (the IR the kernels run, after
/// rescaling) says which values mixed precision computes in f64: the
/// chirp's `cis` is marked, not every value is, f32 marks none, and the
/// header names the precision.
#[test]
fn emit_adjoint_marks_the_values_mixed_precision_keeps_in_f64() {
    let (ok, out, err) = gwml(&["compile", "examples/chirp_fit.gw", "--precision", "mixed", "--emit", "adjoint"]);
    assert!(ok, "{err}");
    assert!(out.contains("(precision mixed,"), "{out}");
    assert!(out.lines().any(|l| l.contains(" f64 = cis ")), "no cis computed in f64:\n{out}");
    let values = out.lines().filter(|l| l.trim_start().starts_with('%')).count();
    let wide = out.lines().filter(|l| l.contains(" f64 = ")).count();
    assert!(wide > 0 && wide < values, "{wide} of {values} values in f64");
    let (ok, out, _) = gwml(&["compile", "examples/chirp_fit.gw", "--precision", "f32", "--emit", "adjoint"]);
    assert!(ok && !out.contains(" f64 = "), "f32 marks nothing:\n{out}");
}

/// `gwml ... | head` that stops reading early: a broken pipe ends gwml
/// quietly (status 141, as SIGPIPE would), never with a panic.
#[test]
fn a_closed_stdout_ends_quietly() {
    let scratch = tempfile::Builder::new().prefix("gwml-pipe-").tempdir().unwrap();
    let dir = scratch.path();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_gwml"))
        .args(["data", "glitch", "--n", "20", "--out"])
        .arg(dir.join("g.npz"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(141), "{err}");
}
