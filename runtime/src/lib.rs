//! gwml runtime: compile a model, bind parameters and data by name, run
//! the JIT kernels, and read outputs and gradients by name.
//!
//! ```no_run
//! let model = gwml_runtime::Model::from_file("examples/chirp_fit.gw")?;
//! let scene = model.scene(Some("chirp_fit"))?;
//! let mut run = scene.bind();
//! run.param("mc", 30.0)?;
//! let out = run.value_and_grad()?;
//! println!("{} {}", out.scalar("loss")?, out.grad("loss", "mc")?);
//! # Ok::<(), gwml_runtime::Error>(())
//! ```

pub mod batch;
pub mod checkpoint;
pub mod dataset;
pub mod fit;
pub mod noise;
pub mod npy;
pub mod optim;
pub mod spectrum;
pub mod train;

use gwml_compiler::codegen::{self, BufferKind, Kernel};
use gwml_compiler::front::diagnostics::did_you_mean;
use gwml_compiler::ir::{Elem, Function, Precision, Shape};
use gwml_compiler::{CompileError, Options, PipelineError, Program, ScenePipeline};
use num_complex::Complex64 as C64;
use std::fmt;
use std::path::Path;
use std::sync::OnceLock;

/// Anything that can go wrong between source text and results.
#[derive(Debug)]
pub enum Error {
    /// The source has errors (render them with [`CompileError::render`]).
    Compile(CompileError),
    /// A scene name that does not exist, or none chosen among several.
    Scene(String),
    /// Code generation failed.
    Codegen(codegen::CodegenError),
    /// A compiler bug caught by the IR verifier (see [`PipelineError::Internal`]).
    Internal(String),
    /// Reading a file failed.
    Io(String),
    /// A name given to `param`/`input`/`scalar`/`grad` that the scene lacks.
    UnknownName {
        /// "param", "input", "output" or "gradient".
        kind: &'static str,
        /// The name given.
        name: String,
        /// The closest existing name.
        suggestion: Option<String>,
    },
    /// Bad data or parameter values.
    Bind(String),
    /// An item of a [`batch`] failed (the lowest such index).
    Item {
        /// The item's index (its row of values).
        index: usize,
        /// What went wrong with it.
        error: Box<Error>,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Compile(e) => write!(f, "{}", e.render(false)),
            Error::Scene(s) | Error::Io(s) | Error::Bind(s) | Error::Internal(s) => write!(f, "{s}"),
            Error::Codegen(e) => write!(f, "{e}"),
            Error::UnknownName { kind, name, suggestion } => {
                write!(f, "the scene has no {kind} `{name}`")?;
                if let Some(s) = suggestion {
                    write!(f, "; did you mean `{s}`?")?;
                }
                Ok(())
            }
            Error::Item { index, error } => write!(f, "batch item {index}: {error}"),
        }
    }
}

impl Error {
    /// The error as a command line prints it: a compile error with its
    /// source spans (in colour when `color`), anything else after `error: `.
    pub fn render(&self, color: bool) -> String {
        match self {
            Error::Compile(c) => c.render(color),
            other => format!("error: {other}"),
        }
    }
}

impl std::error::Error for Error {}

impl From<CompileError> for Error {
    fn from(e: CompileError) -> Self {
        Error::Compile(e)
    }
}

impl From<PipelineError> for Error {
    fn from(e: PipelineError) -> Self {
        match e {
            PipelineError::Scene(s) => Error::Scene(s),
            PipelineError::Compile(c) => Error::Compile(c),
            internal @ PipelineError::Internal { .. } => Error::Internal(internal.to_string()),
        }
    }
}

/// A checked program, ready to compile its scenes.
#[derive(Clone, Debug)]
pub struct Model {
    /// The checked program.
    pub program: Program,
}

impl Model {
    /// Compiles source text (`name` is used in diagnostics).
    pub fn from_source(name: &str, text: &str) -> Result<Model, Error> {
        Ok(Model { program: Program::parse(name, text)? })
    }

    /// Reads and compiles a `.gw` file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Model, Error> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io(format!("cannot read {}: {e}", path.display())))?;
        Model::from_source(&path.display().to_string(), &text)
    }

    /// JIT-compiles scene `name` (or the only scene) with default options.
    pub fn scene(&self, name: Option<&str>) -> Result<Scene, Error> {
        self.scene_with(name, Options::default())
    }

    /// JIT-compiles scene `name` with `opts`.
    pub fn scene_with(&self, name: Option<&str>, opts: Options) -> Result<Scene, Error> {
        let pipeline = self.program.pipeline(name, opts)?;
        Scene::new(pipeline)
    }
}

/// A compiled scene: the forward kernel (built now) and the forward+gradient
/// kernel (built the first time a gradient is asked for).
pub struct Scene {
    /// Every IR stage of the scene.
    pub pipeline: ScenePipeline,
    forward_ir: Function,
    forward: Kernel,
    gradient: OnceLock<Result<Kernel, codegen::CodegenError>>,
}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Scene").field("name", &self.pipeline.optimized.name).finish()
    }
}

impl Scene {
    fn new(pipeline: ScenePipeline) -> Result<Scene, Error> {
        let forward_ir = pipeline.forward().map_err(Error::from)?;
        let forward = codegen::compile(&forward_ir).map_err(Error::Codegen)?;
        Ok(Scene { pipeline, forward_ir, forward, gradient: OnceLock::new() })
    }

    /// The IR that the gradient kernel runs (forward and adjoint).
    pub fn ir(&self) -> &Function {
        &self.pipeline.optimized
    }

    /// The forward-only IR.
    pub fn forward_ir(&self) -> &Function {
        &self.forward_ir
    }

    /// The forward kernel.
    pub fn forward_kernel(&self) -> &Kernel {
        &self.forward
    }

    /// The forward+gradient kernel, compiling it on first use.
    pub fn gradient_kernel(&self) -> Result<&Kernel, Error> {
        self.gradient.get_or_init(|| codegen::compile(&self.pipeline.optimized)).as_ref().map_err(|e| Error::Codegen(e.clone()))
    }

    /// Starts a run with every param at its default and inputs at their defaults.
    pub fn bind(&self) -> Run<'_> {
        let f = self.ir();
        Run {
            scene: self,
            params: f.params.iter().map(|p| p.default).collect(),
            inputs: f.inputs.iter().map(|i| i.default.clone()).collect(),
            stale: vec![false; f.inputs.len()],
            scratch: Vec::new(),
            allocated_for: None,
            filled_for: None,
            scalars: Vec::new(),
        }
    }
}

/// Storage for one buffer, in its precision (see `codegen::BufferInfo`).
enum Buffer {
    F64(Vec<f64>),
    F32(Vec<f32>),
}

impl Buffer {
    /// Allocates fallibly, so a scene over a huge grid is an error, not an abort.
    fn new(precision: Precision, floats: usize) -> Result<Buffer, Error> {
        fn zeros<T: Clone + Default>(n: usize) -> Result<Vec<T>, Error> {
            let mut v = Vec::new();
            v.try_reserve_exact(n).map_err(|_| {
                Error::Bind(format!("cannot allocate a buffer of {n} values: the scene's grids are too large for this machine's memory"))
            })?;
            v.resize(n, T::default());
            Ok(v)
        }
        Ok(match precision {
            Precision::F64 => Buffer::F64(zeros(floats)?),
            Precision::F32 | Precision::Mixed => Buffer::F32(zeros(floats)?),
        })
    }
    fn ptr(&mut self) -> *mut u8 {
        match self {
            Buffer::F64(v) => v.as_mut_ptr() as *mut u8,
            Buffer::F32(v) => v.as_mut_ptr() as *mut u8,
        }
    }
    /// The first `n` values times `scale`, in f64 (one pass, no per-element
    /// dispatch: outputs are read after every call).
    fn real(&self, n: usize, scale: f64) -> Vec<f64> {
        // Written into a zeroed vector by index (not collected from an
        // iterator) so the copy vectorises: outputs of 8,000 bins are
        // copied on every call.
        let mut out = vec![0.0; n];
        match self {
            Buffer::F64(v) => out.iter_mut().zip(&v[..n]).for_each(|(o, x)| *o = x * scale),
            Buffer::F32(v) => out.iter_mut().zip(&v[..n]).for_each(|(o, x)| *o = *x as f64 * scale),
        }
        out
    }

    /// The first `n` interleaved (re, im) pairs times `scale`, as complex numbers.
    fn complex(&self, n: usize, scale: f64) -> Vec<C64> {
        let mut out = vec![C64::new(0.0, 0.0); n];
        match self {
            Buffer::F64(v) => out.iter_mut().zip(v[..2 * n].chunks_exact(2)).for_each(|(o, c)| *o = C64::new(c[0] * scale, c[1] * scale)),
            Buffer::F32(v) => {
                out.iter_mut().zip(v[..2 * n].chunks_exact(2)).for_each(|(o, c)| *o = C64::new(c[0] as f64 * scale, c[1] as f64 * scale))
            }
        }
        out
    }
}

/// A value the scene produced.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// A real scalar.
    Real(f64),
    /// A complex scalar.
    Complex(C64),
    /// A real array.
    RealArray(Vec<f64>),
    /// A complex array.
    ComplexArray(Vec<C64>),
}

/// Outputs and gradients of one run.
#[derive(Clone, Debug)]
pub struct Outputs {
    /// Params used, in declared units, in declaration order.
    pub params: Vec<(String, f64)>,
    /// Outputs in declaration order (base units).
    pub values: Vec<(String, Value)>,
    /// Gradients `(output, param, d output / d param)` per declared unit of the param.
    pub grads: Vec<(String, String, f64)>,
    /// Gradients `(output, input, d output / d input)` with respect to
    /// trainable inputs (the weights of learned components), one value per
    /// element, per declared unit of the input.
    pub input_grads: Vec<(String, String, Vec<f64>)>,
}

impl Outputs {
    /// The output `name`.
    pub fn value(&self, name: &str) -> Result<&Value, Error> {
        self.values
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v)
            .ok_or_else(|| unknown("output", name, self.values.iter().map(|(n, _)| n.as_str())))
    }

    /// The real scalar output `name`.
    pub fn scalar(&self, name: &str) -> Result<f64, Error> {
        match self.value(name)? {
            Value::Real(x) => Ok(*x),
            _ => Err(Error::Bind(format!("output `{name}` is not a real scalar"))),
        }
    }

    /// The gradient of `output` with respect to trainable input `input` (a weight tensor).
    pub fn input_grad(&self, output: &str, input: &str) -> Result<&[f64], Error> {
        self.input_grads.iter().find(|(o, i, _)| o == output && i == input).map(|g| g.2.as_slice()).ok_or_else(|| {
            let names: Vec<String> = self.input_grads.iter().map(|(o, i, _)| format!("{o}/{i}")).collect();
            unknown("gradient", &format!("{output}/{input}"), names.iter().map(|s| s.as_str()))
        })
    }

    /// The gradient of `output` with respect to `param`.
    pub fn grad(&self, output: &str, param: &str) -> Result<f64, Error> {
        self.grads.iter().find(|(o, p, _)| o == output && p == param).map(|g| g.2).ok_or_else(|| {
            let names: Vec<String> = self.grads.iter().map(|(o, p, _)| format!("{o}/{p}")).collect();
            unknown("gradient", &format!("{output}/{param}"), names.iter().map(|s| s.as_str()))
        })
    }
}

fn unknown<'a>(kind: &'static str, name: &str, names: impl Iterator<Item = &'a str>) -> Error {
    Error::UnknownName { kind, name: name.to_string(), suggestion: did_you_mean(name, names).map(str::to_string) }
}

/// Params and data bound to a scene, ready to run. Buffers are allocated on
/// the first run and reused, so repeated runs do not allocate per-bin arrays.
pub struct Run<'s> {
    scene: &'s Scene,
    params: Vec<Option<f64>>,
    inputs: Vec<Option<Vec<C64>>>,
    scratch: Vec<(bool, Buffer)>,
    /// Which kernel's layout `scratch` was allocated for (forward or gradient).
    allocated_for: Option<*const Kernel>,
    /// Which kernel's buffers hold the tables and the bound inputs (but
    /// those marked `stale`), or `None`: buffers are refilled only then.
    filled_for: Option<*const Kernel>,
    /// Per input, whether it was bound since its buffer was last filled.
    stale: Vec<bool>,
    scalars: Vec<f64>,
}

impl<'s> Run<'s> {
    fn func(&self) -> &'s Function {
        self.scene.ir()
    }

    /// Binds a trained checkpoint: every weight input of the scene from its
    /// tensor, and scalar params the checkpoint holds (trained params).
    /// Returns how many weights were bound; every weight must be present.
    pub fn load_weights(&mut self, ck: &checkpoint::Checkpoint) -> Result<usize, Error> {
        let func = self.func();
        let mut bound = 0;
        for input in func.inputs.iter().filter(|i| i.is_weight()) {
            let Some(t) = ck.get(&input.name) else {
                return Err(Error::Bind(format!("the checkpoint has no tensor `{}` for the scene's weight", input.name)));
            };
            self.input_real(&input.name, &t.data)?;
            bound += 1;
        }
        for t in ck.tensors.iter().filter(|t| t.shape.is_empty()) {
            if func.params.iter().any(|p| p.name == t.name) {
                self.param(&t.name, t.data[0])?;
            }
        }
        Ok(bound)
    }

    /// Sets param `name` (in its declared unit).
    pub fn param(&mut self, name: &str, value: f64) -> Result<&mut Self, Error> {
        let f = self.func();
        let i =
            f.params.iter().position(|p| p.name == name).ok_or_else(|| unknown("param", name, f.params.iter().map(|p| p.name.as_str())))?;
        if !value.is_finite() {
            return Err(Error::Bind(format!("param `{name}` = {value} is not finite")));
        }
        self.params[i] = Some(value);
        Ok(self)
    }

    /// Sets param `name` from text such as `2 ms` or `30 Msun`: a value
    /// with a unit is converted to the param's declared unit (a unit of
    /// another dimension is an error); a bare number is in the declared unit.
    pub fn param_quantity(&mut self, name: &str, text: &str) -> Result<&mut Self, Error> {
        let f = self.func();
        let p = f.params.iter().find(|p| p.name == name).ok_or_else(|| unknown("param", name, f.params.iter().map(|p| p.name.as_str())))?;
        let (x, unit) = gwml_compiler::front::units::parse_quantity(text).map_err(|e| Error::Bind(format!("param `{name}`: {e}")))?;
        let value = match unit {
            None => x,
            Some(u) if u.dim.to_string() == p.dim => x * u.scale / p.scale,
            Some(u) => {
                return Err(Error::Bind(format!(
                    "param `{name}` is in {} (dimension {}), but `{}` is in {} (dimension {})",
                    p.unit,
                    p.dim,
                    text.trim(),
                    u.name,
                    u.dim
                )))
            }
        };
        self.param(name, value)
    }

    /// Binds a real input (in its declared unit).
    pub fn input_real(&mut self, name: &str, data: &[f64]) -> Result<&mut Self, Error> {
        self.bind_input(name, data.len(), false, |k| C64::new(data[k], 0.0))
    }

    /// Binds a complex input (in its declared unit).
    pub fn input_complex(&mut self, name: &str, data: &[C64]) -> Result<&mut Self, Error> {
        self.bind_input(name, data.len(), true, |k| data[k])
    }

    /// Validates and stores the `len` values `value(k)`, reusing the
    /// input's previous storage (a run binds new data per example).
    fn bind_input(&mut self, name: &str, len: usize, complex: bool, value: impl Fn(usize) -> C64) -> Result<&mut Self, Error> {
        let f = self.func();
        let i =
            f.inputs.iter().position(|p| p.name == name).ok_or_else(|| unknown("input", name, f.inputs.iter().map(|p| p.name.as_str())))?;
        let info = &f.inputs[i];
        if complex && info.ty.elem == Elem::Real {
            return Err(Error::Bind(format!("input `{name}` is real, but complex data was given")));
        }
        let want = f.len_of(info.ty.shape);
        if len != want {
            let grid = match info.ty.shape {
                Shape::Grid(g) => format!(" (grid `{}`)", f.grid(g).name),
                Shape::Scalar => " (a scalar)".into(),
            };
            return Err(Error::Bind(format!("input `{name}` needs {want} values{grid}, but {len} were given")));
        }
        if let Some(k) = (0..len).find(|k| {
            let z = value(*k);
            !z.re.is_finite() || !z.im.is_finite()
        }) {
            return Err(Error::Bind(format!("input `{name}` has a non-finite value ({}) at index {k}", value(k))));
        }
        let stored = self.inputs[i].get_or_insert_with(Vec::new);
        stored.clear();
        stored.extend((0..len).map(|k| value(k) * info.scale));
        self.stale[i] = true;
        Ok(self)
    }

    /// Runs the forward kernel.
    pub fn forward(&mut self) -> Result<Outputs, Error> {
        let kernel = &self.scene.forward;
        let func = &self.scene.forward_ir;
        self.execute(kernel, func)
    }

    /// Runs the fused forward+gradient kernel.
    pub fn value_and_grad(&mut self) -> Result<Outputs, Error> {
        let kernel = self.scene.gradient_kernel()?;
        let func = self.scene.ir();
        self.execute(kernel, func)
    }

    fn execute(&mut self, kernel: &Kernel, func: &Function) -> Result<Outputs, Error> {
        let layout = &kernel.layout;
        let mut params = Vec::with_capacity(func.params.len());
        for (p, v) in func.params.iter().zip(&self.params) {
            let v = v.ok_or_else(|| Error::Bind(format!("param `{}` has no default; set it (e.g. `--set {}=VALUE`)", p.name, p.name)))?;
            if let Some((lo, hi)) = p.bounds {
                if !(lo..=hi).contains(&v) {
                    return Err(Error::Bind(format!("param `{}` = {v} is outside its bounds {lo}..{hi}", p.name)));
                }
            }
            params.push(v * p.scale);
        }
        // (Re)allocate buffers for this kernel's layout.
        let floats = |b: &codegen::BufferInfo| b.len * if b.complex { 2 } else { 1 };
        let refill_all = self.filled_for != Some(kernel as *const Kernel);
        if refill_all || self.stale.iter().any(|s| *s) {
            if self.allocated_for != Some(kernel as *const Kernel) {
                self.scratch =
                    layout.buffers.iter().map(|b| Ok((b.complex, Buffer::new(b.precision, floats(b))?))).collect::<Result<_, Error>>()?;
                self.allocated_for = Some(kernel as *const Kernel);
            }
            for ((_, buf), info) in self.scratch.iter_mut().zip(&layout.buffers) {
                match info.kind {
                    BufferKind::Input(i) if refill_all || self.stale[i] => {
                        let data = self.inputs[i].as_ref().ok_or_else(|| {
                            Error::Bind(format!(
                                "input `{}` is not bound and has no default; bind it (e.g. `--input {}=FILE.npy`)",
                                func.inputs[i].name, func.inputs[i].name
                            ))
                        })?;
                        fill(buf, data, info.complex);
                    }
                    BufferKind::Table(k) if refill_all => {
                        let data: Vec<C64> = func.tables[k].data.iter().map(|x| C64::new(*x, 0.0)).collect();
                        fill(buf, &data, false);
                    }
                    _ => {}
                }
            }
            self.stale.iter_mut().for_each(|s| *s = false);
            self.filled_for = Some(kernel as *const Kernel);
        }
        self.scalars.clear();
        self.scalars.resize(layout.scalar_slots, 0.0);
        let ptrs: Vec<*mut u8> = self.scratch.iter_mut().map(|(_, b)| b.ptr()).collect();
        // SAFETY: params has one entry per scene param; every buffer was
        // allocated from the kernel's own layout (length and precision), and
        // scalars has layout.scalar_slots entries.
        unsafe { kernel.call(params.as_ptr(), ptrs.as_ptr(), self.scalars.as_mut_ptr()) };
        let read_scalar = |v: gwml_compiler::ir::Value| -> Value {
            let s = layout.scalars.iter().find(|s| s.value == v).expect("every scalar root has a slot");
            if s.complex {
                Value::Complex(C64::new(self.scalars[s.slot], self.scalars[s.slot + 1]))
            } else {
                Value::Real(self.scalars[s.slot])
            }
        };
        let mut values = Vec::new();
        for (oi, o) in func.outputs.iter().enumerate() {
            // Rescaled f32 kernels return outputs times 2^-exponent.
            let scale = 2f64.powi(o.exponent);
            let v = if func.ty(o.value).shape == Shape::Scalar {
                match read_scalar(o.value) {
                    Value::Real(x) => Value::Real(x * scale),
                    Value::Complex(z) => Value::Complex(z * scale),
                    other => other,
                }
            } else {
                let k = layout.outputs[oi].expect("array outputs have a buffer");
                let (complex, buf) = &self.scratch[k];
                let n = layout.buffers[k].len;
                if *complex {
                    Value::ComplexArray(buf.complex(n, scale))
                } else {
                    Value::RealArray(buf.real(n, scale))
                }
            };
            values.push((o.name.clone(), v));
        }
        let mut grads = Vec::new();
        for g in &func.grads {
            let Some(v) = g.value else { continue };
            let Value::Real(x) = read_scalar(v) else {
                continue;
            };
            let p = &func.params[g.param];
            grads.push((func.outputs[g.output].name.clone(), p.name.clone(), x * p.scale));
        }
        let mut input_grads = Vec::new();
        for (g, buffer) in func.input_grads.iter().zip(&layout.input_grads) {
            let Some(v) = g.value else { continue };
            let scale = func.inputs[g.input].scale;
            let data = match buffer {
                Some(k) => self.scratch[*k].1.real(layout.buffers[*k].len, scale),
                None => match read_scalar(v) {
                    Value::Real(x) => vec![x * scale],
                    _ => continue,
                },
            };
            input_grads.push((func.outputs[g.output].name.clone(), func.inputs[g.input].name.clone(), data));
        }
        let params_used = func.params.iter().zip(&self.params).map(|(p, v)| (p.name.clone(), v.unwrap_or(f64::NAN))).collect();
        if let Some((name, _)) = values.iter().find(|(_, v)| !value_finite(v)) {
            return Err(Error::Bind(format!(
                "output `{name}` is not finite (NaN or infinity) at these params; check params against their bounds and the data"
            )));
        }
        if let Some((o, p, g)) = grads.iter().find(|(_, _, g)| !g.is_finite()) {
            return Err(Error::Bind(format!(
                "gradient d{o}/d{p} is {g} at these params: the derivative does not exist there (e.g. sqrt or log at 0)"
            )));
        }
        if let Some((o, i, g)) = input_grads.iter().find(|(_, _, g)| g.iter().any(|x| !x.is_finite())) {
            let k = g.iter().position(|x| !x.is_finite()).unwrap_or(0);
            return Err(Error::Bind(format!("gradient d{o}/d{i} is {} at element {k}: the derivative does not exist there", g[k])));
        }
        Ok(Outputs { params: params_used, values, grads, input_grads })
    }
}

fn value_finite(v: &Value) -> bool {
    match v {
        Value::Real(x) => x.is_finite(),
        Value::Complex(z) => z.re.is_finite() && z.im.is_finite(),
        Value::RealArray(a) => all_finite(a, |x| *x),
        Value::ComplexArray(a) => all_finite(a, |z| z.re * 0.0 + z.im * 0.0),
    }
}

/// Whether `f(x)` is finite for every element, without a branch per
/// element: `y · 0` is ±0 for finite `y` and NaN otherwise, and a sum
/// with a NaN is NaN. Four accumulators, so the loop vectorises.
fn all_finite<T>(xs: &[T], f: impl Fn(&T) -> f64) -> bool {
    let mut acc = [0.0f64; 4];
    let chunks = xs.chunks_exact(4);
    let tail: f64 = chunks.remainder().iter().map(|x| f(x) * 0.0).sum();
    for c in chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a += f(x) * 0.0;
        }
    }
    acc.iter().sum::<f64>() + tail == 0.0
}

fn fill(buf: &mut Buffer, data: &[C64], complex: bool) {
    match buf {
        Buffer::F64(v) => {
            for (i, z) in data.iter().enumerate() {
                if complex {
                    v[2 * i] = z.re;
                    v[2 * i + 1] = z.im;
                } else {
                    v[i] = z.re;
                }
            }
        }
        Buffer::F32(v) => {
            for (i, z) in data.iter().enumerate() {
                if complex {
                    v[2 * i] = z.re as f32;
                    v[2 * i + 1] = z.im as f32;
                } else {
                    v[i] = z.re as f32;
                }
            }
        }
    }
}

/// Scenes are shared between threads (batches run one `Run` per thread).
const _: () = {
    const fn shareable<T: Send + Sync>() {}
    shareable::<Scene>();
};
