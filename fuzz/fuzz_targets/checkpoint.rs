//! Any bytes as a safetensors checkpoint.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = gwml_runtime::checkpoint::parse(data, "fuzz.safetensors");
});
