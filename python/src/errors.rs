//! The package's exceptions and how runtime errors become them: a
//! `CompileError` for anything before a scene runs, a `RunError` for
//! binding and running; `str()` of either is what the command line prints.

use gwml_compiler::CompileError as Diagnostics;
use gwml_runtime::Error;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::{create_exception, PyErr};

create_exception!(gwml, GwmlError, PyException, "Base class of the errors gwml raises.");
create_exception!(
    gwml,
    CompileError,
    GwmlError,
    "The source, a setting or a scene name is wrong, or code generation failed. `str()` is the diagnostic \
     `gwml compile` prints (with source spans); `.line`, `.column` (1-based) and `.path` locate the first \
     error when it has a place in a file, and are None otherwise; `.messages` lists every error's one-line summary."
);
create_exception!(
    gwml,
    RunError,
    GwmlError,
    "Binding params or data, or running the scene, failed (unknown names, values outside bounds, data of the \
     wrong dtype or shape, non-finite values or results). `.index` is the failing item of a batch, else None."
);

/// `e`, raised before the scene runs.
pub(crate) fn compile_error(py: Python<'_>, e: Error) -> PyErr {
    let err = CompileError::new_err(e.render(false));
    let (line, column, path, messages) = match &e {
        Error::Compile(c) => {
            let place = first_place(c);
            let messages: Vec<String> = c.diagnostics.iter().map(|d| d.message.clone()).collect();
            (place.as_ref().map(|p| p.0), place.as_ref().map(|p| p.1), place.map(|p| p.2), messages)
        }
        other => (None, None, None, vec![other.to_string()]),
    };
    let value = err.value(py);
    // Setting attributes on a fresh exception object cannot fail in practice;
    // if it did, the exception still carries its message.
    let _ = value.setattr("line", line);
    let _ = value.setattr("column", column);
    let _ = value.setattr("path", path);
    let _ = value.setattr("messages", messages);
    err
}

/// `e`, raised while binding or running.
pub(crate) fn run_error(py: Python<'_>, e: Error) -> PyErr {
    let index = match &e {
        Error::Item { index, .. } => Some(*index),
        _ => None,
    };
    let err = RunError::new_err(e.render(false));
    let _ = err.value(py).setattr("index", index);
    err
}

/// A run error with `message` (for bad arguments the runtime never sees).
pub(crate) fn bind_error(py: Python<'_>, message: String) -> PyErr {
    run_error(py, Error::Bind(message))
}

/// Line and column (1-based, in characters) and file name of the first
/// diagnostic's span.
fn first_place(c: &Diagnostics) -> Option<(usize, usize, String)> {
    let d = c.diagnostics.first()?;
    let file = c.sources.files().find(|(id, _)| *id == d.span.file)?.1;
    let before = file.text.get(..d.span.start)?;
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    Some((line, column, file.name.clone()))
}
