//! The native module of the `gwml` Python package (`gwml._gwml`): models
//! compiled from `.gw` source, scenes run with NumPy data in and out, and
//! the package's exceptions. The pure-Python part (`python/gwml/`) adds
//! `gwml.compile` and the JAX and PyTorch bridges.

mod batch;
mod data;
mod errors;
mod scan;
mod scene;
mod xla;

use errors::{compile_error, CompileError, GwmlError, RunError};
use gwml_compiler::ir::{MathMode, Multiband, Precision, RelativeBinning};
use gwml_compiler::Options;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use scene::{InputInfo, OutputInfo, ParamInfo, Scene};
use std::str::FromStr;

/// A checked `.gw` program and the options its scenes compile with.
#[pyclass(frozen, module = "gwml")]
struct Model {
    model: gwml_runtime::Model,
    options: Options,
}

/// Parses setting `what` from `text` with the compiler's own parser.
fn setting<T: FromStr>(py: Python<'_>, what: &str, text: Option<String>) -> PyResult<Option<T>>
where
    T::Err: std::fmt::Display,
{
    text.map(|t| T::from_str(&t).map_err(|e| compile_error(py, gwml_runtime::Error::Scene(format!("{what}: {e}"))))).transpose()
}

#[pymethods]
impl Model {
    /// Checks a `.gw` program: the file at `source` when `path`, else the
    /// text `source` (`name` is the file name its diagnostics show). The
    /// options override every scene's settings, as the command line's do.
    #[new]
    #[pyo3(signature = (source, *, path=false, name=None, precision=None, math=None, multiband=None, relative_binning=None, knobs=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        source: &str,
        path: bool,
        name: Option<String>,
        precision: Option<String>,
        math: Option<String>,
        multiband: Option<String>,
        relative_binning: Option<String>,
        knobs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Model> {
        let model = if path {
            gwml_runtime::Model::from_file(source)
        } else {
            gwml_runtime::Model::from_source(name.as_deref().unwrap_or("<string>"), source)
        }
        .map_err(|e| compile_error(py, e))?;
        let mut knob_list = Vec::new();
        for (k, v) in knobs.into_iter().flat_map(|d| d.iter()) {
            let name: String = k.extract()?;
            let value = match v.cast::<PyString>() {
                Ok(s) => s.to_string(),
                Err(_) => v.str()?.to_string(),
            };
            knob_list.push((name, value));
        }
        let options = Options {
            precision: setting::<Precision>(py, "precision", precision)?,
            math: setting::<MathMode>(py, "math", math)?,
            multiband: setting::<Multiband>(py, "multiband", multiband)?,
            relative_binning: setting::<RelativeBinning>(py, "relative_binning", relative_binning)?,
            knobs: knob_list,
            ..Options::default()
        };
        Ok(Model { model, options })
    }

    /// The names of the program's scenes, in source order.
    #[getter]
    fn scenes(&self) -> Vec<String> {
        self.model.program.scene_names().into_iter().map(str::to_string).collect()
    }

    /// JIT-compiles scene `name` (or the only scene) with the model's options.
    #[pyo3(signature = (name=None))]
    fn scene(&self, py: Python<'_>, name: Option<&str>) -> PyResult<Scene> {
        let compiled = py.detach(|| self.model.scene_with(name, self.options.clone())).map_err(|e| compile_error(py, e))?;
        Ok(Scene::new(compiled))
    }

    fn __repr__(&self) -> String {
        format!("<gwml.Model scenes=[{}]>", self.scenes().iter().map(|s| format!("'{s}'")).collect::<Vec<_>>().join(", "))
    }
}

#[pymodule]
fn _gwml(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<Model>()?;
    m.add_class::<Scene>()?;
    m.add_class::<ParamInfo>()?;
    m.add_class::<InputInfo>()?;
    m.add_class::<OutputInfo>()?;
    m.add_class::<xla::XlaFunction>()?;
    m.add_function(wrap_pyfunction!(xla::xla_handler, m)?)?;
    m.add_function(wrap_pyfunction!(scan::scan, m)?)?;
    m.add("GwmlError", py.get_type::<GwmlError>())?;
    m.add("CompileError", py.get_type::<CompileError>())?;
    m.add("RunError", py.get_type::<RunError>())?;
    Ok(())
}
