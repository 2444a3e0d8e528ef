//! Any text as a two-column PSD or ASD file.
#![no_main]
use gwml_runtime::spectrum::{Kind, Spectrum};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    for kind in [Kind::Psd, Kind::Asd] {
        if let Ok(s) = Spectrum::parse(text, "fuzz.txt", kind) {
            let _ = s.psd_at(100.0);
        }
    }
});
