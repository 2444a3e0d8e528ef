//! The bad-input corpus: `compiler/tests/corpus/*.gw` (written by
//! `scripts/bad_gw_corpus.py`), wrong programs of every kind — syntax,
//! names, units, shapes, grids, knobs, settings, learned layers, cycles,
//! modules and limits such as deep nesting or huge grids. Each must fail
//! with diagnostics (from checking, or from preparing one of its scenes),
//! every diagnostic a message with a span inside its file and a help line;
//! none may panic. The rendered diagnostics are snapshots in
//! `corpus_snapshots/` (regenerate with `INSTA_UPDATE=always cargo test -p
//! gwml-compiler --test corpus` and review every changed file).

use gwml_compiler::{CompileError, Options, PipelineError, Program};
use std::path::{Path, PathBuf};

fn corpus() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("the corpus folder")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "gw"))
        .collect();
    files.sort();
    files
}

/// The diagnostics of `text`: from checking, else from preparing each scene.
fn diagnose(name: &str, text: &str) -> Result<CompileError, String> {
    let program = match Program::parse(name, text) {
        Err(e) => return Ok(e),
        Ok(p) => p,
    };
    for scene in program.scene_names() {
        match program.pipeline(Some(scene), Options::default()) {
            Ok(_) => {}
            Err(PipelineError::Compile(e)) => return Ok(e),
            Err(other) => return Err(format!("scene `{scene}`: an error without a span: {other}")),
        }
    }
    Err(format!("it compiled (scenes {:?})", program.scene_names()))
}

/// What is wrong with the diagnostics of one file, if anything.
fn problems(err: &CompileError) -> Vec<String> {
    let mut out = Vec::new();
    if err.diagnostics.is_empty() {
        out.push("an error without diagnostics".into());
    }
    for d in &err.diagnostics {
        let len = err.sources.get(d.span.file).text.len();
        if d.message.is_empty() {
            out.push(format!("a diagnostic without a message: {d:?}"));
        }
        if d.help.as_deref().is_none_or(str::is_empty) {
            out.push(format!("no help line: `{}`", d.message));
        }
        if d.span.start > d.span.end || d.span.end > len {
            out.push(format!("span {:?} outside the file (length {len}): `{}`", d.span, d.message));
        }
    }
    out
}

/// On a test thread's 2 MiB stack, although the limits part of the corpus
/// nests expressions 3,000 deep.
#[test]
fn every_wrong_program_gets_spanned_diagnostics_with_help_and_never_panics() {
    let files = corpus();
    assert!(files.len() >= 200, "the corpus has {} files", files.len());
    let mut failures = Vec::new();
    for path in &files {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(path).unwrap();
        let name = format!("{stem}.gw");
        let outcome = std::panic::catch_unwind(|| diagnose(&name, &text));
        let err = match outcome {
            Err(_) => {
                failures.push(format!("{stem}: panicked"));
                continue;
            }
            Ok(Err(why)) => {
                failures.push(format!("{stem}: {why}"));
                continue;
            }
            Ok(Ok(err)) => err,
        };
        failures.extend(problems(&err).into_iter().map(|p| format!("{stem}: {p}")));
        let rendered = err.render(false);
        insta::with_settings!({ snapshot_path => "corpus_snapshots", prepend_module_to_snapshot => false, omit_expression => true }, {
            insta::assert_snapshot!(stem, rendered);
        });
    }
    assert!(failures.is_empty(), "{} of {} corpus files fail:\n{}", failures.len(), files.len(), failures.join("\n"));
}
