//! Crash safety of `gwml train --checkpoint`: killed with SIGKILL at
//! random moments, training always leaves a complete `last.safetensors`
//! (written atomically: a temporary file renamed over the old one), and
//! `--resume` continues from it, losing at most the epoch in progress.

#[path = "common/cli.rs"]
mod cli;
use cli::gwml;
use gwml::runtime::checkpoint;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// The epoch a checkpoint was written after.
fn epoch_of(path: &std::path::Path) -> u64 {
    let ck = checkpoint::load(path).unwrap_or_else(|e| panic!("the checkpoint after a kill does not load: {e}"));
    ck.metadata.get("epoch").expect("checkpoints record their epoch").parse().expect("an epoch number")
}

#[test]
fn sigkill_during_training_leaves_a_complete_checkpoint_and_resume_loses_at_most_one_epoch() {
    let dir = std::env::temp_dir().join(format!("gwml-train-kill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let data = dir.join("train.npz").display().to_string();
    let (ok, _, err) = gwml(&["data", "bursts", "--n", "48", "--seed", "3", "--out", &data]);
    assert!(ok, "{err}");
    let ck = dir.join("ck");
    let last = ck.join("last.safetensors");
    let ck_arg = ck.display().to_string();
    // A fixed sequence of kill delays (a small LCG), spread over starting
    // up, training and writing checkpoints.
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next_delay = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        Duration::from_millis(150 + (state >> 33) % 1200)
    };
    let (mut kills, mut runs, mut last_epoch) = (0, 0, 0u64);
    while kills < 20 {
        runs += 1;
        assert!(runs < 80, "only {kills} of 20 runs were killed while training");
        let mut args = vec!["train", "examples/burst_cnn.gw", "--data", &data, "--epochs", "100000", "--batch", "16"];
        args.extend(["--checkpoint", &ck_arg, "--threads", "1"]);
        if last.exists() {
            args.push("--resume");
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_gwml"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("gwml starts");
        // Epoch lines as they come (stdout is flushed per line).
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = mpsc::channel();
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if let Some(rest) = line.trim_start().strip_prefix("epoch ") {
                    if let Some(n) = rest.split('/').next().and_then(|n| n.parse::<u64>().ok()) {
                        let _ = tx.send(n);
                    }
                }
            }
        });
        let start = Instant::now();
        std::thread::sleep(next_delay());
        child.kill().expect("SIGKILL");
        let status = child.wait().unwrap();
        reader.join().unwrap();
        let printed: Vec<u64> = rx.try_iter().collect();
        assert!(!status.success(), "training of 100,000 epochs ended by itself after {:?}", start.elapsed());
        if !last.exists() {
            assert!(printed.is_empty(), "epochs {printed:?} were reported but no checkpoint was written");
            continue;
        }
        kills += 1;
        let epoch = epoch_of(&last);
        // Nothing is lost but the epoch in progress: every epoch reported
        // done is in the checkpoint, and checkpoints never go back.
        if let Some(&reported) = printed.last() {
            assert!(epoch >= reported, "epoch {reported} was reported, but the checkpoint holds epoch {epoch}");
        }
        assert!(epoch >= last_epoch, "the checkpoint went back from epoch {last_epoch} to {epoch}");
        last_epoch = epoch;
    }
    // A final resume continues from the last checkpoint.
    let target = (last_epoch + 1).to_string();
    let (ok, out, err) = gwml(&[
        "train",
        "examples/burst_cnn.gw",
        "--data",
        &data,
        "--epochs",
        &target,
        "--batch",
        "16",
        "--checkpoint",
        &ck_arg,
        "--threads",
        "1",
        "--resume",
    ]);
    assert!(ok, "{err}");
    assert!(err.contains(&format!("after epoch {last_epoch}")), "{err}");
    assert!(out.contains(&format!("epoch {target}/{target}")), "{out}");
    assert!(last_epoch >= 3, "the kills should fall after several epochs (last checkpoint: epoch {last_epoch})");
    let _ = std::fs::remove_dir_all(&dir);
}
