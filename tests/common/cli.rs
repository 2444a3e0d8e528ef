//! Running the `gwml` binary from the end-to-end tests.

use std::process::Command;

/// Runs `gwml ARGS` in the repository root: (success, stdout, stderr).
pub fn gwml(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_gwml")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().expect("gwml runs");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Runs `gwml ARGS`, which must succeed and print JSON.
#[allow(dead_code)] // not every test file reads JSON
pub fn json(args: &[&str]) -> serde_json::Value {
    let (ok, stdout, stderr) = gwml(args);
    assert!(ok, "gwml {args:?} failed: {stderr}");
    serde_json::from_str(&stdout).expect("valid JSON")
}
