//! `gwml tradeoff` end to end: the table, its files, and a failing setting
//! reported in its row instead of aborting the sweep.

#[path = "common/cli.rs"]
mod cli;

use cli::gwml;

/// `gwml tradeoff` on the W1 likelihood in f64 with 3 timed calls and
/// multibanding off, plus `extra`.
fn w1_tradeoff(extra: &[&str]) -> (bool, String, String) {
    let mut args =
        vec!["tradeoff", "examples/taylorf2_tradeoff.gw", "--psd", "psd", "--reps", "3", "--precision", "f64", "--multiband", "off"];
    args.extend_from_slice(extra);
    gwml(&args)
}

#[test]
fn tradeoff_sweeps_math_modes_and_writes_csv_json_and_png() {
    let scratch = tempfile::Builder::new().prefix("gwml-tradeoff-").tempdir().unwrap();
    let dir = scratch.path();
    let (csv, json, png) = (dir.join("t.csv"), dir.join("t.json"), dir.join("t.png"));
    let (ok, stdout, stderr) =
        w1_tradeoff(&["--csv", csv.to_str().unwrap(), "--json", json.to_str().unwrap(), "--plot", png.to_str().unwrap()]);
    assert!(ok, "{stderr}");
    assert!(stderr.contains("[1/3] f64 exact"), "{stderr}");
    let rows: Vec<&str> = stdout.lines().filter(|l| l.contains("| f64 |")).collect();
    assert_eq!(rows.len(), 3, "{stdout}");
    // The reference has no error and is never dominated in accuracy.
    let exact = rows.iter().find(|r| r.contains("| exact |")).unwrap();
    assert!(exact.starts_with("| * |") && exact.contains("| 0.0e0 | 0.0e0 | 0.0e0 |"), "{exact}");
    let items: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let items = items.as_array().unwrap();
    assert_eq!(items.len(), 3);
    for it in items {
        let (m, g) = (it["mismatch"].as_f64().unwrap(), it["grad_error"].as_f64().unwrap());
        let bound = match it["math"].as_str().unwrap() {
            "exact" => (0.0, 0.0),
            "fast" => (1e-18, 1e-8),
            _ => (1e-8, 1e-2),
        };
        assert!(m <= bound.0 && g <= bound.1, "{it}");
    }
    assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 4);
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
}

/// `exp` of 100 needs its operand at true scale and its result (2.7e43)
/// is beyond f32's largest value, so no rescaling saves it: f32 fails to
/// compile, that row says so, and the f64 rows are still measured.
#[test]
fn a_failing_setting_is_reported_in_its_row() {
    let scratch = tempfile::Builder::new().prefix("gwml-tradeoff-fail-").tempdir().unwrap();
    let dir = scratch.path();
    let file = dir.join("overflow.gw");
    std::fs::write(
        &file,
        "scene s {
            grid f = frequencies(from: 1 Hz, to: 64 Hz, step: 1 Hz)
            param a = 1.0
            output y = log(sum(exp(a * 100.0 * f / 64 Hz)))
            grad y wrt [a]
        }",
    )
    .unwrap();
    let (ok, stdout, stderr) = gwml(&["tradeoff", file.to_str().unwrap(), "--reps", "2", "--math", "exact"]);
    assert!(ok, "{stderr}");
    let f32_row = stdout.lines().find(|l| l.contains("| f32 |")).expect("an f32 row");
    assert!(f32_row.contains("failed:") && f32_row.contains("precision: mixed"), "{f32_row}");
    assert!(stdout.lines().any(|l| l.starts_with("| * | f64 | exact |")), "{stdout}");
}

/// `--sweep` measures the scene's own knobs: the grid resolution `df` (the
/// waveform output is then on another grid, so it has no mismatch, while the
/// loss is compared) and the template's PN order (a different waveform).
#[test]
fn tradeoff_sweeps_scene_knobs() {
    let scratch = tempfile::Builder::new().prefix("gwml-tradeoff-knobs-").tempdir().unwrap();
    let dir = scratch.path();
    let json = dir.join("t.json");
    let (ok, stdout, stderr) =
        w1_tradeoff(&["--math", "exact", "--sweep", "df=0.125 Hz,0.5 Hz", "--sweep", "pn_order=6,7", "--json", json.to_str().unwrap()]);
    assert!(ok, "{stderr}");
    assert!(stderr.contains("[2/5] f64 exact df=0.125 Hz pn_order=6"), "{stderr}");
    assert!(stdout.contains("| knobs |") && stdout.contains("| (scene) |"), "{stdout}");
    let items: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let items = items.as_array().unwrap();
    assert_eq!(items.len(), 5, "the reference and 2 × 2 knob settings");
    let row = |df: &str, pn: &str| {
        items
            .iter()
            .find(|it| it["knobs"]["df"] == df && it["knobs"]["pn_order"] == pn)
            .unwrap_or_else(|| panic!("no row df={df} pn_order={pn}"))
    };
    // The scene's own values, set explicitly: the reference again.
    let same = row("0.125 Hz", "7");
    assert_eq!((same["output_error"].as_f64(), same["grad_error"].as_f64(), same["mismatch"].as_f64()), (Some(0.0), Some(0.0), Some(0.0)));
    // A 3PN template against 3.5PN data: another waveform.
    assert!(row("0.125 Hz", "6")["mismatch"].as_f64().unwrap() > 1e-3);
    // A coarser grid: four times fewer bins; the loss moves, the waveform is not compared.
    let coarse = row("0.5 Hz", "7");
    assert!(coarse["mismatch"].is_null(), "{coarse}");
    assert!(coarse["output_error"].as_f64().unwrap() > 1e-6, "{coarse}");
    assert!(coarse["grad_us"].as_f64().unwrap() < same["grad_us"].as_f64().unwrap() * 10.0);
}

#[test]
fn a_sweep_of_a_knob_the_scene_lacks_is_refused_with_a_suggestion() {
    let (ok, _, stderr) = gwml(&["tradeoff", "examples/taylorf2_tradeoff.gw", "--reps", "2", "--sweep", "pn_ordr=5"]);
    assert!(!ok);
    assert!(stderr.contains("has no knob `pn_ordr`") && stderr.contains("did you mean `pn_order`?"), "{stderr}");
    let (ok, _, stderr) = gwml(&["tradeoff", "examples/taylorf2_tradeoff.gw", "--reps", "2", "--sweep", "pn_order"]);
    assert!(!ok && stderr.contains("expected NAME=VALUE"), "{stderr}");
}

/// `--knob` sets a scene knob for every row, the reference included: the
/// f64-exact row at df = 0.5 Hz is the reference (no error, 1.00×). A
/// knob both set and swept is refused.
#[test]
fn tradeoff_knob_sets_every_row_and_the_reference() {
    let (ok, stdout, stderr) = w1_tradeoff(&["--math", "exact,fast", "--knob", "df=0.5 Hz"]);
    assert!(ok, "{stderr}");
    assert!(stderr.contains("[1/2] f64 exact df=0.5 Hz") && stderr.contains("[2/2] f64 fast df=0.5 Hz"), "{stderr}");
    let rows: Vec<&str> = stdout.lines().filter(|l| l.contains("| f64 |")).collect();
    assert_eq!(rows.len(), 2, "{stdout}");
    assert!(rows.iter().all(|r| r.contains("| df=0.5 Hz |")), "{stdout}");
    let exact = rows.iter().find(|r| r.contains("| exact |")).unwrap();
    assert!(exact.contains("| 1.00× | 0.0e0 | 0.0e0 | 0.0e0 |"), "{exact}");
    let fast = rows.iter().find(|r| r.contains("| fast |")).unwrap();
    assert!(!fast.contains("| 0.0e0 |") && !fast.contains("| - |"), "compared, on the same grid: {fast}");
    let (ok, _, stderr) = w1_tradeoff(&["--knob", "df=0.5 Hz", "--sweep", "df=1 Hz"]);
    assert!(!ok && stderr.contains("knob `df` is both set (--knob) and swept (--sweep)"), "{stderr}");
}

/// The full-band W1 likelihood (`taylorf2_tradeoff_full.gw`, the README's
/// second tradeoff table), default sweep: every precision and math setting
/// without multibanding, `f32 fastest` included, stays within the issue's
/// bounds (waveform mismatch ≤ 1e-6, gradient relative error ≤ 1e-4); the
/// multibanded rows (swept by default for a waveform) stay within their
/// tolerance's bound, mismatch ≤ tolerance²/2; the relative-binning rows
/// (swept by default for a likelihood over a waveform) leave the waveform
/// output within 1e-6 and, in f64 and mixed with exact math, keep
/// |Δ loss| ≤ 1e-3 and the gradient within 1e-4.
#[test]
fn full_band_likelihood_stays_within_the_accuracy_bounds_in_every_setting() {
    let json = std::env::temp_dir().join(format!("gwml-tradeoff-full-{}.json", std::process::id()));
    let (ok, stdout, stderr) =
        gwml(&["tradeoff", "examples/taylorf2_tradeoff_full.gw", "--psd", "psd", "--reps", "3", "--json", json.to_str().unwrap()]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("| algorithm |") && stdout.contains("relative_binning=100"), "{stdout}");
    let items: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let items = items.as_array().unwrap();
    assert_eq!(
        items.len(),
        72,
        "three precisions × three math modes × (exact, multiband 1e-2, 2e-3, 1e-3, 1e-4, relative binning 50, 100, 200)"
    );
    for it in items {
        let (m, g) = (it["mismatch"].as_f64().unwrap(), it["grad_error"].as_f64().unwrap());
        if it["relative_binning"].as_str().unwrap() != "off" {
            assert_eq!(it["multiband"], "off", "{it}");
            assert!(m <= 1e-6 && g.is_finite(), "{it}");
            // Relative binning's own error (fast and fastest math add their own).
            if it["precision"] != "f32" && it["math"] == "exact" {
                assert!(g <= 1e-4 && it["delta_loss"].as_f64().unwrap() <= 1e-3, "{it}");
            }
            continue;
        }
        match it["multiband"].as_str().unwrap() {
            "off" => assert!(m <= 1e-6 && g <= 1e-4, "{it}"),
            tol => {
                let tol: f64 = tol.parse().unwrap();
                assert!(m <= tol * tol / 2.0 + 1e-9 && g.is_finite(), "{it}");
            }
        }
    }
    std::fs::remove_file(&json).ok();
}
