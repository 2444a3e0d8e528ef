//! The JAX bridge's XLA custom call: a scene output and its gradient as an
//! XLA FFI handler (the C ABI of `xla/ffi/api/c_api.h`, API version 0.3,
//! which jaxlib ships under `jax.ffi.include_dir()`), so a jitted JAX
//! program calls gwml's kernels directly, without a round trip through
//! Python (`jax.pure_callback` costs ~90 µs a call on this machine).
//!
//! `gwml.jax` registers [`handler`] once as the CPU target
//! `gwml_scene_call` and calls it with one f64 (or f32) argument of shape
//! `(..., n_params)`, one or two results (the output of shape `(...)`,
//! then, for value and gradient, the gradient of the argument's shape) and
//! one attribute, `function`: the id of an [`XlaFunction`] in [`REGISTRY`].

use crate::scene::{Scene, Shared};
use gwml_runtime::batch::Mode;
use gwml_runtime::Outputs;
use pyo3::prelude::*;
use std::collections::HashMap;
use std::ffi::{c_char, c_void, CString};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// A scene output as a function of some of its params, as the handler runs it.
struct Function {
    shared: Arc<Shared>,
    output: String,
    params: Vec<String>,
}

/// Functions the handler can run, by id; an entry lives as long as its
/// [`XlaFunction`].
static REGISTRY: Mutex<Option<HashMap<u64, Arc<Function>>>> = Mutex::new(None);
static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// A scene output registered for the XLA handler (`gwml.jax` holds one
/// per bridged function; dropping it unregisters the function).
#[pyclass(frozen, module = "gwml")]
pub(crate) struct XlaFunction {
    /// The id XLA passes to the handler as attribute `function`.
    #[pyo3(get)]
    id: u64,
}

#[pymethods]
impl XlaFunction {
    /// Registers `output` of `scene` as a function of `params` (already
    /// checked by the Python side: a real scalar with those gradients).
    #[new]
    fn new(scene: &Scene, output: String, params: Vec<String>) -> XlaFunction {
        let id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
        let f = Arc::new(Function { shared: scene.shared().clone(), output, params });
        REGISTRY.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert_with(HashMap::new).insert(id, f);
        XlaFunction { id }
    }
}

impl Drop for XlaFunction {
    fn drop(&mut self) {
        if let Some(map) = REGISTRY.lock().unwrap_or_else(|e| e.into_inner()).as_mut() {
            map.remove(&self.id);
        }
    }
}

/// The handler as a capsule for `jax.ffi.register_ffi_target`.
#[pyfunction]
pub(crate) fn xla_handler(py: Python<'_>) -> PyResult<Py<PyAny>> {
    let f: unsafe extern "C" fn(*mut CallFrame) -> *mut c_void = handler;
    // SAFETY: a capsule holding a function pointer, with no name and no
    // destructor (the function lives as long as the module).
    unsafe {
        let capsule = pyo3::ffi::PyCapsule_New(f as *mut c_void, std::ptr::null(), None);
        Bound::from_owned_ptr_or_err(py, capsule).map(Bound::unbind)
    }
}

// The C ABI (xla/ffi/api/c_api.h); enums are C ints.

#[repr(C)]
struct ExtensionBase {
    struct_size: usize,
    kind: i32,
    next: *mut ExtensionBase,
}

#[repr(C)]
struct ApiVersion {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    major: i32,
    minor: i32,
}

#[repr(C)]
struct Metadata {
    struct_size: usize,
    api_version: ApiVersion,
    traits: u32,
    state_type_id: i64,
}

#[repr(C)]
struct MetadataExtension {
    base: ExtensionBase,
    metadata: *mut Metadata,
}

#[repr(C)]
struct Buffer {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    dtype: i32,
    data: *mut c_void,
    rank: i64,
    dims: *const i64,
}

#[repr(C)]
struct List {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    size: i64,
    types: *const i32,
    items: *const *mut c_void,
}

#[repr(C)]
struct Attrs {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    size: i64,
    types: *const i32,
    names: *const *const ByteSpan,
    attrs: *const *mut c_void,
}

#[repr(C)]
struct ByteSpan {
    ptr: *const c_char,
    len: usize,
}

#[repr(C)]
struct Scalar {
    dtype: i32,
    value: *const c_void,
}

#[repr(C)]
pub(crate) struct CallFrame {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    api: *const Api,
    ctx: *mut c_void,
    stage: i32,
    args: List,
    rets: List,
    attrs: Attrs,
    future: *mut c_void,
}

#[repr(C)]
struct ErrorCreateArgs {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    message: *const c_char,
    errc: i32,
}

#[repr(C)]
struct Api {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    api_version: ApiVersion,
    internal_api: *const c_void,
    error_create: Option<unsafe extern "C" fn(*mut ErrorCreateArgs) -> *mut c_void>,
}

const EXTENSION_METADATA: i32 = 1;
const STAGE_EXECUTE: i32 = 3;
const ATTR_SCALAR: i32 = 3;
const DTYPE_S64: i32 = 5;
const DTYPE_U64: i32 = 9;
const DTYPE_F32: i32 = 11;
const DTYPE_F64: i32 = 12;
const ERROR_INVALID_ARGUMENT: i32 = 3;

/// The XLA FFI handler: answers XLA's metadata query with the API version
/// it was written against, and at the execute stage runs the function
/// named by attribute `function` on every row of its argument.
///
/// # Safety
/// Called by XLA with a valid call frame, laid out as in c_api.h 0.3.
pub(crate) unsafe extern "C" fn handler(frame: *mut CallFrame) -> *mut c_void {
    let frame = &mut *frame;
    let ext = frame.extension_start;
    if !ext.is_null() && (*ext).kind == EXTENSION_METADATA {
        let metadata = &mut *(*(ext as *mut MetadataExtension)).metadata;
        metadata.api_version =
            ApiVersion { struct_size: std::mem::size_of::<ApiVersion>(), extension_start: std::ptr::null_mut(), major: 0, minor: 3 };
        metadata.traits = 0;
        return std::ptr::null_mut();
    }
    if frame.stage != STAGE_EXECUTE {
        return std::ptr::null_mut();
    }
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(frame)));
    let message = match outcome {
        Ok(Ok(())) => return std::ptr::null_mut(),
        Ok(Err(message)) => message,
        Err(_) => "gwml: internal error (a panic) in the XLA custom call".to_string(),
    };
    error(frame.api, &message)
}

/// An XLA error carrying `message` (XLA copies the text).
unsafe fn error(api: *const Api, message: &str) -> *mut c_void {
    let Some(create) = api.as_ref().and_then(|a| a.error_create) else { return std::ptr::null_mut() };
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    let mut args = ErrorCreateArgs {
        struct_size: std::mem::size_of::<ErrorCreateArgs>(),
        extension_start: std::ptr::null_mut(),
        message: text.as_ptr(),
        errc: ERROR_INVALID_ARGUMENT,
    };
    create(&mut args)
}

/// The id in attribute `function`.
unsafe fn function_id(attrs: &Attrs) -> Option<u64> {
    for k in 0..attrs.size as usize {
        let name = &**attrs.names.add(k);
        let name = std::slice::from_raw_parts(name.ptr as *const u8, name.len);
        if name != b"function" || *attrs.types.add(k) != ATTR_SCALAR {
            continue;
        }
        let scalar = &*(*attrs.attrs.add(k) as *const Scalar);
        return match scalar.dtype {
            DTYPE_S64 => Some(*(scalar.value as *const i64) as u64),
            DTYPE_U64 => Some(*(scalar.value as *const u64)),
            _ => None,
        };
    }
    None
}

/// The buffer `list[k]`, its dtype checked to be f32 or f64.
unsafe fn buffer(list: &List, k: usize) -> Result<&Buffer, String> {
    if k >= list.size as usize {
        return Err(format!("gwml: the custom call has {} buffers, {} needed", list.size, k + 1));
    }
    let b = &*(*list.items.add(k) as *const Buffer);
    if b.dtype != DTYPE_F64 && b.dtype != DTYPE_F32 {
        return Err(format!("gwml: buffers must be float32 or float64 (XLA dtype {} given)", b.dtype));
    }
    Ok(b)
}

unsafe fn len(b: &Buffer) -> usize {
    (0..b.rank as usize).map(|k| *b.dims.add(k) as usize).product()
}

unsafe fn read(b: &Buffer) -> Vec<f64> {
    let n = len(b);
    if b.dtype == DTYPE_F64 {
        std::slice::from_raw_parts(b.data as *const f64, n).to_vec()
    } else {
        std::slice::from_raw_parts(b.data as *const f32, n).iter().map(|x| *x as f64).collect()
    }
}

unsafe fn write(b: &Buffer, values: &[f64]) -> Result<(), String> {
    if len(b) != values.len() {
        return Err(format!("gwml: a result buffer holds {} values, {} computed", len(b), values.len()));
    }
    if b.dtype == DTYPE_F64 {
        std::slice::from_raw_parts_mut(b.data as *mut f64, values.len()).copy_from_slice(values);
    } else {
        std::slice::from_raw_parts_mut(b.data as *mut f32, values.len()).iter_mut().zip(values).for_each(|(o, x)| *o = *x as f32);
    }
    Ok(())
}

unsafe fn execute(frame: &CallFrame) -> Result<(), String> {
    let id = function_id(&frame.attrs).ok_or("gwml: the custom call has no integer attribute `function`")?;
    let f = REGISTRY
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .as_ref()
        .and_then(|m| m.get(&id).cloned())
        .ok_or_else(|| format!("gwml: function {id} is no longer registered (its gwml.jax function was released)"))?;
    let x = read(buffer(&frame.args, 0)?);
    let n = f.params.len();
    if n == 0 || !x.len().is_multiple_of(n) {
        return Err(format!("gwml: the argument's last axis must hold the {n} params {:?}", f.params));
    }
    let grad = frame.rets.size >= 2;
    let mode = if grad { Mode::ValueAndGrad } else { Mode::Forward };
    let names: Vec<&str> = f.params.iter().map(String::as_str).collect();
    let outs = f.shared.run_rows(&names, &x, &[], &[], mode, None).map_err(|e| e.render(false))?;
    let values: Vec<f64> = outs.iter().map(|o| o.scalar(&f.output)).collect::<Result<_, _>>().map_err(|e| e.render(false))?;
    write(buffer(&frame.rets, 0)?, &values)?;
    if grad {
        let grads = gradients(&outs, &f.output, &names).map_err(|e| e.render(false))?;
        write(buffer(&frame.rets, 1)?, &grads)?;
    }
    Ok(())
}

/// Row-major gradients of `output` with respect to `names`, one row per run.
fn gradients(outs: &[Outputs], output: &str, names: &[&str]) -> Result<Vec<f64>, gwml_runtime::Error> {
    let mut g = Vec::with_capacity(outs.len() * names.len());
    for o in outs {
        for p in names {
            g.push(o.grad(output, p)?);
        }
    }
    Ok(g)
}
