//! Any bytes as a GWOSC strain file (HDF5).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("gwml-fuzz-{}.hdf5", std::process::id()));
    std::fs::write(&path, data).unwrap();
    if let Ok(reader) = gwml_strain::gwosc::open(&path) {
        let _ = reader.read_samples(0, 16);
    }
    let _ = gwml_strain::gwosc::read(&path);
});
