//! `Scene.batch`: many parameter sets in one call, spread over the cores by
//! the runtime's batch runner with the interpreter's lock released; results
//! stacked along a first axis of items.

use crate::data::{shape_of, shaped, DataRef};
use crate::errors::{bind_error, run_error};
use crate::scene::Scene;
use gwml_runtime::batch::Mode;
use gwml_runtime::{Outputs, Value};
use num_complex::Complex64 as C64;
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

pub(crate) fn run<'py>(
    scene: &Scene,
    py: Python<'py>,
    params: &Bound<'py, PyDict>,
    inputs: Option<&Bound<'py, PyDict>>,
    grad: bool,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    // Varied params (arrays) and fixed ones (numbers).
    let mut varied: Vec<(String, PyReadonlyArrayDyn<'py, f64>)> = Vec::new();
    let mut fixed: Vec<(String, f64)> = Vec::new();
    for (k, v) in params.iter() {
        let name: String = k.extract().map_err(|_| bind_error(py, "param names must be strings".into()))?;
        if let Ok(x) = v.extract::<f64>() {
            fixed.push((name, x));
            continue;
        }
        let array = py
            .import("numpy")?
            .call_method1("asarray", (&v, "float64"))
            .map_err(|_| bind_error(py, format!("batch param `{name}`: expected a 1-D array of numbers (or one number for every item)")))?;
        let array = array.cast_into::<PyArrayDyn<f64>>().map_err(|_| bind_error(py, format!("batch param `{name}`: not an array")))?;
        if array.ndim() != 1 {
            return Err(bind_error(
                py,
                format!("batch param `{name}` must be 1-D (one value per item), but has shape {:?}", array.shape()),
            ));
        }
        varied.push((name, array.readonly()));
    }
    let n = varied.first().map_or(0, |(_, a)| a.len());
    if let Some((name, a)) = varied.iter().find(|(_, a)| a.len() != n) {
        return Err(bind_error(py, format!("batch param `{name}` has {} values, but `{}` has {n}", a.len(), varied[0].0)));
    }
    let k = varied.len();
    let mut values = vec![0.0; n * k];
    for (j, (_, a)) in varied.iter().enumerate() {
        for (i, x) in a.as_array().iter().enumerate() {
            values[i * k + j] = *x;
        }
    }
    let names: Vec<&str> = varied.iter().map(|(n, _)| n.as_str()).collect();
    let fixed: Vec<(&str, f64)> = fixed.iter().map(|(n, x)| (n.as_str(), *x)).collect();
    let given = scene.input_args(inputs)?;
    let views: Vec<(usize, DataRef<'_>)> = given.iter().map(|(i, g)| (*i, g.view())).collect();
    let mode = if grad { Mode::ValueAndGrad } else { Mode::Forward };
    let shared = scene.shared();
    let outs = py.detach(|| shared.run_rows(&names, &values, &fixed, &views, mode, threads)).map_err(|e| run_error(py, e))?;
    let outputs = stack_outputs(py, scene, &outs, n)?;
    if !grad {
        return Ok(outputs.into_any());
    }
    let grads = stack_grads(py, &outs)?;
    Ok(PyTuple::new(py, [outputs.into_any(), grads.into_any()])?.into_any())
}

/// `{output: array}` with items along the first axis.
fn stack_outputs<'py>(py: Python<'py>, scene: &Scene, outs: &[Outputs], n: usize) -> PyResult<Bound<'py, PyDict>> {
    let func = scene.shared().scene.ir();
    let dict = PyDict::new(py);
    for (k, o) in func.outputs.iter().enumerate() {
        let mut dims = vec![n];
        dims.extend(shape_of(func, func.ty(o.value).shape));
        let mut real: Vec<f64> = Vec::new();
        let mut complex: Vec<C64> = Vec::new();
        for out in outs {
            match &out.values[k].1 {
                Value::Real(x) => real.push(*x),
                Value::RealArray(a) => real.extend_from_slice(a),
                Value::Complex(z) => complex.push(*z),
                Value::ComplexArray(a) => complex.extend_from_slice(a),
            }
        }
        let array = if complex.is_empty() { PyArray1::from_vec(py, real).into_any() } else { PyArray1::from_vec(py, complex).into_any() };
        dict.set_item(&o.name, shaped(array, &dims)?)?;
    }
    Ok(dict)
}

/// `{output: {param: array over items}}`.
fn stack_grads<'py>(py: Python<'py>, outs: &[Outputs]) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    let Some(first) = outs.first() else { return Ok(dict) };
    for (k, (o, p, _)) in first.grads.iter().enumerate() {
        let column: Vec<f64> = outs.iter().map(|out| out.grads[k].2).collect();
        let inner = match dict.get_item(o)? {
            Some(d) => d.cast_into::<PyDict>()?,
            None => {
                let d = PyDict::new(py);
                dict.set_item(o, &d)?;
                d
            }
        };
        inner.set_item(p, PyArray1::from_vec(py, column))?;
    }
    Ok(dict)
}
