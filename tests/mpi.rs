//! `--mpi` under `mpirun -n 2` (feature `mpi`; `scripts/test.sh` runs these
//! when `mpirun` is installed): a scan on two ranks writes exactly what one
//! process writes, a rank killed with SIGKILL fails the job and the rerun
//! scans only the missing blocks, and training on two ranks follows one
//! process at the same global batch.
#![cfg(feature = "mpi")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_gwml");

/// A scratch folder for one test, removed when it is dropped.
fn scratch() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("gwml-mpi-").tempdir().unwrap()
}

/// `name` in the test's scratch folder.
fn temp(dir: &tempfile::TempDir, name: &str) -> PathBuf {
    dir.path().join(name)
}

fn gwml(args: &[&str]) -> Output {
    let out = Command::new(BIN).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().expect("gwml runs");
    assert!(out.status.success(), "gwml {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

/// `mpirun -n 2 gwml ARGS`, one thread per rank.
fn mpirun(args: &[&str]) -> Command {
    let mut c = Command::new("mpirun");
    c.args(["--allow-run-as-root", "--oversubscribe", "-n", "2", BIN]).args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn strain(dir: &tempfile::TempDir, name: &str) -> String {
    let path = temp(dir, name).display().to_string();
    gwml(&["data", "strain", "--duration", "224", "--seed", "21", "--glitch-rate", "10", "--out", &path]);
    path
}

#[test]
fn a_scan_on_two_ranks_writes_what_one_process_writes() {
    let dir = scratch();
    let file = strain(&dir, "two.hdf5");
    let one = temp(&dir, "one.csv").display().to_string();
    let two = temp(&dir, "two.csv").display().to_string();
    gwml(&["scan", &file, "--block", "64", "--threads", "1", "--out", &one]);
    let out = mpirun(&["scan", &file, "--block", "64", "--threads", "1", "--mpi", "--out", &two]).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("MPI: 2 ranks share"), "{stdout}");
    assert_eq!(stdout.matches("wrote ").count(), 1, "rank 0 alone writes: {stdout}");
    let text = std::fs::read_to_string(&two).unwrap();
    assert!(text.lines().count() > 5, "{text}");
    assert_eq!(text, std::fs::read_to_string(&one).unwrap());
}

#[test]
fn a_killed_rank_fails_the_job_and_the_rerun_does_only_the_missing_blocks() {
    let dir = scratch();
    let file = strain(&dir, "kill.hdf5");
    let one = temp(&dir, "kill-one.csv").display().to_string();
    let out = temp(&dir, "kill.csv").display().to_string();
    gwml(&["scan", &file, "--no-classify", "--block", "64", "--threads", "1", "--out", &one]);
    let args = ["scan", &file, "--no-classify", "--block", "64", "--threads", "1", "--mpi", "--out", &out];
    let job = mpirun(&args).stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let parts = PathBuf::from(format!("{out}.parts"));
    let finished = || {
        std::fs::read_dir(&parts)
            .map_or(0, |d| d.filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with("block-")).count())
    };
    let started = std::time::Instant::now();
    while finished() == 0 && started.elapsed().as_secs() < 300 {
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    // Rank 1: the gwml process of this job whose environment says so.
    let rank1 = std::fs::read_dir("/proc")
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .find(|pid| {
            let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
            let environ = std::fs::read(format!("/proc/{pid}/environ")).unwrap_or_default();
            let has = |hay: &[u8], needle: &str| hay.windows(needle.len()).any(|w| w == needle.as_bytes());
            has(&cmdline, &out) && !has(&cmdline, "mpirun") && has(&environ, "OMPI_COMM_WORLD_RANK=1")
        })
        .expect("rank 1 is running");
    Command::new("kill").args(["-9", &rank1.to_string()]).status().unwrap();
    let result = job.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(!result.status.success(), "the job fails");
    assert!(stderr.contains("rank 1") && stderr.contains("signal 9"), "mpirun names the rank and the signal: {stderr}");
    assert!(!Path::new(&out).exists(), "no output from a failed job");
    let done = finished();
    assert!(done >= 1, "finished blocks are recorded");
    let rerun = mpirun(&args).output().unwrap();
    let stdout = String::from_utf8_lossy(&rerun.stdout);
    assert!(rerun.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&rerun.stderr));
    assert!(stdout.contains(&format!("({done} finished before)")), "only the missing blocks: {stdout}");
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&one).unwrap(), "the merged output is the same");
}

/// Reads a loss-curve CSV as rows of numbers (empty fields as NaN).
fn curve(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path).unwrap().lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect()).collect()
}

#[test]
fn training_on_two_ranks_follows_one_process() {
    let dir = scratch();
    let train = temp(&dir, "train.npz").display().to_string();
    let val = temp(&dir, "val.npz").display().to_string();
    gwml(&["data", "bursts", "--n", "96", "--seed", "3", "--out", &train]);
    gwml(&["data", "bursts", "--n", "32", "--seed", "4", "--out", &val]);
    let run = |tag: &str, mpi: bool| -> (Vec<Vec<f64>>, Vec<f64>) {
        let history = temp(&dir, &format!("{tag}.csv"));
        let ck = temp(&dir, &format!("ck-{tag}"));
        let (h, c) = (history.display().to_string(), ck.display().to_string());
        let args = [
            "train",
            "examples/burst_cnn.gw",
            "--data",
            &train,
            "--val",
            &val,
            "--epochs",
            "3",
            "--batch",
            "16",
            "--threads",
            "1",
            "--seed",
            "7",
            "--checkpoint",
            &c,
            "--history",
            &h,
            "--quiet",
        ];
        if mpi {
            let out = mpirun(&[&args[..], &["--mpi"]].concat()).output().unwrap();
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
            assert_eq!(stdout.matches("wrote ").count(), 1, "rank 0 alone writes: {stdout}");
        } else {
            gwml(&args);
        }
        let weights = gwml::runtime::checkpoint::load(&ck.join("last.safetensors")).unwrap();
        let flat = weights.tensors.iter().flat_map(|t| t.data.clone()).collect();
        (curve(&history), flat)
    };
    let (one, w1) = run("one", false);
    let (two, w2) = run("two", true);
    assert_eq!(one.len(), 3);
    let close = |a: f64, b: f64| (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-300);
    for (a, b) in one.iter().zip(&two) {
        assert!(a.iter().zip(b).all(|(x, y)| close(*x, *y)), "loss curves differ: {a:?} vs {b:?}");
    }
    assert_eq!(w1.len(), w2.len());
    let scale = w1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst = w1.iter().zip(&w2).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst <= 1e-9 * scale, "weights differ by {worst:e} (largest {scale:e})");
}
