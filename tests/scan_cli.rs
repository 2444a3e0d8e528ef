//! `gwml data strain`, `gwml scan` and `gwml qscan` from the command line:
//! bad inputs are one-line errors with exit status 1 (never a panic),
//! missing data is a reported skip, the outputs hold no NaN, and a Q-scan's
//! loudest tile sits on an injected glitch.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn gwml(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gwml")).args(args).output().expect("gwml runs")
}

fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/strain").join(name).display().to_string()
}

/// A scratch folder for one test, removed when it is dropped.
fn scratch() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("gwml-scan-cli-").tempdir().unwrap()
}

/// `name` in the test's scratch folder.
fn temp(dir: &tempfile::TempDir, name: &str) -> PathBuf {
    dir.path().join(name)
}

/// Exit status 1 and one line on standard error containing `needle`.
fn fails_with(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "status {:?}, stderr {err}", out.status);
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
    assert!(err.contains(needle), "{err:?} lacks {needle:?}");
}

fn strain(dir: &tempfile::TempDir, name: &str, args: &[&str]) -> String {
    let path = temp(dir, name).display().to_string();
    let mut all = vec!["data", "strain", "--out", &path];
    all.extend_from_slice(args);
    let out = gwml(&all);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    path
}

#[test]
fn broken_files_are_one_line_errors() {
    let dir = scratch();
    let csv = temp(&dir, "t.csv").display().to_string();
    for (file, needle) in [
        ("gwosc_truncated.hdf5", "truncated"),
        ("not_hdf5.hdf5", "not an HDF5 file"),
        ("gwosc_missing_xspacing.hdf5", "missing attribute `Xspacing`"),
        ("no_such_file.hdf5", "cannot read"),
    ] {
        fails_with(&gwml(&["scan", &fixture(file), "--out", &csv]), needle);
    }
    // A .npy needs its rate and start.
    let npy = fixture("gwosc_contiguous.strain.npy");
    fails_with(&gwml(&["scan", &npy, "--out", &csv]), "--sample-rate and --gps-start");
}

#[test]
fn a_sample_rate_the_classifier_was_not_trained_for_is_an_error() {
    let dir = scratch();
    let csv = temp(&dir, "rate.csv").display().to_string();
    // 512 Hz against the shipped classifier's 4096 Hz.
    fails_with(&gwml(&["scan", &fixture("gwosc_contiguous.hdf5"), "--out", &csv]), "expects 4096 Hz");
}

#[test]
fn missing_data_and_file_gaps_are_reported_skips_overlaps_are_errors() {
    let dir = scratch();
    let a = strain(&dir, "a.hdf5", &["--duration", "48", "--seed", "1", "--gap", "20:4", "--gps-start", "1000000000"]);
    let b = strain(&dir, "b.hdf5", &["--duration", "48", "--seed", "2", "--gps-start", "1000000050"]);
    let c = strain(&dir, "c.hdf5", &["--duration", "48", "--seed", "3", "--gps-start", "1000000040"]);
    let json = temp(&dir, "gaps.json").display().to_string();
    let out = gwml(&["scan", &a, &b, "--no-classify", "--out", &json]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("skipped 4 s: data-quality bit 0 (DATA) clear"), "{stdout}");
    assert!(stdout.contains("skipped 2 s: no file covers them"), "{stdout}");
    let text = std::fs::read_to_string(&json).unwrap();
    assert!(!text.contains("NaN") && !text.contains("nan"), "{text}");
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(doc["skipped"].as_array().unwrap().iter().any(|s| s["reason"] == "no file covers them"));
    // c overlaps a (starts at 40 s, a ends at 48 s).
    fails_with(&gwml(&["scan", &a, &c, "--no-classify", "--out", &json]), "overlaps");

    // All samples missing: nothing scanned, nothing written but the header.
    let empty = strain(&dir, "empty.hdf5", &["--duration", "32", "--gap", "0:32", "--glitch-rate", "0"]);
    let csv = temp(&dir, "empty.csv").display().to_string();
    let out = gwml(&["scan", &empty, "--no-classify", "--out", &csv]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("scanned 0 s"));
    assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 1);
}

#[test]
fn bad_arguments_are_one_line_errors() {
    let dir = scratch();
    let out = temp(&dir, "x.hdf5").display().to_string();
    fails_with(&gwml(&["data", "strain", "--duration", "10", "--out", &out]), "--duration 10");
    fails_with(&gwml(&["data", "strain", "--duration", "64", "--out", &out, "--gap", "60:10"]), "--gap 60:10");
    fails_with(&gwml(&["data", "strain", "--duration", "64", "--out", &out, "--snr", "30..8"]), "SNR");
    fails_with(&gwml(&["data", "strain", "--duration", "64", "--out", &out, "--snr", "loud"]), "expected a range LO..HI, got `loud`");
    let csv = temp(&dir, "bad.txt").display().to_string();
    fails_with(&gwml(&["scan", &fixture("gwosc_contiguous.hdf5"), "--out", &csv]), "write .csv or .json");
    let triggers = temp(&dir, "sig.csv").display().to_string();
    fails_with(
        &gwml(&["scan", &fixture("gwosc_contiguous.hdf5"), "--out", &triggers, "--min-significance", "0"]),
        "--min-significance must be positive and finite, got 0",
    );
}

/// `--snr class` draws each class at its own range (Koi Fish 12-400, the
/// others from 6.5) and `--real-fits` gives some Blips a real fit's shape,
/// whose truth rows carry no formula params.
#[test]
fn per_class_snr_and_real_fit_shapes() {
    let dir = scratch();
    let truth = temp(&dir, "class_truth.csv").display().to_string();
    let args = ["--duration", "256", "--glitch-rate", "20", "--classes", "koi-fish,blip", "--snr", "class", "--real-fits"];
    strain(&dir, "class.hdf5", &[&args[..], &["--truth", &truth]].concat());
    let text = std::fs::read_to_string(&truth).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let f0 = header.iter().position(|h| *h == "f0").expect("an f0 column");
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    let snr = |r: &Vec<&str>| r[2].parse::<f64>().unwrap();
    let koi: Vec<f64> = rows.iter().filter(|r| r[1] == "Koi Fish").map(snr).collect();
    let blips: Vec<&Vec<&str>> = rows.iter().filter(|r| r[1] == "Blip").collect();
    assert!(koi.len() >= 10 && koi.iter().all(|s| (12.0..=400.0).contains(s)), "Koi Fish SNRs {koi:?}");
    assert!(blips.iter().all(|r| (6.5..=100.0).contains(&snr(r))));
    let real = blips.iter().filter(|r| r[f0].is_empty()).count();
    assert!(real >= 3 && real < blips.len(), "{real} of {} Blips without formula params", blips.len());
}

#[test]
fn scanning_in_small_blocks_finds_what_one_block_finds() {
    let dir = scratch();
    let file = strain(&dir, "blocks.hdf5", &["--duration", "200", "--seed", "9", "--glitch-rate", "12", "--gap", "120:3"]);
    let run = |block: &str, out: &str| {
        let path = temp(&dir, out).display().to_string();
        let o = gwml(&["scan", &file, "--no-classify", "--block", block, "--out", &path]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8_lossy(&o.stdout).to_string();
        // Each trigger's time and span.
        let text = std::fs::read_to_string(&path).unwrap();
        let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
        let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
        let (start, end) = (column("start"), column("end"));
        let times: Vec<(f64, f64, f64)> = text
            .lines()
            .skip(1)
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap_or(f64::NAN)).collect();
                (v[0], v[start], v[end])
            })
            .collect();
        (times, stdout)
    };
    let (whole, whole_out) = run("1024", "whole.csv");
    let (blocks, blocks_out) = run("64", "blocks.csv");
    assert!(whole.len() >= 20, "{} triggers", whole.len());
    // Same searched seconds and skips, and nearly the same triggers: a
    // 64 s block estimates each PSD from at most 64 s instead of 128 s,
    // which moves a long glitch's loudest tile within its span (by up to
    // ~0.15 s for a 2 s Scratchy) and a few quiet triggers across the
    // threshold. A trigger is matched within 50 ms or by overlapping spans.
    let line = |s: &str, p: &str| s.lines().find(|l| l.starts_with(p)).unwrap_or("").split(" in ").next().unwrap().to_string();
    assert_eq!(line(&whole_out, "scanned"), line(&blocks_out, "scanned"));
    let same = |a: &(f64, f64, f64), b: &(f64, f64, f64)| (a.0 - b.0).abs() < 0.05 || (a.1 <= b.2 && b.1 <= a.2);
    let matched = whole.iter().filter(|t| blocks.iter().any(|b| same(t, b))).count();
    assert!(matched as f64 >= 0.9 * whole.len() as f64, "{whole:?} vs {blocks:?}");
    assert!((blocks.len() as f64 - whole.len() as f64).abs() <= 0.15 * whole.len() as f64, "{whole:?} vs {blocks:?}");
}

/// `--resume`: a scan killed (SIGKILL) after its first finished block is
/// rerun with only the missing blocks and writes exactly what an
/// uninterrupted scan writes; parts of a scan with other settings are
/// refused.
#[test]
fn a_killed_scan_resumes_with_the_missing_blocks_only() {
    let dir = scratch();
    let file = strain(&dir, "resume.hdf5", &["--duration", "224", "--seed", "4", "--glitch-rate", "10"]);
    let whole = temp(&dir, "resume-whole.csv").display().to_string();
    let out = temp(&dir, "resume.csv").display().to_string();
    let args = |path: &str| -> Vec<String> {
        ["scan", &file, "--no-classify", "--block", "64", "--threads", "1", "--out", path].iter().map(|s| s.to_string()).collect()
    };
    let o = gwml(&args(&whole).iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let parts = PathBuf::from(format!("{out}.parts"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_gwml")).args(args(&out)).arg("--resume").spawn().expect("gwml runs");
    let started = std::time::Instant::now();
    let finished = || {
        std::fs::read_dir(&parts)
            .map_or(0, |d| d.filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with("block-")).count())
    };
    while finished() == 0 && started.elapsed().as_secs() < 300 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().expect("SIGKILL");
    child.wait().unwrap();
    let done = finished();
    assert!(done >= 1 && !Path::new(&out).exists(), "killed after {done} blocks, before writing the output");
    let refused = gwml(&[args(&out).iter().map(String::as_str).collect::<Vec<_>>(), vec!["--resume", "--snr-threshold", "9"]].concat());
    fails_with(&refused, "finished blocks of another scan");
    let o = gwml(&[args(&out).iter().map(String::as_str).collect::<Vec<_>>(), vec!["--resume"]].concat());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains(&format!("resuming: {done} of ")), "{stdout}");
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&whole).unwrap(), "the resumed scan writes what one run writes");
    assert!(!parts.exists(), "the parts are removed once the output is written");
}

/// Without the `mpi` feature, `--mpi` says how to get it.
#[cfg(not(feature = "mpi"))]
#[test]
fn mpi_needs_the_feature() {
    let out = gwml(&["scan", &fixture("gwosc_contiguous.hdf5"), "--mpi"]);
    fails_with(&out, "--features mpi");
}

/// `gwml qscan`: the loudest tile of every duration's image is on the
/// glitch, the PNG is written, and bad times are one-line errors.
#[test]
fn the_loudest_tile_is_on_the_glitch_and_bad_times_are_errors() {
    let dir = scratch();
    let (file, truth) = (temp(&dir, "s.hdf5"), temp(&dir, "truth.csv"));
    let (file, truth) = (file.display().to_string(), truth.display().to_string());
    let out = gwml(&[
        "data",
        "strain",
        "--duration",
        "128",
        "--out",
        &file,
        "--truth",
        &truth,
        "--glitch-rate",
        "4",
        "--snr",
        "15..30",
        "--gap",
        "100:4",
        "--seed",
        "5",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The loudest injection at least 20 s from the ends and the gap, with
    // the span of the central 90 % of its whitened energy.
    let text = std::fs::read_to_string(&truth).unwrap();
    let (gps, snr, label, span) = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let number = |i: usize| f[i].parse::<f64>().unwrap();
            (number(0), number(2), f[1].to_string(), (number(3), number(4)))
        })
        .filter(|(t, ..)| {
            let s = t - 1_264_000_000.0;
            (20.0..80.0).contains(&s)
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .expect("an injection between 20 and 80 s");
    let png = temp(&dir, "q.png").display().to_string();
    let out = gwml(&["qscan", &file, "--gps", &gps.to_string(), "--out", &png]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<&str> = stdout.lines().filter(|l| l.contains("loudest tile")).collect();
    assert_eq!(lines.len(), 4, "one line per default duration: {stdout}");
    for l in lines {
        // "... loudest tile +0.002 s at 123.9 Hz, normalised energy 180.6 ..."
        let after = l.split("loudest tile ").nth(1).unwrap();
        let offset: f64 = after.split(' ').next().unwrap().parse().unwrap();
        let energy: f64 = l.split("normalised energy ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
        // On the glitch: within 50 ms of its energy's span (a long
        // glitch's loudest tile may be anywhere along it).
        let at = gps + offset;
        assert!(at > span.0 - 0.05 && at < span.1 + 0.05, "loudest tile {offset} s from the {label} (SNR {snr}, span {span:?}): {l}");
        assert!(energy > 25.0, "an SNR {snr} glitch gives normalised energy {energy}: {l}");
    }
    assert_eq!(&std::fs::read(&png).unwrap()[..4], b"\x89PNG");
    // Bad times.
    fails_with(&gwml(&["qscan", &file, "--gps", "1263999000", "--out", &png]), "is not in the data");
    fails_with(&gwml(&["qscan", &file, "--gps", "1264000101", "--out", &png]), "missing data");
    fails_with(&gwml(&["qscan", &file, "--gps", "1264000000.5", "--out", &png]), "too near an end");
    fails_with(&gwml(&["qscan", &file, "--gps", &gps.to_string(), "--durations", "40", "--out", &png]), "duration too long");
    // `gwml explain` of the same glitch: every family fitted, the JSON
    // complete, the injected family best (a Koi Fish may be called a Blip:
    // its whitened head is too faint to tell at this SNR).
    let json = temp(&dir, "explain.json").display().to_string();
    let png = temp(&dir, "explain.png").display().to_string();
    let out = gwml(&["explain", &file, "--gps", &gps.to_string(), "--json", &json, "--plot", &png]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("best: ") && stdout.contains("likely cause: "), "{stdout}");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let fits = doc["fits"].as_array().unwrap();
    // One fit per family (a variant, such as a blip with an echo, only where it fits better).
    assert_eq!(fits.len(), gwml_lab::explain::FAMILIES.iter().filter(|f| f.variant_of.is_none()).count(), "{doc}");
    for f in fits {
        assert!(f["ln_evidence"].as_f64().unwrap().is_finite(), "{f}");
        assert!(f["params"]["snr"]["value"].as_f64().unwrap() >= 0.0, "{f}");
    }
    let best = doc["label"].as_str().unwrap();
    assert!(best == label || (label == "Koi Fish" && best == "Blip"), "injected {label} (SNR {snr}), explained as {best}: {stdout}");
    assert!(doc["fits"][0]["ln_bayes_factor_vs_noise"].as_f64().unwrap() > 10.0, "{doc}");
    assert_eq!(&std::fs::read(&png).unwrap()[..4], b"\x89PNG");
    fails_with(&gwml(&["explain", &file, "--gps", "1263999000"]), "is not in the data");
    fails_with(&gwml(&["explain", &file, "--gps", "1264000101"]), "missing data");
    fails_with(&gwml(&["explain", &file, "--gps", "1264000001"]), "too near an end");
    fails_with(&gwml(&["explain", &file, "--gps", &gps.to_string(), "--window", "40"]), "--window 40");
    // `gwml scan --explain` writes the best family, Bayes factors and params into each row.
    let csv = temp(&dir, "explained.csv").display().to_string();
    let out = gwml(&["scan", &file, "--explain", "--out", &csv]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let family = header.iter().position(|h| *h == "family").expect("a family column");
    let params = header.iter().position(|h| *h == "family_params").expect("a params column");
    // Triggers within 16 s of the gap cannot be explained (their 32 s of
    // data reach it): each row says so, and the rest are judged.
    let rows: Vec<Vec<&str>> = text.lines().skip(1).filter(|l| !l.contains("missing data")).map(|l| l.split(',').collect()).collect();
    assert!(!rows.is_empty());
    let families: Vec<&str> = gwml_lab::explain::FAMILIES.iter().map(|f| f.scene).collect();
    let explained = rows.iter().filter(|r| families.contains(&r[family])).count();
    assert!(2 * explained >= rows.len(), "{explained} of {} triggers explained by a family: {text}", rows.len());
    assert!(rows.iter().filter(|r| !r[family].is_empty() && r[family] != "noise").all(|r| r[params].starts_with("t0_gps=")), "{text}");
}
