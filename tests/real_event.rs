//! GW150914 in real LIGO data: the 32 s H1 file GWOSC published for the
//! event (`fixtures/strain/H-H1_LOSC_4_V2-1126259446-32.hdf5`, 4096 Hz,
//! GPS 1126259446-1126259478; LIGO Scientific Collaboration and Virgo
//! Collaboration, Gravitational Wave Open Science Center, CC BY 4.0;
//! Abbott et al. 2016, Phys. Rev. Lett. 116 061102). `gwml scan` finds the
//! merger and the shipped classifier calls it a Chirp; `gwml explain`
//! prefers the merger-ringdown chirp to every glitch family, with a chirp
//! mass near the published one.

use std::path::Path;
use std::process::{Command, Output};

/// GPS time of GW150914's merger at the detectors (Abbott et al. 2016).
const MERGER_GPS: f64 = 1126259462.42;

fn gwml(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gwml")).args(args).output().expect("gwml runs")
}

fn event_file() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/strain/H-H1_LOSC_4_V2-1126259446-32.hdf5").display().to_string()
}

#[test]
fn scan_finds_gw150914_and_calls_it_a_chirp() {
    let dir = tempfile::Builder::new().prefix("gwml-real-event-").tempdir().unwrap();
    let csv = dir.path().join("t.csv").display().to_string();
    let out = gwml(&["scan", &event_file(), "--out", &csv]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut rows = text.lines();
    let header: Vec<&str> = rows.next().expect("a header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<Vec<&str>> = rows.map(|r| r.split(',').collect()).collect();
    let time = |r: &[&str]| r[col("gps_time")].parse::<f64>().unwrap();
    let near: Vec<&Vec<&str>> = rows.iter().filter(|r| (time(r) - MERGER_GPS).abs() < 0.05).collect();
    assert_eq!(near.len(), 1, "one trigger within 50 ms of the merger:\n{text}");
    assert_eq!(near[0][col("label")], "Chirp", "{text}");
    assert!(near[0][col("snr")].parse::<f64>().unwrap() > 10.0, "{text}");
    // Broadband rows (the Q 2.8 plane) sum at most 0.5 s: over 2.2 s, the
    // one at 60 Hz took in the mains line's wandering and made a trigger of
    // SNR 9.9 at GPS 1126259471.45, which `gwml explain` names noise.
    let late = rows.iter().filter(|r| time(r) > MERGER_GPS + 5.0).count();
    assert_eq!(late, 0, "no trigger in the 12 s after the merger:\n{text}");
}

#[test]
fn explain_prefers_a_merger_ringdown_chirp_with_the_published_chirp_mass() {
    let dir = tempfile::Builder::new().prefix("gwml-real-event-").tempdir().unwrap();
    let json = dir.path().join("e.json").display().to_string();
    let out = gwml(&["explain", &event_file(), "--gps", &MERGER_GPS.to_string(), "--json", &json]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["label"], "Chirp", "{doc}");
    let fits = doc["fits"].as_array().unwrap();
    let best = &fits[0];
    assert_eq!(best["family"], "chirp_imr", "{doc}");
    // The best glitch family (Koi Fish, a head and a body, took it before
    // the merger-ringdown variant) trails by more than ten units of ln B.
    let glitch = fits.iter().find(|f| !f["family"].as_str().unwrap().starts_with("chirp")).unwrap();
    assert!(glitch["ln_bayes_factor_vs_best"].as_f64().unwrap() < -10.0, "{doc}");
    // GWTC-1 (Abbott et al. 2019, Phys. Rev. X 9 031040): source-frame chirp
    // mass 28.6 (+1.6 -1.5) Msun at redshift 0.09, 31.2 Msun in the detector
    // frame; H1's matched-filter SNR ~20 (of the network's 24).
    let param = |name: &str| (best["params"][name]["value"].as_f64().unwrap(), best["params"][name]["sigma"].as_f64().unwrap());
    let (mc, sigma) = param("mc");
    assert!((mc - 31.2).abs() < 3.0 * sigma.max(1.0), "chirp mass {mc} ± {sigma}");
    let (snr, _) = param("snr");
    assert!((15.0..23.0).contains(&snr), "SNR {snr}");
    // The merger (the strain's peak), at GWOSC's event time to ~20 ms.
    let t0 = best["t0_gps"].as_f64().unwrap();
    assert!((t0 - MERGER_GPS).abs() < 0.02, "merger at GPS {t0}");
}
