//! Any bytes as a `.npy` file: data or a clear error, never a panic or an
//! allocation sized by a lying header.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("gwml-fuzz-{}.npy", std::process::id()));
    std::fs::write(&path, data).unwrap();
    let _ = gwml_runtime::npy::read(&path);
    let _ = gwml_runtime::dataset::Dataset::read(&path);
});
