//! `gwml.Scene`: a compiled scene with a run kept between calls, so its
//! buffers are reused and what it computes from the data alone (the
//! prelude: relative binning's summary data, (d|d)) is recomputed only
//! when the data change.

use crate::data::{self, shape_of, value_to_py, Data, DataRef, Given};
use crate::errors::{bind_error, run_error};
use gwml_compiler::front::diagnostics::did_you_mean;
use gwml_compiler::ir::{Elem, Function, InputRole};
use gwml_runtime::batch::{Batch, Mode};
use gwml_runtime::{Error, Outputs, Run, Value};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString, PyTuple};
use self_cell::self_cell;
use std::sync::{Arc, Mutex};

type RunOf<'a> = Run<'a>;

self_cell!(
    /// A run bound to the scene it borrows, owned together.
    struct SceneRun {
        owner: Arc<gwml_runtime::Scene>,
        #[covariant]
        dependent: RunOf,
    }
);

/// What a run holds between calls.
struct State {
    run: SceneRun,
    /// Per input: the data bound now (`None`: the input's default).
    bound: Vec<Option<Arc<Data>>>,
    /// Per input: what [`Scene::bind`] set, used when a call gives none.
    held: Vec<Option<Arc<Data>>>,
}

/// A param's value as given: a number in the declared unit, or text with a unit.
enum ParamArg {
    Number(f64),
    Quantity(String),
}

/// A compiled scene of a model: run it, take its gradients, batch it.
///
/// Params not given take their defaults at every call; inputs not given
/// take what `bind` set, else their defaults. Calls from several Python
/// threads are safe (they take turns; `batch` runs items on all cores).
#[pyclass(frozen, module = "gwml")]
pub(crate) struct Scene {
    shared: Arc<Shared>,
}

/// A compiled scene and its run: what `gwml.Scene` and the functions the
/// JAX bridge registers with XLA (`xla.rs`) share.
pub(crate) struct Shared {
    pub(crate) scene: Arc<gwml_runtime::Scene>,
    state: Mutex<State>,
}

impl Shared {
    /// The run, taken in turn by callers on any thread. Only taken with the
    /// interpreter's lock released (or on a thread that never holds it), so
    /// a thread waiting here never blocks one that needs the interpreter.
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Runs the params `names` at every row of `values` (row-major, one
    /// value per name), with `fixed` params, inputs `given` and otherwise
    /// the held inputs. One row runs on the kept run (its buffers and
    /// prelude values stay); more rows are one batch over `threads`.
    pub(crate) fn run_rows(
        &self,
        names: &[&str],
        values: &[f64],
        fixed: &[(&str, f64)],
        given: &[(usize, DataRef<'_>)],
        mode: Mode,
        threads: Option<usize>,
    ) -> Result<Vec<Outputs>, Error> {
        if !names.is_empty() && names.len() == values.len() {
            let params: Vec<(String, ParamArg)> = names
                .iter()
                .zip(values)
                .chain(fixed.iter().map(|(n, v)| (n, v)))
                .map(|(n, v)| (n.to_string(), ParamArg::Number(*v)))
                .collect();
            return Ok(vec![self.lock().execute(&params, given, mode)?]);
        }
        let held: Vec<(usize, Arc<Data>)> = {
            let state = self.lock();
            state.held.iter().enumerate().filter_map(|(i, h)| h.clone().map(|h| (i, h))).collect()
        };
        let inputs = &self.scene.ir().inputs;
        let mut batch = Batch::new(names, values).mode(mode).threads(threads);
        for (name, x) in fixed {
            batch = batch.set(name, *x);
        }
        let held_not_given = held.iter().filter(|(i, _)| !given.iter().any(|g| g.0 == *i)).map(|(i, h)| (*i, h.view()));
        for (i, data) in given.iter().copied().chain(held_not_given) {
            let name = inputs[i].name.as_str();
            batch = match data {
                DataRef::Real(d) => batch.input_real(name, d),
                DataRef::Complex(d) => batch.input_complex(name, d),
            };
        }
        self.scene.batch(&batch)
    }
}

/// A param of a scene: `name`, `unit` (declared), `default` and `bounds`
/// (in that unit, or None).
#[pyclass(frozen, get_all, module = "gwml")]
pub(crate) struct ParamInfo {
    name: String,
    unit: String,
    default: Option<f64>,
    bounds: Option<(f64, f64)>,
}

/// An input of a scene: `name`, `unit`, `shape` (a tuple; `()` for a
/// scalar), `dtype` ("float64" or "complex128"), `has_default`, and `role`
/// ("data", "weight", "dropout_mask" or "noise").
#[pyclass(frozen, get_all, module = "gwml")]
pub(crate) struct InputInfo {
    name: String,
    unit: String,
    /// As NumPy gives it: `()` for a scalar.
    shape: Py<PyTuple>,
    dtype: &'static str,
    has_default: bool,
    role: &'static str,
}

/// An output of a scene: `name`, `unit` (base units), `shape`, `dtype`,
/// and `grads`, the params `value_and_grad` differentiates it by.
#[pyclass(frozen, get_all, module = "gwml")]
pub(crate) struct OutputInfo {
    name: String,
    unit: String,
    /// As NumPy gives it: `()` for a scalar.
    shape: Py<PyTuple>,
    dtype: &'static str,
    grads: Vec<String>,
}

#[pymethods]
impl ParamInfo {
    fn __repr__(&self) -> String {
        let default = self.default.map_or("None".into(), |d| format!("{d:?}"));
        let bounds = self.bounds.map_or("None".into(), |(a, b)| format!("({a:?}, {b:?})"));
        format!("ParamInfo(name='{}', unit='{}', default={default}, bounds={bounds})", self.name, self.unit)
    }
}

#[pymethods]
impl InputInfo {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "InputInfo(name='{}', unit='{}', shape={}, dtype='{}', has_default={}, role='{}')",
            self.name,
            self.unit,
            self.shape.bind(py),
            self.dtype,
            if self.has_default { "True" } else { "False" },
            self.role
        )
    }
}

#[pymethods]
impl OutputInfo {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "OutputInfo(name='{}', unit='{}', shape={}, dtype='{}', grads=[{}])",
            self.name,
            self.unit,
            self.shape.bind(py),
            self.dtype,
            self.grads.iter().map(|g| format!("'{g}'")).collect::<Vec<_>>().join(", ")
        )
    }
}

fn dtype(elem: Elem) -> &'static str {
    match elem {
        Elem::Complex => "complex128",
        _ => "float64",
    }
}

impl Scene {
    pub(crate) fn new(scene: gwml_runtime::Scene) -> Scene {
        let scene = Arc::new(scene);
        let n = scene.ir().inputs.len();
        let run = SceneRun::new(scene.clone(), |s| s.bind());
        let state = Mutex::new(State { run, bound: vec![None; n], held: vec![None; n] });
        Scene { shared: Arc::new(Shared { scene, state }) }
    }

    fn func(&self) -> &Function {
        self.shared.scene.ir()
    }

    /// Params from a dict of name → number or quantity text.
    fn param_args(&self, params: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, ParamArg)>> {
        let Some(params) = params else { return Ok(Vec::new()) };
        let mut out = Vec::with_capacity(params.len());
        for (k, v) in params.iter() {
            let name: String = k.extract().map_err(|_| bind_error(k.py(), "param names must be strings".into()))?;
            let arg =
                if let Ok(s) = v.cast::<PyString>() {
                    ParamArg::Quantity(s.to_string())
                } else {
                    ParamArg::Number(v.extract::<f64>().map_err(|_| {
                        bind_error(v.py(), format!("param `{name}` needs a number (or text with a unit such as \"30 Msun\")"))
                    })?)
                };
            out.push((name, arg));
        }
        Ok(out)
    }

    /// The index of the input a dict key names (a `RunError` with a
    /// suggestion when it names none).
    fn input_index(&self, key: &Bound<'_, PyAny>) -> PyResult<usize> {
        let py = key.py();
        let func = self.func();
        let name: String = key.extract().map_err(|_| bind_error(py, "input names must be strings".into()))?;
        func.inputs.iter().position(|p| p.name == name).ok_or_else(|| {
            let suggestion = did_you_mean(&name, func.inputs.iter().map(|p| p.name.as_str())).map(str::to_string);
            run_error(py, Error::UnknownName { kind: "input", name, suggestion })
        })
    }

    /// Inputs from a dict of name → data, by input index.
    pub(crate) fn input_args<'py>(&self, inputs: Option<&Bound<'py, PyDict>>) -> PyResult<Vec<(usize, Given<'py>)>> {
        let Some(inputs) = inputs else { return Ok(Vec::new()) };
        let func = self.func();
        let mut out = Vec::with_capacity(inputs.len());
        for (k, v) in inputs.iter() {
            let i = self.input_index(&k)?;
            out.push((i, data::given(func, &func.inputs[i], &v)?));
        }
        Ok(out)
    }

    /// Binds, sets and runs with the interpreter's lock released.
    fn call(
        &self,
        py: Python<'_>,
        params: Option<&Bound<'_, PyDict>>,
        inputs: Option<&Bound<'_, PyDict>>,
        mode: Mode,
    ) -> PyResult<Outputs> {
        let params = self.param_args(params)?;
        let given = self.input_args(inputs)?;
        let views: Vec<(usize, DataRef<'_>)> = given.iter().map(|(i, g)| (*i, g.view())).collect();
        let result = py.detach(|| self.shared.lock().execute(&params, &views, mode));
        result.map_err(|e| run_error(py, e))
    }

    /// One run's outputs as a dict.
    fn outputs_dict<'py>(&self, py: Python<'py>, out: &Outputs) -> PyResult<Bound<'py, PyDict>> {
        let func = self.func();
        let dict = PyDict::new(py);
        for ((name, value), o) in out.values.iter().zip(&func.outputs) {
            dict.set_item(name, value_to_py(py, value, &shape_of(func, func.ty(o.value).shape))?)?;
        }
        Ok(dict)
    }

    /// One run's gradients as `{output: {param or weight: value}}`.
    fn grads_dict<'py>(&self, py: Python<'py>, out: &Outputs) -> PyResult<Bound<'py, PyDict>> {
        let func = self.func();
        let dict = PyDict::new(py);
        let entry = |output: &str| -> PyResult<Bound<'py, PyDict>> {
            match dict.get_item(output)? {
                Some(d) => Ok(d.cast_into::<PyDict>()?),
                None => {
                    let d = PyDict::new(py);
                    dict.set_item(output, &d)?;
                    Ok(d)
                }
            }
        };
        for (o, p, g) in &out.grads {
            entry(o)?.set_item(p, *g)?;
        }
        for (o, i, g) in &out.input_grads {
            let info = func.inputs.iter().find(|x| &x.name == i).expect("gradients name scene inputs");
            entry(o)?.set_item(i, value_to_py(py, &Value::RealArray(g.clone()), &shape_of(func, info.ty.shape))?)?;
        }
        Ok(dict)
    }
}

impl State {
    /// Makes the bound data what this call asks for (rebinding only what
    /// changed), sets the params, and runs.
    fn execute(&mut self, params: &[(String, ParamArg)], given: &[(usize, DataRef<'_>)], mode: Mode) -> Result<Outputs, Error> {
        let State { run, bound, held } = self;
        run.with_dependent_mut(|scene, run| -> Result<Outputs, Error> {
            let inputs = &scene.ir().inputs;
            for i in 0..inputs.len() {
                let name = &inputs[i].name;
                if let Some((_, data)) = given.iter().find(|(k, _)| *k == i) {
                    if bound[i].as_deref().map(Data::view) != Some(*data) {
                        bind(run, name, *data)?;
                        bound[i] = Some(Arc::new(data.to_data()));
                    }
                } else if let Some(h) = &held[i] {
                    if !bound[i].as_ref().is_some_and(|b| Arc::ptr_eq(b, h)) {
                        bind(run, name, h.view())?;
                        bound[i] = Some(h.clone());
                    }
                } else if bound[i].is_some() {
                    run.reset_input(name)?;
                    bound[i] = None;
                }
            }
            run.reset_params();
            for (name, arg) in params {
                match arg {
                    ParamArg::Number(x) => run.param(name, *x)?,
                    ParamArg::Quantity(text) => run.param_quantity(name, text)?,
                };
            }
            match mode {
                Mode::Forward => run.forward(),
                Mode::ValueAndGrad => run.value_and_grad(),
            }
        })
    }
}

impl State {
    /// The median time in µs of `repeats` calls of the run alone (after one
    /// call through [`State::execute`] binds and sets everything): what
    /// the same call costs from Rust, for `benches/peers/python_api.py`.
    fn time_native(&mut self, params: &[(String, ParamArg)], mode: Mode, repeats: usize) -> Result<f64, Error> {
        self.execute(params, &[], mode)?;
        self.run.with_dependent_mut(|_, run| {
            let mut times = Vec::with_capacity(repeats);
            for _ in 0..repeats.max(1) {
                let start = std::time::Instant::now();
                std::hint::black_box(match mode {
                    Mode::Forward => run.forward(),
                    Mode::ValueAndGrad => run.value_and_grad(),
                }?);
                times.push(start.elapsed().as_secs_f64() * 1e6);
            }
            times.sort_by(f64::total_cmp);
            Ok(times[times.len() / 2])
        })
    }
}

fn bind(run: &mut Run<'_>, name: &str, data: DataRef<'_>) -> Result<(), Error> {
    match data {
        DataRef::Real(d) => run.input_real(name, d),
        DataRef::Complex(d) => run.input_complex(name, d),
    }
    .map(drop)
}

#[pymethods]
impl Scene {
    /// The scene's name.
    #[getter]
    fn name(&self) -> String {
        self.func().name.clone()
    }

    /// The params, in declaration order: `{name: ParamInfo}`.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for p in &self.func().params {
            let info = ParamInfo { name: p.name.clone(), unit: p.unit.clone(), default: p.default, bounds: p.bounds };
            dict.set_item(&p.name, Py::new(py, info)?)?;
        }
        Ok(dict)
    }

    /// The inputs a caller may bind, in declaration order: `{name: InputInfo}`.
    #[getter]
    fn inputs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let func = self.func();
        let dict = PyDict::new(py);
        for i in &func.inputs {
            let role = match i.role {
                InputRole::Data => "data",
                InputRole::Weight => "weight",
                InputRole::DropoutMask(_) => "dropout_mask",
                InputRole::Noise => "noise",
                InputRole::Cached => continue,
            };
            let info = InputInfo {
                name: i.name.clone(),
                unit: i.unit.clone(),
                shape: PyTuple::new(py, shape_of(func, i.ty.shape))?.unbind(),
                dtype: dtype(i.ty.elem),
                has_default: i.default.is_some(),
                role,
            };
            dict.set_item(&i.name, Py::new(py, info)?)?;
        }
        Ok(dict)
    }

    /// The outputs, in declaration order: `{name: OutputInfo}`.
    #[getter]
    fn outputs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let func = self.func();
        let dict = PyDict::new(py);
        for (k, o) in func.outputs.iter().enumerate() {
            let ty = func.ty(o.value);
            let grads = func.grads.iter().filter(|g| g.output == k).map(|g| func.params[g.param].name.clone()).collect();
            let info = OutputInfo {
                name: o.name.clone(),
                unit: o.unit.clone(),
                shape: PyTuple::new(py, shape_of(func, ty.shape))?.unbind(),
                dtype: dtype(ty.elem),
                grads,
            };
            dict.set_item(&o.name, Py::new(py, info)?)?;
        }
        Ok(dict)
    }

    /// Holds `inputs` (`{name: data}`) for every later call that does not
    /// give them; `None` as a value returns that input to its default.
    fn bind(&self, py: Python<'_>, inputs: &Bound<'_, PyDict>) -> PyResult<()> {
        let func = self.func();
        let mut set: Vec<(usize, Option<Arc<Data>>)> = Vec::new();
        for (k, v) in inputs.iter() {
            let i = self.input_index(&k)?;
            let data = if v.is_none() { None } else { Some(Arc::new(data::given(func, &func.inputs[i], &v)?.view().to_data())) };
            set.push((i, data));
        }
        // Bound now, so bad data (shape, non-finite values) fail here.
        py.detach(|| -> Result<(), Error> {
            let mut state = self.shared.lock();
            let State { run, bound, held } = &mut *state;
            run.with_dependent_mut(|scene, run| {
                for (i, d) in set {
                    let name = &scene.ir().inputs[i].name;
                    match &d {
                        Some(d) => bind(run, name, d.view())?,
                        None => run.reset_input(name).map(drop)?,
                    }
                    bound[i] = d.clone();
                    held[i] = d;
                }
                Ok(())
            })
        })
        .map_err(|e| run_error(py, e))
    }

    /// Runs the forward kernel: `{output: value}` (floats, complex numbers,
    /// float64 / complex128 arrays shaped like their grids).
    #[pyo3(signature = (params=None, inputs=None))]
    fn run<'py>(
        &self,
        py: Python<'py>,
        params: Option<&Bound<'py, PyDict>>,
        inputs: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let out = self.call(py, params, inputs, Mode::Forward)?;
        self.outputs_dict(py, &out)
    }

    /// Runs the fused forward+gradient kernel: `(outputs, grads)` with
    /// `grads[output][param]` per declared unit of the param (and
    /// `grads[output][weight]`, an array, for trainable weights).
    #[pyo3(signature = (params=None, inputs=None))]
    fn value_and_grad<'py>(
        &self,
        py: Python<'py>,
        params: Option<&Bound<'py, PyDict>>,
        inputs: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let out = self.call(py, params, inputs, Mode::ValueAndGrad)?;
        PyTuple::new(py, [self.outputs_dict(py, &out)?.into_any(), self.grads_dict(py, &out)?.into_any()])
    }

    /// Runs many parameter sets in one call, over all cores with the
    /// interpreter's lock released. `params` maps names to 1-D arrays (one
    /// value per item, all of one length) or to numbers (the same in every
    /// item). Returns `{output: array}` with the items along the first axis,
    /// and with `grad=True` `(outputs, grads)`, `grads[output][param]` an
    /// array over items. `threads=None` uses every core.
    #[pyo3(signature = (params, inputs=None, *, grad=false, threads=None))]
    fn batch<'py>(
        &self,
        py: Python<'py>,
        params: &Bound<'py, PyDict>,
        inputs: Option<&Bound<'py, PyDict>>,
        grad: bool,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        crate::batch::run(self, py, params, inputs, grad, threads)
    }

    /// For benchmarks: the median time in µs of `repeats` calls made from
    /// Rust with these params and the held inputs (`grad`: the fused
    /// forward+gradient kernel), to set against the same call from Python.
    #[pyo3(signature = (params=None, *, grad=true, repeats=1000))]
    fn _time_native(&self, py: Python<'_>, params: Option<&Bound<'_, PyDict>>, grad: bool, repeats: usize) -> PyResult<f64> {
        let params = self.param_args(params)?;
        let mode = if grad { Mode::ValueAndGrad } else { Mode::Forward };
        py.detach(|| self.shared.lock().time_native(&params, mode, repeats)).map_err(|e| run_error(py, e))
    }

    fn __repr__(&self) -> String {
        format!("<gwml.Scene '{}'>", self.func().name)
    }
}

impl Scene {
    pub(crate) fn shared(&self) -> &Arc<Shared> {
        &self.shared
    }
}
