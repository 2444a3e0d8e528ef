//! Differential on mutated text: every scene of a program that checks is
//! JIT-compiled and run (value and gradient, at the params' and inputs'
//! defaults), and what it returns is compared with the reference
//! interpreter on the same IR. Scenes in f64 with exact math must agree to
//! 1e-7 relative; others must only not panic.
#![no_main]
use gwml_runtime::Model;
use libfuzzer_sys::fuzz_target;

#[path = "common/differential.rs"]
mod differential;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(model) = Model::from_source("fuzz.gw", text) else { return };
    for name in model.program.scene_names() {
        if let Ok(scene) = model.scene(Some(name)) {
            differential::check(&scene, name);
        }
    }
});
