//! `gwml tradeoff` end to end: the table, its files, and a failing setting
//! reported in its row instead of aborting the sweep.

#[path = "common/cli.rs"]
mod cli;

use cli::gwml;

#[test]
fn tradeoff_sweeps_math_modes_and_writes_csv_json_and_png() {
    let dir = std::env::temp_dir().join(format!("gwml-tradeoff-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, json, png) = (dir.join("t.csv"), dir.join("t.json"), dir.join("t.png"));
    let (ok, stdout, stderr) = gwml(&[
        "tradeoff",
        "examples/taylorf2_tradeoff.gw",
        "--psd",
        "psd",
        "--reps",
        "3",
        "--precision",
        "f64",
        "--csv",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    assert!(stderr.contains("[1/3] precision f64, math exact"), "{stderr}");
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
    std::fs::remove_dir_all(&dir).ok();
}

/// `exp` of 100 needs its operand at true scale and its result (2.7e43)
/// is beyond f32's largest value, so no rescaling saves it: f32 fails to
/// compile, that row says so, and the f64 rows are still measured.
#[test]
fn a_failing_setting_is_reported_in_its_row() {
    let dir = std::env::temp_dir().join(format!("gwml-tradeoff-fail-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
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
    std::fs::remove_dir_all(&dir).ok();
}
