//! Any text through checking, rendering and, for programs that check, every
//! scene's pipeline (every pass, with the IR verifier on): diagnostics or
//! IR, never a panic.
#![no_main]
use gwml_compiler::{Options, Program};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match Program::parse("fuzz.gw", text) {
        Err(e) => {
            let _ = e.render(false);
        }
        Ok(program) => {
            for scene in program.scene_names() {
                let options = Options { verify: true, ..Options::default() };
                if let Err(e) = program.pipeline(Some(scene), options) {
                    let _ = e.to_string();
                }
            }
        }
    }
});
