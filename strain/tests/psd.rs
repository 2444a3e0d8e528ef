//! Welch's PSD against `scipy.signal.welch` (fixtures from
//! `scripts/strain_fixtures.py`): every bin within 1e-10 relative.

use gwml_strain::psd::{Average, Welch, WelchOptions};
use std::path::Path;

#[test]
fn welch_matches_scipy_median_and_mean_with_and_without_detrending() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/strain");
    let bytes = std::fs::read(dir.join("welch_input.npy")).unwrap();
    let x: Vec<f64> = npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap();
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("welch_expected.json")).unwrap()).unwrap();
    let fs = doc["fs"].as_f64().unwrap();
    let cases = doc["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 8);
    for case in cases {
        let n = case["nperseg"].as_u64().unwrap() as usize;
        let average = if case["average"] == "median" { Average::Median } else { Average::Mean };
        let options = WelchOptions { segment: n, overlap: n / 2, average, detrend: case["detrend"].as_bool().unwrap() };
        let psd = Welch::new(fs, options).unwrap().estimate(&x).unwrap();
        let want: Vec<f64> = case["psd"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert_eq!(psd.values.len(), want.len(), "{case:?}");
        assert_eq!(psd.df, case["df"].as_f64().unwrap());
        let worst = psd.values.iter().zip(&want).map(|(a, b)| ((a - b) / b).abs()).fold(0.0, f64::max);
        assert!(worst <= 1e-10, "nperseg {n} {:?}: worst relative error {worst:e}", options);
    }
}
