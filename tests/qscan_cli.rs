//! `gwml qscan` from the command line: the loudest tile of every duration's
//! image sits on an injected glitch, the PNG is written, and times outside
//! the data, in missing data or too near its ends are one-line errors.

use std::path::PathBuf;
use std::process::{Command, Output};

fn gwml(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gwml")).args(args).output().expect("gwml runs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("gwml-qscan-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Exit status 1 and one line on standard error containing `needle`.
fn fails_with(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "status {:?}, stderr {err}", out.status);
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
    assert!(err.contains(needle), "{err:?} lacks {needle:?}");
}

#[test]
fn the_loudest_tile_is_on_the_glitch_and_bad_times_are_errors() {
    let (file, truth) = (temp("s.hdf5"), temp("truth.csv"));
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
    // The loudest injection at least 20 s from the ends and the gap.
    let text = std::fs::read_to_string(&truth).unwrap();
    let (gps, snr) = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse::<f64>().unwrap(), f[2].parse::<f64>().unwrap())
        })
        .filter(|(t, _)| {
            let s = t - 1_264_000_000.0;
            (20.0..80.0).contains(&s)
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .expect("an injection between 20 and 80 s");
    let png = temp("q.png").display().to_string();
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
        assert!(offset.abs() < 0.05, "loudest tile {offset} s from the injection (SNR {snr}): {l}");
        assert!(energy > 25.0, "an SNR {snr} glitch gives normalised energy {energy}: {l}");
    }
    assert_eq!(&std::fs::read(&png).unwrap()[..4], b"\x89PNG");
    // Bad times.
    fails_with(&gwml(&["qscan", &file, "--gps", "1263999000", "--out", &png]), "is not in the data");
    fails_with(&gwml(&["qscan", &file, "--gps", "1264000101", "--out", &png]), "missing data");
    fails_with(&gwml(&["qscan", &file, "--gps", "1264000000.5", "--out", &png]), "too near an end");
    fails_with(&gwml(&["qscan", &file, "--gps", &gps.to_string(), "--durations", "40", "--out", &png]), "duration too long");
}
