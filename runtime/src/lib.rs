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
mod buffers;
pub mod checkpoint;
pub mod dataset;
pub mod fit;
pub mod noise;
pub mod npy;
pub mod optim;
pub mod spectrum;
pub mod train;

use buffers::{Buffers, KernelKey};
use gwml_compiler::codegen::{self, Kernel};
use gwml_compiler::front::diagnostics::did_you_mean;
use gwml_compiler::ir::{Elem, Function, Shape};
use gwml_compiler::{CompileError, KernelIr, Options, PipelineError, Program, ScenePipeline};
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
    /// The forward-only computation, whole.
    forward_ir: Function,
    forward: Compiled,
    gradient: OnceLock<Result<Compiled, codegen::CodegenError>>,
}

/// One compiled kernel of a scene, and the prelude that computes its
/// cached inputs from the data when staging split one off
/// (`passes::stage`).
struct Compiled {
    main: (Function, Kernel),
    prelude: Option<(Function, Kernel)>,
}

impl Compiled {
    fn new(ir: &KernelIr) -> Result<Compiled, codegen::CodegenError> {
        let prelude = match &ir.prelude {
            Some(p) => Some((p.clone(), codegen::compile(p)?)),
            None => None,
        };
        Ok(Compiled { main: (ir.main.clone(), codegen::compile(&ir.main)?), prelude })
    }
}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Scene").field("name", &self.pipeline.optimized.name).finish()
    }
}

impl Scene {
    fn new(pipeline: ScenePipeline) -> Result<Scene, Error> {
        let forward_ir = pipeline.forward().map_err(Error::from)?;
        let forward = Compiled::new(&forward_ir).map_err(Error::Codegen)?;
        Ok(Scene { pipeline, forward_ir: forward_ir.whole, forward, gradient: OnceLock::new() })
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
        &self.forward.main.1
    }

    /// The IR of the forward kernel's prelude, if staging split one off.
    pub fn forward_prelude(&self) -> Option<&Function> {
        self.forward.prelude.as_ref().map(|p| &p.0)
    }

    fn gradient(&self) -> Result<&Compiled, Error> {
        self.gradient.get_or_init(|| Compiled::new(&self.pipeline.kernel)).as_ref().map_err(|e| Error::Codegen(e.clone()))
    }

    /// The forward+gradient kernel, compiling it on first use.
    pub fn gradient_kernel(&self) -> Result<&Kernel, Error> {
        Ok(&self.gradient()?.main.1)
    }

    /// Starts a run with every param at its default and inputs at their defaults.
    pub fn bind(&self) -> Run<'_> {
        let f = self.ir();
        let inputs: Vec<Option<Vec<C64>>> = f.inputs.iter().map(|i| i.default.clone()).collect();
        Run {
            scene: self,
            params: f.params.iter().map(|p| p.default).collect(),
            bound_at: vec![0; inputs.len()],
            bindings: 0,
            inputs,
            main: Vec::new(),
            prelude: Buffers::default(),
            caches: Vec::new(),
            prelude_runs: 0,
        }
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
/// the first run and reused, so repeated runs do not allocate per-bin arrays;
/// values the scene computes from the data alone (its prelude) are
/// recomputed only after data are bound.
pub struct Run<'s> {
    scene: &'s Scene,
    params: Vec<Option<f64>>,
    /// The data of every input callers bind (cached inputs come after them).
    inputs: Vec<Option<Vec<C64>>>,
    /// Per input, the count of bindings (`bindings`) when it was last
    /// bound: buffers filled before then hold stale data.
    bound_at: Vec<u64>,
    /// How many times data were bound to this run.
    bindings: u64,
    /// The buffers of each main kernel run so far (forward, gradient),
    /// kept apart so a fit that alternates the two neither reallocates
    /// nor refills them.
    main: Vec<Buffers>,
    prelude: Buffers,
    /// Per prelude kernel (forward, gradient) run since data were last
    /// bound: its outputs, the main kernel's cached inputs in order.
    caches: Vec<(KernelKey, Vec<Vec<C64>>)>,
    prelude_runs: usize,
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

    /// Puts every param back at its default (a param without one is unset
    /// again), as [`Scene::bind`] starts; bound data stay.
    pub fn reset_params(&mut self) -> &mut Self {
        for (v, p) in self.params.iter_mut().zip(&self.scene.ir().params) {
            *v = p.default;
        }
        self
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
    /// `fiducial.NAME`, the fiducial of a relative-binning scene, is set
    /// the same way, in param `NAME`'s unit.
    pub fn param_quantity(&mut self, name: &str, text: &str) -> Result<&mut Self, Error> {
        if let Some(param) = name.strip_prefix("fiducial.") {
            if self.func().inputs.iter().any(|i| i.name == name) {
                let value = self.quantity_in_unit_of(param, text)?;
                return self.input_real(name, &[value]);
            }
        }
        let value = self.quantity_in_unit_of(name, text)?;
        self.param(name, value)
    }

    /// `text` (a number with an optional unit) in the declared unit of param `name`.
    fn quantity_in_unit_of(&self, name: &str, text: &str) -> Result<f64, Error> {
        let f = self.func();
        let p = f.params.iter().find(|p| p.name == name).ok_or_else(|| unknown("param", name, f.params.iter().map(|p| p.name.as_str())))?;
        let (x, unit) = gwml_compiler::front::units::parse_quantity(text).map_err(|e| Error::Bind(format!("param `{name}`: {e}")))?;
        match unit {
            None => Ok(x),
            Some(u) if u.dim.to_string() == p.dim => Ok(x * u.scale / p.scale),
            Some(u) => Err(Error::Bind(format!(
                "param `{name}` is in {} (dimension {}), but `{}` is in {} (dimension {})",
                p.unit,
                p.dim,
                text.trim(),
                u.name,
                u.dim
            ))),
        }
    }

    /// Binds a real input (in its declared unit).
    pub fn input_real(&mut self, name: &str, data: &[f64]) -> Result<&mut Self, Error> {
        self.bind_input(name, data.len(), false, |k| C64::new(data[k], 0.0))
    }

    /// Binds a complex input (in its declared unit).
    pub fn input_complex(&mut self, name: &str, data: &[C64]) -> Result<&mut Self, Error> {
        self.bind_input(name, data.len(), true, |k| data[k])
    }

    /// Puts input `name` back at its default data (unbound again if it has none).
    pub fn reset_input(&mut self, name: &str) -> Result<&mut Self, Error> {
        let f = self.func();
        let i =
            f.inputs.iter().position(|p| p.name == name).ok_or_else(|| unknown("input", name, f.inputs.iter().map(|p| p.name.as_str())))?;
        self.inputs[i].clone_from(&f.inputs[i].default);
        self.mark_bound(i);
        Ok(self)
    }

    /// Input `i` changed: the main kernel and the prelude refill it, and
    /// values computed from the data are stale.
    fn mark_bound(&mut self, i: usize) {
        self.bindings += 1;
        self.bound_at[i] = self.bindings;
        self.caches.clear();
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
        self.mark_bound(i);
        Ok(self)
    }

    /// How many times this run computed the values its scene takes from
    /// the data alone (its prelude, see `passes::stage`): once per bound
    /// data and kernel, not once per call.
    pub fn prelude_runs(&self) -> usize {
        self.prelude_runs
    }

    /// Runs the forward kernel.
    pub fn forward(&mut self) -> Result<Outputs, Error> {
        let scene = self.scene;
        self.execute(&scene.forward)
    }

    /// Runs the fused forward+gradient kernel.
    pub fn value_and_grad(&mut self) -> Result<Outputs, Error> {
        let scene = self.scene;
        self.execute(scene.gradient()?)
    }

    /// The data of input `i` of a kernel's function: bound by the caller,
    /// or (after them) computed by the prelude.
    fn data<'a>(inputs: &'a [Option<Vec<C64>>], cache: &'a [Vec<C64>], func: &Function, i: usize) -> Result<&'a [C64], Error> {
        if i >= inputs.len() {
            return Ok(&cache[i - inputs.len()]);
        }
        inputs[i].as_deref().ok_or_else(|| {
            let name = &func.inputs[i].name;
            Error::Bind(format!("input `{name}` is not bound and has no default; bind it (e.g. `--input {name}=FILE.npy`)"))
        })
    }

    /// Runs `compiled.prelude` unless its outputs for the bound data are
    /// kept; returns the index of those outputs in `caches`.
    fn run_prelude(&mut self, compiled: &Compiled, params: &[f64]) -> Result<Option<usize>, Error> {
        let Some((func, kernel)) = &compiled.prelude else { return Ok(None) };
        if let Some(k) = self.caches.iter().position(|c| c.0 == KernelKey::of(kernel)) {
            return Ok(Some(k));
        }
        let (inputs, bound_at, since) = (&self.inputs, &self.bound_at, self.prelude.filled_at());
        self.prelude.call(kernel, func, params, &|i| Self::data(inputs, &[], func, i), &|i| bound_at[i] > since, self.bindings)?;
        let mut cache = Vec::with_capacity(func.outputs.len());
        for oi in 0..func.outputs.len() {
            let v = self.prelude.output(kernel, func, oi);
            if !value_finite(&v) {
                return Err(Error::Bind(
                    "the values the scene computes from its data alone are not finite (NaN or infinity); check the data \
                     (and, with relative binning, that the waveform at the `fiducial.*` inputs is nonzero on the whole grid)"
                        .into(),
                ));
            }
            cache.push(as_complex(v));
        }
        self.caches.push((KernelKey::of(kernel), cache));
        self.prelude_runs += 1;
        Ok(Some(self.caches.len() - 1))
    }

    fn execute(&mut self, compiled: &Compiled) -> Result<Outputs, Error> {
        let (func, kernel) = (&compiled.main.0, &compiled.main.1);
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
        let prelude = self.run_prelude(compiled, &params)?;
        let n_bound = self.inputs.len();
        let slot = match self.main.iter().position(|b| b.holds(kernel)) {
            Some(slot) => slot,
            None => {
                self.main.push(Buffers::default());
                self.main.len() - 1
            }
        };
        let main = &mut self.main[slot];
        let since = main.filled_at();
        // The prelude's outputs are recomputed only after a binding (which
        // clears them), and this kernel's prelude runs before it: buffers
        // filled at the current count already hold them.
        let recomputed = self.bindings > since;
        let cache: &[Vec<C64>] = prelude.map_or(&[], |k| &self.caches[k].1);
        let (inputs, bound_at) = (&self.inputs, &self.bound_at);
        let stale = |i: usize| if i < n_bound { bound_at[i] > since } else { recomputed };
        main.call(kernel, func, &params, &|i| Self::data(inputs, cache, func, i), &stale, self.bindings)?;
        let main = &self.main[slot];
        let values: Vec<(String, Value)> =
            (0..func.outputs.len()).map(|oi| (func.outputs[oi].name.clone(), main.output(kernel, func, oi))).collect();
        let mut grads = Vec::new();
        for g in &func.grads {
            let Some(v) = g.value else { continue };
            let Value::Real(x) = main.scalar(kernel, v) else {
                continue;
            };
            let p = &func.params[g.param];
            grads.push((func.outputs[g.output].name.clone(), p.name.clone(), x * p.scale));
        }
        let layout = &kernel.layout;
        let mut input_grads = Vec::new();
        for (g, buffer) in func.input_grads.iter().zip(&layout.input_grads) {
            let Some(v) = g.value else { continue };
            let scale = func.inputs[g.input].scale;
            let data = match buffer {
                Some(k) => main.scratch[*k].1.real(layout.buffers[*k].len, scale),
                None => match main.scalar(kernel, v) {
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

/// A value as complex numbers (one for a scalar).
fn as_complex(v: Value) -> Vec<C64> {
    match v {
        Value::Real(x) => vec![C64::new(x, 0.0)],
        Value::Complex(z) => vec![z],
        Value::RealArray(a) => a.into_iter().map(|x| C64::new(x, 0.0)).collect(),
        Value::ComplexArray(a) => a,
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

/// Scenes are shared between threads (batches run one `Run` per thread),
/// and a run can move to another thread (the Python package runs it with
/// the interpreter's lock released).
const _: () = {
    const fn shareable<T: Send + Sync>() {}
    const fn movable<T: Send>() {}
    shareable::<Scene>();
    movable::<Run<'static>>();
};
