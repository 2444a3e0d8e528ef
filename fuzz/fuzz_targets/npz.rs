//! Any bytes as a `.npz` dataset (a zip of `.npy` members).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("gwml-fuzz-{}.npz", std::process::id()));
    std::fs::write(&path, data).unwrap();
    let _ = gwml_runtime::dataset::Dataset::read(&path);
});
