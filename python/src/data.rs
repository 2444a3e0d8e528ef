//! NumPy in and out: data given for a scene input is read in place when
//! its dtype and layout allow (a contiguous float64 or complex128 array),
//! and results come back as float64 / complex128 arrays shaped like the
//! scene's grids.

use crate::errors::bind_error;
use gwml_compiler::ir::{Elem, Function, InputInfo, Shape};
use gwml_runtime::Value;
use num_complex::Complex64 as C64;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyComplex, PyFloat, PyInt};

/// Data owned by the package: a copy of what was bound to an input.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Data {
    Real(Vec<f64>),
    Complex(Vec<C64>),
}

/// Data borrowed from the caller (or from [`Data`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum DataRef<'a> {
    Real(&'a [f64]),
    Complex(&'a [C64]),
}

impl Data {
    pub(crate) fn view(&self) -> DataRef<'_> {
        match self {
            Data::Real(v) => DataRef::Real(v),
            Data::Complex(v) => DataRef::Complex(v),
        }
    }
}

impl DataRef<'_> {
    pub(crate) fn to_data(self) -> Data {
        match self {
            DataRef::Real(v) => Data::Real(v.to_vec()),
            DataRef::Complex(v) => Data::Complex(v.to_vec()),
        }
    }
}

/// What the caller gave for one input, kept borrowed while it is used.
pub(crate) enum Given<'py> {
    Real(PyReadonlyArrayDyn<'py, f64>),
    Complex(PyReadonlyArrayDyn<'py, C64>),
    Owned(Data),
}

impl Given<'_> {
    /// The values in C (row-major) order.
    pub(crate) fn view(&self) -> DataRef<'_> {
        match self {
            Given::Real(a) => DataRef::Real(a.as_slice().expect("checked contiguous in `given`")),
            Given::Complex(a) => DataRef::Complex(a.as_slice().expect("checked contiguous in `given`")),
            Given::Owned(d) => d.view(),
        }
    }
}

/// The scene's shape of input `info`: `()` for a scalar, the grid's dims otherwise.
pub(crate) fn shape_of(func: &Function, shape: Shape) -> Vec<usize> {
    match shape {
        Shape::Scalar => Vec::new(),
        Shape::Grid(g) => func.grid(g).dims.clone(),
    }
}

/// Reads `obj` as data for input `info`: a float64 (or, for a complex
/// input, complex128) NumPy array of the input's shape or flat with as
/// many values, a Python number for a scalar input, or a sequence NumPy
/// turns into such an array. Anything else is a `RunError` naming the input.
pub(crate) fn given<'py>(func: &Function, info: &InputInfo, obj: &Bound<'py, PyAny>) -> PyResult<Given<'py>> {
    let py = obj.py();
    let name = &info.name;
    let complex = info.ty.elem == Elem::Complex;
    if obj.is_instance_of::<PyFloat>() || obj.is_instance_of::<PyInt>() {
        return Ok(Given::Owned(Data::Real(vec![obj.extract::<f64>()?])));
    }
    if obj.is_instance_of::<PyComplex>() {
        if !complex {
            return Err(bind_error(py, format!("input `{name}` is real, but a complex number was given")));
        }
        return Ok(Given::Owned(Data::Complex(vec![obj.extract::<C64>()?])));
    }
    let array = match obj.cast::<PyUntypedArray>() {
        Ok(a) => a.clone(),
        Err(_) => {
            let converted = py
                .import("numpy")?
                .call_method1("asarray", (obj,))
                .map_err(|_| bind_error(py, format!("input `{name}`: expected a NumPy array or a number, got a {}", type_name(obj))))?;
            converted.cast_into::<PyUntypedArray>().map_err(|_| bind_error(py, format!("input `{name}`: not an array")))?
        }
    };
    let want = shape_of(func, info.ty.shape);
    let got = array.shape().to_vec();
    let size: usize = got.iter().product();
    let wanted: usize = want.iter().product();
    if got.len() > 1 && got != want {
        return Err(bind_error(py, format!("input `{name}` has shape {}, but the scene's is {}", tuple(&got), tuple(&want))));
    }
    if size != wanted {
        let what = if want.is_empty() { "a scalar: 1 value".to_string() } else { format!("{wanted} values, shape {}", tuple(&want)) };
        return Err(bind_error(py, format!("input `{name}` needs {what}, but an array of shape {} was given", tuple(&got))));
    }
    let dtype = array.dtype();
    let dtype_name = dtype.str()?.to_string();
    if let Ok(a) = array.cast::<PyArrayDyn<f64>>() {
        let ro = a.readonly();
        if ro.as_slice().is_ok() {
            return Ok(Given::Real(ro));
        }
        return Ok(Given::Owned(Data::Real(ro.as_array().iter().copied().collect())));
    }
    if let Ok(a) = array.cast::<PyArrayDyn<C64>>() {
        if !complex {
            return Err(bind_error(py, format!("input `{name}` is real, but a complex128 array was given")));
        }
        let ro = a.readonly();
        if ro.as_slice().is_ok() {
            return Ok(Given::Complex(ro));
        }
        return Ok(Given::Owned(Data::Complex(ro.as_array().iter().copied().collect())));
    }
    let want_dtype = if complex { "complex128 (or float64)" } else { "float64" };
    Err(bind_error(
        py,
        format!(
            "input `{name}` needs {want_dtype} data, but the array's dtype is {dtype_name}; convert it with `.astype(numpy.{})`",
            if complex { "complex128" } else { "float64" }
        ),
    ))
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "value".into())
}

/// `(a, b)` as Python prints a shape.
fn tuple(dims: &[usize]) -> String {
    match dims {
        [] => "()".into(),
        [n] => format!("({n},)"),
        _ => format!("({})", dims.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

/// A result as Python sees it: a float, a complex, or an array shaped `dims`.
pub(crate) fn value_to_py<'py>(py: Python<'py>, value: &Value, dims: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Real(x) => PyFloat::new(py, *x).into_any(),
        Value::Complex(z) => PyComplex::from_doubles(py, z.re, z.im).into_any(),
        Value::RealArray(a) => shaped(numpy::PyArray1::from_slice(py, a).into_any(), dims)?,
        Value::ComplexArray(a) => shaped(numpy::PyArray1::from_slice(py, a).into_any(), dims)?,
    })
}

/// `array` reshaped to `dims` when they have more than one axis.
pub(crate) fn shaped<'py>(array: Bound<'py, PyAny>, dims: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    if dims.len() > 1 {
        array.call_method1("reshape", (dims.to_vec(),))
    } else {
        Ok(array)
    }
}
