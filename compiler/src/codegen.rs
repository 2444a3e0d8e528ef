//! Code generation: fuse the optimised IR into loops and JIT-compile it
//! with Cranelift.
//!
//! # Fusion
//! Every value gets an *epoch*: reductions finish at the end of a loop, so
//! `epoch(reduce(x)) = epoch(x) + 1` and every other value takes the largest
//! epoch of its operands. All array instructions of one epoch over one grid
//! run in ONE loop, together with the reductions that consume them. A
//! forward pass and the adjoint of an elementwise chain (whose seeds do not
//! depend on a reduction) therefore share a loop, and the gradients w.r.t.
//! scalar params accumulate in registers with no intermediate arrays.
//! Arrays are stored to a scratch buffer only when a later loop reads them
//! or they are outputs. A transform (`Op::Dft`) behaves like a reduction
//! for scheduling (`epoch(dft(x)) = epoch(x) + 1`): its operand is stored,
//! the call runs before the loops of its epoch, and they read its result
//! from its buffer. Broadcasts, grid coordinates and inputs are
//! recomputed (or reloaded) in each loop that uses them.
//!
//! # Kernel ABI
//! `extern "C" fn(params: *const f64, buffers: *const *mut u8, scalars: *mut f64)`:
//! `params` holds the scene's params in base units; `buffers[k]` points at
//! buffer `k` of [`Layout::buffers`] (elements of the buffer's precision,
//! complex interleaved re/im) holding exactly `len` elements, which the
//! runtime guarantees; scalar results are written as f64 to
//! `scalars[slot]` (complex results take two slots).

use crate::dft::{gwml_dft_f32, gwml_dft_f64, DftPlan};
use crate::ir::*;
use crate::mathlib::{self, MathEmitter, SlowPath};
use crate::tensor::{gwml_tensor_f32, gwml_tensor_f64};
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, AbiParam, FuncRef, InstBuilder, MemFlagsData, Signature, StackSlotData, StackSlotKind, Type};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};
use std::collections::{HashMap, HashSet};
use std::fmt;

/// What a buffer passed to the kernel holds.
#[derive(Clone, Debug, PartialEq)]
pub enum BufferKind {
    /// Input number `i` (read only).
    Input(usize),
    /// An intermediate array read by a later loop.
    Scratch,
    /// Array output number `i` (index into [`Function::outputs`]).
    Output(usize),
    /// Precomputed table number `i` (index into [`Function::tables`], read only).
    Table(usize),
    /// Gradient number `i` of [`Function::input_grads`] (an array).
    InputGrad(usize),
}

/// One buffer the kernel reads or writes.
#[derive(Clone, Debug, PartialEq)]
pub struct BufferInfo {
    /// Its role.
    pub kind: BufferKind,
    /// Number of elements.
    pub len: usize,
    /// Complex elements take two floats.
    pub complex: bool,
    /// Element precision: [`Precision::storage`] of the scene's, except
    /// that in mixed precision the tables, scratch arrays and outputs of
    /// values computed in f64 are f64 (unless a library call reads them).
    pub precision: Precision,
}

/// Where a scalar result is written.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarSlot {
    /// The IR value.
    pub value: Value,
    /// First slot in the `scalars` array.
    pub slot: usize,
    /// Complex results take `slot` and `slot + 1`.
    pub complex: bool,
}

/// How the runtime must call a kernel.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// Buffers in call order.
    pub buffers: Vec<BufferInfo>,
    /// Scalar results.
    pub scalars: Vec<ScalarSlot>,
    /// Total scalar slots.
    pub scalar_slots: usize,
    /// Number of fused loops.
    pub loops: usize,
    /// How many of them are split at an interval condition (emitted once
    /// for each side of it, see `Gen::emit_loop`).
    pub split_loops: usize,
    /// How many sums, in split loops, add nothing on one side (the
    /// condition makes their terms +0 there) and are not accumulated on it.
    pub sums_skipped: usize,
    /// The scene's precision (each buffer states its element type).
    pub precision: Precision,
    /// Per entry of [`Function::outputs`], the buffer holding it (`None`
    /// for a scalar, which has a slot in `scalars`).
    pub outputs: Vec<Option<usize>>,
    /// Per entry of [`Function::input_grads`], the buffer holding it
    /// (`None` for a scalar, which has a slot in `scalars`).
    pub input_grads: Vec<Option<usize>>,
}

/// Code generation failed (a compiler bug or an unsupported target).
#[derive(Clone, Debug)]
pub struct CodegenError(pub String);

impl fmt::Display for CodegenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "code generation failed: {}", self.0)
    }
}

impl std::error::Error for CodegenError {}

type KernelFn = unsafe extern "C" fn(*const f64, *const *mut u8, *mut f64);

/// What a library call in a kernel points at (a planned transform or a
/// tensor op's sizes); boxed so its address is stable.
enum PlanBox {
    F64(Box<DftPlan<f64>>),
    F32(Box<DftPlan<f32>>),
    Tensor(Box<TensorOp>),
}

impl PlanBox {
    fn new(dft: Dft, n: usize, precision: Precision) -> PlanBox {
        match precision {
            Precision::F64 => PlanBox::F64(Box::new(DftPlan::new(dft, n))),
            Precision::F32 | Precision::Mixed => PlanBox::F32(Box::new(DftPlan::new(dft, n))),
        }
    }

    fn work_floats(&self) -> usize {
        match self {
            PlanBox::F64(p) => p.work_floats(),
            PlanBox::F32(p) => p.work_floats(),
            PlanBox::Tensor(_) => 0,
        }
    }

    fn address(&self) -> i64 {
        match self {
            PlanBox::F64(p) => &**p as *const DftPlan<f64> as i64,
            PlanBox::F32(p) => &**p as *const DftPlan<f32> as i64,
            PlanBox::Tensor(t) => &**t as *const TensorOp as i64,
        }
    }
}

/// A JIT-compiled scene.
pub struct Kernel {
    module: Option<JITModule>,
    /// Transform plans the code points at (kept alive with it).
    _plans: Vec<PlanBox>,
    entry: KernelFn,
    /// Calling convention.
    pub layout: Layout,
    /// Cranelift IR text (before optimisation), for `--emit clif`.
    pub clif: String,
    /// Cranelift instructions in the kernel.
    pub clif_insts: usize,
}

impl Kernel {
    /// Calls the kernel.
    ///
    /// # Safety
    /// `params` must hold one value per scene param, `buffers` one pointer per
    /// [`Layout::buffers`] entry to at least `len` (×2 if complex) elements of
    /// the layout's precision, writable for scratch and output buffers, and
    /// `scalars` at least [`Layout::scalar_slots`] values.
    pub unsafe fn call(&self, params: *const f64, buffers: *const *mut u8, scalars: *mut f64) {
        unsafe { (self.entry)(params, buffers, scalars) }
    }
}

// SAFETY: after `finalize_definitions` the kernel's code and data are never
// written again; the generated function keeps no state between calls (every
// buffer it touches is passed in by the caller), so one kernel may be called
// from several threads at once, each with its own buffers.
unsafe impl Send for Kernel {}
unsafe impl Sync for Kernel {}

impl Drop for Kernel {
    fn drop(&mut self) {
        if let Some(m) = self.module.take() {
            // SAFETY: the kernel is being dropped, so no pointer into its code survives.
            unsafe { m.free_memory() };
        }
    }
}

impl fmt::Debug for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Kernel").field("layout", &self.layout).finish()
    }
}

/// Per-value scheduling decisions.
struct Schedule {
    epoch: Vec<u32>,
    /// Loops in emission order: (epoch, grid, member instructions).
    loops: Vec<(u32, GridId, Vec<usize>)>,
    /// Scalar instructions per epoch (excluding reductions).
    scalars: Vec<Vec<usize>>,
    /// Array values stored to a buffer: value index → buffer index.
    stored: HashMap<usize, usize>,
    /// Library calls (transforms and tensor ops) per epoch, run before that epoch's loops.
    calls: Vec<Vec<usize>>,
    /// Per call: its plan (index into the kernel's plans) and work buffer.
    call_plans: HashMap<usize, (usize, Option<usize>)>,
    /// Per loop: the interval condition it is split on, if any, and whether
    /// it holds on the grid's first points (see [`Gen::emit_loop`]).
    splits: Vec<Option<(usize, bool)>>,
}

impl Schedule {
    /// Whether array value `i` is read from the buffer an earlier loop
    /// stored it to, in a loop of `epoch`.
    fn reloaded(&self, i: usize, epoch: u32) -> bool {
        self.stored.contains_key(&i) && self.epoch[i] < epoch
    }

    /// The interval condition loop `l` is split on, if any: the first (by
    /// instruction) that a select computed in the loop tests, on the
    /// loop's grid, with whether it holds on the grid's first points.
    fn split_condition(&self, func: &Function, l: usize) -> Option<(usize, bool)> {
        let (epoch, grid, ref members) = self.loops[l];
        let mut seen = std::collections::HashSet::new();
        let mut stack: Vec<usize> = members.clone();
        let mut best: Option<(usize, bool)> = None;
        while let Some(i) = stack.pop() {
            let inst = func.insts[i];
            if inst.ty.shape == Shape::Scalar && !matches!(inst.op, Op::Reduce(..)) || !seen.insert(i) {
                continue;
            }
            if on_demand(&inst.op) || is_call(&inst.op) || self.reloaded(i, epoch) {
                continue;
            }
            if let Op::Select(c, ..) = inst.op {
                if let Some((g, first)) = func.interval_condition(c) {
                    if g == grid && best.is_none_or(|(b, _)| c.index() < b) {
                        best = Some((c.index(), first));
                    }
                }
            }
            stack.extend(inst.op.operands().iter().map(|v| v.index()));
        }
        best
    }
}

fn on_demand(op: &Op) -> bool {
    matches!(op, Op::Broadcast(..) | Op::GridCoord(_) | Op::Input(_) | Op::Table(_))
}

/// Ops computed by a library call on whole buffers, between fused loops.
fn is_call(op: &Op) -> bool {
    matches!(op, Op::Dft(..) | Op::Tensor(..))
}

/// Values that already live in a buffer of their own (no store needed).
fn in_buffer(op: &Op) -> bool {
    matches!(op, Op::Input(_) | Op::Table(_)) || is_call(op)
}

fn schedule(func: &Function, wide: &[bool], layout: &mut Layout, plans: &mut Vec<PlanBox>) -> Schedule {
    let n = func.insts.len();
    let storage = func.precision.storage();
    // Library calls read and write their buffers in the storage precision.
    let call_operands: std::collections::HashSet<usize> =
        func.insts.iter().filter(|i| is_call(&i.op)).flat_map(|i| i.op.operands()).map(|v| v.index()).collect();
    let mut epoch = vec![0u32; n];
    for (i, inst) in func.insts.iter().enumerate() {
        epoch[i] = match inst.op {
            Op::Reduce(_, a) => epoch[a.index()] + 1,
            op if is_call(&op) => op.operands().iter().map(|v| epoch[v.index()] + 1).max().unwrap_or(0),
            op => op.operands().iter().map(|v| epoch[v.index()]).max().unwrap_or(0),
        };
    }
    let max_epoch = epoch.iter().copied().max().unwrap_or(0);
    let mut scalars = vec![Vec::new(); max_epoch as usize + 1];
    let mut calls = vec![Vec::new(); max_epoch as usize + 1];
    let mut loop_map: HashMap<(u32, GridId), Vec<usize>> = HashMap::new();
    let roots: Vec<Value> = func.roots();
    for (i, inst) in func.insts.iter().enumerate() {
        match (inst.op, inst.ty.shape) {
            (Op::Reduce(_, a), _) => {
                let Shape::Grid(g) = func.ty(a).shape else {
                    continue;
                };
                loop_map.entry((epoch[a.index()], g)).or_default().push(i);
            }
            (op, _) if is_call(&op) => {
                calls[epoch[i] as usize].push(i);
                // A call reads its operands from memory: values that are
                // otherwise recomputed on demand get a loop that stores them.
                for a in op.operands() {
                    let op = func.insts[a.index()].op;
                    let Shape::Grid(g) = func.ty(a).shape else { continue };
                    if on_demand(&op) && !in_buffer(&op) {
                        let members = loop_map.entry((epoch[a.index()], g)).or_default();
                        if !members.contains(&a.index()) {
                            members.push(a.index());
                        }
                    }
                }
            }
            (op, Shape::Grid(g)) => {
                if !on_demand(&op) || roots.contains(&Value(i as u32)) {
                    loop_map.entry((epoch[i], g)).or_default().push(i);
                }
            }
            (_, Shape::Scalar) => scalars[epoch[i] as usize].push(i),
        }
    }
    let mut loops: Vec<(u32, GridId, Vec<usize>)> = loop_map.into_iter().map(|((e, g), m)| (e, g, m)).collect();
    loops.sort_by_key(|(e, g, _)| (*e, *g));
    // Which arrays must be stored: outputs, and values read by another loop.
    let mut home: HashMap<usize, usize> = HashMap::new();
    for (li, (_, _, members)) in loops.iter().enumerate() {
        for &m in members {
            if !matches!(func.insts[m].op, Op::Reduce(..)) {
                home.insert(m, li);
            }
        }
    }
    let mut stored = HashMap::new();
    let need_store = |v: usize, kind: BufferKind, layout: &mut Layout, stored: &mut HashMap<usize, usize>| {
        if stored.contains_key(&v) && kind == BufferKind::Scratch {
            return;
        }
        let ty = func.insts[v].ty;
        let kept_wide = wide[v] && !call_operands.contains(&v) && !is_call(&func.insts[v].op);
        let precision = if kept_wide { Precision::F64 } else { storage };
        layout.buffers.push(BufferInfo { kind, len: func.len_of(ty.shape), complex: ty.elem == Elem::Complex, precision });
        stored.insert(v, layout.buffers.len() - 1);
    };
    // Outputs of the same value (CSE merges `output a = x` and
    // `output b = x`) share the buffer of the first.
    for (oi, o) in func.outputs.iter().enumerate() {
        let buffer = (func.ty(o.value).shape != Shape::Scalar).then(|| match stored.get(&o.value.index()) {
            Some(&buf) => buf,
            None => {
                need_store(o.value.index(), BufferKind::Output(oi), layout, &mut stored);
                layout.buffers.len() - 1
            }
        });
        layout.outputs.push(buffer);
    }
    for (gi, g) in func.input_grads.iter().enumerate() {
        let buffer = match g.value {
            Some(v) if func.ty(v).shape != Shape::Scalar => Some(match stored.get(&v.index()) {
                Some(&buf) => buf,
                None => {
                    need_store(v.index(), BufferKind::InputGrad(gi), layout, &mut stored);
                    stored[&v.index()]
                }
            }),
            _ => None,
        };
        layout.input_grads.push(buffer);
    }
    let mut call_plans = HashMap::new();
    for &d in calls.iter().flatten() {
        need_store(d, BufferKind::Scratch, layout, &mut stored);
        for a in func.insts[d].op.operands() {
            if !in_buffer(&func.insts[a.index()].op) {
                need_store(a.index(), BufferKind::Scratch, layout, &mut stored);
            }
        }
        let plan = match func.insts[d].op {
            Op::Dft(dft, a) => {
                let time = if dft.inverse { func.insts[d].ty.shape } else { func.ty(a).shape };
                PlanBox::new(dft, func.len_of(time), storage)
            }
            Op::Tensor(t, ..) => PlanBox::Tensor(Box::new(t)),
            _ => unreachable!("only library calls are listed"),
        };
        let work = (plan.work_floats() > 0).then(|| {
            layout.buffers.push(BufferInfo { kind: BufferKind::Scratch, len: plan.work_floats(), complex: false, precision: storage });
            layout.buffers.len() - 1
        });
        plans.push(plan);
        call_plans.insert(d, (plans.len() - 1, work));
    }
    for (li, (_, _, members)) in loops.iter().enumerate() {
        for &m in members {
            for v in func.insts[m].op.operands() {
                if let Some(&h) = home.get(&v.index()) {
                    if h != li && !on_demand(&func.insts[v.index()].op) {
                        need_store(v.index(), BufferKind::Scratch, layout, &mut stored);
                    }
                }
            }
        }
    }
    let mut sched = Schedule { epoch, loops, scalars, stored, calls, call_plans, splits: Vec::new() };
    sched.splits = (0..sched.loops.len()).map(|l| sched.split_condition(func, l)).collect();
    layout.split_loops = sched.splits.iter().flatten().count();
    sched
}

/// A value in generated code: real part, and imaginary part for complex.
#[derive(Clone, Copy)]
struct Cv {
    re: cranelift_codegen::ir::Value,
    im: Option<cranelift_codegen::ir::Value>,
}

impl Cv {
    fn real(re: cranelift_codegen::ir::Value) -> Cv {
        Cv { re, im: None }
    }
}

/// libm functions the kernels may call, resolved to this process's symbols.
mod libm {
    unsafe extern "C" {
        pub fn cbrt(x: f64) -> f64;
        pub fn exp(x: f64) -> f64;
        pub fn log(x: f64) -> f64;
        pub fn sin(x: f64) -> f64;
        pub fn cos(x: f64) -> f64;
        pub fn tan(x: f64) -> f64;
        pub fn tanh(x: f64) -> f64;
        pub fn pow(x: f64, y: f64) -> f64;
        pub fn atan2(y: f64, x: f64) -> f64;
        pub fn sincos(x: f64, s: *mut f64, c: *mut f64);
        pub fn cbrtf(x: f32) -> f32;
        pub fn expf(x: f32) -> f32;
        pub fn logf(x: f32) -> f32;
        pub fn sinf(x: f32) -> f32;
        pub fn cosf(x: f32) -> f32;
        pub fn tanf(x: f32) -> f32;
        pub fn tanhf(x: f32) -> f32;
        pub fn powf(x: f32, y: f32) -> f32;
        pub fn atan2f(y: f32, x: f32) -> f32;
        pub fn sincosf(x: f32, s: *mut f32, c: *mut f32);
    }
}

const MATH1: &[&str] = &["cbrt", "exp", "log", "sin", "cos", "tan", "tanh"];
const MATH2: &[&str] = &["pow", "atan2"];

fn libm_symbols() -> Vec<(&'static str, *const u8)> {
    vec![
        ("cbrt", libm::cbrt as *const u8),
        ("exp", libm::exp as *const u8),
        ("log", libm::log as *const u8),
        ("sin", libm::sin as *const u8),
        ("cos", libm::cos as *const u8),
        ("tan", libm::tan as *const u8),
        ("tanh", libm::tanh as *const u8),
        ("pow", libm::pow as *const u8),
        ("atan2", libm::atan2 as *const u8),
        ("sincos", libm::sincos as *const u8),
        ("cbrtf", libm::cbrtf as *const u8),
        ("expf", libm::expf as *const u8),
        ("logf", libm::logf as *const u8),
        ("sinf", libm::sinf as *const u8),
        ("cosf", libm::cosf as *const u8),
        ("tanf", libm::tanf as *const u8),
        ("tanhf", libm::tanhf as *const u8),
        ("powf", libm::powf as *const u8),
        ("atan2f", libm::atan2f as *const u8),
        ("sincosf", libm::sincosf as *const u8),
        ("gwml_dft_f64", gwml_dft_f64 as *const u8),
        ("gwml_dft_f32", gwml_dft_f32 as *const u8),
        ("gwml_tensor_f64", gwml_tensor_f64 as *const u8),
        ("gwml_tensor_f32", gwml_tensor_f32 as *const u8),
    ]
}

/// Compiles `func` (optimised IR) to a native kernel.
pub fn compile(func: &Function) -> Result<Kernel, CodegenError> {
    compile_with(func, false).map(|(kernel, _)| kernel)
}

/// The machine code `func` compiles to, as Cranelift prints it (its VCode:
/// one block per label, stack slots as `<offset:1>+N(%rsp)`), for `--emit
/// asm`. Compiles the kernel again with the disassembler on, which
/// [`compile`] leaves off because it slows compilation.
pub fn disassemble(func: &Function) -> Result<String, CodegenError> {
    compile_with(func, true).map(|(_, asm)| asm.unwrap_or_default())
}

/// [`compile`], also returning the disassembly when `disasm` is set.
fn compile_with(func: &Function, disasm: bool) -> Result<(Kernel, Option<String>), CodegenError> {
    let err = |e: &dyn fmt::Display| CodegenError(e.to_string());
    if let Some(problem) = f32_range_problem(func) {
        return Err(CodegenError(problem));
    }
    let mut flags = settings::builder();
    flags.set("opt_level", "speed").map_err(|e| err(&e))?;
    flags.set("enable_verifier", if cfg!(debug_assertions) { "true" } else { "false" }).map_err(|e| err(&e))?;
    let isa = cranelift_native::builder().map_err(|e| err(&e))?.finish(settings::Flags::new(flags)).map_err(|e| err(&e))?;
    let mut jb = JITBuilder::with_isa(isa, default_libcall_names());
    for (name, ptr) in libm_symbols() {
        jb.symbol(name, ptr);
    }
    let mut module = JITModule::new(jb);
    let ptr = module.target_config().pointer_type();
    let mut ctx = module.make_context();
    for _ in 0..3 {
        ctx.func.signature.params.push(AbiParam::new(ptr));
    }
    let id = module.declare_function("gwml_kernel", Linkage::Export, &ctx.func.signature).map_err(|e| err(&e))?;
    let mut layout = Layout {
        buffers: Vec::new(),
        scalars: Vec::new(),
        scalar_slots: 0,
        loops: 0,
        split_loops: 0,
        sums_skipped: 0,
        precision: func.precision,
        outputs: Vec::new(),
        input_grads: Vec::new(),
    };
    let storage = func.precision.storage();
    let wide = crate::passes::precision::wide_values(func);
    for (i, input) in func.inputs.iter().enumerate() {
        layout.buffers.push(BufferInfo {
            kind: BufferKind::Input(i),
            len: func.len_of(input.ty.shape),
            complex: input.ty.elem == Elem::Complex,
            precision: storage,
        });
    }
    for (k, t) in func.tables.iter().enumerate() {
        let phase = func.insts.iter().enumerate().any(|(i, inst)| wide[i] && inst.op == Op::Table(k as u32));
        let precision = if phase { Precision::F64 } else { storage };
        layout.buffers.push(BufferInfo { kind: BufferKind::Table(k), len: t.data.len(), complex: false, precision });
    }
    let mut plans = Vec::new();
    let sched = schedule(func, &wide, &mut layout, &mut plans);
    layout.loops = sched.loops.len();
    for r in func.roots() {
        let ty = func.ty(r);
        if ty.shape == Shape::Scalar && !layout.scalars.iter().any(|s| s.value == r) {
            let complex = ty.elem == Elem::Complex;
            layout.scalars.push(ScalarSlot { value: r, slot: layout.scalar_slots, complex });
            layout.scalar_slots += if complex { 2 } else { 1 };
        }
    }
    let mut fbc = FunctionBuilderContext::new();
    let storage_ty = if storage == Precision::F32 { types::F32 } else { types::F64 };
    let math64 = MathEmitter::new(module.isa(), types::F64, func.math);
    let math32 = MathEmitter::new(module.isa(), types::F32, func.math);
    let sums_skipped = {
        let b = FunctionBuilder::new(&mut ctx.func, &mut fbc);
        let mut g = Gen {
            func,
            b,
            module: &mut module,
            layout: &layout,
            sched: &sched,
            vals: HashMap::new(),
            imports: HashMap::new(),
            ptr,
            bufs: Vec::new(),
            ft: storage_ty,
            storage: storage_ty,
            wide,
            vector: None,
            sincos_slot: None,
            sums_skipped: HashSet::new(),
            plans: &plans,
            math64,
            math32,
        };
        g.emit_body()?;
        g.b.seal_all_blocks();
        let cfg = g.module.target_config();
        g.b.finalize(cfg);
        g.sums_skipped.len()
    };
    layout.sums_skipped = sums_skipped;
    let clif = ctx.func.display().to_string();
    let clif_insts = ctx.func.dfg.num_insts();
    ctx.set_disasm(disasm);
    module.define_function(id, &mut ctx).map_err(|e| CodegenError(format!("{e:?}")))?;
    let asm = ctx.compiled_code().and_then(|c| c.vcode.clone());
    module.clear_context(&mut ctx);
    module.finalize_definitions().map_err(|e| err(&e))?;
    let code = module.get_finalized_function(id);
    // SAFETY: `code` is the finalized function with the signature declared above.
    let entry: KernelFn = unsafe { std::mem::transmute::<*const u8, KernelFn>(code) };
    Ok((Kernel { module: Some(module), _plans: plans, entry, layout, clif, clif_insts }, asm))
}

/// In f32, a value (or table) whose largest magnitude at the scene's
/// defaults is outside f32's normal range would flush to 0 or overflow, and
/// a masked division could turn that into a silently wrong result: such a
/// scene is refused, pointing to mixed precision.
fn f32_range_problem(func: &Function) -> Option<String> {
    if func.precision != Precision::F32 {
        return None;
    }
    let (lo, hi) = (f32::MIN_POSITIVE as f64, f32::MAX as f64);
    let out = |m: f64| m > 0.0 && (m < lo || m > hi);
    let what = if let Some(t) = func.tables.iter().position(|t| out(t.data.iter().fold(0.0, |m, x| m.max(x.abs())))) {
        format!("a precomputed table (table {t})")
    } else {
        let magnitudes = crate::passes::precision::default_magnitudes(func)?;
        // Constants (and their broadcasts) are exempt: `masked_div` compares
        // with f64::MAX, which is +inf in f32 and still masks what it should.
        let computed = |i: usize| !matches!(func.insts[i].op, Op::Const(_) | Op::Broadcast(..)) && func.insts[i].ty.elem != Elem::Bool;
        let i = (0..func.insts.len()).find(|i| computed(*i) && out(magnitudes[*i]))?;
        format!("value %{i} (largest magnitude {:e} at the scene's defaults)", magnitudes[i])
    };
    Some(format!(
        "precision f32 cannot hold {what}: it is outside f32's range 1.2e-38..3.4e38; use `precision: mixed`, which computes such values in f64"
    ))
}

struct Gen<'a> {
    func: &'a Function,
    b: FunctionBuilder<'a>,
    module: &'a mut JITModule,
    layout: &'a Layout,
    sched: &'a Schedule,
    /// Scalars and reduction results (valid everywhere after definition).
    vals: HashMap<usize, Cv>,
    imports: HashMap<&'static str, FuncRef>,
    ptr: Type,
    bufs: Vec<cranelift_codegen::ir::Value>,
    /// The float type of the instruction being emitted (the lane type in a
    /// vectorised loop).
    ft: Type,
    /// In a vectorised loop: its lane type, whose values are 128-bit
    /// vectors of that type. In an f32x4 loop of a mixed-precision scene,
    /// the values computed in f64 are *split*: two f64x2 halves per four
    /// lanes ([`Gen::wide_operand`]).
    vector: Option<Type>,
    /// The float type of inputs, outputs and library-call buffers.
    storage: Type,
    /// Per instruction: computed in f64 although the storage is f32
    /// ([`crate::passes::precision::wide_values`]).
    wide: Vec<bool>,
    sincos_slot: Option<cranelift_codegen::ir::StackSlot>,
    /// Sums not accumulated on a side of a split loop (see [`Gen::known_zero`]).
    sums_skipped: HashSet<usize>,
    plans: &'a [PlanBox],
    math64: MathEmitter,
    math32: MathEmitter,
}

/// The most operations (a complex one counting twice) a loop body may have
/// to run two copies per vectorised iteration (see [`Gen::small_body`]).
const SMALL_BODY: usize = 32;

/// Per-iteration state of one loop.
struct LoopCtx {
    epoch: u32,
    index: cranelift_codegen::ir::Value,
    /// Values in the loop's lane type.
    vals: HashMap<usize, Cv>,
    /// In a split loop: values as two f64x2 halves (lanes 0–1, 2–3).
    halves: HashMap<usize, [Cv; 2]>,
    /// An interval condition whose truth is known over the index range
    /// being emitted (see [`Gen::emit_loop`]): selects on it take one side.
    known: Option<(usize, bool)>,
}

/// The accumulators of a loop's reductions: real part, and imaginary part
/// (or, in f32x4 loops, lanes 2–3).
type Accs = Vec<(cranelift_codegen::ir::Value, Option<cranelift_codegen::ir::Value>)>;

impl<'a> Gen<'a> {
    fn f32(&self) -> bool {
        self.ft == types::F32
    }

    /// Whether `v` is the constant +0 (in every lane).
    fn is_zero_const(&self, v: Option<cranelift_codegen::ir::Value>) -> bool {
        use cranelift_codegen::ir::{InstructionData, Opcode, ValueDef};
        let Some(v) = v else { return false };
        let ValueDef::Result(inst, _) = self.b.func.dfg.value_def(v) else { return false };
        match self.b.func.dfg.insts[inst] {
            InstructionData::UnaryIeee64 { imm, .. } => imm.bits() == 0,
            InstructionData::UnaryIeee32 { imm, .. } => imm.bits() == 0,
            InstructionData::Unary { opcode: Opcode::Splat, arg } => self.is_zero_const(Some(arg)),
            _ => false,
        }
    }

    fn fconst(&mut self, x: f64) -> cranelift_codegen::ir::Value {
        let c = if self.f32() { self.b.ins().f32const(x as f32) } else { self.b.ins().f64const(x) };
        self.splat(c)
    }

    /// `x` (converted to float type `ty`) in every lane when emitting a
    /// vectorised loop, else `x` converted.
    fn splat_cv(&mut self, x: Cv, ty: Type) -> Cv {
        let x = self.cast_cv(x, ty);
        Cv { re: self.splat(x.re), im: x.im.map(|im| self.splat(im)) }
    }

    /// `x` in every lane when emitting a vectorised loop, else `x`.
    fn splat(&mut self, x: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        let ty = self.b.func.dfg.value_type(x);
        match self.vector {
            Some(_) if !ty.is_vector() => self.b.ins().splat(vector_of(ty), x),
            _ => x,
        }
    }

    /// A vector whose lane `k` is lane `from(k)` of the concatenation of
    /// the same-typed vectors `a` and `b`.
    fn shuffle_lanes(
        &mut self,
        a: cranelift_codegen::ir::Value,
        b: cranelift_codegen::ir::Value,
        from: impl Fn(usize) -> usize,
    ) -> cranelift_codegen::ir::Value {
        let ty = self.b.func.dfg.value_type(a);
        let size = ty.lane_bits() as usize / 8;
        let bytes: Vec<u8> = (0..ty.lane_count() as usize)
            .flat_map(|k| {
                let lane = from(k);
                (0..size).map(move |i| (lane * size + i) as u8)
            })
            .collect();
        let mask = self.b.func.dfg.immediates.push(bytes.into());
        let (a, b) = (mathlib::bitcast(&mut self.b, types::I8X16, a), mathlib::bitcast(&mut self.b, types::I8X16, b));
        let r = self.b.ins().shuffle(a, b, mask);
        mathlib::bitcast(&mut self.b, ty, r)
    }

    /// `c ? x : y`, for a truth value `c` (a lane mask in vectorised loops).
    fn select(
        &mut self,
        c: cranelift_codegen::ir::Value,
        x: cranelift_codegen::ir::Value,
        y: cranelift_codegen::ir::Value,
    ) -> cranelift_codegen::ir::Value {
        mathlib::select(&mut self.b, c, x, y)
    }

    fn import(&mut self, name: &'static str) -> Result<FuncRef, CodegenError> {
        if let Some(f) = self.imports.get(name) {
            return Ok(*f);
        }
        let ft = self.ft;
        let mut sig = Signature::new(self.module.isa().default_call_conv());
        let base = name.strip_suffix('f').filter(|b| MATH1.contains(b) || MATH2.contains(b) || *b == "sincos").unwrap_or(name);
        if name.starts_with("gwml_dft_") || name.starts_with("gwml_tensor_") {
            // (plan, input, output, work): see `dft::gwml_dft_f64`;
            // (op, a, b, output): see `tensor::gwml_tensor_f64`.
            for _ in 0..4 {
                sig.params.push(AbiParam::new(self.ptr));
            }
        } else if base == "sincos" {
            sig.params.push(AbiParam::new(ft));
            sig.params.push(AbiParam::new(self.ptr));
            sig.params.push(AbiParam::new(self.ptr));
        } else {
            let arity = if MATH2.contains(&base) { 2 } else { 1 };
            for _ in 0..arity {
                sig.params.push(AbiParam::new(ft));
            }
            sig.returns.push(AbiParam::new(ft));
        }
        let id = self.module.declare_function(name, Linkage::Import, &sig).map_err(|e| CodegenError(e.to_string()))?;
        let f = self.module.declare_func_in_func(id, self.b.func);
        self.imports.insert(name, f);
        Ok(f)
    }

    fn call(&mut self, base: &'static str, args: &[cranelift_codegen::ir::Value]) -> Result<cranelift_codegen::ir::Value, CodegenError> {
        let name: &'static str = if self.f32() { f32_name(base) } else { base };
        let f = self.import(name)?;
        let c = self.b.ins().call(f, args);
        Ok(self.b.inst_results(c)[0])
    }

    /// Whether `name` is emitted inline (`mathlib`) rather than called in
    /// libm. The policy follows mathlib's measurements: in f64, inline
    /// sin/cos/sincos/cbrt are as exact as libm and faster, so `exact` uses
    /// them; exp/log/pow are only faster at reduced accuracy. In f32, glibc's
    /// float functions are faster than the inline code except cbrt.
    fn inline_math(&self, name: &str) -> bool {
        self.inline_math_in(name, self.f32())
    }

    /// Whether `name` is emitted inline in f32 (`f32`) or f64 code.
    fn inline_math_in(&self, name: &str, f32: bool) -> bool {
        match (self.func.math, f32) {
            (MathMode::Exact, false) => matches!(name, "sin" | "cos" | "sincos" | "cbrt"),
            (MathMode::Exact, true) => false,
            (_, false) => matches!(name, "sin" | "cos" | "sincos" | "cbrt" | "exp" | "log" | "pow"),
            (_, true) => name == "cbrt",
        }
    }

    /// `name(args)` (f64 names) inline or through libm, per [`Gen::inline_math`].
    fn math(
        &mut self,
        name: &'static str,
        args: &[cranelift_codegen::ir::Value],
    ) -> Result<Vec<cranelift_codegen::ir::Value>, CodegenError> {
        if self.f32() && args.len() == 1 && !self.inline_math(name) && self.inline_math_in(name, false) {
            return self.math_in_f64(name, args[0]);
        }
        if !self.inline_math(name) {
            if name == "sincos" {
                let (s, c) = self.libm_sincos(args[0])?;
                return Ok(vec![s, c]);
            }
            return Ok(vec![self.call(name, args)?]);
        }
        // The inline code's cold path calls libm: import what it may need first.
        let slow_names: &[&'static str] = if name == "sincos" { &["sin", "cos"] } else { std::slice::from_ref(&name) };
        for n in slow_names {
            let n = if self.f32() { f32_name(n) } else { n };
            self.import(n)?;
        }
        let f32 = self.f32();
        let Gen { b, imports, math64, math32, .. } = self;
        let math = if f32 { math32 } else { math64 };
        let imports: &HashMap<&'static str, FuncRef> = imports;
        let mut slow = |fb: &mut FunctionBuilder, n: &'static str, a: &[cranelift_codegen::ir::Value]| slow_call(fb, imports, f32, n, a);
        let slow: &mut SlowPath = &mut slow;
        Ok(match name {
            "sincos" => {
                let (s, c) = math.sincos(b, args[0], slow);
                vec![s, c]
            }
            "sin" => vec![math.sin(b, args[0], slow)],
            "cos" => vec![math.cos(b, args[0], slow)],
            "exp" => vec![math.exp(b, args[0], slow)],
            "log" => vec![math.log(b, args[0], slow)],
            "cbrt" => vec![math.cbrt(b, args[0], slow)],
            "pow" => vec![math.pow(b, args[0], args[1], slow)],
            other => return Err(CodegenError(format!("no inline code for `{other}`"))),
        })
    }

    /// `name(x)` for an f32 (or f32x4) `x` by the inline f64 code, where
    /// f32 has none: promoted (an f32x4 as two f64x2 halves), computed,
    /// and rounded back to f32, so f32 loops with sin, cos, `cis` and (in
    /// `fast`/`fastest`) exp vectorise, and their tails compute the same.
    fn math_in_f64(
        &mut self,
        name: &'static str,
        x: cranelift_codegen::ir::Value,
    ) -> Result<Vec<cranelift_codegen::ir::Value>, CodegenError> {
        let vector = self.vector;
        let parts = match vector {
            Some(_) => {
                let (low, high) = self.promote_halves(x);
                vec![low, high]
            }
            None => vec![self.b.ins().fpromote(types::F64, x)],
        };
        let results: Result<Vec<Vec<_>>, _> = self.in_f64(|g| parts.iter().map(|&p| g.math(name, &[p])).collect());
        let results = results?;
        Ok((0..results[0].len())
            .map(|k| match vector {
                Some(_) => self.demote_pair(results[0][k], results[1][k]),
                None => self.b.ins().fdemote(types::F32, results[0][k]),
            })
            .collect())
    }

    /// `emit(self)` with f64 as the float type (and f64x2 lanes in a
    /// vectorised loop), restoring the current types afterwards.
    fn in_f64<T>(&mut self, emit: impl FnOnce(&mut Self) -> T) -> T {
        let (ft, vector) = (self.ft, self.vector);
        self.ft = types::F64;
        self.vector = vector.map(|_| types::F64);
        let result = emit(self);
        (self.ft, self.vector) = (ft, vector);
        result
    }

    /// The f32x4 of two f64x2 halves (lanes 0–1, then 2–3), rounded.
    fn demote_pair(&mut self, low: cranelift_codegen::ir::Value, high: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        let (low, high) = (self.b.ins().fvdemote(low), self.b.ins().fvdemote(high));
        // Lanes 0–1 of each demoted half.
        self.shuffle_lanes(low, high, |lane| if lane < 2 { lane } else { lane + 2 })
    }

    fn math1(&mut self, name: &'static str, x: cranelift_codegen::ir::Value) -> Result<cranelift_codegen::ir::Value, CodegenError> {
        Ok(self.math(name, &[x])?[0])
    }

    fn sincos(
        &mut self,
        x: cranelift_codegen::ir::Value,
    ) -> Result<(cranelift_codegen::ir::Value, cranelift_codegen::ir::Value), CodegenError> {
        let r = self.math("sincos", &[x])?;
        Ok((r[0], r[1]))
    }

    fn libm_sincos(
        &mut self,
        x: cranelift_codegen::ir::Value,
    ) -> Result<(cranelift_codegen::ir::Value, cranelift_codegen::ir::Value), CodegenError> {
        let slot = match self.sincos_slot {
            Some(s) => s,
            None => {
                let s = self.b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 3));
                self.sincos_slot = Some(s);
                s
            }
        };
        let name = if self.f32() { "sincosf" } else { "sincos" };
        let f = self.import(name)?;
        let size = self.ft.bytes() as i32;
        let ps = self.b.ins().stack_addr(self.ptr, slot, 0);
        let pc = self.b.ins().stack_addr(self.ptr, slot, size);
        self.b.ins().call(f, &[x, ps, pc]);
        let s = self.b.ins().stack_load(self.ptr, self.ft, slot, 0);
        let c = self.b.ins().stack_load(self.ptr, self.ft, slot, size);
        Ok((s, c))
    }

    fn emit_body(&mut self) -> Result<(), CodegenError> {
        let entry = self.b.create_block();
        self.b.append_block_params_for_function_params(entry);
        self.b.switch_to_block(entry);
        let params = self.b.block_params(entry).to_vec();
        let (params_ptr, bufs_ptr, scalars_ptr) = (params[0], params[1], params[2]);
        let flags = MemFlagsData::trusted();
        for k in 0..self.layout.buffers.len() {
            let p = self.b.ins().load(self.ptr, flags, bufs_ptr, (k * self.ptr.bytes() as usize) as i32);
            self.bufs.push(p);
        }
        let max_epoch = self.sched.scalars.len();
        for e in 0..max_epoch {
            for &i in &self.sched.scalars[e] {
                let v = self.scalar_inst(i, params_ptr)?;
                self.vals.insert(i, v);
            }
            for &d in &self.sched.calls[e] {
                self.emit_call(d)?;
            }
            let loops: Vec<usize> = (0..self.sched.loops.len()).filter(|l| self.sched.loops[*l].0 as usize == e).collect();
            for l in loops {
                self.emit_loop(l)?;
            }
        }
        // Scalar results, widened to f64.
        for s in &self.layout.scalars {
            let v = self.vals[&s.value.index()];
            let re = self.widen(v.re);
            self.b.ins().store(flags, re, scalars_ptr, (s.slot * 8) as i32);
            if s.complex {
                let im = v.im.unwrap_or(v.re);
                let im = self.widen(im);
                self.b.ins().store(flags, im, scalars_ptr, (s.slot * 8 + 8) as i32);
            }
        }
        self.b.ins().return_(&[]);
        Ok(())
    }

    /// The buffer holding table `t`.
    fn table_buffer(&self, t: u32) -> usize {
        self.layout.buffers.iter().position(|b| b.kind == BufferKind::Table(t as usize)).expect("tables have buffers")
    }

    /// The buffer an array operand of a library call is read from (for an
    /// input, a table or a call's result, the buffer it lives in).
    fn operand_buffer(&self, a: Value) -> usize {
        match self.func.insts[a.index()].op {
            Op::Input(k) => k as usize,
            Op::Table(t) => self.table_buffer(t),
            _ => self.sched.stored[&a.index()],
        }
    }

    /// Calls the library routine behind instruction `d` (a transform or a
    /// tensor op) on buffers.
    fn emit_call(&mut self, d: usize) -> Result<(), CodegenError> {
        let (plan, work) = self.sched.call_plans[&d];
        let plan = self.b.ins().iconst(self.ptr, self.plans[plan].address());
        let out = self.bufs[self.sched.stored[&d]];
        let (f, args) = match self.func.insts[d].op {
            Op::Dft(_, a) => {
                let f = self.import(if self.storage == types::F32 { "gwml_dft_f32" } else { "gwml_dft_f64" })?;
                let work = self.bufs[work.expect("transforms have work buffers")];
                (f, vec![plan, self.bufs[self.operand_buffer(a)], out, work])
            }
            Op::Tensor(_, _, a, b) => {
                let f = self.import(if self.storage == types::F32 { "gwml_tensor_f32" } else { "gwml_tensor_f64" })?;
                (f, vec![plan, self.bufs[self.operand_buffer(a)], self.bufs[self.operand_buffer(b)], out])
            }
            _ => unreachable!("only library calls are scheduled as calls"),
        };
        self.b.ins().call(f, &args);
        Ok(())
    }

    /// `v` converted to float type `ty` (truth values pass unchanged).
    fn cast(&mut self, v: cranelift_codegen::ir::Value, ty: Type) -> cranelift_codegen::ir::Value {
        match (self.b.func.dfg.value_type(v), ty) {
            (types::F32, types::F64) => self.b.ins().fpromote(types::F64, v),
            (types::F64, types::F32) => self.b.ins().fdemote(types::F32, v),
            _ => v,
        }
    }

    fn cast_cv(&mut self, v: Cv, ty: Type) -> Cv {
        let re = self.cast(v.re, ty);
        Cv { re, im: v.im.map(|im| self.cast(im, ty)) }
    }

    fn widen(&mut self, v: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        self.cast(v, types::F64)
    }

    /// The float type instruction `i` is computed in.
    fn ty_of(&self, i: usize) -> Type {
        if self.wide[i] {
            types::F64
        } else {
            self.storage
        }
    }

    /// The element type of buffer `buf`.
    fn buffer_ty(&self, buf: usize) -> Type {
        if self.layout.buffers[buf].precision == Precision::F64 {
            types::F64
        } else {
            types::F32
        }
    }

    fn scalar_inst(&mut self, i: usize, params_ptr: cranelift_codegen::ir::Value) -> Result<Cv, CodegenError> {
        let inst = self.func.insts[i];
        self.ft = self.ty_of(i);
        Ok(match inst.op {
            Op::Const(b) => Cv::real(self.fconst(f64::from_bits(b))),
            Op::ConstComplex(r, im) => {
                let re = self.fconst(f64::from_bits(r));
                let im = self.fconst(f64::from_bits(im));
                Cv { re, im: Some(im) }
            }
            Op::Param(p) => {
                let v = self.b.ins().load(types::F64, MemFlagsData::trusted(), params_ptr, (p * 8) as i32);
                Cv::real(self.cast(v, self.ft))
            }
            Op::Input(k) => {
                let zero = self.b.ins().iconst(types::I64, 0);
                let v = self.load_elem(k as usize, zero, inst.ty.elem == Elem::Complex);
                self.cast_cv(v, self.ft)
            }
            op => {
                let ft = self.ft;
                let mut ops = Vec::new();
                for v in op.operands() {
                    let x = self.vals[&v.index()];
                    ops.push(self.cast_cv(x, ft));
                }
                self.elementwise(inst, &ops, None)?
            }
        })
    }

    /// Element `index` of buffer `buf`, in the buffer's element type.
    fn load_elem(&mut self, buf: usize, index: cranelift_codegen::ir::Value, complex: bool) -> Cv {
        let ty = self.buffer_ty(buf);
        let size = ty.bytes() as i64 * if complex { 2 } else { 1 };
        let off = self.b.ins().imul_imm_s(index, size);
        let addr = self.b.ins().iadd(self.bufs[buf], off);
        let flags = MemFlagsData::trusted();
        if self.vector.is_some() {
            // Consecutive elements; buffers are only element-aligned.
            let flags = MemFlagsData::new().with_notrap();
            let v = self.b.ins().load(vector_of(ty), flags, addr, 0);
            if !complex {
                return Cv::real(v);
            }
            // Interleaved (re, im) pairs: two vectors, split into even and odd lanes.
            let w = self.b.ins().load(vector_of(ty), flags, addr, 16);
            let re = self.shuffle_lanes(v, w, |k| 2 * k);
            let im = self.shuffle_lanes(v, w, |k| 2 * k + 1);
            return Cv { re, im: Some(im) };
        }
        let re = self.b.ins().load(ty, flags, addr, 0);
        let im = complex.then(|| self.b.ins().load(ty, flags, addr, ty.bytes() as i32));
        Cv { re, im }
    }

    /// Stores `v`, converted to the buffer's element type.
    fn store_elem(&mut self, buf: usize, index: cranelift_codegen::ir::Value, v: Cv, complex: bool) {
        let ty = self.buffer_ty(buf);
        let v = self.cast_cv(v, ty);
        let size = ty.bytes() as i64 * if complex { 2 } else { 1 };
        let off = self.b.ins().imul_imm_s(index, size);
        let addr = self.b.ins().iadd(self.bufs[buf], off);
        if self.vector.is_some() {
            let flags = MemFlagsData::new().with_notrap();
            let Some(im) = v.im.filter(|_| complex) else {
                self.b.ins().store(flags, v.re, addr, 0);
                return;
            };
            // Back to interleaved (re, im) pairs: lane j of the pair of
            // output vectors is lane j/2 of re (even j) or of im (odd j).
            let lanes = (16 / ty.bytes()) as usize;
            let pick = |j: usize| if j.is_multiple_of(2) { j / 2 } else { lanes + j / 2 };
            let first = self.shuffle_lanes(v.re, im, pick);
            let second = self.shuffle_lanes(v.re, im, |k| pick(k + lanes));
            self.b.ins().store(flags, first, addr, 0);
            self.b.ins().store(flags, second, addr, 16);
            return;
        }
        let flags = MemFlagsData::trusted();
        self.b.ins().store(flags, v.re, addr, 0);
        if complex {
            let im = v.im.expect("complex value has an imaginary part");
            self.b.ins().store(flags, im, addr, ty.bytes() as i32);
        }
    }

    /// Emits loop `l`: when [`Gen::vector_lane`] allows, a vectorised loop
    /// over as many whole vectors as fit, then a scalar loop over the rest.
    ///
    /// A loop whose selects test an interval condition (the ISCO cut
    /// `f <= f_isco`, see [`Function::interval_condition`]) is *split*:
    /// the kernel finds the index where the condition changes by a binary
    /// search over the grid (evaluating the condition exactly as the loop
    /// would, so the split agrees with it point by point), and emits the
    /// loop once for each side with the selects resolved. What a select
    /// throws away is then not computed at all: above the ISCO, the
    /// waveform's phase and, since `Builder` sinks the mask through
    /// products, every term of its adjoint. Reductions run on each side
    /// from zero and are added at the end.
    fn emit_loop(&mut self, l: usize) -> Result<(), CodegenError> {
        let (_, grid, ref members) = self.sched.loops[l];
        let len = self.func.grids[grid.0 as usize].len as i64;
        let reductions: Vec<(usize, Reduce, bool)> = members
            .iter()
            .filter_map(|&m| match self.func.insts[m].op {
                Op::Reduce(r, a) => Some((m, r, self.func.ty(a).elem == Elem::Complex)),
                _ => None,
            })
            .collect();
        let (zero, n) = (self.b.ins().iconst(types::I64, 0), self.b.ins().iconst(types::I64, len));
        let mut total: Option<Accs> = None;
        let ranges = match self.sched.splits[l] {
            Some((c, first)) => {
                let k = self.split_point(l, c, first, (zero, n));
                vec![(zero, k, Some((c, first))), (k, n, Some((c, !first)))]
            }
            None => vec![(zero, n, None)],
        };
        let whole = ranges.len() == 1;
        for (from, to, known) in ranges {
            let accs = self.emit_loop_part(l, (from, to), whole.then_some(len), known, &reductions)?;
            total = Some(match total {
                None => accs,
                Some(before) => before
                    .into_iter()
                    .zip(accs)
                    .zip(&reductions)
                    .map(|(((re0, im0), (re1, im1)), &(_, r, _))| {
                        let re = self.reduce_step(r, re0, re1);
                        let im = im0.zip(im1).map(|(a, b)| self.b.ins().fadd(a, b));
                        (re, im)
                    })
                    .collect(),
            });
        }
        for (&(m, ..), (re, im)) in reductions.iter().zip(total.unwrap_or_default()) {
            let ty = self.ty_of(m);
            let re = self.cast(re, ty);
            let im = im.map(|x| self.cast(x, ty));
            self.vals.insert(m, Cv { re, im });
        }
        Ok(())
    }

    /// Loop `l` over indices `from..to` (`len`, when the range is the whole
    /// grid, lets the vector and scalar parts be sized at compile time),
    /// with `known` resolving selects; returns the reductions' partial
    /// results, accumulated from zero (−∞ for a maximum).
    fn emit_loop_part(
        &mut self,
        l: usize,
        (from, to): (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value),
        len: Option<i64>,
        known: Option<(usize, bool)>,
        reductions: &[(usize, Reduce, bool)],
    ) -> Result<Accs, CodegenError> {
        // Accumulators of reductions (f64 even in f32 mode).
        let mut accs: Accs = reductions
            .iter()
            .map(|&(_, r, complex)| {
                let init = if r == Reduce::Max { f64::NEG_INFINITY } else { 0.0 };
                (self.b.ins().f64const(init), complex.then(|| self.b.ins().f64const(0.0)))
            })
            .collect();
        let mut start = from;
        // Whether the scalar loop has nothing left to do, known statically.
        let mut no_tail = len == Some(0);
        if let Some(lane) = self.vector_lane(l) {
            let lanes = (16 / lane.bytes()) as i64;
            let copies = if self.small_body(l, known) { 2 } else { 1 };
            let chunk = lanes * copies as i64;
            // The end of the whole chunks (`copies` vectors each):
            // statically when the range is the grid, else
            // `from + (to − from) & −chunk`.
            let end = match len {
                Some(len) if len < chunk => None,
                Some(len) => {
                    no_tail = len % chunk == 0;
                    Some(self.b.ins().iconst(types::I64, len - len % chunk))
                }
                None => {
                    let count = self.b.ins().isub(to, from);
                    let whole = self.b.ins().band_imm_s(count, -chunk);
                    Some(self.b.ins().iadd(from, whole))
                }
            };
            if let Some(end) = end {
                // Vectorised reductions accumulate in f64x2: complex ones
                // (f64 loops only) in two, re and im; real f32x4 ones in
                // two as well, lanes 0–1 and 2–3, the second in the slot of
                // the imaginary part.
                let init: Vec<_> = accs
                    .iter()
                    .map(|&(re, im)| {
                        let v = self.b.ins().splat(types::F64X2, re);
                        let second = match im {
                            Some(im) => Some(self.b.ins().splat(types::F64X2, im)),
                            None => (lane == types::F32).then_some(v),
                        };
                        (v, second)
                    })
                    .collect();
                self.vector = Some(lane);
                let out = self.emit_loop_range(l, (from, end), (lanes, copies), known, &init);
                self.vector = None;
                let out = out?;
                accs = Vec::new();
                for ((v, second), &(_, r, complex)) in out.into_iter().zip(reductions) {
                    accs.push(match second {
                        Some(im) if complex => (self.horizontal(r, v), Some(self.horizontal(r, im))),
                        Some(high) => {
                            let v = self.reduce_step(r, v, high);
                            (self.horizontal(r, v), None)
                        }
                        None => (self.horizontal(r, v), None),
                    });
                }
                start = end;
            }
        }
        if !no_tail {
            accs = self.emit_loop_range(l, (start, to), (1, 1), known, &accs)?;
        }
        Ok(accs)
    }

    /// The first index of loop `l`'s grid (indices `zero..n`) where
    /// condition `c` no longer has the value `first` it has on the grid's
    /// first points (`n` if none): a binary search, each step evaluating
    /// `c` as the loop's scalar code would.
    fn split_point(
        &mut self,
        l: usize,
        c: usize,
        first: bool,
        (zero, n): (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value),
    ) -> cranelift_codegen::ir::Value {
        let (lo, hi) = (self.b.declare_var(types::I64), self.b.declare_var(types::I64));
        self.b.def_var(lo, zero);
        self.b.def_var(hi, n);
        let (header, body, exit) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let (a, b) = (self.b.use_var(lo), self.b.use_var(hi));
        let done = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, a, b);
        self.b.ins().brif(done, exit, &[], body, &[]);
        self.b.switch_to_block(body);
        let sum = self.b.ins().iadd(a, b);
        let mid = self.b.ins().ushr_imm_u(sum, 1);
        let mut lc = LoopCtx { epoch: self.sched.loops[l].0, index: mid, vals: HashMap::new(), halves: HashMap::new(), known: None };
        let ft = self.ft;
        let holds = self.loop_operand(&mut lc, Value(c as u32)).expect("an interval condition is a comparison").re;
        self.ft = ft;
        let same = if first { holds } else { self.b.ins().icmp_imm_s(IntCC::Equal, holds, 0) };
        let after = self.b.ins().iadd_imm_s(mid, 1);
        let (a2, b2) = (self.b.ins().select(same, after, a), self.b.ins().select(same, b, mid));
        self.b.def_var(lo, a2);
        self.b.def_var(hi, b2);
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(exit);
        self.b.use_var(lo)
    }

    /// One loop of `l`'s members over indices `from..to` in steps of
    /// `step` (the lane count when vectorised), with reduction accumulators
    /// starting at `init` (in member order); returns their final values.
    fn emit_loop_range(
        &mut self,
        l: usize,
        (from, to): (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value),
        (step, copies): (i64, usize),
        known: Option<(usize, bool)>,
        init: &[(cranelift_codegen::ir::Value, Option<cranelift_codegen::ir::Value>)],
    ) -> Result<Accs, CodegenError> {
        let members = self.sched.loops[l].2.clone();
        // Per copy of the body, each reduction's accumulators (all start
        // from `init`: the vectorised part, the only one with copies,
        // starts from the reductions' identities).
        let mut accs: Vec<Vec<(usize, Variable, Option<Variable>)>> = Vec::new();
        for _ in 0..copies {
            let mut copy = Vec::new();
            let reductions = members.iter().filter(|&&m| matches!(self.func.insts[m].op, Op::Reduce(..)));
            for (&m, &(re0, im0)) in reductions.zip(init) {
                let re = self.b.declare_var(self.b.func.dfg.value_type(re0));
                self.b.def_var(re, re0);
                let im = im0.map(|v| {
                    let im = self.b.declare_var(self.b.func.dfg.value_type(v));
                    self.b.def_var(im, v);
                    im
                });
                copy.push((m, re, im));
            }
            accs.push(copy);
        }
        let ivar = self.b.declare_var(types::I64);
        self.b.def_var(ivar, from);
        let header = self.b.create_block();
        let body = self.b.create_block();
        let exit = self.b.create_block();
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let i = self.b.use_var(ivar);
        // The exit is the taken branch and the body the fall-through on
        // purpose. Cranelift's egraph (0.135) hoists loop-invariant values
        // (splats, the scalar PN coefficients) out of a loop only in the
        // loop's blocks it visits before the exit: visiting the exit ends
        // the loop for it. It visits a `brif`'s successors in an order
        // that puts the exit first when the body is the taken branch. With
        // that order, 2 values were hoisted in W1's strain kernel; with
        // this one, 131 (and the kernel runs ~20 % faster).
        let done = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, i, to);
        self.b.ins().brif(done, exit, &[], body, &[]);
        self.b.switch_to_block(body);
        for (copy, accs) in accs.iter().enumerate() {
            let index = if copy == 0 { i } else { self.b.ins().iadd_imm_s(i, step * copy as i64) };
            self.emit_body_copy(l, &members, index, known, accs)?;
        }
        let next = self.b.ins().iadd_imm_s(i, step * copies as i64);
        self.b.def_var(ivar, next);
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(exit);
        // The copies' partial results, combined.
        let mut out: Accs = Vec::new();
        for (k, &(m, re, im)) in accs[0].iter().enumerate() {
            let Op::Reduce(r, a) = self.func.insts[m].op else { unreachable!("accumulators belong to reductions") };
            let complex = self.func.ty(a).elem == Elem::Complex;
            let (mut re, mut im) = (self.b.use_var(re), im.map(|v| self.b.use_var(v)));
            for copy in &accs[1..] {
                let (_, re1, im1) = copy[k];
                let re1 = self.b.use_var(re1);
                re = self.reduce_step(r, re, re1);
                if let (Some(x), Some(im1)) = (im, im1) {
                    let y = self.b.use_var(im1);
                    // The second slot: an imaginary part, or lanes 2–3.
                    im = Some(if complex { self.b.ins().fadd(x, y) } else { self.reduce_step(r, x, y) });
                }
            }
            out.push((re, im));
        }
        Ok(out)
    }

    /// One copy of loop `l`'s body, at `index`, accumulating into `accs`.
    fn emit_body_copy(
        &mut self,
        l: usize,
        members: &[usize],
        index: cranelift_codegen::ir::Value,
        known: Option<(usize, bool)>,
        accs: &[(usize, Variable, Option<Variable>)],
    ) -> Result<(), CodegenError> {
        let mut lc = LoopCtx { epoch: self.sched.loops[l].0, index, vals: HashMap::new(), halves: HashMap::new(), known };
        for &m in members {
            let inst = self.func.insts[m];
            if !self.emitted(m, known) {
                if matches!(inst.op, Op::Reduce(..)) {
                    self.sums_skipped.insert(m);
                }
                continue;
            }
            if let Op::Reduce(r, a) = inst.op {
                let (_, re_var, im_var) = *accs.iter().find(|(k, ..)| *k == m).expect("accumulator declared");
                if self.vector == Some(types::F32) {
                    // f32x4 (real) → two f64x2 halves, into the two accumulators.
                    let [low, high] = self.wide_operand(&mut lc, a)?.map(|h| h.re);
                    let iv = im_var.expect("f32x4 reductions have two accumulators");
                    let acc = self.b.use_var(re_var);
                    let next = self.reduce_step(r, acc, low);
                    self.b.def_var(re_var, next);
                    let acc = self.b.use_var(iv);
                    let next = self.reduce_step(r, acc, high);
                    self.b.def_var(iv, next);
                    continue;
                }
                let x = self.loop_operand(&mut lc, a)?;
                let acc = self.b.use_var(re_var);
                let xr = self.widen(x.re);
                let next = self.reduce_step(r, acc, xr);
                self.b.def_var(re_var, next);
                if let (Some(iv), Some(xi)) = (im_var, x.im) {
                    let acc = self.b.use_var(iv);
                    let xi = self.widen(xi);
                    let next = self.b.ins().fadd(acc, xi);
                    self.b.def_var(iv, next);
                }
                continue;
            }
            if self.split(m) {
                let halves = self.wide_operand(&mut lc, Value(m as u32))?;
                if let Some(&buf) = self.sched.stored.get(&m) {
                    self.store_halves(buf, lc.index, halves, inst.ty.elem == Elem::Complex);
                }
                continue;
            }
            let v = self.loop_operand(&mut lc, Value(m as u32))?;
            if let Some(&buf) = self.sched.stored.get(&m) {
                self.ft = self.buffer_ty(buf);
                let v = if inst.ty.elem == Elem::Bool {
                    // Truth values travel between loops as 1.0 / 0.0.
                    let (one, zero) = (self.fconst(1.0), self.fconst(0.0));
                    Cv::real(self.select(v.re, one, zero))
                } else {
                    v
                };
                self.store_elem(buf, lc.index, v, inst.ty.elem == Elem::Complex);
            }
        }
        Ok(())
    }

    /// One step of reduction `r`: `acc + x` or `max(acc, x)`.
    fn reduce_step(
        &mut self,
        r: Reduce,
        acc: cranelift_codegen::ir::Value,
        x: cranelift_codegen::ir::Value,
    ) -> cranelift_codegen::ir::Value {
        if r == Reduce::Max {
            self.b.ins().fmax(acc, x)
        } else {
            self.b.ins().fadd(acc, x)
        }
    }

    /// Reduction `r` over the two lanes of an f64x2.
    fn horizontal(&mut self, r: Reduce, v: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        let (a, b) = (self.b.ins().extractlane(v, 0), self.b.ins().extractlane(v, 1));
        self.reduce_step(r, a, b)
    }

    /// Lanes 0–1 and 2–3 of an f32x4, each promoted to an f64x2.
    fn promote_halves(&mut self, x: cranelift_codegen::ir::Value) -> (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value) {
        let low = self.b.ins().fvpromote_low(x);
        let swapped = self.shuffle_lanes(x, x, |k| (k + 2) % 4);
        (low, self.b.ins().fvpromote_low(swapped))
    }

    /// The lane type loop `l` can be vectorised in (128-bit vectors: f64x2
    /// or f32x4), or `None` to keep it scalar. Vectorised loops hold real
    /// and complex values and truth values of the lane type, computed by
    /// arithmetic, comparisons, selects, `sqrt`, `abs`, `min`/`max`,
    /// complex parts, small integer powers and sin, cos, `cis` and
    /// (`fast`/`fastest`) exp (no library calls; in f32 through the f64
    /// code, [`Gen::math_in_f64`]), reading buffers of that type (complex
    /// ones are de-interleaved). In mixed precision, an f32x4 loop also
    /// holds the values computed in f64, split in two f64x2 halves (not
    /// truth values or selects), and reads and writes buffers of either
    /// type. Reductions accumulate in f64x2: two accumulators for real
    /// f32x4 ones; complex reductions only in f64x2 loops.
    fn vector_lane(&self, l: usize) -> Option<Type> {
        let mut lanes = vec![self.storage];
        if self.storage != types::F64 {
            // Mixed precision: a loop of f64 values only (say a complex
            // reduction of a phase) may still vectorise in f64x2.
            lanes.push(types::F64);
        }
        lanes.into_iter().find(|&lane| self.vectorises_in(l, lane))
    }

    /// Whether loop `l` can be vectorised with `lane`-typed vectors (see
    /// [`Gen::vector_lane`]).
    fn vectorises_in(&self, l: usize, lane: Type) -> bool {
        let (epoch, _, ref members) = self.sched.loops[l];
        let mut seen = std::collections::HashSet::new();
        for &m in members {
            let ok = match self.func.insts[m].op {
                // f32x4 reductions use the imaginary accumulator for lanes 2–3.
                Op::Reduce(_, a) => {
                    (lane == types::F64 || self.func.ty(a).elem != Elem::Complex) && self.vectorisable(a.index(), lane, epoch, &mut seen)
                }
                _ => {
                    self.vectorisable(m, lane, epoch, &mut seen) && self.sched.stored.get(&m).is_none_or(|&buf| self.buffer_fits(buf, lane))
                }
            };
            if !ok {
                return false;
            }
        }
        !members.is_empty()
    }

    /// Whether value `i`, and what a loop of `epoch` computes it from, can
    /// be emitted with `lane`-typed vectors (see [`Gen::vector_lane`]).
    fn vectorisable(&self, i: usize, lane: Type, epoch: u32, seen: &mut std::collections::HashSet<usize>) -> bool {
        if !seen.insert(i) {
            return true;
        }
        let inst = self.func.insts[i];
        if inst.ty.shape == Shape::Scalar {
            return inst.ty.elem != Elem::Bool;
        }
        // Split into f64x2 halves in an f32x4 loop (mixed precision).
        let split = lane == types::F32 && self.wide[i];
        if split && (inst.ty.elem == Elem::Bool || matches!(inst.op, Op::Select(..))) {
            return false;
        }
        if self.ty_of(i) != lane && !split {
            return false;
        }
        let buffer_ok = |buf: usize| self.buffer_fits(buf, lane);
        let mut operands_ok = || inst.op.operands().iter().all(|o| self.vectorisable(o.index(), lane, epoch, seen));
        match inst.op {
            Op::Broadcast(..) => operands_ok(),
            Op::GridCoord(_) => true,
            Op::Input(k) => buffer_ok(k as usize),
            Op::Table(t) => buffer_ok(self.table_buffer(t)),
            Op::Dft(..) | Op::Tensor(..) => buffer_ok(self.sched.stored[&i]),
            _ if self.reloaded(i, epoch) => buffer_ok(self.sched.stored[&i]),
            Op::Unary(u, _) => {
                let inline = matches!(
                    u,
                    UnOp::Neg | UnOp::Sqrt | UnOp::Abs | UnOp::Sign | UnOp::Re | UnOp::Im | UnOp::Conj | UnOp::Abs2 | UnOp::ToComplex
                );
                // The inline f64 sin/cos/sincos and exp take f64x2 (a
                // complex exp needs both exp and sincos); f32x4 goes
                // through them as two promoted halves.
                let f64_math = |name| self.inline_math_in(name, false);
                let math = match u {
                    UnOp::Sin => f64_math("sin"),
                    UnOp::Cos => f64_math("cos"),
                    UnOp::Cis => f64_math("sincos"),
                    UnOp::Exp => f64_math("exp") && f64_math("sincos"),
                    _ => false,
                };
                (inline || math) && operands_ok()
            }
            Op::Binary(op, ..) => !matches!(op, BinOp::Pow | BinOp::Atan2) && operands_ok(),
            Op::PowConst(_, bits) => pow_const_is_inline(f64::from_bits(bits)) && operands_ok(),
            Op::Select(..) => operands_ok(),
            _ => false,
        }
    }

    /// Whether a `lane`-typed vector loop can read and write buffer `buf`:
    /// one of the lane type, or any in an f32x4 loop (whose split values
    /// convert between f32 and f64).
    fn buffer_fits(&self, buf: usize, lane: Type) -> bool {
        lane == types::F32 || self.buffer_ty(buf) == lane
    }

    /// The value of `v` inside the current loop iteration, in the loop's
    /// lane type (split values are rounded from their f64 halves).
    fn loop_operand(&mut self, lc: &mut LoopCtx, v: Value) -> Result<Cv, CodegenError> {
        let i = v.index();
        if let Some(x) = lc.vals.get(&i) {
            return Ok(*x);
        }
        let inst = self.func.insts[i];
        if inst.ty.shape == Shape::Scalar {
            let x = self.vals[&i];
            return Ok(match self.vector {
                Some(lane) => self.splat_cv(x, lane),
                None => x,
            });
        }
        if let Some(taken) = self.resolved(lc.known, i) {
            let x = self.loop_operand(lc, taken)?;
            lc.vals.insert(i, x);
            return Ok(x);
        }
        if let Op::Binary(BinOp::Sub, a, b) = inst.op {
            if self.known_constant(lc.known, b.index()) == Some((0, 0)) {
                // x − (+0) is x, bit for bit (also for x = −0).
                let x = self.loop_operand(lc, a)?;
                let x = self.cast_cv(x, self.ty_of(i));
                lc.vals.insert(i, x);
                return Ok(x);
            }
        }
        if self.split(i) {
            let halves = self.wide_operand(lc, v)?;
            let x = self.demote_cv(halves);
            lc.vals.insert(i, x);
            return Ok(x);
        }
        let ty = self.ty_of(i);
        let x = match inst.op {
            Op::Broadcast(a, _) => {
                let x = self.vals[&a.index()];
                self.splat_cv(x, ty)
            }
            Op::GridCoord(g) => {
                let x = match self.vector {
                    // f32x4: lanes 0–1 and 2–3 as two f64x2, rounded to f32.
                    Some(types::F32) => {
                        let (low, high) = (self.grid_coords(g, lc.index, 0), self.grid_coords(g, lc.index, 2));
                        self.demote_pair(low, high)
                    }
                    _ => {
                        let x = self.grid_coords(g, lc.index, 0);
                        self.cast(x, ty)
                    }
                };
                Cv::real(x)
            }
            Op::Input(_) | Op::Table(_) | Op::Dft(..) | Op::Tensor(..) => {
                let x = self.load_lanes(self.operand_buffer(v), lc.index, inst.ty.elem == Elem::Complex);
                self.cast_cv(x, ty)
            }
            // Stored by an earlier loop: reload instead of recomputing.
            _ if self.reloaded(i, lc.epoch) => {
                let buf = self.sched.stored[&i];
                let v = self.load_lanes(buf, lc.index, inst.ty.elem == Elem::Complex);
                if inst.ty.elem == Elem::Bool {
                    self.ft = self.vector.unwrap_or_else(|| self.buffer_ty(buf));
                    let zero = self.fconst(0.0);
                    Cv::real(self.b.ins().fcmp(FloatCC::NotEqual, v.re, zero))
                } else {
                    self.cast_cv(v, ty)
                }
            }
            op => {
                let mut ops = Vec::new();
                for o in op.operands() {
                    ops.push(self.loop_operand(lc, o)?);
                }
                for o in &mut ops {
                    *o = self.cast_cv(*o, ty);
                }
                self.ft = ty;
                self.elementwise(inst, &ops, Some(lc))?
            }
        };
        lc.vals.insert(i, x);
        Ok(x)
    }

    /// The side a select `i` takes when its condition is known over the
    /// range being emitted.
    fn resolved(&self, known: Option<(usize, bool)>, i: usize) -> Option<Value> {
        let (c, holds) = known?;
        match self.func.insts[i].op {
            Op::Select(k, a, b) if k.index() == c => Some(if holds { a } else { b }),
            _ => None,
        }
    }

    /// The value every element of array `i` statically holds in the range
    /// being emitted, as (re, im) bit patterns: a broadcast constant, or a
    /// select the known condition resolves to one.
    fn known_constant(&self, known: Option<(usize, bool)>, i: usize) -> Option<(u64, u64)> {
        if let Some(taken) = self.resolved(known, i) {
            return self.known_constant(known, taken.index());
        }
        match self.func.insts[i].op {
            Op::Broadcast(a, _) => match self.func.insts[a.index()].op {
                Op::Const(x) => Some((x, 0)),
                Op::ConstComplex(re, im) => Some((re, im)),
                _ => None,
            },
            _ => None,
        }
    }

    /// Whether loop member `m` is emitted in a range where `known` holds
    /// (the whole loop when `None`): with a condition known, a sum whose
    /// terms it makes +0 is skipped, and of the rest only what is stored
    /// (and what that needs, on demand): the rest may be thrown away.
    fn emitted(&self, m: usize, known: Option<(usize, bool)>) -> bool {
        match self.func.insts[m].op {
            Op::Reduce(r, a) => !(r == Reduce::Sum && self.known_zero(known, a.index())),
            _ => known.is_none() || self.sched.stored.contains_key(&m),
        }
    }

    /// Whether loop `l`'s body, with `known` resolving selects, is a few
    /// arithmetic operations (at most [`SMALL_BODY`], no function calls
    /// or inline transcendentals). Such a loop is bound by the latency of
    /// its reductions' accumulators (an f64x2 add every 4 cycles): its
    /// vectorised part runs two copies of the body per iteration, each
    /// with its own accumulators, added at the end.
    fn small_body(&self, l: usize, known: Option<(usize, bool)>) -> bool {
        let members = &self.sched.loops[l].2;
        let mut seen = HashSet::new();
        let mut cost = 0;
        let mut stack: Vec<usize> = Vec::new();
        for &m in members.iter().filter(|&&m| self.emitted(m, known)) {
            stack.push(match self.func.insts[m].op {
                Op::Reduce(_, a) => a.index(),
                _ => m,
            });
        }
        while let Some(i) = stack.pop() {
            let inst = self.func.insts[i];
            if inst.ty.shape == Shape::Scalar || !seen.insert(i) {
                continue;
            }
            if let Some(taken) = self.resolved(known, i) {
                stack.push(taken.index());
                continue;
            }
            if matches!(inst.op, Op::Broadcast(..)) {
                continue; // hoisted out of the loop
            }
            cost += if inst.ty.elem == Elem::Complex { 2 } else { 1 };
            match inst.op {
                Op::GridCoord(_) | Op::Input(_) | Op::Table(_) | Op::Dft(..) | Op::Tensor(..) => {}
                _ if self.reloaded(i, self.sched.loops[l].0) => {}
                Op::Unary(UnOp::Neg | UnOp::Abs | UnOp::Re | UnOp::Im | UnOp::Conj | UnOp::Abs2 | UnOp::ToComplex, a) => {
                    stack.push(a.index())
                }
                Op::Binary(
                    BinOp::Add
                    | BinOp::Sub
                    | BinOp::Mul
                    | BinOp::Div
                    | BinOp::Min
                    | BinOp::Max
                    | BinOp::Lt
                    | BinOp::Le
                    | BinOp::Gt
                    | BinOp::Ge,
                    a,
                    b,
                ) => stack.extend([a.index(), b.index()]),
                Op::Select(c, a, b) => stack.extend([c.index(), a.index(), b.index()]),
                _ => return false,
            }
        }
        cost <= SMALL_BODY
    }

    /// Whether array `i` is +0 (and +0i) over the range being emitted, so
    /// that `x − i` is exactly `x` and a sum gains nothing from it (a sum
    /// starts at +0, and never reaches −0, so adding ±0 leaves it as is).
    fn known_zero(&self, known: Option<(usize, bool)>, i: usize) -> bool {
        self.known_constant(known, i).is_some_and(|(re, im)| f64::from_bits(re) == 0.0 && f64::from_bits(im) == 0.0)
    }

    /// Whether array value `i` is split in the loop being emitted: computed
    /// in f64 (mixed precision) inside an f32x4 loop.
    fn split(&self, i: usize) -> bool {
        self.vector == Some(types::F32) && self.wide[i]
    }

    /// Whether array value `i` is read from the buffer an earlier loop
    /// stored it to, in a loop of `epoch`.
    fn reloaded(&self, i: usize, epoch: u32) -> bool {
        self.sched.reloaded(i, epoch)
    }

    /// In a split loop: value `v` as two f64x2 halves, lanes 0–1 and 2–3
    /// (a value computed in f32 is promoted, a scalar splat). Each f64
    /// operation is emitted once per half, as the scalar tail would
    /// compute it lane by lane.
    fn wide_operand(&mut self, lc: &mut LoopCtx, v: Value) -> Result<[Cv; 2], CodegenError> {
        let i = v.index();
        if let Some(h) = lc.halves.get(&i) {
            return Ok(*h);
        }
        let inst = self.func.insts[i];
        let halves = if let Some(taken) = self.resolved(lc.known, i) {
            self.wide_operand(lc, taken)?
        } else if inst.ty.shape == Shape::Scalar {
            let x = self.vals[&i];
            let x = self.in_f64(|g| g.splat_cv(x, types::F64));
            [x, x]
        } else if !self.wide[i] {
            let x = self.loop_operand(lc, v)?;
            self.promote_cv(x)
        } else {
            match inst.op {
                Op::Broadcast(a, _) => self.wide_operand(lc, a)?,
                Op::GridCoord(g) => [0, 2].map(|first| Cv::real(self.grid_coords(g, lc.index, first))),
                Op::Input(_) | Op::Table(_) | Op::Dft(..) | Op::Tensor(..) => {
                    self.load_halves(self.operand_buffer(v), lc.index, inst.ty.elem == Elem::Complex)
                }
                _ if self.reloaded(i, lc.epoch) => self.load_halves(self.sched.stored[&i], lc.index, inst.ty.elem == Elem::Complex),
                op => {
                    let mut ops = Vec::new();
                    for o in op.operands() {
                        ops.push(self.wide_operand(lc, o)?);
                    }
                    let mut halves = Vec::new();
                    for h in 0..2 {
                        let ops: Vec<Cv> = ops.iter().map(|o| o[h]).collect();
                        halves.push(self.in_f64(|g| g.elementwise(inst, &ops, None))?);
                    }
                    [halves[0], halves[1]]
                }
            }
        };
        lc.halves.insert(i, halves);
        Ok(halves)
    }

    /// Coordinates `index + first` (and `+ 1` in lane 1 of a vectorised
    /// loop's f64x2) of grid `g`, `start + k · step` in f64 (exact in `k`:
    /// indices are far below 2^53).
    fn grid_coords(&mut self, g: GridId, index: cranelift_codegen::ir::Value, first: i64) -> cranelift_codegen::ir::Value {
        let grid = &self.func.grids[g.0 as usize];
        let (start, step) = (grid.start, grid.step);
        let fi = self.b.ins().fcvt_from_sint(types::F64, index);
        let (st, s0) = (self.b.ins().f64const(step), self.b.ins().f64const(start));
        let (fi, st, s0) = match self.vector {
            Some(_) => {
                let base = self.b.ins().splat(types::F64X2, fi);
                let (k0, k1) = (self.b.ins().f64const(first as f64), self.b.ins().f64const(first as f64 + 1.0));
                let k = self.b.ins().scalar_to_vector(types::F64X2, k0);
                let k = self.b.ins().insertlane(k, k1, 1);
                let fi = self.b.ins().fadd(base, k);
                (fi, self.b.ins().splat(types::F64X2, st), self.b.ins().splat(types::F64X2, s0))
            }
            None => (fi, st, s0),
        };
        let prod = self.b.ins().fmul(fi, st);
        self.b.ins().fadd(s0, prod)
    }

    /// Elements `index..` of buffer `buf` in the loop's lane type: as
    /// [`Gen::load_elem`], except that a split loop reads an f64 buffer as
    /// two f64x2 halves rounded to one f32x4.
    fn load_lanes(&mut self, buf: usize, index: cranelift_codegen::ir::Value, complex: bool) -> Cv {
        if self.vector == Some(types::F32) && self.buffer_ty(buf) == types::F64 {
            let halves = self.load_halves(buf, index, complex);
            return self.demote_cv(halves);
        }
        self.load_elem(buf, index, complex)
    }

    /// In a split loop: four elements from `index` of buffer `buf` as two
    /// f64x2 halves (an f32 buffer's f32x4 promoted).
    fn load_halves(&mut self, buf: usize, index: cranelift_codegen::ir::Value, complex: bool) -> [Cv; 2] {
        if self.buffer_ty(buf) == types::F32 {
            let x = self.load_elem(buf, index, complex);
            return self.promote_cv(x);
        }
        self.in_f64(|g| {
            let second = g.b.ins().iadd_imm_s(index, 2);
            [g.load_elem(buf, index, complex), g.load_elem(buf, second, complex)]
        })
    }

    /// In a split loop: stores the halves of four elements from `index` to
    /// buffer `buf` (rounded to one f32x4 for an f32 buffer).
    fn store_halves(&mut self, buf: usize, index: cranelift_codegen::ir::Value, halves: [Cv; 2], complex: bool) {
        if self.buffer_ty(buf) == types::F32 {
            let x = self.demote_cv(halves);
            return self.store_elem(buf, index, x, complex);
        }
        self.in_f64(|g| {
            let second = g.b.ins().iadd_imm_s(index, 2);
            g.store_elem(buf, index, halves[0], complex);
            g.store_elem(buf, second, halves[1], complex);
        })
    }

    /// An f32x4 value as two f64x2 halves.
    fn promote_cv(&mut self, x: Cv) -> [Cv; 2] {
        let (re_low, re_high) = self.promote_halves(x.re);
        let im = x.im.map(|im| self.promote_halves(im));
        [Cv { re: re_low, im: im.map(|h| h.0) }, Cv { re: re_high, im: im.map(|h| h.1) }]
    }

    /// Two f64x2 halves as one f32x4 value, rounded.
    fn demote_cv(&mut self, [low, high]: [Cv; 2]) -> Cv {
        let re = self.demote_pair(low.re, high.re);
        let im = match (low.im, high.im) {
            (Some(a), Some(b)) => Some(self.demote_pair(a, b)),
            _ => None,
        };
        Cv { re, im }
    }

    /// Emits one elementwise operation on already-computed operands.
    fn elementwise(&mut self, inst: Inst, ops: &[Cv], _lc: Option<&mut LoopCtx>) -> Result<Cv, CodegenError> {
        let ins_complex = |k: usize| ops.get(k).is_some_and(|o| o.im.is_some());
        Ok(match inst.op {
            Op::Unary(u, _) => {
                let a = ops[0];
                let x = a.re;
                match u {
                    UnOp::Neg => Cv { re: self.b.ins().fneg(x), im: a.im.map(|i| self.b.ins().fneg(i)) },
                    UnOp::Sqrt => Cv::real(self.b.ins().sqrt(x)),
                    UnOp::Cbrt => Cv::real(self.math1("cbrt", x)?),
                    UnOp::Exp if ins_complex(0) => {
                        let e = self.math1("exp", x)?;
                        let (s, c) = self.sincos(a.im.expect("complex"))?;
                        Cv { re: self.b.ins().fmul(e, c), im: Some(self.b.ins().fmul(e, s)) }
                    }
                    UnOp::Exp => Cv::real(self.math1("exp", x)?),
                    UnOp::Log => Cv::real(self.math1("log", x)?),
                    UnOp::Sin => Cv::real(self.math1("sin", x)?),
                    UnOp::Cos => Cv::real(self.math1("cos", x)?),
                    UnOp::Tan => Cv::real(self.call("tan", &[x])?),
                    UnOp::Tanh => Cv::real(self.call("tanh", &[x])?),
                    UnOp::Abs if ins_complex(0) => {
                        let im = a.im.expect("complex");
                        let rr = self.b.ins().fmul(x, x);
                        let ii = self.b.ins().fmul(im, im);
                        let s = self.b.ins().fadd(rr, ii);
                        Cv::real(self.b.ins().sqrt(s))
                    }
                    UnOp::Abs => Cv::real(self.b.ins().fabs(x)),
                    UnOp::Sign => {
                        // 1 for x > 0, -1 for x < 0, x * 0 otherwise (keeps ±0 and NaN).
                        let one = self.fconst(1.0);
                        let mone = self.fconst(-1.0);
                        let zero = self.fconst(0.0);
                        let z = self.b.ins().fmul(x, zero);
                        let pos = self.b.ins().fcmp(FloatCC::GreaterThan, x, zero);
                        let neg = self.b.ins().fcmp(FloatCC::LessThan, x, zero);
                        let t = self.select(neg, mone, z);
                        Cv::real(self.select(pos, one, t))
                    }
                    UnOp::Re => Cv::real(x),
                    UnOp::Im => Cv::real(a.im.expect("complex")),
                    UnOp::Conj => Cv { re: x, im: a.im.map(|i| self.b.ins().fneg(i)) },
                    UnOp::Abs2 => {
                        let im = a.im.expect("complex");
                        let rr = self.b.ins().fmul(x, x);
                        let ii = self.b.ins().fmul(im, im);
                        Cv::real(self.b.ins().fadd(rr, ii))
                    }
                    UnOp::Cis => {
                        let (s, c) = self.sincos(x)?;
                        Cv { re: c, im: Some(s) }
                    }
                    UnOp::ToComplex => Cv { re: x, im: Some(self.fconst(0.0)) },
                }
            }
            Op::Binary(op, _, _) => {
                let (a, c) = (ops[0], ops[1]);
                let complex = a.im.is_some();
                match op {
                    BinOp::Add => Cv {
                        re: self.b.ins().fadd(a.re, c.re),
                        im: complex.then(|| self.b.ins().fadd(a.im.expect("complex"), c.im.expect("complex"))),
                    },
                    BinOp::Sub => Cv {
                        re: self.b.ins().fsub(a.re, c.re),
                        im: complex.then(|| self.b.ins().fsub(a.im.expect("complex"), c.im.expect("complex"))),
                    },
                    // A real factor (one whose imaginary part is the constant
                    // +0, e.g. `tocomplex x`) scales both parts: the same
                    // values as the full product, up to the sign of a zero.
                    BinOp::Mul if complex && (self.is_zero_const(a.im) || self.is_zero_const(c.im)) => {
                        let (z, x) = if self.is_zero_const(c.im) { (a, c.re) } else { (c, a.re) };
                        Cv { re: self.b.ins().fmul(z.re, x), im: Some(self.b.ins().fmul(z.im.expect("complex"), x)) }
                    }
                    BinOp::Mul if complex => {
                        let (ar, ai, cr, ci) = (a.re, a.im.expect("complex"), c.re, c.im.expect("complex"));
                        let rr = self.b.ins().fmul(ar, cr);
                        let ii = self.b.ins().fmul(ai, ci);
                        let ri = self.b.ins().fmul(ar, ci);
                        let ir = self.b.ins().fmul(ai, cr);
                        Cv { re: self.b.ins().fsub(rr, ii), im: Some(self.b.ins().fadd(ri, ir)) }
                    }
                    BinOp::Mul => Cv::real(self.b.ins().fmul(a.re, c.re)),
                    BinOp::Div if complex => {
                        // a * conj(c) / |c|^2, as in eval::complex_div.
                        let (ar, ai, cr, ci) = (a.re, a.im.expect("complex"), c.re, c.im.expect("complex"));
                        let cc = self.b.ins().fmul(cr, cr);
                        let dd = self.b.ins().fmul(ci, ci);
                        let d = self.b.ins().fadd(cc, dd);
                        let rr = self.b.ins().fmul(ar, cr);
                        let ii = self.b.ins().fmul(ai, ci);
                        let num_re = self.b.ins().fadd(rr, ii);
                        let ir = self.b.ins().fmul(ai, cr);
                        let ri = self.b.ins().fmul(ar, ci);
                        let num_im = self.b.ins().fsub(ir, ri);
                        Cv { re: self.b.ins().fdiv(num_re, d), im: Some(self.b.ins().fdiv(num_im, d)) }
                    }
                    BinOp::Div => Cv::real(self.b.ins().fdiv(a.re, c.re)),
                    BinOp::Pow => Cv::real(self.math("pow", &[a.re, c.re])?[0]),
                    BinOp::Atan2 => Cv::real(self.call("atan2", &[a.re, c.re])?),
                    BinOp::Min => Cv::real(self.b.ins().fmin(a.re, c.re)),
                    BinOp::Max => Cv::real(self.b.ins().fmax(a.re, c.re)),
                    BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
                        let cc = match op {
                            BinOp::Lt => FloatCC::LessThan,
                            BinOp::Le => FloatCC::LessThanOrEqual,
                            BinOp::Gt => FloatCC::GreaterThan,
                            _ => FloatCC::GreaterThanOrEqual,
                        };
                        Cv::real(self.b.ins().fcmp(cc, a.re, c.re))
                    }
                    BinOp::Eq | BinOp::Ne => {
                        let cc = if op == BinOp::Eq { FloatCC::Equal } else { FloatCC::NotEqual };
                        let r = self.b.ins().fcmp(cc, a.re, c.re);
                        match (a.im, c.im) {
                            (Some(ai), Some(ci)) => {
                                let i = self.b.ins().fcmp(cc, ai, ci);
                                Cv::real(if op == BinOp::Eq { self.b.ins().band(r, i) } else { self.b.ins().bor(r, i) })
                            }
                            _ => Cv::real(r),
                        }
                    }
                    BinOp::Complex => Cv { re: a.re, im: Some(c.re) },
                }
            }
            Op::PowConst(_, bits) => Cv::real(self.pow_const(ops[0].re, f64::from_bits(bits))?),
            Op::Select(..) => {
                let (c, x, y) = (ops[0].re, ops[1], ops[2]);
                let re = self.select(c, x.re, y.re);
                let im = match (x.im, y.im) {
                    (Some(xi), Some(yi)) => Some(self.select(c, xi, yi)),
                    _ => None,
                };
                Cv { re, im }
            }
            Op::Broadcast(..) => ops[0],
            other => return Err(CodegenError(format!("unexpected operation in elementwise code: {other:?}"))),
        })
    }

    /// `x^c`: repeated multiplication for small integer c, sqrt for ±1/2,
    /// otherwise a call to `pow`.
    fn pow_const(&mut self, x: cranelift_codegen::ir::Value, c: f64) -> Result<cranelift_codegen::ir::Value, CodegenError> {
        if pow_const_is_small_integer(c) {
            let n = c.abs() as u32;
            let mut result: Option<cranelift_codegen::ir::Value> = None;
            let mut base = x;
            let mut k = n;
            while k > 0 {
                if k & 1 == 1 {
                    result = Some(match result {
                        Some(r) => self.b.ins().fmul(r, base),
                        None => base,
                    });
                }
                k >>= 1;
                if k > 0 {
                    base = self.b.ins().fmul(base, base);
                }
            }
            let r = match result {
                Some(r) => r,
                None => self.fconst(1.0),
            };
            return Ok(if c < 0.0 {
                let one = self.fconst(1.0);
                self.b.ins().fdiv(one, r)
            } else {
                r
            });
        }
        if c == 0.5 {
            return Ok(self.b.ins().sqrt(x));
        }
        let e = self.fconst(c);
        Ok(self.math("pow", &[x, e])?[0])
    }
}

/// The 128-bit vector of lane type `ty` (f64x2 or f32x4).
fn vector_of(ty: Type) -> Type {
    ty.by(16 / ty.bytes()).expect("a 128-bit vector of a float type")
}

/// `x^c` by repeated multiplication (see [`Gen::pow_const`]).
fn pow_const_is_small_integer(c: f64) -> bool {
    c == c.trunc() && c.abs() <= 16.0
}

/// `x^c` without a `pow` call: repeated multiplication or `sqrt`.
fn pow_const_is_inline(c: f64) -> bool {
    pow_const_is_small_integer(c) || c == 0.5
}

/// Calls libm's `name` (f64 name) from the inline code's cold path; the
/// functions were imported beforehand (see [`Gen::math`]).
fn slow_call(
    fb: &mut FunctionBuilder,
    imports: &HashMap<&'static str, FuncRef>,
    f32: bool,
    name: &'static str,
    args: &[cranelift_codegen::ir::Value],
) -> Vec<cranelift_codegen::ir::Value> {
    if name == "sincos" {
        let s = slow_call(fb, imports, f32, "sin", args)[0];
        let c = slow_call(fb, imports, f32, "cos", args)[0];
        return vec![s, c];
    }
    let f = imports[if f32 { f32_name(name) } else { name }];
    let call = fb.ins().call(f, args);
    fb.inst_results(call).to_vec()
}

fn f32_name(base: &'static str) -> &'static str {
    match base {
        "cbrt" => "cbrtf",
        "exp" => "expf",
        "log" => "logf",
        "sin" => "sinf",
        "cos" => "cosf",
        "tan" => "tanf",
        "tanh" => "tanhf",
        "pow" => "powf",
        "atan2" => "atan2f",
        "sincos" => "sincosf",
        other => other,
    }
}
